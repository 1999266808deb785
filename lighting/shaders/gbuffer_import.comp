// gbuffer_import.comp: a host engine's G-buffer images into the lighting pass's G-buffer and the visibility rays'
// receivers (lighting/shared/gbuffer_import.h), one invocation per pixel: the frame is then lit, and its contact
// rays traced, from the host's surfaces without a primary ray of the library's.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/portable.h"
#include "compute/shared/trace_rays.h"
#include "lighting/shared/shading_layout.h"
#include "lighting/shared/lighting_interface.h"
#include "lighting/shared/gbuffer_import.h"
#include "lighting/shared/gbuffer_resolve.h"

layout(local_size_x = VS_IMPORT_GROUP_WIDTH, local_size_y = VS_IMPORT_GROUP_HEIGHT, local_size_z = 1) in;

layout(set = 0, binding = VS_IMPORT_BINDING_DEPTH) uniform sampler2D hostDepth;
layout(set = 0, binding = VS_IMPORT_BINDING_NORMAL) uniform sampler2D hostNormal;
layout(set = 0, binding = VS_IMPORT_BINDING_ALBEDO) uniform sampler2D hostAlbedo;
layout(std430, set = 0, binding = VS_IMPORT_BINDING_RECORD) readonly buffer RecordBlock { HostGBufferRecord record; };
layout(std430, set = 0, binding = VS_IMPORT_BINDING_GBUFFER) writeonly buffer GBufferBlock { GBufferTexel gbuffer[]; };
layout(std430, set = 0, binding = VS_IMPORT_BINDING_RECEIVERS) writeonly buffer ReceiverBlock { VisibilityReceiver receivers[]; };

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (uint(p.x) >= record.info.x || uint(p.y) >= record.info.y) return;
  uint pixel = uint(p.y) * record.info.x + uint(p.x);
  float depth = texelFetch(hostDepth, p, 0).r;
  vec4 normal = texelFetch(hostNormal, p, 0);
  vec4 albedo = texelFetch(hostAlbedo, p, 0);
  GBufferTexel texel = vsImportTexel(record, pixel, depth, normal, albedo);
  gbuffer[pixel] = texel;
  receivers[pixel] = vsReceiverOf(texel);
}
