// trace_rays.h: the records of the ray kinds besides the shadow texel (DESIGN.md §6), readable as C++ and
// GLSL: a ray given by its caller, the closest-hit record, a camera whose primary rays are made where they are
// traced (compute/shared/camera_rays.h), and the receivers and lights that visibility rays are made from
// (compute/shared/visibility_rays.h). Any-hit rays read the same TraceRay and answer one word (1: some solid
// voxel lies in [tMin, tMax]).
#ifndef VOXSHADOW_TRACE_RAYS_H
#define VOXSHADOW_TRACE_RAYS_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// The face of its voxel through which a ray entered, in the object's brick space, named by the face's outward
// normal: a ray moving toward +x enters through the voxel's -x face (VS_FACE_NEG_X). VS_FACE_NONE: the ray
// started inside the voxel.
const uint VS_FACE_NEG_X = 0u;
const uint VS_FACE_POS_X = 1u;
const uint VS_FACE_NEG_Y = 2u;
const uint VS_FACE_POS_Y = 3u;
const uint VS_FACE_NEG_Z = 4u;
const uint VS_FACE_POS_Z = 5u;
const uint VS_FACE_NONE = 6u;

// A ray origin + t * direction, t in [tMin, tMax]. The origin is two floats whose sum holds it to about 48 bits
// (as a view's eye), so that a ray keeps its precision far from the world origin.
struct TraceRay {
  vec4 originHigh;  // xyz: the origin rounded to float; w: tMin
  vec4 originLow;   // xyz: origin - originHigh, rounded; w: tMax
  vec4 direction;   // xyz: the direction (t is measured in its length); w: 0
};

// The closest hit of a TraceRay. On a miss: hit 0, t the ray's tMax, everything else 0.
struct RayHit {
  ivec4 voxel;    // xyz: the hit voxel in its object's brick space; w: the entry face (VS_FACE_*)
  float t;        // where the ray enters the voxel
  uint instance;  // the instance's index in the scene
  uint material;  // the voxel's palette index (1..255)
  uint hit;       // 1 on a hit
};

// Visibility rays (toward the lights, from surface points): one any-hit ray per receiver and light, made where
// it is traced (compute/shared/visibility_rays.h), so that a frame uploads a receiver per pixel instead of a
// TraceRay per pixel and light. A trace reads this record, then its lights, then its receivers; ray
// k * counts.x + l is receiver k's ray toward light l. Every member is 16-byte aligned (std140 = std430).
struct VisibilityRays {
  vec4 boundsMin;  // xyz: the world box out of which rays toward a direction end; w: 0
  vec4 boundsMax;  // xyz; w: 0
  uvec4 counts;    // x: lights, y: receivers; z: 0 when the receivers follow the lights in the trace's buffer, 1
                   // when they are the device's (one per pixel, VS_BINDING_RECEIVERS); w: with z = 1, 1 when the
                   // buffer lists the receivers' pixels after the lights (else receiver k is pixel k)
};

// The record and a light in 4-byte words: where a trace's listed pixels start in its buffer.
const uint VS_VISIBILITY_RECORD_WORDS = 12u;
const uint VS_VISIBILITY_LIGHT_WORDS = 8u;

const float VS_VISIBILITY_TOWARD_POINT = 0.0f;      // the ray ends at the light's position
const float VS_VISIBILITY_TOWARD_DIRECTION = 1.0f;  // the ray leaves the world box along a direction

struct VisibilityLight {
  vec4 target;  // xyz: the light's position, or the unit vector toward it; w: the longest ray (< 0: unbounded,
                // 0: the light needs no ray)
  vec4 kind;    // x: VS_VISIBILITY_TOWARD_POINT or VS_VISIBILITY_TOWARD_DIRECTION; y: toward a point, the
                // light's range (> 0: a receiver farther from it than the range by VS_VISIBILITY_REACH_MARGIN,
                // compute/shared/visibility_rays.h, gets no ray; 0: every receiver gets one); zw: 0
};

struct VisibilityReceiver {
  vec4 position;  // xyz: the surface point; w: how far off its face (along the normal) the rays start
  vec4 normal;    // xyz: the unit face normal; w: 1 for a surface, 0 for none (its rays are empty)
};

// A camera's pixel rays, eye-relative: the camera position in two floats (as a view's eye, DESIGN.md §6), its
// unit basis in float, and the frame's size. Every member is 16-byte aligned, so std140 and std430 agree.
struct CameraRays {
  vec4 originHigh;  // xyz: the camera position rounded to float; w: tan(vertical half angle) * aspect
  vec4 originLow;   // xyz: position - originHigh, rounded; w: tan(vertical half angle)
  vec4 forward;     // xyz: unit, toward the target; w: the near plane's distance
  vec4 right;       // xyz: unit; w: the far plane's distance
  vec4 up;          // xyz: unit, orthogonal to forward and right; w: 0
  uvec4 size;       // x: width, y: height (pixels), z: listed pixels (0: every pixel, row-major), w: 0
};

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
// A ray from an origin in double: the origin is split into two floats before any rounding.
static inline TraceRay makeTraceRay(const glm::dvec3& origin, const glm::dvec3& direction, float tMin, float tMax) {
  TraceRay ray{};
  glm::vec3 high, low;
  splitToFloats(origin, high, low);
  ray.originHigh = glm::vec4(high, tMin);
  ray.originLow = glm::vec4(low, tMax);
  ray.direction = glm::vec4(glm::vec3(direction), 0.0f);
  return ray;
}

VS_LAYOUT_CHECK(TraceRay, 48);
VS_OFFSET_CHECK(TraceRay, originLow, 16);
VS_OFFSET_CHECK(TraceRay, direction, 32);
VS_LAYOUT_CHECK(RayHit, 32);
VS_OFFSET_CHECK(RayHit, t, 16);
VS_OFFSET_CHECK(RayHit, instance, 20);
VS_OFFSET_CHECK(RayHit, material, 24);
VS_OFFSET_CHECK(RayHit, hit, 28);
VS_LAYOUT_CHECK(CameraRays, 96);
VS_OFFSET_CHECK(CameraRays, originLow, 16);
VS_OFFSET_CHECK(CameraRays, forward, 32);
VS_OFFSET_CHECK(CameraRays, right, 48);
VS_OFFSET_CHECK(CameraRays, up, 64);
VS_OFFSET_CHECK(CameraRays, size, 80);
VS_LAYOUT_CHECK(VisibilityRays, 48);
VS_OFFSET_CHECK(VisibilityRays, boundsMax, 16);
VS_OFFSET_CHECK(VisibilityRays, counts, 32);
VS_LAYOUT_CHECK(VisibilityLight, 32);
static_assert(sizeof(VisibilityRays) == 4 * VS_VISIBILITY_RECORD_WORDS &&
                  sizeof(VisibilityLight) == 4 * VS_VISIBILITY_LIGHT_WORDS,
              "VS_VISIBILITY_*_WORDS: the record's and a light's size in words");
VS_OFFSET_CHECK(VisibilityLight, kind, 16);
VS_LAYOUT_CHECK(VisibilityReceiver, 32);
VS_OFFSET_CHECK(VisibilityReceiver, normal, 16);
}  // namespace vs::gpu
#endif

#endif
