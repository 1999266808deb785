// camera_rays.h: the primary rays of a camera (DESIGN.md §6-7), made where they are traced, readable as C++ and
// GLSL. The host fills one CameraRays record (compute/shared/trace_rays.h) a frame; the trace shader makes each
// pixel's ray from it on the device (nothing per ray is uploaded), and the CPU makes the very same rays with the
// same operations, so both backends trace bit-identical rays and the G-buffer resolve can make them again on
// the host.
#ifndef VOXSHADOW_CAMERA_RAYS_H
#define VOXSHADOW_CAMERA_RAYS_H

#include "compute/shared/lanes.h"
#include "compute/shared/trace_rays.h"

VS_NAMESPACE_BEGIN

// The ray of pixel `pixel` (row-major, row 0 at the top): from the camera through the pixel's centre, unit
// direction, t from the near plane to the far plane (clipped as a rasteriser clips, so that whatever the camera
// sees lies in one of the cascades, whose splits start at `near`). Only operations that round correctly on
// every device (VS_DIV, VS_SQRT, no contraction), so both backends make the same bits.
VS_LANE_INLINE TraceRay vsCameraRay(CameraRays camera, uint pixel) {
  uint x = pixel % camera.size.x;
  uint y = pixel / camera.size.x;
  VS_PRECISE float sx = (VS_DIV(float(x) + 0.5f, float(camera.size.x)) * 2.0f - 1.0f) * camera.originHigh.w;
  VS_PRECISE float sy = (1.0f - VS_DIV(float(y) + 0.5f, float(camera.size.y)) * 2.0f) * camera.originLow.w;
  VS_PRECISE vec3 d = vec3(camera.forward) + vec3(camera.right) * sx + vec3(camera.up) * sy;
  VS_PRECISE float len = VS_SQRT(d.x * d.x + d.y * d.y + d.z * d.z);
  VS_PRECISE vec3 u = vec3(VS_DIV(d.x, len), VS_DIV(d.y, len), VS_DIV(d.z, len));
  VS_PRECISE float along = u.x * camera.forward.x + u.y * camera.forward.y + u.z * camera.forward.z;
  TraceRay ray;
  ray.originHigh = vec4(vec3(camera.originHigh), VS_DIV(camera.forward.w, along));
  ray.originLow = vec4(vec3(camera.originLow), VS_DIV(camera.right.w, along));
  ray.direction = vec4(u, 0.0f);
  return ray;
}

VS_NAMESPACE_END

#endif
