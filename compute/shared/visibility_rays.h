// visibility_rays.h: the visibility rays of ray-traced and contact shadows (DESIGN.md §6-7), from a surface point
// toward a light, made where they are traced, readable as C++ and GLSL. The host fills one receiver per pixel
// and one record per light (compute/shared/trace_rays.h); the trace shader makes each (receiver, light) ray on
// the device, and the CPU and the lighting's change tracking make the very same rays with the same operations.
//
// The arithmetic is in double, as the host's was before the rays moved to the device: additions,
// multiplications, divisions and square roots, none of them contracted (`precise`), each correctly rounded
// wherever the device's doubles are IEEE (as lavapipe's and the GPUs' are; the camera rays' VS_DIV relies on the
// same), then rounded to the ray's floats once.
#ifndef VOXSHADOW_VISIBILITY_RAYS_H
#define VOXSHADOW_VISIBILITY_RAYS_H

#include "compute/shared/lanes.h"
#include "compute/shared/trace_rays.h"

VS_NAMESPACE_BEGIN

#ifdef VS_GLSL
#define VS_DOUBLE_TO_FLOAT3(v) vec3(v)
#else
// The host's guaranteed rounding (voxel/portable.h): the vectorizer once kept a conversion at double precision.
#define VS_DOUBLE_TO_FLOAT3(v) roundedToFloat(v)
#endif

// A light's reach for its rays (VisibilityLight.kind.y), relative: wide enough that the lighting pass's float
// distance to the light, from the same floats, cannot fall within the range where the rays' double one
// exceeds it by this much. The pass gives a receiver beyond the range shadow term 1 without reading its ray
// (lighting/shared/shadow_lookup.h, vsShadowTerm), so a ray skipped there changes no term.
const double VS_VISIBILITY_REACH_MARGIN = double(1.0e-4f);

// The ray that answers nothing: tMax < tMin, which every tracer reports clear.
VS_LANE_INLINE TraceRay vsEmptyVisibilityRay() {
  TraceRay ray;
  ray.originHigh = vec4(0.0f, 0.0f, 0.0f, 1.0f);
  ray.originLow = vec4(0.0f, 0.0f, 0.0f, 0.0f);
  ray.direction = vec4(0.0f, 1.0f, 0.0f, 0.0f);
  return ray;
}

// Where o + t d leaves the box [lo, hi] (t >= 0), by slabs in double; 0 for an empty box (lo > hi on an axis).
VS_LANE_INLINE double vsExitDistance(dvec3 o, dvec3 d, dvec3 lo, dvec3 hi) {
  if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z) return double(0.0f);
  bool found = false;
  double exit = double(0.0f);
  for (int a = 0; a < 3; ++a) {
    if (d[a] == double(0.0f)) continue;
    VS_PRECISE double t0 = (lo[a] - o[a]) / d[a];
    VS_PRECISE double t1 = (hi[a] - o[a]) / d[a];
    double far = t0 > t1 ? t0 : t1;
    exit = found && exit < far ? exit : far;
    found = true;
  }
  return exit > double(0.0f) ? exit : double(0.0f);
}

// Receiver `r`'s ray toward `light`: from the surface point moved off its face by r.position.w along the
// normal, toward the light's position (ending there) or along the unit vector toward it (ending where it leaves
// the record's world box), cut to the light's longest ray when that is > 0. The empty ray (vsEmptyVisibilityRay)
// where the receiver has no surface, the light needs no ray, the receiver's surface point lies beyond the
// light's range (kind.y, with VS_VISIBILITY_REACH_MARGIN), the start is the light's position, or the surface
// faces away from the light.
VS_LANE_INLINE TraceRay vsVisibilityRay(VisibilityRays frame, VisibilityLight light, VisibilityReceiver r) {
  if (r.normal.w == 0.0f || light.target.w == 0.0f) return vsEmptyVisibilityRay();
  if (light.kind.x == VS_VISIBILITY_TOWARD_POINT && light.kind.y > 0.0f) {
    VS_PRECISE dvec3 fromLight = dvec3(vec3(r.position)) - dvec3(vec3(light.target));
    VS_PRECISE double distance = sqrt(fromLight.x * fromLight.x + fromLight.y * fromLight.y + fromLight.z * fromLight.z);
    VS_PRECISE double reach = double(light.kind.y) * (double(1.0f) + VS_VISIBILITY_REACH_MARGIN);
    if (distance > reach) return vsEmptyVisibilityRay();
  }
  VS_PRECISE dvec3 n = dvec3(vec3(r.normal));
  VS_PRECISE dvec3 origin = dvec3(vec3(r.position)) + n * double(r.position.w);
  VS_PRECISE dvec3 toLight = dvec3(vec3(light.target));
  VS_PRECISE double length = double(0.0f);
  if (light.kind.x == VS_VISIBILITY_TOWARD_DIRECTION) {
    length = vsExitDistance(origin, toLight, dvec3(vec3(frame.boundsMin)), dvec3(vec3(frame.boundsMax)));
  } else {
    VS_PRECISE dvec3 d = toLight - origin;
    length = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (!(length > double(0.0f))) return vsEmptyVisibilityRay();
    toLight = dvec3(d.x / length, d.y / length, d.z / length);
  }
  VS_PRECISE double facing = n.x * toLight.x + n.y * toLight.y + n.z * toLight.z;
  if (!(facing > double(0.0f))) return vsEmptyVisibilityRay();
  if (light.target.w > 0.0f && double(light.target.w) < length) length = double(light.target.w);
  vec3 high = VS_DOUBLE_TO_FLOAT3(origin);
  TraceRay ray;
  ray.originHigh = vec4(high, 0.0f);
  ray.originLow = vec4(vec3(origin - dvec3(high)), float(length));
  ray.direction = vec4(vec3(toLight), 0.0f);
  return ray;
}

#undef VS_DOUBLE_TO_FLOAT3

VS_NAMESPACE_END

#endif
