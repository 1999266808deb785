// scene_arrays.h: the portable traversal compiled as C++ over SceneData's arrays.
//
// compute/shared/traverse.h is included inside this struct, so its functions become member functions and
// read the arrays through members named exactly like the shader's buffers.
#ifndef VOXSHADOW_SCENE_ARRAYS_H
#define VOXSHADOW_SCENE_ARRAYS_H

#include <cmath>

#include "compute/scene_data.h"

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

#include "compute/shared/traverse.h"
};

}  // namespace vs::gpu

#endif
