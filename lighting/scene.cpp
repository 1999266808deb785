// scene.cpp: loading a scene file into objects, instances and trace arrays; moving instances.
#include "lighting/scene.h"

#include <cmath>
#include <string>

#include "voxel/error.h"
#include "voxel/vox_scene.h"

namespace vs {

Scene Scene::load(const std::filesystem::path& sceneFile) {
  Scene scene;
  scene.desc_ = parseSceneFile(sceneFile);
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
  return scene;
}

void Scene::moveInstance(std::size_t i, const glm::dmat4& transform) {
  if (i >= instances_.size())
    throwBadInput("moveInstance: instance " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(instances_.size()) + ")");
  glm::dmat3 linear(transform);
  double det = glm::determinant(linear);
  if (!std::isfinite(det) || det == 0.0 || transform[0][3] != 0.0 || transform[1][3] != 0.0 ||
      transform[2][3] != 0.0 || transform[3][3] != 1.0)
    throwBadInput("moveInstance: instance " + std::to_string(i) + ": transform must be affine and invertible");
  SceneInstance& inst = instances_[i];
  inst.brickToWorld = transform * brickToAsset_[i];
  if (sourceInstances_[instanceSource_[i]] == 1) desc_.instances[instanceSource_[i]].transform = transform;
  data_.moveInstance(i, inst.brickToWorld);
}

}  // namespace vs
