// scene_data.h: a scene's objects, instances and BVH as the flat arrays that both trace backends read.
#ifndef VOXSHADOW_SCENE_DATA_H
#define VOXSHADOW_SCENE_DATA_H

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "bvh/bvh.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "voxel/brickmap.h"

namespace vs {

// One placed copy of an object: `brickToWorld` maps the object's brick space to world space
// (instance transform * the asset's own brickToObject).
struct SceneInstance {
  std::uint32_t object = 0;
  glm::dmat4 brickToWorld{1.0};
};

// The scene-wide arrays named as the shader's buffers (compute/shared/traverse.h). Objects' records are
// concatenated; each ObjectRecord holds its bases. Built once, then updated in place by edits and moves.
struct SceneData {
  std::vector<std::uint32_t> regionTable;
  std::vector<gpu::Region> regions;
  std::vector<gpu::Sector> sectors;
  std::vector<gpu::Brick> bricks;
  std::vector<std::uint32_t> occupancy;
  std::vector<std::uint32_t> payload;  // palette bytes of the bricks with more than one material
  std::vector<gpu::ObjectRecord> objects;
  std::vector<gpu::InstanceRecord> instances;
  std::vector<Aabb> instanceBounds;  // world boxes, the BVH's input
  Bvh bvh;
  Aabb worldBounds;  // union of all instance boxes; empty when the scene has no solid voxel

  // Preconditions: every instance's object index < brickmaps.size(); transforms finite and invertible.
  // Throws vs::Error(BadInput) otherwise.
  static SceneData build(std::span<const Brickmap* const> brickmaps, std::span<const SceneInstance> instances);

  // Where instance i would be after a move, computed aside from the arrays, so that a caller can check the
  // moved world before anything changes: the instance's record and world box, and the world's new bounds.
  struct Placement {
    gpu::InstanceRecord record{};
    Aabb box;
    Aabb worldBounds;
  };
  // Preconditions: i < instances.size(), brickToWorld finite and invertible; throws vs::Error(BadInput)
  // otherwise, and changes nothing.
  Placement placeInstance(std::size_t i, const glm::dmat4& brickToWorld) const;
  // Takes a placement of instance i made by placeInstance on these arrays, and refits the BVH (rebuilding
  // it when refit quality drops). Precondition: i < instances.size().
  void applyPlacement(std::size_t i, const Placement& placement);
  // placeInstance, then applyPlacement: a refused move changes nothing.
  void moveInstance(std::size_t i, const glm::dmat4& brickToWorld);
};

// Builds the GPU record of one instance (both affine maps and the world box of its object's solid voxels).
gpu::InstanceRecord makeInstanceRecord(const glm::dmat4& brickToWorld, const VoxelBox& objectVoxels,
                                       std::uint32_t objectIndex, std::uint32_t instanceId, Aabb* worldBox);

}  // namespace vs

#endif
