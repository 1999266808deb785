// scene_arrays.h: the portable traversal compiled as C++ over SceneData's arrays.
//
// compute/shared/traverse.h is included inside this struct, so its functions become member functions and
// read the arrays through members named exactly like the shader's buffers.
#ifndef VOXSHADOW_SCENE_ARRAYS_H
#define VOXSHADOW_SCENE_ARRAYS_H

#include <cmath>

#include "compute/scene_data.h"
#include "compute/shared/lanes.h"

namespace vs::gpu {

struct SceneArrays {
  const uint* regionTable = nullptr;
  const Region* regions = nullptr;
  const Sector* sectors = nullptr;
  const Brick* bricks = nullptr;
  const uint* occupancy = nullptr;
  const uint* payload = nullptr;
  const ObjectRecord* objects = nullptr;
  const InstanceRecord* instances = nullptr;
  const BvhNode* nodes = nullptr;
  const uint* instanceIndices = nullptr;
  const uint* nodeEscapes = nullptr;
  uint nodeCount = 0;
  // The box table of the scene (compute/box_table.h), or null: object walks then read the brickmap hierarchy.
  const int* boxTable = nullptr;

  // No arrays: for callers of the pieces that read only what they are given (vsWorldRay) or the members they
  // set themselves.
  SceneArrays() = default;
  explicit SceneArrays(const vs::SceneData& scene)
      : regionTable(scene.regionTable.data()),
        regions(scene.regions.data()),
        sectors(scene.sectors.data()),
        bricks(scene.bricks.data()),
        occupancy(scene.occupancy.data()),
        payload(scene.payload.data()),
        objects(scene.objects.data()),
        instances(scene.instances.data()),
        nodes(scene.bvh.nodes().data()),
        instanceIndices(scene.bvh.instanceIndices().data()),
        nodeEscapes(scene.bvh.nodeEscapes().data()),
        nodeCount(static_cast<uint>(scene.bvh.nodes().size())) {}

#define VS_READ_BOX_CODE(i) boxTable[i]
#define VS_BOX_TABLE (boxTable != nullptr)
#include "compute/shared/traverse.h"
#undef VS_BOX_TABLE
#undef VS_READ_BOX_CODE
};

}  // namespace vs::gpu

#endif
