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

struct InstanceRecord {
  Affine worldToBrick;  // world space -> the object's brick space (index + 0.5)
  Affine brickToWorld;  // its inverse
  vec4 boundsMin;       // world AABB of the instance (xyz)
  vec4 boundsMax;
  uvec4 info;           // x: object index, y: instance id (user-visible), zw: reserved
};

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
VS_LAYOUT_CHECK(BvhNode, 32);
VS_OFFSET_CHECK(BvhNode, rightOrFirst, 12);
VS_OFFSET_CHECK(BvhNode, boundsMax, 16);
VS_OFFSET_CHECK(BvhNode, count, 28);
VS_LAYOUT_CHECK(Affine, 48);
VS_LAYOUT_CHECK(InstanceRecord, 144);
VS_OFFSET_CHECK(InstanceRecord, brickToWorld, 48);
VS_OFFSET_CHECK(InstanceRecord, boundsMin, 96);
VS_OFFSET_CHECK(InstanceRecord, boundsMax, 112);
VS_OFFSET_CHECK(InstanceRecord, info, 128);
}  // namespace vs::gpu
#endif

#endif
