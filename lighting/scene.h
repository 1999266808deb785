// scene.h: the runtime scene: parsed description, loaded objects, placed instances and trace arrays.
#ifndef VOXSHADOW_SCENE_H
#define VOXSHADOW_SCENE_H

#include <cstddef>
#include <filesystem>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "compute/scene_data.h"
#include "lighting/light_views.h"
#include "lighting/scene_file.h"
#include "voxel/voxel_object.h"

namespace vs {

class Scene {
 public:
  // Parses the scene file, loads every asset once (object index = asset index in file order), places the
  // instances and builds the trace arrays. Preconditions: none; every problem is a vs::Error naming the file
  // and JSON path (an asset's load error keeps its kind and reads "<scene>: assets.<name>: <loader message>").
  // Also refuses (BadInput) instances that reach beyond limits::kMaxCoordinate and shadowed lights farther
  // than limits::kMaxRayVoxels from an object, in its voxels (voxel/valid_range.h).
  static Scene load(const std::filesystem::path& sceneFile);
  // The same from a parsed description (parseSceneFile), e.g. after checking its paths.
  static Scene load(SceneDesc desc);

  const SceneDesc& desc() const { return desc_; }
  std::span<const VoxelObject> objects() const { return objects_; }
  std::span<const SceneInstance> instances() const { return instances_; }
  const SceneData& data() const { return data_; }
  const Aabb& worldBounds() const { return data_.worldBounds; }

  // The shadow views of the current lights over the current world bounds.
  std::vector<LightView> lightViews() const { return buildLightViews(desc_, data_.worldBounds); }

  // Places instance i with a new object-to-world transform and updates the trace arrays (refit or rebuild).
  // Preconditions: i < instances().size() and transform affine and invertible; throws vs::Error(BadInput)
  // otherwise.
  void moveInstance(std::size_t i, const glm::dmat4& transform);

 private:
  SceneDesc desc_;
  std::vector<VoxelObject> objects_;
  std::vector<SceneInstance> instances_;
  SceneData data_;
};

}  // namespace vs

#endif
