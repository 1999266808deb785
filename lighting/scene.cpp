// scene.cpp: loading a scene file into objects, instances and trace arrays; moving instances.
#include "lighting/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "voxel/error.h"
#include "voxel/valid_range.h"
#include "voxel/vox_scene.h"

namespace vs {

namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Chebyshev distance, in voxels, from a brick-space point to an object's voxel box.
double voxelsFromBox(const glm::dvec3& p, const VoxelBox& box) {
  double d = 0.0;
  for (int a = 0; a < 3; ++a) d = std::max({d, double(box.min[a]) - p[a], p[a] - double(box.max[a])});
  return d;
}

// The checks that need loaded objects: each instance's voxels stay within the coordinate range, and every
// ray origin stays within limits::kMaxRayVoxels of every object, in that object's voxels (a spot light 100 km
// from a 1 mm voxel plate would otherwise re-base its rays too far from the plate for exact depths).
// `sources` names each instance's scene-file instance (a .vox asset places several per scene instance).
// A frame loop's change checks only what it touched: `onlyInstance` (a moved instance; the world bounds kept) or
// `onlyLight` (a moved light); npos checks everything.
constexpr std::size_t kAll = std::size_t(-1);
void checkPlacement(const SceneDesc& desc, std::span<const VoxelObject> objects, std::span<const SceneInstance> instances,
                    std::span<const std::size_t> sources, const Aabb& worldBounds, std::size_t onlyInstance = kAll,
                    std::size_t onlyLight = kAll, std::size_t movedInstance = kAll,
                    const glm::dmat4* movedBrickToWorld = nullptr) {
  // A move is checked before it is made: instance movedInstance is read at movedBrickToWorld, its new place.
  auto brickToWorld = [&](std::size_t i) -> const glm::dmat4& {
    return i == movedInstance ? *movedBrickToWorld : instances[i].brickToWorld;
  };
  const std::string file = desc.file.string();
  auto named = [&](std::size_t i) {
    return "instances[" + std::to_string(sources[i]) + "] (asset '" + desc.instances[sources[i]].asset + "')";
  };
  auto skipped = [](std::size_t i, std::size_t only) { return only != kAll && i != only; };
  for (std::size_t i = 0; i < instances.size(); ++i) {
    if (skipped(i, onlyInstance)) continue;
    const VoxelBox box = objects[instances[i].object].brickmap.bounds();
    const std::string where = file + ": " + named(i);
    if (box.empty()) continue;
    for (int c = 0; c < 8; ++c) {
      glm::dvec4 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y, (c & 4) ? box.max.z : box.min.z, 1.0);
      glm::dvec3 w(brickToWorld(i) * p);
      for (int a = 0; a < 3; ++a)
        if (!limits::isWorldCoordinate(w[a]))
          throwBadInput(where + ": reaches " + num(w[a]) + " on axis " + std::to_string(a) +
                        "; the world must lie within +-" + num(limits::kMaxCoordinate));
    }
  }
  // Directional rays start on a near plane just outside the world bounds: the bounds' corners, widened by the
  // views' margin, bound them.
  std::vector<glm::dvec3> boundsCorners;
  if (!worldBounds.empty()) {
    glm::dvec3 lo(worldBounds.min), hi(worldBounds.max), pad(0.01 * glm::length(hi - lo) + 1e-3);
    lo -= pad;
    hi += pad;
    for (int c = 0; c < 8; ++c) boundsCorners.push_back({(c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z});
  }
  for (std::size_t li = 0; li < desc.lights.size(); ++li) {
    const LightDesc& light = desc.lights[li];
    if (!light.shadow || skipped(li, onlyLight)) continue;
    std::vector<glm::dvec3> origins =
        light.type == LightType::Directional ? boundsCorners : std::vector<glm::dvec3>{glm::dvec3(light.position)};
    for (std::size_t i = 0; i < instances.size(); ++i) {
      if (skipped(i, onlyInstance)) continue;
      const VoxelBox box = objects[instances[i].object].brickmap.bounds();
      if (box.empty()) continue;
      const glm::dmat4 worldToBrick = glm::inverse(brickToWorld(i));
      double worst = 0.0;
      for (const glm::dvec3& o : origins) worst = std::max(worst, voxelsFromBox(glm::dvec3(worldToBrick * glm::dvec4(o, 1.0)), box));
      if (worst > limits::kMaxRayVoxels)
        throwBadInput(file + ": lights[" + std::to_string(li) + "]" +
                      (light.type == LightType::Directional ? ": the scene's extent" : ".position: the light") + " is " +
                      num(worst) + " voxels from " + named(i) + "; rays are exact only within " + num(limits::kMaxRayVoxels) +
                      " voxels of an object (move the light closer or use coarser voxels)");
    }
  }
}

}  // namespace

Scene Scene::load(const std::filesystem::path& sceneFile) { return load(parseSceneFile(sceneFile)); }

Scene Scene::load(SceneDesc desc) {
  Scene scene;
  scene.desc_ = std::move(desc);
  const std::filesystem::path& sceneFile = scene.desc_.file;
  scene.objects_.reserve(scene.desc_.assets.size());
  // Per asset: each placement's object (absolute index) and brick-to-asset map.
  std::vector<std::vector<std::pair<std::uint32_t, glm::dmat4>>> placements(scene.desc_.assets.size());
  for (std::size_t a = 0; a < scene.desc_.assets.size(); ++a) {
    const AssetDesc& asset = scene.desc_.assets[a];
    const std::size_t first = scene.objects_.size();
    std::vector<std::string> notes;
    try {
      if (asset.vox) {
        VoxAssetOptions options;
        options.voxelSize = asset.voxelSize;
        options.model = asset.model;
        options.frame = asset.frame;
        VoxAsset vox = loadVox(asset.file.string(), options);
        for (const VoxPlacement& p : vox.placements)
          placements[a].push_back({std::uint32_t(first + p.object), p.brickToAsset});
        for (VoxelObject& o : vox.objects) scene.objects_.push_back(std::move(o));
        notes = std::move(vox.notes);
      } else {
        LoadOptions options;
        options.grid = asset.grid;
        options.densityThreshold = asset.densityThreshold;
        options.color = asset.color;
        scene.objects_.push_back(loadVdb(asset.file.string(), options));
        placements[a].push_back({std::uint32_t(first), scene.objects_.back().brickToObject});
      }
    } catch (const Error& e) {
      throw Error(e.kind(), sceneFile.string() + ": assets." + asset.name + ": " + e.what());
    }
    scene.assetObjects_.push_back({first, scene.objects_.size() - first});
    scene.assetNotes_.push_back(std::move(notes));
  }
  scene.instances_.reserve(scene.desc_.instances.size());
  for (std::size_t s = 0; s < scene.desc_.instances.size(); ++s) {
    const InstanceDesc& inst = scene.desc_.instances[s];
    for (const auto& [object, brickToAsset] : placements[inst.assetIndex]) {
      SceneInstance placed;
      placed.object = object;
      placed.brickToWorld = inst.transform * brickToAsset;
      // The product of two valid transforms can still collapse (a scale that cancels a voxel size is fine, but
      // one whose product leaves float range is not): refuse it here, where the file and instance are known.
      glm::dmat3 linear(placed.brickToWorld);
      double det = glm::determinant(linear);
      double cols = glm::length(linear[0]) * glm::length(linear[1]) * glm::length(linear[2]);
      if (!std::isfinite(det) || !(std::abs(det) > 1e-12 * cols))
        throwBadInput(sceneFile.string() + ": instances[" + std::to_string(s) + "]: the transform times asset '" +
                      inst.asset + "''s voxel transform is singular (not invertible)");
      scene.instances_.push_back(placed);
      scene.brickToAsset_.push_back(brickToAsset);
      scene.instanceSource_.push_back(s);
    }
    scene.sourceInstances_.push_back(placements[inst.assetIndex].size());
  }
  std::vector<const Brickmap*> brickmaps;
  brickmaps.reserve(scene.objects_.size());
  for (const VoxelObject& object : scene.objects_) brickmaps.push_back(&object.brickmap);
  scene.data_ = SceneData::build(brickmaps, scene.instances_);
  checkPlacement(scene.desc_, scene.objects_, scene.instances_, scene.instanceSource_, scene.data_.worldBounds);
  return scene;
}

void Scene::setCamera(const CameraDesc& camera) {
  checkCamera(camera, "Scene::setCamera: camera");
  desc_.camera = camera;
}

void Scene::moveInstance(std::size_t i, const glm::dmat4& transform) {
  if (i >= instances_.size())
    throwBadInput("moveInstance: instance " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(instances_.size()) + ")");
  const std::string where = "moveInstance: instance " + std::to_string(i);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(transform[c][r]))
        throwBadInput(where + ": transform[" + std::to_string(c) + "][" + std::to_string(r) + "] is " +
                      num(transform[c][r]) + "; every entry must be finite");
  glm::dmat3 linear(transform);
  double det = glm::determinant(linear);
  if (!std::isfinite(det) || det == 0.0 || transform[0][3] != 0.0 || transform[1][3] != 0.0 ||
      transform[2][3] != 0.0 || transform[3][3] != 1.0)
    throwBadInput(where + ": transform must be affine and invertible");
  // Everything is computed and checked aside first and the scene changes only after every check passed, so
  // a refused move leaves each array, bound and the BVH as they were.
  const glm::dmat4 brickToWorld = transform * brickToAsset_[i];
  const SceneData::Placement placement = data_.placeInstance(i, brickToWorld);
  // The load's placement checks, on the moved world: the moved instance alone, unless the world's bounds (where
  // directional rays start) changed with it.
  const bool sameBounds =
      placement.worldBounds.min == data_.worldBounds.min && placement.worldBounds.max == data_.worldBounds.max;
  checkPlacement(desc_, objects_, instances_, instanceSource_, placement.worldBounds, sameBounds ? i : kAll, kAll, i,
                 &brickToWorld);
  data_.applyPlacement(i, placement);
  instances_[i].brickToWorld = brickToWorld;
  if (sourceInstances_[instanceSource_[i]] == 1) desc_.instances[instanceSource_[i]].transform = transform;
}

void Scene::moveLight(std::size_t i, const glm::vec3& position, const glm::vec3& direction) {
  if (i >= desc_.lights.size())
    throwBadInput("moveLight: light " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(desc_.lights.size()) + ")");
  LightDesc& light = desc_.lights[i];
  const std::string where = "moveLight: lights[" + std::to_string(i) + "] '" + light.name + "'";
  // The new values are checked on a copy and only then take the light's place.
  LightDesc moved = light;
  if (light.type != LightType::Directional) {
    for (int a = 0; a < 3; ++a)
      if (!limits::isWorldCoordinate(position[a]))
        throwBadInput(where + ".position: coordinates must be between " + num(-limits::kMaxCoordinate) + " and " +
                      num(limits::kMaxCoordinate) + ", not " + num(position[a]));
    moved.position = position;
  }
  if (light.type != LightType::Point) {
    const double length = glm::length(glm::dvec3(direction));
    if (!(length > 0.0) || !std::isfinite(length)) throwBadInput(where + ".direction: must be a finite non-zero vector");
    moved.direction = glm::vec3(glm::dvec3(direction) / length);
  }
  std::swap(light, moved);
  try {
    checkPlacement(desc_, objects_, instances_, instanceSource_, data_.worldBounds, kAll, i);
  } catch (const Error&) {
    std::swap(light, moved);
    throw;
  }
}

void Scene::setLightColor(std::size_t i, const glm::vec3& color, float intensity) {
  if (i >= desc_.lights.size())
    throwBadInput("setLightColor: light " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(desc_.lights.size()) + ")");
  const std::string where = "setLightColor: lights[" + std::to_string(i) + "] '" + desc_.lights[i].name + "'";
  for (int a = 0; a < 3; ++a)
    if (!(color[a] >= 0.0f && color[a] <= limits::kMaxRadiometric))
      throwBadInput(where + ".color: components must be between 0 and " + num(limits::kMaxRadiometric) + ", not " +
                    num(color[a]));
  if (!(intensity >= 0.0f && intensity <= limits::kMaxRadiometric))
    throwBadInput(where + ".intensity: must be between 0 and " + num(limits::kMaxRadiometric) + ", not " + num(intensity));
  desc_.lights[i].color = color;
  desc_.lights[i].intensity = intensity;
}

}  // namespace vs
