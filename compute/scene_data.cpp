#include "compute/scene_data.h"

#include <cmath>
#include <string>

#include <glm/gtc/matrix_access.hpp>

#include "voxel/error.h"

namespace vs {
namespace {

gpu::Affine toAffine(const glm::dmat4& m) {
  // GLM is column-major: m[col][row]. The record stores rows.
  gpu::Affine a;
  a.row0 = glm::vec4(float(m[0][0]), float(m[1][0]), float(m[2][0]), float(m[3][0]));
  a.row1 = glm::vec4(float(m[0][1]), float(m[1][1]), float(m[2][1]), float(m[3][1]));
  a.row2 = glm::vec4(float(m[0][2]), float(m[1][2]), float(m[2][2]), float(m[3][2]));
  return a;
}

bool isFinite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

}  // namespace

gpu::InstanceRecord makeInstanceRecord(const glm::dmat4& brickToWorld, const VoxelBox& objectVoxels,
                                       std::uint32_t objectIndex, std::uint32_t instanceId, Aabb* worldBox) {
  if (!isFinite(brickToWorld)) throwBadInput("instance " + std::to_string(instanceId) + ": transform is not finite");
  glm::dmat3 linear(brickToWorld);
  double det = glm::determinant(linear);
  double scale = std::cbrt(std::abs(det));
  if (!(std::abs(det) > 0.0) || !std::isfinite(det) || scale < 1e-12) {
    throwBadInput("instance " + std::to_string(instanceId) + ": transform is singular");
  }
  gpu::InstanceRecord rec{};
  // The anchor: the centre of the object's voxels in world space, rounded to float once; both affines are taken
  // about it in double, so the only rounding left in a re-based ray is that of the record's own entries.
  glm::dvec3 centre = objectVoxels.empty()
                          ? glm::dvec3(0.0)
                          : (glm::dvec3(objectVoxels.min) + glm::dvec3(objectVoxels.max)) * 0.5;
  glm::vec3 anchor = gpu::roundedToFloat(glm::dvec3(brickToWorld * glm::dvec4(centre, 1.0)));
  glm::dmat4 toAnchor(1.0), fromAnchor(1.0);
  toAnchor[3] = glm::dvec4(-glm::dvec3(anchor), 1.0);
  fromAnchor[3] = glm::dvec4(glm::dvec3(anchor), 1.0);
  rec.brickToWorld = toAffine(toAnchor * brickToWorld);
  rec.worldToBrick = toAffine(glm::inverse(brickToWorld) * fromAnchor);
  rec.info = glm::uvec4(objectIndex, instanceId, 0u, 0u);
  rec.anchor = glm::vec4(anchor, 0.0f);

  Aabb box;
  if (!objectVoxels.empty()) {
    for (int corner = 0; corner < 8; ++corner) {
      glm::dvec4 p((corner & 1) ? objectVoxels.max.x : objectVoxels.min.x,
                   (corner & 2) ? objectVoxels.max.y : objectVoxels.min.y,
                   (corner & 4) ? objectVoxels.max.z : objectVoxels.min.z, 1.0);
      glm::dvec3 w(brickToWorld * p);
      box.extend(glm::vec3(w));
    }
    // The trace clips rays against the object's brick-space box; the world box only culls, so it must never
    // be smaller than the float image of that box: pad it by a few ulps of its extent.
    glm::vec3 pad = (glm::abs(box.min) + glm::abs(box.max) + (box.max - box.min)) * 1e-6f;
    box.min -= pad;
    box.max += pad;
  }
  rec.boundsMin = glm::vec4(box.min, 0.0f);
  rec.boundsMax = glm::vec4(box.max, 0.0f);
  if (worldBox) *worldBox = box;
  return rec;
}

SceneData SceneData::build(std::span<const Brickmap* const> brickmaps, std::span<const SceneInstance> instances) {
  SceneData scene;
  for (const Brickmap* bm : brickmaps) {
    gpu::ObjectRecord rec{};
    VoxelBox bounds = bm->bounds();
    rec.regionOrigin = glm::ivec4(bm->regionOrigin(), 0);
    rec.regionDims = glm::ivec4(bm->regionDims(), 0);
    rec.voxelMin = glm::ivec4(bounds.empty() ? glm::ivec3(0) : bounds.min, 0);
    rec.voxelMax = glm::ivec4(bounds.empty() ? glm::ivec3(0) : bounds.max, 0);
    rec.bases = glm::uvec4(scene.regionTable.size(), scene.regions.size(), scene.sectors.size(), scene.bricks.size());
    rec.bases2 = glm::uvec4(scene.occupancy.size(), scene.payload.size(), 0u, 0u);
    scene.regionTable.insert(scene.regionTable.end(), bm->regionTable().begin(), bm->regionTable().end());
    scene.regions.insert(scene.regions.end(), bm->regions().begin(), bm->regions().end());
    scene.sectors.insert(scene.sectors.end(), bm->sectors().begin(), bm->sectors().end());
    scene.bricks.insert(scene.bricks.end(), bm->bricks().begin(), bm->bricks().end());
    scene.occupancy.insert(scene.occupancy.end(), bm->occupancyWords().begin(), bm->occupancyWords().end());
    scene.payload.insert(scene.payload.end(), bm->payloadWords().begin(), bm->payloadWords().end());
    scene.objects.push_back(rec);
  }
  // 32-bit indices address every array on both sides.
  if (scene.occupancy.size() > 0xffffffffull || scene.bricks.size() > 0xffffffffull ||
      scene.payload.size() > 0xffffffffull) {
    throwBadInput("scene: brickmap arrays exceed 2^32 entries");
  }
  scene.instances.reserve(instances.size());
  scene.instanceBounds.reserve(instances.size());
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const SceneInstance& inst = instances[i];
    if (inst.object >= brickmaps.size()) {
      throwBadInput("instance " + std::to_string(i) + ": object index " + std::to_string(inst.object) +
                    " out of range (" + std::to_string(brickmaps.size()) + " objects)");
    }
    Aabb box;
    scene.instances.push_back(makeInstanceRecord(inst.brickToWorld, brickmaps[inst.object]->bounds(), inst.object,
                                                 static_cast<std::uint32_t>(i), &box));
    scene.instanceBounds.push_back(box);
    if (!box.empty()) scene.worldBounds.extend(box);
  }
  scene.bvh = Bvh::build(scene.instanceBounds);
  return scene;
}

SceneData::Placement SceneData::placeInstance(std::size_t i, const glm::dmat4& brickToWorld) const {
  if (i >= instances.size()) throwBadInput("moveInstance: instance " + std::to_string(i) + " out of range");
  const std::uint32_t object = instances[i].info.x;
  const gpu::ObjectRecord& obj = objects[object];
  const VoxelBox voxels{glm::ivec3(obj.voxelMin), glm::ivec3(obj.voxelMax)};
  Placement p;
  p.record = makeInstanceRecord(brickToWorld, voxels, object, static_cast<std::uint32_t>(i), &p.box);
  for (std::size_t k = 0; k < instanceBounds.size(); ++k) {
    const Aabb& b = k == i ? p.box : instanceBounds[k];
    if (!b.empty()) p.worldBounds.extend(b);
  }
  return p;
}

void SceneData::applyPlacement(std::size_t i, const Placement& placement) {
  if (i >= instances.size()) throwBadInput("moveInstance: instance " + std::to_string(i) + " out of range");
  instances[i] = placement.record;
  instanceBounds[i] = placement.box;
  worldBounds = placement.worldBounds;
  bvh.refit(instanceBounds);
  if (bvh.shouldRebuild()) bvh = Bvh::build(instanceBounds);
}

void SceneData::moveInstance(std::size_t i, const glm::dmat4& brickToWorld) {
  applyPlacement(i, placeInstance(i, brickToWorld));
}

}  // namespace vs
