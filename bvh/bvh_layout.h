// bvh_layout.h: GPU-visible records of instances and the instance BVH (DESIGN.md §5), readable as C++ and GLSL.
#ifndef VOXSHADOW_BVH_LAYOUT_H
#define VOXSHADOW_BVH_LAYOUT_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// Depth-first flattened binary BVH node; an interior node's left child is the next node.
struct BvhNode {
  vec3 boundsMin;
  uint rightOrFirst;  // interior: index of the right child; leaf: first entry in the instance-index list
  vec3 boundsMax;
  uint count;         // 0: interior node; > 0: leaf holding `count` instances
};

// An affine map stored as three rows (x' = dot(row0.xyz, p) + row0.w, ...).
struct Affine {
  vec4 row0;
  vec4 row1;
  vec4 row2;
};

// Both affines are taken about the instance's anchor (a float point near the instance, exact as stored): a
// world point p enters brick space as worldToBrick(p - anchor), and brickToWorld gives p - anchor. The
// anchor's own brick coordinates are rounded once, from double, so that rays re-based near the instance
// (compute/shared/traverse.h, vsInstanceRay) keep their precision however far from the world origin it lies.
struct InstanceRecord {
  Affine worldToBrick;  // world space relative to the anchor -> the object's brick space (index + 0.5)
  Affine brickToWorld;  // its inverse: brick space -> world space relative to the anchor
  vec4 boundsMin;       // world AABB of the instance (xyz)
  vec4 boundsMax;
  uvec4 info;           // x: object index, y: instance id (user-visible), zw: reserved
  vec4 anchor;          // xyz: the anchor in world space; w: 0
};

// The records read as 16-byte texels (a shader may fetch them from an RGBA32 texel buffer): a node is
// (boundsMin, rightOrFirst), (boundsMax, count); an instance's members are one texel each, an Affine three.
const uint VS_NODE_TEXELS = 2u;
const uint VS_INSTANCE_TEXELS = 10u;
const uint VS_INSTANCE_BRICK_TO_WORLD_TEXEL = 3u;
const uint VS_INSTANCE_BOUNDS_MIN_TEXEL = 6u;
const uint VS_INSTANCE_BOUNDS_MAX_TEXEL = 7u;
const uint VS_INSTANCE_INFO_TEXEL = 8u;
const uint VS_INSTANCE_ANCHOR_TEXEL = 9u;

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
VS_LAYOUT_CHECK(BvhNode, 16 * VS_NODE_TEXELS);
VS_OFFSET_CHECK(BvhNode, rightOrFirst, 12);
VS_OFFSET_CHECK(BvhNode, boundsMax, 16);
VS_OFFSET_CHECK(BvhNode, count, 28);
VS_LAYOUT_CHECK(Affine, 48);
VS_LAYOUT_CHECK(InstanceRecord, 16 * VS_INSTANCE_TEXELS);
VS_OFFSET_CHECK(InstanceRecord, brickToWorld, 16 * VS_INSTANCE_BRICK_TO_WORLD_TEXEL);
VS_OFFSET_CHECK(InstanceRecord, boundsMin, 16 * VS_INSTANCE_BOUNDS_MIN_TEXEL);
VS_OFFSET_CHECK(InstanceRecord, boundsMax, 16 * VS_INSTANCE_BOUNDS_MAX_TEXEL);
VS_OFFSET_CHECK(InstanceRecord, info, 16 * VS_INSTANCE_INFO_TEXEL);
VS_OFFSET_CHECK(InstanceRecord, anchor, 16 * VS_INSTANCE_ANCHOR_TEXEL);
}  // namespace vs::gpu
#endif

#endif
