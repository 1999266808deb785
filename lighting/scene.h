// scene.h: the runtime scene: parsed description, loaded objects, placed instances and trace arrays.
#ifndef VOXSHADOW_SCENE_H
#define VOXSHADOW_SCENE_H

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
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

// One accepted change to a scene, as a frame loop's consumers (FrameRenderer, the trace backends) need to
// know it: where voxels may differ, which lights' layers must be traced again, what the trace arrays changed.
struct SceneChange {
  std::uint64_t revision = 0;     // Scene::revision() right after the change
  std::vector<Aabb> boxes;        // world boxes whose voxels may differ (a moved instance's old and new box,
                                  // an edit's box under every instance of the object, an added or removed instance)
  std::vector<std::uint64_t> lights;  // ids (Scene::lightId) of lights whose shadow views changed
  bool shading = false;           // lights' colours, count or enabled state changed: every pixel is shaded again
  SceneDelta arrays;              // what the trace arrays changed (compute/scene_data.h)
};

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

  // A copy is a scene of its own: its own trace arrays and id, an empty journal. A move keeps both.
  Scene(const Scene& other);
  Scene& operator=(const Scene& other);
  Scene(Scene&&) noexcept = default;
  Scene& operator=(Scene&&) noexcept = default;

  struct ObjectRange {
    std::size_t first = 0, count = 0;  // objects()[first, first + count)
  };
  // Per asset (desc().assets order): its objects, and the loader's notes (.vox: choices it made).
  std::span<const ObjectRange> assetObjects() const { return assetObjects_; }
  const std::vector<std::string>& assetNotes(std::size_t asset) const { return assetNotes_[asset]; }
  // Per instance: the scene-file instance (index into desc().instances) it was placed from; kAdded for one
  // that addInstance placed.
  static constexpr std::size_t kAdded = std::size_t(-1);
  std::span<const std::size_t> instanceSources() const { return instanceSource_; }

  const SceneDesc& desc() const { return desc_; }
  std::span<const VoxelObject> objects() const { return objects_; }
  std::span<const SceneInstance> instances() const { return instances_; }
  const SceneData& data() const { return *data_; }
  const Aabb& worldBounds() const { return data_->worldBounds; }

  // The shadow views of the current lights over the current world bounds.
  std::vector<LightView> lightViews() const { return buildLightViews(desc_, data_->worldBounds); }

  // Replaces the camera, as a frame loop does every frame (a scene file's camera is checked alike:
  // checkCamera). Throws vs::Error(BadInput) naming the field, and keeps the camera it had, when it is invalid.
  void setCamera(const CameraDesc& camera);

  // Places instance i with a new asset-to-world transform (what the scene file's instance transform is:
  // a .vox placement keeps its place within its asset) and updates the trace arrays (refit or rebuild).
  // desc() follows when the instance is its scene instance's only one. Preconditions: i < instances().size(),
  // transform affine and invertible, and the moved world within the limits load() checks (the instance's
  // voxels within limits::kMaxCoordinate, shadowed lights within limits::kMaxRayVoxels of it); throws
  // vs::Error(BadInput), and leaves the instance where it was, otherwise. A FrameRenderer learns of the move
  // from the change journal.
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

  // --- The game's changes (DESIGN.md §11). Each is checked as a scene file's values are; a refused change
  // throws vs::Error(BadInput) naming the call, the index and the field, and changes nothing. Each accepted
  // change advances revision() and is recorded in the change journal.

  // Sets every voxel of `box` (object `object`'s brick space, voxel v covering [v, v + 1)) to palette index
  // `material`; 0 clears. Preconditions: object < objects().size(); the box within +-Brickmap::kMaxCoordinate
  // and at most Brickmap::kMaxEditVoxels voxels (split larger fills); every instance of the object stays within
  // limits::kMaxCoordinate.
  void fillVoxels(std::size_t object, const VoxelBox& box, std::uint8_t material);
  // Sets single voxels (coord, material; material 0 clears), in order, as one change. Preconditions as fillVoxels.
  void setVoxels(std::size_t object, std::span<const SolidVoxel> voxels);

  // Adds an object built in memory: its brickmap (voxel/brickmap.h: Brickmap::build from voxels, or edited),
  // palette (entry 0 unused, 1..255 linear RGB; missing entries read as grey) and brick-to-object map
  // (brick space to the object's own space, e.g. a voxel size: glm::scale). Returns its index. Adds no
  // instance: addInstance places it. Preconditions: brickToObject affine, finite, invertible; at most 255 + 1
  // palette entries.
  std::size_t addObject(Brickmap brickmap, std::vector<glm::vec3> palette, const glm::dmat4& brickToObject);
  std::size_t addObject(VoxelObject object);

  // Places object `object` with `transform` (object space to world). Returns the instance's index: the lowest
  // slot a removed instance left, else a new one; indices of other instances never change. Preconditions as
  // moveInstance, object < objects().size().
  std::size_t addInstance(std::size_t object, const glm::dmat4& transform);
  // Removes instance i: its slot stays, empty (instanceActive(i) false), until addInstance reuses it.
  // Preconditions: i < instances().size(), the instance active.
  void removeInstance(std::size_t i);
  // Shows object `object` at instance i's place instead of its current object (a .vox animation's frames):
  // its brick-to-world becomes the instance's transform times the new object's brickToObject. Preconditions:
  // i active, object < objects().size(), the result within the limits moveInstance checks.
  void setInstanceObject(std::size_t i, std::size_t object);
  bool instanceActive(std::size_t i) const { return i < active_.size() && active_[i] != 0; }
  // The instance's object-to-world transform (what moveInstance sets).
  glm::dmat4 instanceTransform(std::size_t i) const;

  // Adds a light, checked as a scene file's light is (its name must be new, or empty: "light<i>"). Returns
  // its index (the last). Removing light i moves the later lights down by one; lightId(i) does not change
  // with that, so consumers follow lights by id.
  std::size_t addLight(LightDesc light);
  void removeLight(std::size_t i);
  // A disabled light lights nothing and traces nothing; enabling it again checks it as moveLight does.
  void setLightEnabled(std::size_t i, bool enabled);
  std::uint64_t lightId(std::size_t i) const { return lightIds_.at(i); }

  // --- What changed. id() names this scene among all scenes of the process (kept by a move); revision()
  // counts its accepted changes. changesSince(r) gives the changes after revision r, oldest first, or null
  // when the journal (the last kJournalLength changes) no longer reaches back that far: then redo everything.
  static constexpr std::size_t kJournalLength = 1024;
  std::uint64_t id() const { return id_; }
  std::uint64_t revision() const { return revision_; }
  bool changesSince(std::uint64_t revision, std::vector<const SceneChange*>& out) const;
  // The trace arrays, shared: a tracer bound to them keeps them alive (FrameRenderer binds through this).
  std::shared_ptr<const SceneData> sharedData() const { return data_; }

  // --- Threads. A scene's const calls may run on several threads at once; a change (the calls above that are
  // not const, and copy assignment) must overlap nothing else on the same scene. A reader that takes long
  // (FrameRenderer::render) holds a Reading for its length: a change meanwhile is refused with
  // vs::Error(Runtime), nothing changed, and a Reading taken while a change runs is refused the same way.
  // Several Readings may be held at once (renderers on several threads rendering one scene).
  class Reading {
   public:
    Reading(const Scene& scene, const char* reader);
    ~Reading();
    Reading(const Reading&) = delete;
    Reading& operator=(const Reading&) = delete;

   private:
    const Scene& scene_;
  };

 private:
  class Changing;
  // Readings held (> 0) or a change running (-1). Copies and moves of a scene start at 0.
  struct UseCount {
    std::atomic<int> value{0};
    UseCount() = default;
    UseCount(const UseCount&) noexcept {}
    UseCount& operator=(const UseCount&) noexcept { return *this; }
  };
  mutable UseCount use_;
  SceneDesc desc_;
  std::vector<VoxelObject> objects_;
  std::vector<SceneInstance> instances_;
  std::vector<glm::dmat4> brickToAsset_;      // per instance
  std::vector<std::size_t> instanceSource_;   // per instance
  std::vector<std::size_t> sourceInstances_;  // per scene-file instance: how many instances it became
  std::vector<ObjectRange> assetObjects_;
  std::vector<std::vector<std::string>> assetNotes_;
  std::vector<char> active_;                 // per instance slot
  std::vector<std::uint64_t> lightIds_;      // per light
  std::uint64_t nextLightId_ = 1;
  std::shared_ptr<SceneData> data_ = std::make_shared<SceneData>();
  std::uint64_t id_ = 0;
  std::uint64_t revision_ = 0;
  std::deque<SceneChange> journal_;

  Scene();
  void record(SceneChange change);
  void editObject(std::size_t object, const char* call, const VoxelBox& box,
                  const std::function<EditResult(Brickmap&)>& edit);
  std::vector<const Brickmap*> brickmaps() const;
  std::string instanceName(std::size_t i) const;
};

}  // namespace vs

#endif
