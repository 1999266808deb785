// scene.h: the runtime scene: parsed description, loaded objects, placed instances and trace arrays.
#ifndef VOXSHADOW_SCENE_H
#define VOXSHADOW_SCENE_H

#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "compute/scene_data.h"
#include "lighting/light_views.h"
#include "lighting/scene_file.h"
#include "voxel/voxel_object.h"

namespace vs {

class Scene {
 public:
  // Parses the scene file, loads every asset once (a .vdb asset is one object, a .vox asset one object per
  // distinct model it places; objects in asset order), places the instances (a scene instance of a .vox
  // asset becomes one instance per placement, its transform applied to the whole scene graph) and builds
  // the trace arrays. Preconditions: none; every problem is a vs::Error naming the file and JSON path (an
  // asset's load error keeps its kind and reads "<scene>: assets.<name>: <loader message>").
  // Also refuses (BadInput) instances that reach beyond limits::kMaxCoordinate and shadowed lights farther
  // than limits::kMaxRayVoxels from an object, in its voxels (voxel/valid_range.h).
  static Scene load(const std::filesystem::path& sceneFile);
  // The same from a parsed description (parseSceneFile), e.g. after checking its paths.
  static Scene load(SceneDesc desc);

  struct ObjectRange {
    std::size_t first = 0, count = 0;  // objects()[first, first + count)
  };
  // Per asset (desc().assets order): its objects, and the loader's notes (.vox: choices it made).
  std::span<const ObjectRange> assetObjects() const { return assetObjects_; }
  const std::vector<std::string>& assetNotes(std::size_t asset) const { return assetNotes_[asset]; }
  // Per instance: the scene-file instance (index into desc().instances) it was placed from.
  std::span<const std::size_t> instanceSources() const { return instanceSource_; }

  const SceneDesc& desc() const { return desc_; }
  std::span<const VoxelObject> objects() const { return objects_; }
  std::span<const SceneInstance> instances() const { return instances_; }
  const SceneData& data() const { return data_; }
  const Aabb& worldBounds() const { return data_.worldBounds; }

  // The shadow views of the current lights over the current world bounds.
  std::vector<LightView> lightViews() const { return buildLightViews(desc_, data_.worldBounds); }

  // Replaces the camera, as a frame loop does every frame (a scene file's camera is checked alike:
  // checkCamera). Throws vs::Error(BadInput) naming the field, and keeps the camera it had, when it is invalid.
  void setCamera(const CameraDesc& camera);

  // Places instance i with a new asset-to-world transform (what the scene file's instance transform is:
  // a .vox placement keeps its place within its asset) and updates the trace arrays (refit or rebuild).
  // desc() follows when the instance is its scene instance's only one. Preconditions: i < instances().size(),
  // transform affine and invertible, and the moved world within the limits load() checks (the instance's
  // voxels within limits::kMaxCoordinate, shadowed lights within limits::kMaxRayVoxels of it); throws
  // vs::Error(BadInput), and leaves the instance where it was, otherwise. Then call Tracer::instancesMoved.
  void moveInstance(std::size_t i, const glm::dmat4& transform);

  // Moves light i (a frame loop's sun, or a carried torch): `position` for spot and point lights, `direction`
  // (where the light travels; normalised here) for directional and spot lights; the other is ignored. Only
  // the moved light's layers change (FrameRenderer traces them again). Preconditions: i < desc().lights.size(),
  // position within limits::kMaxCoordinate, direction finite and non-zero, shadowed lights within
  // limits::kMaxRayVoxels of every object; throws vs::Error(BadInput) naming the field, and keeps the light as
  // it was, otherwise.
  void moveLight(std::size_t i, const glm::vec3& position, const glm::vec3& direction);
  // Sets light i's colour and intensity (no layer changes). Preconditions: i < desc().lights.size(), every
  // value in [0, limits::kMaxRadiometric]; throws vs::Error(BadInput) naming the field otherwise.
  void setLightColor(std::size_t i, const glm::vec3& color, float intensity);

 private:
  SceneDesc desc_;
  std::vector<VoxelObject> objects_;
  std::vector<SceneInstance> instances_;
  std::vector<glm::dmat4> brickToAsset_;      // per instance
  std::vector<std::size_t> instanceSource_;   // per instance
  std::vector<std::size_t> sourceInstances_;  // per scene-file instance: how many instances it became
  std::vector<ObjectRange> assetObjects_;
  std::vector<std::vector<std::string>> assetNotes_;
  SceneData data_;
};

}  // namespace vs

#endif
