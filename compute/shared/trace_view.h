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
// Stack depth of the CPU tiles' BVH traversal (the portable one is stackless); the builder keeps trees
// shallower than this (bvh/bvh.h).
const int VS_BVH_STACK_SIZE = 64;

// What one step of an object walk found (compute/shared/traverse.h).
const int VS_WALK_CONTINUE = 0;
const int VS_WALK_HIT = 1;
const int VS_WALK_MISS = 2;

// The box table's codes, one per brick (written by compute/cpu/lane_tracer.cpp, read by the CPU lanes and by
// vsObjectWalkBoxes in traverse.h): VS_BOX_FULL for a full brick, the index of its first occupancy word (>= 0;
// in the scene's occupancy array on the CPU, in the table's copy of it on the GPU) for a partial one, else
// -1 - box for an empty one, where box holds six extents of
// VS_BOX_EXTENT_BITS bits each (-x, +x, -y, +y, -z, +z, in cells of 2^log2 voxels, from bit 0) and log2 from
// bit VS_BOX_LOG2_SHIFT.
const int VS_BOX_FULL = int(0x80000000u);
const int VS_BOX_EXTENT_BITS = 4;
const int VS_BOX_EXTENT_MASK = 15;
const int VS_BOX_LOG2_SHIFT = 24;

// No voxel coordinate shifted right by a level's log2 reaches this: marks an object walk's cache as empty.
const int VS_NO_CELL = 0x7fffffff;

struct TraceView {
  mat4 viewProj;     // world -> clip
  mat4 invViewProj;  // clip -> world
  vec4 origin;       // xyz: light position (linear-distance views); w: range (their miss value)
  ivec4 rect;        // texels to trace: x0, y0, x1, y1 (x1, y1 exclusive)
  ivec4 info;        // x: width, y: height, z: encoding, w: depth point
};

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
// The descriptor of a whole view (its rectangle covers every texel). The inverse is taken in double: the rays
// of texels far from the view's centre inherit its rounding.
inline TraceView makeTraceView(const glm::dmat4& viewProj, int width, int height, int encoding, int depthPoint,
                               glm::vec4 origin = glm::vec4(0.0f)) {
  TraceView view{};
  view.viewProj = glm::mat4(viewProj);
  view.invViewProj = glm::mat4(glm::inverse(viewProj));
  view.origin = origin;
  view.rect = glm::ivec4(0, 0, width, height);
  view.info = glm::ivec4(width, height, encoding, depthPoint);
  return view;
}

VS_LAYOUT_CHECK(TraceView, 176);
VS_OFFSET_CHECK(TraceView, invViewProj, 64);
VS_OFFSET_CHECK(TraceView, origin, 128);
VS_OFFSET_CHECK(TraceView, rect, 144);
VS_OFFSET_CHECK(TraceView, info, 160);
}  // namespace vs::gpu
#endif

#endif
