// gbuffer_resolve.comp: a camera trace's closest hits into the lighting pass's G-buffer, on the device that traced
// them (lighting/shared/gbuffer_resolve.h, the function the CPU resolve runs): one invocation per hit, written at
// its pixel with its visibility receiver, so neither crosses from the host to the lighting pass or the
// visibility rays.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/portable.h"
#include "compute/shared/trace_rays.h"
#include "lighting/shared/shading_layout.h"
#include "lighting/shared/lighting_interface.h"
#include "lighting/shared/gbuffer_resolve.h"

layout(local_size_x = VS_RESOLVE_GROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = VS_RESOLVE_BINDING_HITS) readonly buffer HitBlock { RayHit hits[]; };
// The trace's listed pixels (the camera record comes in the push block).
layout(std430, set = 0, binding = VS_RESOLVE_BINDING_CAMERA) readonly buffer CameraBlock { uint cameraPixels[]; };
layout(std430, set = 0, binding = VS_RESOLVE_BINDING_INSTANCES) readonly buffer InstanceBlock { GBufferInstance instances[]; };
layout(std430, set = 0, binding = VS_RESOLVE_BINDING_PALETTE) readonly buffer PaletteBlock { vec4 palette[]; };
layout(std430, set = 0, binding = VS_RESOLVE_BINDING_GBUFFER) writeonly buffer GBufferBlock { GBufferTexel gbuffer[]; };
layout(std430, set = 0, binding = VS_RESOLVE_BINDING_RECEIVERS) writeonly buffer ReceiverBlock { VisibilityReceiver receivers[]; };

layout(push_constant) uniform PushBlock { ResolvePush push; };

void main() {
  // Rows of workgroups along y where a frame has more than maxComputeWorkGroupCount[0] of them.
  uint index = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * VS_RESOLVE_GROUP_SIZE + gl_LocalInvocationID.x;
  if (index >= push.counts.x) return;
  uint pixel = push.camera.size.z == 0u ? index : cameraPixels[index];
  RayHit h = hits[index];
  GBufferTexel texel;
  // A miss reads no table (a scene without instances has none). The tracer names only instances of the scene it
  // traced; a record past the table (which the host's resolve refuses) would be a miss here rather than a read
  // out of bounds.
  if (h.hit == 0u || h.instance >= push.counts.y) {
    h.hit = 0u;
    texel = vsResolveHit(push.camera, pixel, h, GBufferInstance(vec4[6](vec4(0.0f), vec4(0.0f), vec4(0.0f), vec4(0.0f),
                                                                    vec4(0.0f), vec4(0.0f)), uvec4(0u)), vec3(0.0f));
  } else {
    GBufferInstance inst = instances[h.instance];
    int slot = vsPaletteSlot(inst, h.material);
    vec3 albedo = slot >= 0 ? vec3(palette[slot]) : vec3(VS_MISSING_ALBEDO);
    texel = vsResolveHit(push.camera, pixel, h, inst, albedo);
  }
  gbuffer[pixel] = texel;
  receivers[pixel] = vsReceiverOf(texel);
}
