// trace_view.h: the per-layer descriptor of a shadow trace (DESIGN.md §6), readable as C++ and GLSL.
//
// The record lives with the trace kernels, not in lighting/, because compute/ consumes it and sits below
// lighting/ in the module order; lighting/ fills it from its light views.
#ifndef VOXSHADOW_TRACE_VIEW_H
#define VOXSHADOW_TRACE_VIEW_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// How a layer's texels are encoded (DESIGN.md §2).
const int VS_ENCODING_NDC_DEPTH = 0;        // directional: NDC depth 0..1 of the hit, 1 on a miss
const int VS_ENCODING_LINEAR_DISTANCE = 1;  // spot, point: world distance from the light, range on a miss
const int VS_DEPTH_POINT_ENTRY = 0;         // where the ray enters the hit voxel
const int VS_DEPTH_POINT_VOXEL_CENTER = 1;  // the hit voxel's centre, projected like the entry point

// Larger than any t a trace produces; marks "no hit" in box tests.
const float VS_T_INFINITY = 3.0e38f;

// What one step of an object walk found (compute/shared/traverse.h).
const int VS_WALK_CONTINUE = 0;
const int VS_WALK_HIT = 1;
const int VS_WALK_MISS = 2;

// The box table's codes, one per brick (written by compute/box_table.cpp, read by the CPU lanes and by
// vsObjectWalkBoxes in traverse.h): VS_BOX_FULL for a full brick, the index of its first occupancy word (>= 0;
// in the table's own copy of the occupancy words, on both backends) for a partial one, else
// -1 - box for an empty one, where box holds six extents of
// VS_BOX_EXTENT_BITS bits each (-x, +x, -y, +y, -z, +z, in cells of 2^log2 voxels, from bit 0) and log2 from
// bit VS_BOX_LOG2_SHIFT.
const int VS_BOX_FULL = int(0x80000000u);
const int VS_BOX_EXTENT_BITS = 4;
const int VS_BOX_EXTENT_MASK = 15;
const int VS_BOX_LOG2_SHIFT = 24;

// No voxel coordinate shifted right by a level's log2 reaches this: marks an object walk's cache as empty.
const int VS_NO_CELL = 0x7fffffff;

// Rays are generated eye-relative (DESIGN.md §6): the eye is kept apart, in two floats whose sum holds it to
// about 48 bits, and the texel's NDC point is unprojected through clipToEye, the inverse of the
// view-projection about the eye, inverted in double. A float inverse of viewProj would add the eye's
// translation into every unprojected point and lose the ray's direction to cancellation.
struct TraceView {
  mat4 viewProj;   // world -> clip (for whoever samples the layer; rays never use it)
  mat4 clipToEye;  // clip -> world relative to the eye: inverse(viewProj * translate(eye)), from double
  vec4 eyeHigh;    // xyz: the eye rounded to float (the light, or a directional view's centre); w: range
                   // (the miss value of linear-distance views)
  vec4 eyeLow;     // xyz: eye - eyeHigh, rounded; w: 0
  ivec4 rect;      // texels to trace: x0, y0, x1, y1 (x1, y1 exclusive)
  ivec4 info;      // x: width, y: height, z: encoding, w: depth point
};

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
// The view-projection about the eye: eye-relative world points to clip space, in double.
static inline glm::dmat4 eyeToClip(const glm::dmat4& worldToClip, const glm::dvec3& eye) {
  glm::dmat4 translate(1.0);
  translate[3] = glm::dvec4(eye, 1.0);
  return worldToClip * translate;
}

// The descriptor of a whole view (its rectangle covers every texel), from matrices in double: the eye is split
// into two floats and the eye-relative inverse is taken before any rounding. `eye` is where linear-distance
// views' rays start (the light); for NDC-depth views any point near the view (its centre) serves.
static inline TraceView makeTraceView(const glm::dmat4& worldToClip, const glm::dvec3& eye, int width,
                                      int height, int encoding, int depthPoint, float range) {
  TraceView view{};
  view.viewProj = glm::mat4(worldToClip);
  view.clipToEye = glm::mat4(glm::inverse(eyeToClip(worldToClip, eye)));
  glm::vec3 high, low;
  splitToFloats(eye, high, low);
  view.eyeHigh = glm::vec4(high, range);
  view.eyeLow = glm::vec4(low, 0.0f);
  view.rect = glm::ivec4(0, 0, width, height);
  view.info = glm::ivec4(width, height, encoding, depthPoint);
  return view;
}

// The same, with the eye of linear-distance views given as origin.xyz and their range as origin.w; an NDC-depth
// view takes the centre of its near plane as its eye.
static inline TraceView makeTraceView(const glm::dmat4& worldToClip, int width, int height, int encoding,
                                      int depthPoint, glm::vec4 origin = glm::vec4(0.0f)) {
  glm::dvec3 eye(origin);
  if (encoding == VS_ENCODING_NDC_DEPTH) {
    glm::dvec4 centre = glm::inverse(worldToClip) * glm::dvec4(0.0, 0.0, 0.0, 1.0);
    eye = glm::dvec3(centre) / centre.w;
  }
  return makeTraceView(worldToClip, eye, width, height, encoding, depthPoint, origin.w);
}

// The eye of a view as the trace kernels see it (eyeHigh + eyeLow), in double.
static inline glm::dvec3 viewEye(const TraceView& view) {
  return glm::dvec3(glm::vec3(view.eyeHigh)) + glm::dvec3(glm::vec3(view.eyeLow));
}

VS_LAYOUT_CHECK(TraceView, 192);
VS_OFFSET_CHECK(TraceView, clipToEye, 64);
VS_OFFSET_CHECK(TraceView, eyeHigh, 128);
VS_OFFSET_CHECK(TraceView, eyeLow, 144);
VS_OFFSET_CHECK(TraceView, rect, 160);
VS_OFFSET_CHECK(TraceView, info, 176);
}  // namespace vs::gpu
#endif

#endif
