// gbuffer_import.h: a host engine's G-buffer pixel (its depth, normal and albedo) as the lighting pass's G-buffer
// texel, readable as C++ and GLSL (the import pass, lighting/shaders/gbuffer_import.comp; its tests compute the
// same texels on the host). The conventions are Vulkan's (README "Embedding in an engine", the host's G-buffer):
// row 0 at the top at NDC y = -1, depth after the perspective divide as the host's viewport wrote it, the
// host's projection mapping view space to clip space; reversed or infinite depth is the projection's business.
#ifndef VOXSHADOW_GBUFFER_IMPORT_H
#define VOXSHADOW_GBUFFER_IMPORT_H

#include "compute/shared/lanes.h"
#include "lighting/shared/shading_layout.h"

VS_NAMESPACE_BEGIN

// The texel of pixel `pixel` (row-major) whose depth image holds `depth`, normal image `normalSample` and albedo
// image `albedoSample` (read where record.info.w has VS_HOST_GBUFFER_ALBEDO). A pixel at the sky's depth is a
// miss (a texel of zeros, as vsResolveHit gives a ray that hit nothing). Position: the eye (two floats) plus the
// view position unprojected from the pixel's centre and depth, turned into the world; view depth: the view
// position along the camera's forward axis (the cascade choice); normal: unit, in the world, w the receivers'
// voxel size (their contact rays' start, vsReceiverOf). The texel names no instance, material or face
// (info.x, y, z all ones): the host's surfaces need not be voxels.
VS_LANE_INLINE GBufferTexel vsImportTexel(HostGBufferRecord record, uint pixel, float depth, vec4 normalSample,
                                          vec4 albedoSample) {
  GBufferTexel texel;
  texel.position = vec4(0.0f);
  texel.normal = vec4(0.0f);
  texel.albedo = vec4(0.0f);
  texel.info = uvec4(0u);
  if (depth == record.eyeLow.w) return texel;
  uint width = record.info.x;
  uint x = pixel % width;
  uint y = pixel / width;
  VS_PRECISE vec4 ndc = vec4((float(x) + 0.5f) / float(width) * 2.0f - 1.0f,
                             (float(y) + 0.5f) / float(record.info.y) * 2.0f - 1.0f, depth, 1.0f);
  VS_PRECISE vec4 view = record.clipToView * ndc;
  VS_PRECISE vec3 viewPosition = vec3(view) / view.w;
  VS_PRECISE vec3 turned = vec3(record.viewToWorld * vec4(viewPosition, 0.0f));
  VS_PRECISE vec3 p = vec3(record.eyeHigh) + (turned + vec3(record.eyeLow));
  VS_PRECISE float viewDepth = dot(viewPosition, vec3(record.forward));
  vec3 n = vec3(normalSample);
  if (record.info.z == VS_HOST_NORMAL_UNSIGNED) n = n * 2.0f - vec3(1.0f);
  if ((record.info.w & VS_HOST_GBUFFER_VIEW_NORMALS) != 0u) n = vec3(record.viewToWorld * vec4(n, 0.0f));
  n = n * inversesqrt(max(dot(n, n), 1e-30f));
  texel.position = vec4(p, viewDepth);
  texel.normal = vec4(n, record.eyeHigh.w);
  texel.albedo = (record.info.w & VS_HOST_GBUFFER_ALBEDO) != 0u ? vec4(vec3(albedoSample), 1.0f) : vec4(1.0f);
  texel.info = uvec4(0xffffffffu, 0xffffffffu, 0xffffffffu, 1u);
  return texel;
}

VS_NAMESPACE_END

#endif
