// scene.cpp: loading a scene file into objects, instances and trace arrays; moving instances.
#include "lighting/scene.h"

#include <cmath>
#include <string>

#include "voxel/error.h"

namespace vs {

Scene Scene::load(const std::filesystem::path& sceneFile) {
  Scene scene;
  scene.desc_ = parseSceneFile(sceneFile);
  scene.objects_.reserve(scene.desc_.assets.size());
  for (const AssetDesc& asset : scene.desc_.assets) {
    LoadOptions options;
    options.grid = asset.grid;
    options.densityThreshold = asset.densityThreshold;
    options.color = asset.color;
    try {
      scene.objects_.push_back(loadVdb(asset.file.string(), options));
    } catch (const Error& e) {
      throw Error(e.kind(), sceneFile.string() + ": assets." + asset.name + ": " + e.what());
    }
  }
  scene.instances_.reserve(scene.desc_.instances.size());
  for (const InstanceDesc& inst : scene.desc_.instances) {
    SceneInstance placed;
    placed.object = std::uint32_t(inst.assetIndex);
    placed.brickToWorld = inst.transform * scene.objects_[inst.assetIndex].brickToObject;
    scene.instances_.push_back(placed);
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
  inst.brickToWorld = transform * objects_[inst.object].brickToObject;
  desc_.instances[i].transform = transform;
  data_.moveInstance(i, inst.brickToWorld);
}

}  // namespace vs
