// gbuffer_resolve.h: a primary ray's closest hit as a G-buffer texel (DESIGN.md §7), readable as C++ and GLSL.
// The CPU resolve (lighting/gbuffer.cpp) and the device's (lighting/shaders/gbuffer_resolve.comp) run this one
// function on the same hit records, so a G-buffer made on the device is the host's bit for bit: only additions
// and multiplications, which round correctly on every device, with no contraction (VS_PRECISE).
#ifndef VOXSHADOW_GBUFFER_RESOLVE_H
#define VOXSHADOW_GBUFFER_RESOLVE_H

#include "compute/shared/camera_rays.h"
#include "lighting/shared/shading_layout.h"

VS_NAMESPACE_BEGIN

// Where the albedo of a hit's material is in the frame's palette array: -1 when the instance's palette has no
// such colour (the texel then gets VS_MISSING_ALBEDO).
VS_LANE_INLINE int vsPaletteSlot(GBufferInstance inst, uint material) {
  return material < inst.palette.y ? int(inst.palette.x + material) : -1;
}
const float VS_MISSING_ALBEDO = 0.8f;

// The texel of pixel `pixel`, whose primary ray (vsCameraRay(camera, pixel), made again here) had closest hit
// `h` on instance `inst`; `albedo` is the colour at vsPaletteSlot. Position: the ray's origin (two floats) plus
// t along its unit direction; view depth: t times the direction's share of the camera's forward axis (the ray
// starts at the eye). A hit without an entry face (the ray started inside a voxel) faces back along the ray.
VS_LANE_INLINE GBufferTexel vsResolveHit(CameraRays camera, uint pixel, RayHit h, GBufferInstance inst, vec3 albedo) {
  GBufferTexel texel;
  texel.position = vec4(0.0f);
  texel.normal = vec4(0.0f);
  texel.albedo = vec4(0.0f);
  texel.info = uvec4(0u);
  if (h.hit == 0u) return texel;
  TraceRay ray = vsCameraRay(camera, pixel);
  VS_PRECISE vec3 d = vec3(ray.direction);
  VS_PRECISE vec3 along = d * h.t + vec3(ray.originLow);
  VS_PRECISE vec3 p = vec3(ray.originHigh) + along;
  VS_PRECISE float forwardShare = d.x * camera.forward.x + d.y * camera.forward.y + d.z * camera.forward.z;
  VS_PRECISE float viewDepth = h.t * forwardShare;
  uint face = uint(h.voxel.w);
  texel.position = vec4(p, viewDepth);
  vec4 faceNormal = inst.faceNormals[face < 6u ? face : 0u];
  texel.normal = vec4(face < 6u ? vec3(faceNormal) : -d, faceNormal.w);
  texel.albedo = vec4(albedo, 1.0f);
  texel.info = uvec4(h.instance, h.material, face, 1u);
  return texel;
}

// A texel as the receiver of visibility rays (compute/shared/visibility_rays.h): its rays start off its face by
// a thousandth of its voxel; a texel without a hit receives none.
VS_LANE_INLINE VisibilityReceiver vsReceiverOf(GBufferTexel texel) {
  VisibilityReceiver r;
  r.position = vec4(0.0f);
  r.normal = vec4(0.0f);
  if (texel.info.w == 0u) return r;
  VS_PRECISE float offset = 1e-3f * texel.normal.w;
  r.position = vec4(vec3(texel.position), offset);
  r.normal = vec4(vec3(texel.normal), 1.0f);
  return r;
}

VS_NAMESPACE_END

#endif
