// shading_layout.h: the records of the deferred lighting pass (DESIGN.md §7), readable as C++ and GLSL: a
// G-buffer texel, a light as the pass shades it, a shadow layer as the pass samples it, and the pass's push
// block. lighting/shared/shading.h is the arithmetic over them, compiled for the shader and for the CPU.
#ifndef VOXSHADOW_SHADING_LAYOUT_H
#define VOXSHADOW_SHADING_LAYOUT_H

#include "compute/shared/trace_rays.h"
#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// ShadeLight.info.x
const int VS_LIGHT_DIRECTIONAL = 0;
const int VS_LIGHT_SPOT = 1;
const int VS_LIGHT_POINT = 2;

// ShadeLight.info.y: the shadow filter; VS_FILTER_NONE for a light without shadow views.
const int VS_FILTER_NONE = -1;
const int VS_FILTER_HARD = 0;
const int VS_FILTER_PCF3 = 1;
const int VS_FILTER_PCF5 = 2;
const int VS_FILTER_POISSON16 = 3;
const int VS_FILTER_PCSS = 4;
const int VS_FILTER_EVSM = 5;  // exponential variance shadow maps: the layer's moments (lighting/shared/evsm.h)

// How the lighting pass compares a receiver with a shadow texel (shading.h, VsReceiver.plane): against the
// receiver's own depth (layers of voxel-centre depths); against its plane at the texel's own ray, rebuilt per
// texel (perspective views: their rays fan out); against its plane through the affine form that an
// orthographic view's parallel rays give (vsPlaneSlope).
const int VS_RECEIVER_DEPTH = 0;
const int VS_RECEIVER_PLANE = 1;
const int VS_RECEIVER_PLANE_AFFINE = 2;

// ShadePush.mode: what the pass writes.
const int VS_SHADE_LIT = 0;             // ambient + lights, linear HDR
const int VS_SHADE_DEBUG_CASCADES = 1;  // the lit image tinted by the first directional light's cascade
const int VS_SHADE_DEBUG_SHADOW = 2;    // the shadow term of each pixel (the mean over its lights), grey
const int VS_SHADE_DEBUG_NORMALS = 3;   // the normal, as 0.5 + 0.5 n

// Widest filter kernels, in texels from the centre: pcf5 reaches 2, poisson16's disc 2.5, pcss at most
// VS_PCSS_MAX_RADIUS. A cascade is chosen for a pixel only when the kernel stays inside its layer (the
// lateral check), so that no sample falls off the layer's edge.
const float VS_POISSON_RADIUS = 2.5f;
const float VS_PCSS_MAX_RADIUS = 8.0f;
// N.L below which the slope-scaled bias stops growing: at grazing light it would otherwise push the
// receiver past its casters.
const float VS_MIN_SLOPE_COSINE = 0.05f;

// One pixel of the G-buffer, from the camera's primary ray (lighting/gbuffer.h).
struct GBufferTexel {
  vec4 position;  // xyz: world position of the hit (the entry point); w: linear view depth, 0 on a miss
  vec4 normal;    // xyz: unit world normal of the entry face; w: the world size of the hit voxel
  vec4 albedo;    // rgb: the voxel's palette colour (linear); a: 1 on a hit, 0 on a miss
  uvec4 info;     // x: instance index; y: palette index; z: entry face (VS_FACE_*); w: 1 on a hit
};

// What the G-buffer resolve (lighting/shared/gbuffer_resolve.h) needs of an instance: its six faces' unit world
// normals (VS_FACE_* order; w of each: the voxel's world size), and where its object's palette starts in the
// frame's palette array and how many colours it has.
struct GBufferInstance {
  vec4 faceNormals[6];
  uvec4 palette;  // x: first colour; y: colour count; zw: 0
};

// The spread of visibility answers into the pass's answers per pixel and light
// (lighting/shaders/visibility_spread.comp).
struct SpreadPush {
  uvec4 counts;  // x: receivers traced; y: lights traced toward; z: the frame's lights; w: the first word of the
                 // receivers' pixel list in the trace's source buffer (0: receiver k is pixel k)
};

// The device resolve's push block (lighting/shaders/gbuffer_resolve.comp). The camera record comes here rather
// than from the trace's buffer: llvmpipe loads a storage buffer's members lane by lane even at an offset that
// every invocation shares, and those loads were half of the resolve's time; a push constant is one scalar load.
// 128 bytes, the size every Vulkan device allows.
struct ResolvePush {
  CameraRays camera;  // the trace's record (VulkanTracer::lastCameraTrace)
  uvec4 counts;       // x: hits to resolve; y: instance records; zw: 0
};

// A host engine's G-buffer as the import pass reads it (lighting/shared/gbuffer_import.h,
// lighting/shaders/gbuffer_import.comp): its matrices inverted in double on the host (lighting/host_gbuffer.h).
struct HostGBufferRecord {
  mat4 clipToView;   // the inverse of the host's view-to-clip projection
  mat4 viewToWorld;  // the rotation of the host's view-to-world map (the eye's position is not in it)
  vec4 eyeHigh;      // xyz: the eye's world position rounded to float; w: the receivers' world voxel size
  vec4 eyeLow;       // xyz: what the rounding left; w: the depth value of a pixel with no surface (the sky)
  vec4 forward;      // xyz: the camera's unit forward axis in view space (view depth = dot(view position, it))
  uvec4 info;        // x, y: width, height; z: VS_HOST_NORMAL_*; w: VS_HOST_GBUFFER_* flags
};
// How the host's normal image holds a unit normal: as it is, or n * 0.5 + 0.5 (an unsigned normalised format).
const uint VS_HOST_NORMAL_SIGNED = 0u;
const uint VS_HOST_NORMAL_UNSIGNED = 1u;
const uint VS_HOST_GBUFFER_VIEW_NORMALS = 1u;  // normals in view space, else world space
const uint VS_HOST_GBUFFER_ALBEDO = 2u;        // an albedo image is bound, else albedo is white

// A light as the pass shades it.
struct ShadeLight {
  vec4 color;      // rgb: colour x intensity; w: 0
  vec4 position;   // xyz: spot and point position; w: range (spot, point)
  vec4 direction;  // xyz: unit direction the light travels (directional, spot); w: cos of the outer cone
  vec4 bias;       // x: constant (world, along L); y: normal offset (texels); z: slope (texels / max(N.L, 0.05));
                   // w: pcss light size (world)
  vec4 extra;      // x: cos of the inner cone; y: contact-shadow length (world, 0: off); z: cascade blend band
                   // (share of each cascade's depth range); w: 0
  ivec4 info;      // x: VS_LIGHT_*; y: VS_FILTER_*; z: its first ShadeView; w: its view count
  vec4 evsm;       // VS_FILTER_EVSM: x, y: the positive and negative warp exponents; z: the light-bleeding
                   // reduction (0..1); w: the blur radius (texels); 0 for other filters
};

// A shadow layer as the pass samples it. The texel rays are rebuilt exactly as the trace kernels built them
// (clipToEye and the split eye of the layer's TraceView), so that a receiver's plane can be met by the very
// ray whose depth a texel stores (vsReceiverPlaneDepth).
// The lighting shader reads ShadeView records through a uniform texel buffer of 16-byte RGBA32UI texels
// (lighting/shaders/deferred_lighting.comp, vsLoadView): a CPU device (llvmpipe) loads a storage buffer one
// lane at a time, a texel fetch as one gather. Each record is this many texels.
const int VS_SHADE_VIEW_TEXELS = 13;
// The texel of a ShadeView record that holds each member (a mat4: its four columns from that texel on), as the
// shader's vsLoadView reads them; the C++ side checks each against the member's offset.
const int VS_SHADE_VIEW_TEXEL_EYE_TO_CLIP = 0;
const int VS_SHADE_VIEW_TEXEL_CLIP_TO_EYE = 4;
const int VS_SHADE_VIEW_TEXEL_EYE = 8;
const int VS_SHADE_VIEW_TEXEL_EYE_LOW = 9;
const int VS_SHADE_VIEW_TEXEL_SPLIT = 10;
const int VS_SHADE_VIEW_TEXEL_INFO = 11;
const int VS_SHADE_VIEW_TEXEL_TRACE = 12;

struct ShadeView {
  mat4 eyeToClip;  // clip = eyeToClip * (p - eye): the view-projection about its eye
  mat4 clipToEye;  // its inverse, inverted in double: the TraceView's
  vec4 eye;        // xyz: the eye of the layer's rays rounded to float, the TraceView's eyeHigh (spot, point: the
                   // light); w: the world size of a texel (directional), or of a texel at unit distance (spot,
                   // point)
  vec4 eyeLow;     // xyz: the rest of the eye (TraceView eyeLow); w: 1 / the miss value: the scale that maps a
                   // stored depth to [0, 1] for EVSM's warp
  vec4 split;      // x, y: the camera view depths a cascade covers; z: the miss value; w: world units per unit
                   // of the encoded depth (pcss)
  ivec4 info;      // x: the layer's first texel in the layer buffer; y: its width (= height); z: VS_ENCODING_*;
                   // w: the cascade index, -1 for other views
  ivec4 trace;     // x: VS_DEPTH_POINT_* of the stored depths; y, z: where window texel (0, 0) is stored (a
                   // cascade's ring offset; 0 for other views); w: the layer's first moment texel in the moment
                   // store (an EVSM light's view, stored in the same ring order as its depths), else -1
};

// One EVSM layer as the moment pass reads it (lighting/shared/evsm.h), beside the ShadeView of the same index.
struct EvsmView {
  ivec4 layer;  // x: the first depth texel in the layer store; y: the resolution N; z: the first moment texel
                // (-1: the view has no moments); w: the blur radius r (texels)
  ivec4 place;  // x, y: where window texel (0, 0) is stored (ring offset); z: the first entry of the view's
                // border map (cube faces, evsmBorder), -1 where texels past the window's edge read its edge;
                // w: 0
  vec4 warp;    // x, y: the positive and negative exponents; z: 1 / the miss value; w: 1 / (2r + 1)
};

// A rectangle of one EVSM layer whose moments a moment pass computes: window texels [x0, x1) x [y0, y1).
// The horizontal pass sums rows y0 - r .. y1 + r into the job's scratch; the vertical pass sums those into the
// moments.
struct EvsmJob {
  ivec4 rect;  // x0, y0, x1, y1 (window texels, inside the window)
  ivec4 info;  // x: the EvsmView; y: its first invocation of the horizontal pass; z: of the vertical pass;
               // w: its first scratch texel
};

// The moment pass's push block.
struct EvsmPush {
  ivec4 pass;  // x: 0 horizontal, 1 vertical; y: the job count; z: the pass's invocations; w: invocations a
               // row of the dispatch grid holds
};

// The pass's push block.
struct ShadePush {
  vec4 ambient;  // rgb: ambient colour x intensity; w: 0
  vec4 sky;      // rgb: the colour of pixels that hit nothing; w: 0
  ivec4 size;    // x: width, y: height (pixels); z: light count; w: VS_SHADE_* mode
  // x: 1 where exact visibility rays replace the shadow maps (ray-traced shadows); y: 0 to shade every pixel,
  // else how many pixels the list (VS_LIGHTING_BINDING_PIXELS) names, the only ones shaded (set by the Vulkan
  // pass itself: the colours do not depend on it); zw: 0
  ivec4 flags;
};

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
VS_LAYOUT_CHECK(GBufferTexel, 64);
VS_OFFSET_CHECK(GBufferTexel, normal, 16);
VS_OFFSET_CHECK(GBufferTexel, albedo, 32);
VS_OFFSET_CHECK(GBufferTexel, info, 48);
VS_LAYOUT_CHECK(GBufferInstance, 112);
VS_OFFSET_CHECK(GBufferInstance, palette, 96);
VS_LAYOUT_CHECK(ResolvePush, 112);
VS_OFFSET_CHECK(ResolvePush, counts, 96);
VS_LAYOUT_CHECK(HostGBufferRecord, 192);
VS_OFFSET_CHECK(HostGBufferRecord, viewToWorld, 64);
VS_OFFSET_CHECK(HostGBufferRecord, eyeHigh, 128);
VS_OFFSET_CHECK(HostGBufferRecord, eyeLow, 144);
VS_OFFSET_CHECK(HostGBufferRecord, forward, 160);
VS_OFFSET_CHECK(HostGBufferRecord, info, 176);
VS_LAYOUT_CHECK(SpreadPush, 16);
VS_LAYOUT_CHECK(ShadeLight, 112);
VS_OFFSET_CHECK(ShadeLight, evsm, 96);
VS_LAYOUT_CHECK(EvsmView, 48);
VS_OFFSET_CHECK(EvsmView, place, 16);
VS_OFFSET_CHECK(EvsmView, warp, 32);
VS_LAYOUT_CHECK(EvsmJob, 32);
VS_OFFSET_CHECK(EvsmJob, info, 16);
VS_LAYOUT_CHECK(EvsmPush, 16);
VS_OFFSET_CHECK(ShadeLight, position, 16);
VS_OFFSET_CHECK(ShadeLight, direction, 32);
VS_OFFSET_CHECK(ShadeLight, bias, 48);
VS_OFFSET_CHECK(ShadeLight, extra, 64);
VS_OFFSET_CHECK(ShadeLight, info, 80);
VS_LAYOUT_CHECK(ShadeView, 208);
static_assert(sizeof(ShadeView) == VS_SHADE_VIEW_TEXELS * 16, "a ShadeView is VS_SHADE_VIEW_TEXELS 16-byte texels");
VS_OFFSET_CHECK(ShadeView, clipToEye, 64);
VS_OFFSET_CHECK(ShadeView, eye, 128);
VS_OFFSET_CHECK(ShadeView, eyeLow, 144);
VS_OFFSET_CHECK(ShadeView, split, 160);
VS_OFFSET_CHECK(ShadeView, info, 176);
VS_OFFSET_CHECK(ShadeView, trace, 192);
static_assert(offsetof(ShadeView, eyeToClip) == 16 * VS_SHADE_VIEW_TEXEL_EYE_TO_CLIP &&
                  offsetof(ShadeView, clipToEye) == 16 * VS_SHADE_VIEW_TEXEL_CLIP_TO_EYE &&
                  offsetof(ShadeView, eye) == 16 * VS_SHADE_VIEW_TEXEL_EYE &&
                  offsetof(ShadeView, eyeLow) == 16 * VS_SHADE_VIEW_TEXEL_EYE_LOW &&
                  offsetof(ShadeView, split) == 16 * VS_SHADE_VIEW_TEXEL_SPLIT &&
                  offsetof(ShadeView, info) == 16 * VS_SHADE_VIEW_TEXEL_INFO &&
                  offsetof(ShadeView, trace) == 16 * VS_SHADE_VIEW_TEXEL_TRACE &&
                  VS_SHADE_VIEW_TEXEL_TRACE + 1 == VS_SHADE_VIEW_TEXELS,
              "ShadeView: the texel of each member, as vsLoadView reads the record");
VS_LAYOUT_CHECK(ShadePush, 64);
VS_OFFSET_CHECK(ShadePush, sky, 16);
VS_OFFSET_CHECK(ShadePush, size, 32);
VS_OFFSET_CHECK(ShadePush, flags, 48);
}  // namespace vs::gpu
#endif

#endif
