// scene.cpp: loading a scene file into objects, instances and trace arrays; moving instances.
#include "lighting/scene.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

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
                    const glm::dmat4* movedBrickToWorld = nullptr, const std::vector<char>* active = nullptr) {
  // Removed instances hold no voxels; an instance being placed is checked whatever its slot says.
  auto absent = [&](std::size_t i) { return active && i != movedInstance && (i >= active->size() || !(*active)[i]); };
  // A move is checked before it is made: instance movedInstance is read at movedBrickToWorld, its new place.
  auto brickToWorld = [&](std::size_t i) -> const glm::dmat4& {
    return i == movedInstance ? *movedBrickToWorld : instances[i].brickToWorld;
  };
  const std::string file = desc.file.string();
  auto named = [&](std::size_t i) {
    if (sources[i] == Scene::kAdded)
      return "instance " + std::to_string(i) + " (object " + std::to_string(instances[i].object) + ")";
    return "instances[" + std::to_string(sources[i]) + "] (asset '" + desc.instances[sources[i]].asset + "')";
  };
  auto skipped = [](std::size_t i, std::size_t only) { return only != kAll && i != only; };
  for (std::size_t i = 0; i < instances.size(); ++i) {
    if (skipped(i, onlyInstance) || absent(i)) continue;
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
    if (!light.shadow || !light.enabled || skipped(li, onlyLight)) continue;
    std::vector<glm::dvec3> origins =
        light.type == LightType::Directional ? boundsCorners : std::vector<glm::dvec3>{glm::dvec3(light.position)};
    for (std::size_t i = 0; i < instances.size(); ++i) {
      if (skipped(i, onlyInstance) || absent(i)) continue;
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

std::uint64_t nextSceneId() {
  static std::atomic<std::uint64_t> next{1};
  return next++;
}

}  // namespace

// Held by each change for its length (Scene::Reading's counterpart).
class Scene::Changing {
 public:
  Changing(Scene& scene, const char* call) : scene_(scene) {
    int idle = 0;
    if (!scene_.use_.value.compare_exchange_strong(idle, -1, std::memory_order_acquire))
      throwRuntime(std::string(call) + ": the scene is " +
                   (idle > 0 ? "being rendered" : "being changed") +
                   " on another thread; a change must wait until that is done (nothing was changed)");
  }
  ~Changing() { scene_.use_.value.store(0, std::memory_order_release); }
  Changing(const Changing&) = delete;
  Changing& operator=(const Changing&) = delete;

 private:
  Scene& scene_;
};

Scene::Reading::Reading(const Scene& scene, const char* reader) : scene_(scene) {
  int count = scene_.use_.value.load(std::memory_order_relaxed);
  do {
    if (count < 0)
      throwRuntime(std::string(reader) +
                   ": the scene is being changed on another thread; render it once the change is done");
  } while (!scene_.use_.value.compare_exchange_weak(count, count + 1, std::memory_order_acquire));
}

Scene::Reading::~Reading() { scene_.use_.value.fetch_sub(1, std::memory_order_release); }

Scene::Scene() : id_(nextSceneId()) {}

Scene::Scene(const Scene& other)
    : desc_(other.desc_),
      objects_(other.objects_),
      instances_(other.instances_),
      brickToAsset_(other.brickToAsset_),
      instanceSource_(other.instanceSource_),
      sourceInstances_(other.sourceInstances_),
      assetObjects_(other.assetObjects_),
      assetNotes_(other.assetNotes_),
      active_(other.active_),
      lightIds_(other.lightIds_),
      nextLightId_(other.nextLightId_),
      data_(std::make_shared<SceneData>(*other.data_)),
      id_(nextSceneId()) {}

Scene& Scene::operator=(const Scene& other) {
  if (this == &other) return *this;
  Changing changing(*this, "Scene::operator=");
  *this = Scene(other);
  return *this;
}

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
  *scene.data_ = SceneData::build(brickmaps, scene.instances_);
  checkPlacement(scene.desc_, scene.objects_, scene.instances_, scene.instanceSource_, scene.data_->worldBounds);
  scene.active_.assign(scene.instances_.size(), 1);
  for (std::size_t l = 0; l < scene.desc_.lights.size(); ++l) scene.lightIds_.push_back(scene.nextLightId_++);
  return scene;
}

void Scene::setCamera(const CameraDesc& camera) {
  Changing changing(*this, "Scene::setCamera");
  checkCamera(camera, "Scene::setCamera: camera");
  desc_.camera = camera;
}

void Scene::moveInstance(std::size_t i, const glm::dmat4& transform) {
  Changing changing(*this, "Scene::moveInstance");
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
  if (!instanceActive(i)) throwBadInput(where + ": the instance was removed");
  const SceneData::Placement placement = data_->placeInstance(i, brickToWorld);
  // The load's placement checks, on the moved world: the moved instance alone, unless the world's bounds (where
  // directional rays start) changed with it.
  const bool sameBounds =
      placement.worldBounds.min == data_->worldBounds.min && placement.worldBounds.max == data_->worldBounds.max;
  checkPlacement(desc_, objects_, instances_, instanceSource_, placement.worldBounds, sameBounds ? i : kAll, kAll, i,
                 &brickToWorld, &active_);
  SceneChange change;
  change.boxes = {data_->instanceBounds[i], placement.box};
  data_->applyPlacement(i, placement, &change.arrays);
  instances_[i].brickToWorld = brickToWorld;
  if (instanceSource_[i] != kAdded && sourceInstances_[instanceSource_[i]] == 1)
    desc_.instances[instanceSource_[i]].transform = transform;
  record(std::move(change));
}

void Scene::moveLight(std::size_t i, const glm::vec3& position, const glm::vec3& direction) {
  Changing changing(*this, "Scene::moveLight");
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
    checkPlacement(desc_, objects_, instances_, instanceSource_, data_->worldBounds, kAll, i, kAll, nullptr, &active_);
  } catch (const Error&) {
    std::swap(light, moved);
    throw;
  }
  SceneChange change;
  change.lights = {lightIds_[i]};
  change.shading = true;
  record(std::move(change));
}

void Scene::setLightColor(std::size_t i, const glm::vec3& color, float intensity) {
  Changing changing(*this, "Scene::setLightColor");
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
  SceneChange change;
  change.shading = true;
  record(std::move(change));
}

}  // namespace vs

namespace vs {

namespace {

// The world corners of a brick-space box under brickToWorld stay within the coordinate range.
void checkReach(const std::string& where, const glm::dmat4& brickToWorld, const VoxelBox& box) {
  if (box.empty()) return;
  for (int c = 0; c < 8; ++c) {
    glm::dvec4 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y, (c & 4) ? box.max.z : box.min.z, 1.0);
    glm::dvec3 w(brickToWorld * p);
    for (int a = 0; a < 3; ++a)
      if (!limits::isWorldCoordinate(w[a]))
        throwBadInput(where + ": reaches " + num(w[a]) + " on axis " + std::to_string(a) +
                      "; the world must lie within +-" + num(limits::kMaxCoordinate));
  }
}

VoxelBox unite(const VoxelBox& a, const VoxelBox& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return {glm::min(a.min, b.min), glm::max(a.max, b.max)};
}

// The world box of brick-space voxels [min, max) under brickToWorld, padded as instance boxes are.
Aabb worldBoxOf(const glm::dmat4& brickToWorld, const VoxelBox& box) {
  Aabb out;
  if (box.empty()) return out;
  makeInstanceRecord(brickToWorld, box, 0u, 0u, &out);
  return out;
}

void checkAffine(const std::string& where, const glm::dmat4& transform) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(transform[c][r]))
        throwBadInput(where + ": transform[" + std::to_string(c) + "][" + std::to_string(r) + "] is " +
                      num(transform[c][r]) + "; every entry must be finite");
  const double det = glm::determinant(glm::dmat3(transform));
  if (!std::isfinite(det) || det == 0.0 || transform[0][3] != 0.0 || transform[1][3] != 0.0 ||
      transform[2][3] != 0.0 || transform[3][3] != 1.0)
    throwBadInput(where + ": transform must be affine and invertible");
}

// A light checked exactly as a scene file's light is: written as the file's JSON and parsed back, in a scene of
// that light alone (with the scene's camera, whose far plane is the default max_distance). Returns the parsed
// light (normalised direction, defaults filled in); a refusal names `where` and the field.
LightDesc checkedLight(const SceneDesc& scene, const LightDesc& light, const std::string& where) {
  using Json = nlohmann::json;
  auto vec = [](const glm::vec3& v) { return Json::array({v.x, v.y, v.z}); };
  Json l = {{"name", light.name}, {"type", lightTypeName(light.type)}, {"color", vec(light.color)},
            {"intensity", light.intensity}};
  if (light.type != LightType::Point) l["direction"] = vec(light.direction);
  if (light.type != LightType::Directional) {
    l["position"] = vec(light.position);
    l["range"] = light.range;
  }
  if (light.type == LightType::Spot) {
    l["outer_cone_deg"] = light.outerConeDeg;
    l["inner_cone_deg"] = light.innerConeDeg;
  }
  if (light.shadow) {
    const ShadowDesc& s = *light.shadow;
    Json sj = {{"resolution", s.resolution}, {"lambda", s.lambda}, {"max_distance", s.maxDistance},
               {"filter", shadowFilterName(s.filter)}, {"depth_bias", s.depthBias}, {"normal_bias", s.normalBias},
               {"slope_bias", s.slopeBias}, {"light_size", s.lightSize}, {"contact_shadow", s.contactShadow},
               {"depth_point", s.depthPoint == gpu::VS_DEPTH_POINT_VOXEL_CENTER ? "voxel_center" : "entry"},
               {"evsm_exponent", {s.evsmPositiveExponent, s.evsmNegativeExponent}}, {"evsm_blur", s.evsmBlur},
               {"light_bleed_reduction", s.lightBleedReduction}};
    if (light.type == LightType::Directional) {
      sj["cascades"] = s.cascades;
      sj["cascade_blend"] = s.cascadeBlend;
    }
    l["shadow"] = sj;
  }
  Json doc = {{"version", 1}, {"lights", Json::array({l})}};
  if (scene.camera) {
    const CameraDesc& c = *scene.camera;
    doc["camera"] = {{"position", vec(c.position)}, {"target", vec(c.target)}, {"up", vec(c.up)},
                     {"fov_deg", c.fovDeg}, {"near", c.nearPlane}, {"far", c.farPlane},
                     {"width", c.width}, {"height", c.height}};
  }
  std::string text;
  try {
    text = doc.dump();
  } catch (const Json::exception&) {
    throwBadInput(where + ": the light's name is not valid UTF-8");
  }
  try {
    SceneDesc parsed = parseSceneJson(text, scene.file);
    return parsed.lights.at(0);
  } catch (const Error& e) {
    // "<file>: lights[0].field: problem" -> "<where>.field: problem".
    std::string message = e.what();
    const std::string prefix = scene.file.string() + ": lights[0]";
    if (message.rfind(prefix, 0) == 0) message = where + message.substr(prefix.size());
    else message = where + ": " + message;
    throw Error(e.kind(), message);
  }
}

}  // namespace

void Scene::record(SceneChange change) {
  change.revision = ++revision_;
  journal_.push_back(std::move(change));
  while (journal_.size() > kJournalLength) journal_.pop_front();
}

bool Scene::changesSince(std::uint64_t revision, std::vector<const SceneChange*>& out) const {
  out.clear();
  if (revision > revision_) return false;
  if (revision == revision_) return true;
  // The journal holds revisions (revision_ - journal_.size(), revision_]: it reaches back to `revision` when
  // the change right after it is still there.
  if (journal_.empty() || journal_.front().revision > revision + 1) return false;
  for (const SceneChange& c : journal_)
    if (c.revision > revision) out.push_back(&c);
  return true;
}

std::vector<const Brickmap*> Scene::brickmaps() const {
  std::vector<const Brickmap*> out;
  out.reserve(objects_.size());
  for (const VoxelObject& o : objects_) out.push_back(&o.brickmap);
  return out;
}

std::string Scene::instanceName(std::size_t i) const {
  if (instanceSource_[i] == kAdded) return "instance " + std::to_string(i);
  return "instance " + std::to_string(i) + " (instances[" + std::to_string(instanceSource_[i]) + "])";
}

glm::dmat4 Scene::instanceTransform(std::size_t i) const {
  if (i >= instances_.size()) throwBadInput("instanceTransform: instance " + std::to_string(i) + " out of range");
  return instances_[i].brickToWorld * glm::inverse(brickToAsset_[i]);
}

void Scene::editObject(std::size_t object, const char* call, const VoxelBox& box,
                       const std::function<EditResult(Brickmap&)>& edit) {
  if (object >= objects_.size())
    throwBadInput(std::string(call) + ": object " + std::to_string(object) + " out of range (the scene has " +
                  std::to_string(objects_.size()) + ")");
  Brickmap& brickmap = objects_[object].brickmap;
  // What a fill may grow the object to, under each of its instances, is checked before the edit.
  const VoxelBox grown = unite(brickmap.bounds(), box);
  for (std::size_t i = 0; i < instances_.size(); ++i)
    if (instanceActive(i) && instances_[i].object == object)
      checkReach(std::string(call) + ": object " + std::to_string(object) + " under " + instanceName(i),
                 instances_[i].brickToWorld, grown);
  // The brickmap refuses a bad box or coordinate before changing anything.
  const EditResult result = edit(brickmap);
  SceneChange change;
  const std::vector<const Brickmap*> all = brickmaps();
  const std::vector<Aabb> boxesBefore = data_->instanceBounds;
  change.arrays = data_->updateObject(std::uint32_t(object), all, result);
  for (std::size_t i = 0; i < instances_.size(); ++i)
    if (instanceActive(i) && instances_[i].object == object) {
      const Aabb b = worldBoxOf(instances_[i].brickToWorld, result.dirtyVoxels);
      if (!b.empty()) change.boxes.push_back(b);
      // A fill beyond the object's box grew it (SceneData::boxHeadroom): every ray through the
      // instance is re-based anew.
      const Aabb& was = boxesBefore[i];
      const Aabb& now = data_->instanceBounds[i];
      if (was.min != now.min || was.max != now.max) {
        if (!was.empty()) change.boxes.push_back(was);
        if (!now.empty()) change.boxes.push_back(now);
      }
    }
  record(std::move(change));
}

void Scene::fillVoxels(std::size_t object, const VoxelBox& box, std::uint8_t material) {
  Changing changing(*this, "Scene::fillVoxels");
  editObject(object, "fillVoxels", material != 0 ? box : VoxelBox{},
             [&](Brickmap& b) { return b.fillBox(box, material); });
}

void Scene::setVoxels(std::size_t object, std::span<const SolidVoxel> voxels) {
  Changing changing(*this, "Scene::setVoxels");
  VoxelBox added;
  for (const SolidVoxel& v : voxels) {
    for (int a = 0; a < 3; ++a)
      if (v.coord[a] < -Brickmap::kMaxCoordinate || v.coord[a] >= Brickmap::kMaxCoordinate)
        throwBadInput("setVoxels: voxel (" + std::to_string(v.coord.x) + ", " + std::to_string(v.coord.y) + ", " +
                      std::to_string(v.coord.z) + "): coordinates must lie within +-" +
                      std::to_string(Brickmap::kMaxCoordinate));
    if (v.material != 0) added = unite(added, VoxelBox{v.coord, v.coord + 1});
  }
  editObject(object, "setVoxels", added, [&](Brickmap& b) {
    EditResult all;
    for (const SolidVoxel& v : voxels) {
      EditResult one = b.setVoxel(v.coord, v.material);
      all.dirty.insert(all.dirty.end(), one.dirty.begin(), one.dirty.end());
      all.dirtyVoxels = unite(all.dirtyVoxels, one.dirtyVoxels);
      all.layoutChanged = all.layoutChanged || one.layoutChanged;
      all.rebuilt = all.rebuilt || one.rebuilt;
    }
    return all;
  });
}

std::size_t Scene::addObject(Brickmap brickmap, std::vector<glm::vec3> palette, const glm::dmat4& brickToObject) {
  checkAffine("addObject: brickToObject", brickToObject);
  if (palette.size() > 256)
    throwBadInput("addObject: palette: at most 256 entries (0 unused, 1..255), not " + std::to_string(palette.size()));
  for (std::size_t k = 0; k < palette.size(); ++k)
    for (int a = 0; a < 3; ++a)
      if (!(palette[k][a] >= 0.0f && palette[k][a] <= limits::kMaxRadiometric))
        throwBadInput("addObject: palette[" + std::to_string(k) + "]: components must be between 0 and " +
                      num(limits::kMaxRadiometric) + ", not " + num(palette[k][a]));
  palette.resize(256, glm::vec3(0.8f));
  VoxelObject object;
  object.file = "(in memory)";
  object.rule = "built in memory";
  object.palette = std::move(palette);
  object.brickToObject = brickToObject;
  object.brickmap = std::move(brickmap);
  return addObject(std::move(object));
}

std::size_t Scene::addObject(VoxelObject object) {
  Changing changing(*this, "Scene::addObject");
  checkAffine("addObject: brickToObject", object.brickToObject);
  SceneChange change;
  const std::uint32_t index = data_->addObject(object.brickmap, &change.arrays);
  objects_.push_back(std::move(object));
  record(std::move(change));
  return index;
}

std::size_t Scene::addInstance(std::size_t object, const glm::dmat4& transform) {
  Changing changing(*this, "Scene::addInstance");
  const std::string where = "addInstance: object " + std::to_string(object);
  if (object >= objects_.size())
    throwBadInput(where + ": out of range (the scene has " + std::to_string(objects_.size()) + " objects)");
  checkAffine(where, transform);
  const glm::dmat4 brickToWorld = transform * objects_[object].brickToObject;
  std::size_t slot = 0;
  while (slot < active_.size() && active_[slot]) ++slot;
  // Checked on copies: the slot it will take, then the world with it.
  std::vector<SceneInstance> instances = instances_;
  std::vector<std::size_t> sources = instanceSource_;
  std::vector<char> active = active_;
  if (slot == instances.size()) {
    instances.emplace_back();
    sources.push_back(kAdded);
    active.push_back(0);
  }
  instances[slot] = SceneInstance{std::uint32_t(object), brickToWorld};
  sources[slot] = kAdded;
  active[slot] = 1;
  Aabb bounds = data_->worldBounds;
  const Aabb box = worldBoxOf(brickToWorld, objects_[object].brickmap.bounds());
  if (!box.empty()) bounds.extend(box);
  checkPlacement(desc_, objects_, instances, sources, bounds, kAll, kAll, kAll, nullptr, &active);
  SceneChange change;
  const std::size_t placed = data_->addInstance(instances[slot], &change.arrays);
  if (placed != slot) throwRuntime("addInstance: the trace arrays placed the instance in slot " + std::to_string(placed) +
                                   ", the scene in " + std::to_string(slot));
  instances_ = std::move(instances);
  instanceSource_ = std::move(sources);
  active_ = std::move(active);
  if (brickToAsset_.size() < instances_.size()) brickToAsset_.resize(instances_.size());
  brickToAsset_[slot] = objects_[object].brickToObject;
  if (!box.empty()) change.boxes.push_back(box);
  record(std::move(change));
  return slot;
}

void Scene::removeInstance(std::size_t i) {
  Changing changing(*this, "Scene::removeInstance");
  if (i >= instances_.size())
    throwBadInput("removeInstance: instance " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(instances_.size()) + ")");
  if (!instanceActive(i)) throwBadInput("removeInstance: instance " + std::to_string(i) + " was removed already");
  SceneChange change;
  if (!data_->instanceBounds[i].empty()) change.boxes.push_back(data_->instanceBounds[i]);
  data_->removeInstance(i, &change.arrays);
  active_[i] = 0;
  record(std::move(change));
}

void Scene::setInstanceObject(std::size_t i, std::size_t object) {
  Changing changing(*this, "Scene::setInstanceObject");
  const std::string where = "setInstanceObject: instance " + std::to_string(i);
  if (i >= instances_.size()) throwBadInput(where + ": out of range (the scene has " + std::to_string(instances_.size()) + ")");
  if (!instanceActive(i)) throwBadInput(where + ": the instance was removed");
  if (object >= objects_.size())
    throwBadInput(where + ": object " + std::to_string(object) + " out of range (the scene has " +
                  std::to_string(objects_.size()) + ")");
  const glm::dmat4 brickToWorld = instanceTransform(i) * objects_[object].brickToObject;
  std::vector<SceneInstance> instances = instances_;
  instances[i] = SceneInstance{std::uint32_t(object), brickToWorld};
  Aabb bounds;
  const Aabb box = worldBoxOf(brickToWorld, objects_[object].brickmap.bounds());
  for (std::size_t k = 0; k < instances.size(); ++k) {
    const Aabb& b = k == i ? box : data_->instanceBounds[k];
    if (instanceActive(k) && !b.empty()) bounds.extend(b);
  }
  checkPlacement(desc_, objects_, instances, instanceSource_, bounds, kAll, kAll, kAll, nullptr, &active_);
  SceneChange change;
  if (!data_->instanceBounds[i].empty()) change.boxes.push_back(data_->instanceBounds[i]);
  data_->setInstanceObject(i, std::uint32_t(object), brickToWorld, &change.arrays);
  if (!box.empty()) change.boxes.push_back(box);
  instances_ = std::move(instances);
  brickToAsset_[i] = objects_[object].brickToObject;
  record(std::move(change));
}

std::size_t Scene::addLight(LightDesc light) {
  Changing changing(*this, "Scene::addLight");
  const std::string where = "addLight: lights[" + std::to_string(desc_.lights.size()) + "]";
  if (light.name.empty()) light.name = "light" + std::to_string(desc_.lights.size());
  for (const LightDesc& l : desc_.lights)
    if (l.name == light.name) throwBadInput(where + ".name: '" + light.name + "' is taken");
  SceneDesc trial = desc_;
  trial.lights.push_back(checkedLight(desc_, light, where));
  trial.lights.back().enabled = light.enabled;
  checkPlacement(trial, objects_, instances_, instanceSource_, data_->worldBounds, kAll, trial.lights.size() - 1, kAll,
                 nullptr, &active_);
  desc_.lights.push_back(std::move(trial.lights.back()));
  lightIds_.push_back(nextLightId_++);
  SceneChange change;
  change.lights = {lightIds_.back()};
  change.shading = true;
  record(std::move(change));
  return desc_.lights.size() - 1;
}

void Scene::removeLight(std::size_t i) {
  Changing changing(*this, "Scene::removeLight");
  if (i >= desc_.lights.size())
    throwBadInput("removeLight: light " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(desc_.lights.size()) + ")");
  SceneChange change;
  change.lights = {lightIds_[i]};
  change.shading = true;
  desc_.lights.erase(desc_.lights.begin() + std::ptrdiff_t(i));
  lightIds_.erase(lightIds_.begin() + std::ptrdiff_t(i));
  record(std::move(change));
}

void Scene::setLightEnabled(std::size_t i, bool enabled) {
  Changing changing(*this, "Scene::setLightEnabled");
  if (i >= desc_.lights.size())
    throwBadInput("setLightEnabled: light " + std::to_string(i) + " out of range (the scene has " +
                  std::to_string(desc_.lights.size()) + ")");
  LightDesc& light = desc_.lights[i];
  if (light.enabled == enabled) return;
  if (enabled) {
    light.enabled = true;
    try {
      checkPlacement(desc_, objects_, instances_, instanceSource_, data_->worldBounds, kAll, i, kAll, nullptr, &active_);
    } catch (const Error&) {
      light.enabled = false;
      throw;
    }
  } else {
    light.enabled = false;
  }
  SceneChange change;
  change.lights = {lightIds_[i]};
  change.shading = true;
  record(std::move(change));
}

}  // namespace vs
