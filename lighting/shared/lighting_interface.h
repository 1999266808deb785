// lighting_interface.h: the lighting shader's interface (lighting/shaders/deferred_lighting.comp), readable as
// C++ and GLSL: the workgroup size and the binding numbers, defined once for the shader and the host
// (lighting/vulkan_lighting.cpp).
#ifndef VOXSHADOW_LIGHTING_INTERFACE_H
#define VOXSHADOW_LIGHTING_INTERFACE_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// 8 x 8 pixels per workgroup, as the trace shader: neighbouring pixels read neighbouring shadow texels.
const uint VS_LIGHTING_GROUP_WIDTH = 8u;
const uint VS_LIGHTING_GROUP_HEIGHT = 8u;

// Storage buffers of descriptor set 0 but for VS_LIGHTING_BINDING_VIEWS.
const uint VS_LIGHTING_BINDING_GBUFFER = 0u;        // GBufferTexel per pixel
const uint VS_LIGHTING_BINDING_LIGHTS = 1u;         // ShadeLight per light
// ShadeView per shadow layer, VS_SHADE_VIEW_TEXELS texels each, read as a uniform texel buffer (RGBA32UI).
const uint VS_LIGHTING_BINDING_VIEWS = 2u;
const uint VS_LIGHTING_BINDING_SHADOW_TEXELS = 3u;  // float: every layer, one after another
const uint VS_LIGHTING_BINDING_VISIBILITY = 4u;     // uint per pixel and light
const uint VS_LIGHTING_BINDING_SHADOW_TERMS = 5u;   // float per pixel and light (written)
const uint VS_LIGHTING_BINDING_COLOR = 6u;          // vec4 per pixel (written)
// uint per listed pixel (row-major index): a frame that shades again only the pixels its changes touched runs
// one invocation per listed pixel (ShadePush.flags.y of them) instead of one per pixel of the frame.
const uint VS_LIGHTING_BINDING_PIXELS = 7u;
// EVSM (lighting/shared/evsm.h; the moment pass, lighting/shaders/evsm_moments.comp, shares this set):
// Each moment texel (p, p^2, n, n^2) as two vec2, the positive warp's and the negative's, in two buffers: half
// the bytes per buffer, for devices whose maxStorageBufferRange is 2^27 (lavapipe).
const uint VS_LIGHTING_BINDING_MOMENTS = 8u;      // vec2 (p, p^2) per moment texel (written by the moment pass)
const uint VS_LIGHTING_BINDING_EVSM_VIEWS = 9u;   // EvsmView per ShadeView
const uint VS_LIGHTING_BINDING_EVSM_JOBS = 10u;   // EvsmJob per rectangle of a moment pass
const uint VS_LIGHTING_BINDING_EVSM_BORDER = 11u; // int: cube faces' texels past their edges, as store indices
const uint VS_LIGHTING_BINDING_EVSM_SCRATCH = 12u;// vec2: the horizontal pass's sums, positive warp
const uint VS_LIGHTING_BINDING_MOMENTS_NEGATIVE = 13u;  // vec2 (n, n^2) per moment texel
const uint VS_LIGHTING_BINDING_EVSM_SCRATCH_NEGATIVE = 14u;  // vec2: the horizontal pass's sums, negative warp
const uint VS_LIGHTING_BINDING_COUNT = 15u;

// Specialisation constants of the lighting shader (constant_id values; lighting/lighting_variant.h makes them):
// the frame's light count, debug mode and ray-traced flag, then per light of the first
// VS_LIGHTING_SPECIALIZED_LIGHTS its kind (VS_LIGHT_*), filter (VS_FILTER_*) and view count, so that a variant
// holds only the code its lights run. -1 (each default): not specialised, read from the records.
const uint VS_LIGHTING_SPECIALIZED_LIGHTS = 8u;
const uint VS_LIGHTING_SPEC_LIGHT_COUNT = 0u;
const uint VS_LIGHTING_SPEC_MODE = 1u;
const uint VS_LIGHTING_SPEC_RAYTRACED = 2u;
const uint VS_LIGHTING_SPEC_FIRST_LIGHT = 3u;  // light k: kind at 3 + 3k, filter at 4 + 3k, view count at 5 + 3k
const uint VS_LIGHTING_SPEC_COUNT = 3u + 3u * VS_LIGHTING_SPECIALIZED_LIGHTS;

// The G-buffer resolve (lighting/shaders/gbuffer_resolve.comp), its own descriptor set: a camera trace's hits and
// listed pixels as the tracer left them on the device (compute/shaders/shadow_trace.comp's VS_BINDING_HITS and
// VS_BINDING_CAMERA), the instances' records, the palette, and the lighting pass's G-buffer and the visibility
// rays' receivers (which a visibility trace reads in place: DeviceReceivers), written in place.
const uint VS_RESOLVE_BINDING_HITS = 0u;       // RayHit per traced ray
const uint VS_RESOLVE_BINDING_CAMERA = 1u;     // the listed pixels (ResolvePush.camera.size.z of them; 0: every pixel)
const uint VS_RESOLVE_BINDING_INSTANCES = 2u;  // GBufferInstance per instance
const uint VS_RESOLVE_BINDING_PALETTE = 3u;    // vec4 per colour
const uint VS_RESOLVE_BINDING_GBUFFER = 4u;    // GBufferTexel per pixel (written)
const uint VS_RESOLVE_BINDING_RECEIVERS = 5u;  // VisibilityReceiver per pixel (written: vsReceiverOf the texel)
const uint VS_RESOLVE_BINDING_COUNT = 6u;
const uint VS_RESOLVE_GROUP_SIZE = 64u;

// The spread of a visibility trace's answers (lighting/shaders/visibility_spread.comp), its own set: the trace's
// answers and source buffer as the tracer left them (VS_BINDING_OCCLUDED, VS_BINDING_VISIBILITY), which traced
// light each of the frame's lights is, and the lighting pass's answers per pixel and light, written in place.
const uint VS_SPREAD_BINDING_ANSWERS = 0u;  // uint per ray (receiver by traced light), nonzero where occluded
const uint VS_SPREAD_BINDING_SOURCE = 1u;   // the trace's record, lights and listed pixels, as words
const uint VS_SPREAD_BINDING_SLOTS = 2u;    // int per light of the frame: its traced index, -1 for none
const uint VS_SPREAD_BINDING_VISIBILITY = 3u;  // uint per pixel and light, 1 where clear (written)
const uint VS_SPREAD_BINDING_COUNT = 4u;
const uint VS_SPREAD_GROUP_SIZE = 64u;

// The import of a host engine's G-buffer (lighting/shaders/gbuffer_import.comp), its own set: the host's depth,
// normal and albedo images (combined image samplers whose immutable sampler takes the nearest texel; read with
// texelFetch), the HostGBufferRecord, and the lighting pass's G-buffer and visibility receivers, written in place.
const uint VS_IMPORT_BINDING_DEPTH = 0u;      // sampled image: depth in .r
const uint VS_IMPORT_BINDING_NORMAL = 1u;     // sampled image: normal in .rgb
const uint VS_IMPORT_BINDING_ALBEDO = 2u;     // sampled image: albedo in .rgb (the normal image where none)
const uint VS_IMPORT_BINDING_RECORD = 3u;     // HostGBufferRecord
const uint VS_IMPORT_BINDING_GBUFFER = 4u;    // GBufferTexel per pixel (written)
const uint VS_IMPORT_BINDING_RECEIVERS = 5u;  // VisibilityReceiver per pixel (written: vsReceiverOf the texel)
const uint VS_IMPORT_BINDING_COUNT = 6u;
const uint VS_IMPORT_GROUP_WIDTH = 8u;
const uint VS_IMPORT_GROUP_HEIGHT = 8u;

// The moment pass: 64 invocations a workgroup, over a flat index of its jobs' texels.
const uint VS_EVSM_GROUP_SIZE = 64u;

VS_NAMESPACE_END

#endif
