#include "compute/scene_data.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

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

glm::dvec3 anchorPointOf(const VoxelBox& objectVoxels) {
  return objectVoxels.empty() ? glm::dvec3(0.0) : (glm::dvec3(objectVoxels.min) + glm::dvec3(objectVoxels.max)) * 0.5;
}

gpu::InstanceRecord makeInstanceRecord(const glm::dmat4& brickToWorld, const VoxelBox& objectVoxels,
                                       std::uint32_t objectIndex, std::uint32_t instanceId, Aabb* worldBox) {
  return makeInstanceRecord(brickToWorld, objectVoxels, anchorPointOf(objectVoxels), objectIndex, instanceId,
                            worldBox);
}

gpu::InstanceRecord makeInstanceRecord(const glm::dmat4& brickToWorld, const VoxelBox& objectVoxels,
                                       const glm::dvec3& anchorPoint, std::uint32_t objectIndex,
                                       std::uint32_t instanceId, Aabb* worldBox) {
  if (!isFinite(brickToWorld)) throwBadInput("instance " + std::to_string(instanceId) + ": transform is not finite");
  glm::dmat3 linear(brickToWorld);
  double det = glm::determinant(linear);
  double scale = std::cbrt(std::abs(det));
  if (!(std::abs(det) > 0.0) || !std::isfinite(det) || scale < 1e-12) {
    throwBadInput("instance " + std::to_string(instanceId) + ": transform is singular");
  }
  gpu::InstanceRecord rec{};
  // The anchor: the object's anchor point (near its voxels) in world space, rounded to float once; both affines
  // are taken about it in double, so the only rounding left in a re-based ray is that of the record's own
  // entries.
  glm::vec3 anchor = gpu::roundedToFloat(glm::dvec3(brickToWorld * glm::dvec4(anchorPoint, 1.0)));
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

namespace {

constexpr int kVoxelArrays = int(SceneData::kVoxelArrayCount);  // SceneArray::RegionTable .. Payload, DirtyRange::Array order
constexpr std::size_t kElementBytes[kVoxelArrays] = {sizeof(std::uint32_t), sizeof(gpu::Region),
                                                     sizeof(gpu::Sector),   sizeof(gpu::Brick),
                                                     sizeof(std::uint32_t), sizeof(std::uint32_t)};
constexpr const char* kArrayNames[kVoxelArrays] = {"regionTable", "regions", "sectors", "bricks", "occupancy",
                                                   "payload"};
using Sizes = std::array<std::size_t, kVoxelArrays>;

Sizes sizesOf(const Brickmap& bm) {
  return {bm.regionTable().size(), bm.regions().size(),        bm.sectors().size(),
          bm.bricks().size(),      bm.occupancyWords().size(), bm.payloadWords().size()};
}

const void* bytesOf(const Brickmap& bm, int a) {
  switch (a) {
    case 0: return bm.regionTable().data();
    case 1: return bm.regions().data();
    case 2: return bm.sectors().data();
    case 3: return bm.bricks().data();
    case 4: return bm.occupancyWords().data();
    default: return bm.payloadWords().data();
  }
}

// The scene's voxel arrays, by index, as bytes.
struct VoxelArrays {
  std::vector<std::uint32_t>* regionTable;
  std::vector<gpu::Region>* regions;
  std::vector<gpu::Sector>* sectors;
  std::vector<gpu::Brick>* bricks;
  std::vector<std::uint32_t>* occupancy;
  std::vector<std::uint32_t>* payload;

  explicit VoxelArrays(SceneData& s)
      : regionTable(&s.regionTable), regions(&s.regions), sectors(&s.sectors), bricks(&s.bricks),
        occupancy(&s.occupancy), payload(&s.payload) {}
  template <class F>
  void visit(int a, F&& f) const {
    switch (a) {
      case 0: f(*regionTable); break;
      case 1: f(*regions); break;
      case 2: f(*sectors); break;
      case 3: f(*bricks); break;
      case 4: f(*occupancy); break;
      default: f(*payload); break;
    }
  }
  std::size_t size(int a) const {
    std::size_t n = 0;
    visit(a, [&](auto& v) { n = v.size(); });
    return n;
  }
  std::uint8_t* bytes(int a) const {
    std::uint8_t* p = nullptr;
    visit(a, [&](auto& v) { p = reinterpret_cast<std::uint8_t*>(v.data()); });
    return p;
  }
  void resize(int a, std::size_t n) const {
    visit(a, [&](auto& v) { v.resize(n); });
  }
};

std::size_t baseOf(const gpu::ObjectRecord& rec, int a) {
  return a < 4 ? std::size_t(rec.bases[a]) : std::size_t(rec.bases2[a - 4]);
}
void setBase(gpu::ObjectRecord& rec, int a, std::size_t base) {
  if (a < 4) rec.bases[a] = std::uint32_t(base);
  else rec.bases2[a - 4] = std::uint32_t(base);
}

// The record of an object whose arrays start at `bases` (the bases fields are filled by the caller).
gpu::ObjectRecord objectRecordOf(const Brickmap& bm) {
  gpu::ObjectRecord rec{};
  VoxelBox bounds = bm.bounds();
  rec.regionOrigin = glm::ivec4(bm.regionOrigin(), 0);
  rec.regionDims = glm::ivec4(bm.regionDims(), 0);
  rec.voxelMin = glm::ivec4(bounds.empty() ? glm::ivec3(0) : bounds.min, 0);
  rec.voxelMax = glm::ivec4(bounds.empty() ? glm::ivec3(0) : bounds.max, 0);
  return rec;
}

VoxelBox voxelsOf(const gpu::ObjectRecord& rec) { return VoxelBox{glm::ivec3(rec.voxelMin), glm::ivec3(rec.voxelMax)}; }

bool sameVoxels(const gpu::ObjectRecord& a, const gpu::ObjectRecord& b) {
  return glm::ivec3(a.voxelMin) == glm::ivec3(b.voxelMin) && glm::ivec3(a.voxelMax) == glm::ivec3(b.voxelMax);
}

// 32-bit indices address every array on both sides.
void checkIndexRange(const Sizes& totals, const std::string& call) {
  for (int a = 0; a < kVoxelArrays; ++a)
    if (totals[a] > 0xffffffffull)
      throwBadInput(call + ": the scene's " + kArrayNames[a] + " array would exceed 2^32 entries");
}

// An empty slot's record. Its box is empty, so the BVH leaves it out and no culling test enters it; and a walk
// of it, were one to start, would begin far outside every object's voxels (|coordinate| < 2^30) with no
// direction, so it could not hit either.
gpu::InstanceRecord emptySlotRecord(std::uint32_t object, std::uint32_t slot, Aabb* box) {
  gpu::InstanceRecord rec{};
  const float far = -2147483648.0f;
  rec.worldToBrick.row0 = glm::vec4(0.0f, 0.0f, 0.0f, far);
  rec.worldToBrick.row1 = glm::vec4(0.0f, 0.0f, 0.0f, far);
  rec.worldToBrick.row2 = glm::vec4(0.0f, 0.0f, 0.0f, far);
  *box = Aabb{};
  rec.boundsMin = glm::vec4(box->min, 0.0f);
  rec.boundsMax = glm::vec4(box->max, 0.0f);
  rec.info = glm::uvec4(object, slot, 0u, 0u);
  rec.anchor = glm::vec4(0.0f);
  return rec;
}

Aabb unionOf(std::span<const Aabb> boxes) {
  Aabb u;
  for (const Aabb& b : boxes)
    if (!b.empty()) u.extend(b);
  return u;
}

// Brick coordinates covering a voxel box, rounded outward.
VoxelBox bricksOf(const VoxelBox& voxels) {
  return VoxelBox{voxels.min >> gpu::VS_BRICK_LOG2,
                  (voxels.max + glm::ivec3((1 << gpu::VS_BRICK_LOG2) - 1)) >> gpu::VS_BRICK_LOG2};
}

void addRange(SceneDelta& d, SceneArray array, std::size_t offset, std::size_t size) {
  if (size > 0) d.ranges.push_back({array, offset, size});
}

void normalizeRanges(std::vector<SceneDirtyRange>& ranges) {
  std::sort(ranges.begin(), ranges.end(), [](const SceneDirtyRange& a, const SceneDirtyRange& b) {
    return a.array != b.array ? a.array < b.array : a.byteOffset < b.byteOffset;
  });
  std::vector<SceneDirtyRange> out;
  for (const SceneDirtyRange& r : ranges) {
    if (r.byteSize == 0) continue;
    if (!out.empty() && out.back().array == r.array && out.back().byteOffset + out.back().byteSize >= r.byteOffset) {
      SceneDirtyRange& last = out.back();
      last.byteSize = std::max(last.byteOffset + last.byteSize, r.byteOffset + r.byteSize) - last.byteOffset;
    } else {
      out.push_back(r);
    }
  }
  ranges = std::move(out);
}

void deliver(SceneDelta* target, const SceneDelta& change) {
  if (target) target->merge(change);
}

}  // namespace

void SceneDelta::merge(const SceneDelta& other) {
  ranges.insert(ranges.end(), other.ranges.begin(), other.ranges.end());
  normalizeRanges(ranges);
  editedBricks.insert(editedBricks.end(), other.editedBricks.begin(), other.editedBricks.end());
  voxelLayout = voxelLayout || other.voxelLayout;
  instances = instances || other.instances;
}

std::size_t SceneDelta::rangeBytes() const {
  std::size_t n = 0;
  for (const SceneDirtyRange& r : ranges) n += r.byteSize;
  return n;
}

SceneData SceneData::build(std::span<const Brickmap* const> brickmaps, std::span<const SceneInstance> instances) {
  SceneData scene;
  for (const Brickmap* bm : brickmaps) {
    gpu::ObjectRecord rec = objectRecordOf(*bm);
    rec.bases = glm::uvec4(scene.regionTable.size(), scene.regions.size(), scene.sectors.size(), scene.bricks.size());
    rec.bases2 = glm::uvec4(scene.occupancy.size(), scene.payload.size(), 0u, 0u);
    scene.regionTable.insert(scene.regionTable.end(), bm->regionTable().begin(), bm->regionTable().end());
    scene.regions.insert(scene.regions.end(), bm->regions().begin(), bm->regions().end());
    scene.sectors.insert(scene.sectors.end(), bm->sectors().begin(), bm->sectors().end());
    scene.bricks.insert(scene.bricks.end(), bm->bricks().begin(), bm->bricks().end());
    scene.occupancy.insert(scene.occupancy.end(), bm->occupancyWords().begin(), bm->occupancyWords().end());
    scene.payload.insert(scene.payload.end(), bm->payloadWords().begin(), bm->payloadWords().end());
    scene.objects.push_back(rec);
    scene.objectAnchors.push_back(anchorPointOf(bm->bounds()));
    scene.objectSizes.push_back(sizesOf(*bm));
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
    scene.instances.push_back(makeInstanceRecord(inst.brickToWorld, brickmaps[inst.object]->bounds(),
                                                 scene.objectAnchors[inst.object], inst.object,
                                                 static_cast<std::uint32_t>(i), &box));
    scene.instanceBounds.push_back(box);
    scene.instanceTransforms.push_back(inst.brickToWorld);
    scene.instanceSlots.push_back(1);
    if (!box.empty()) scene.worldBounds.extend(box);
  }
  scene.bvh = Bvh::build(scene.instanceBounds);
  return scene;
}

void SceneData::refreshBvh(SceneDelta* delta) {
  const bool rebuilt = bvh.update(instanceBounds);
  if (!delta) return;
  SceneDelta d;
  std::size_t bytes = bvh.nodes().size() * sizeof(gpu::BvhNode);
  // A refit keeps the leaf lists and escapes; a rebuild rewrites all three arrays.
  if (rebuilt) bytes += (bvh.instanceIndices().size() + bvh.nodeEscapes().size()) * sizeof(std::uint32_t);
  addRange(d, SceneArray::Bvh, 0, bytes);
  d.instances = true;
  delta->merge(d);
}

void SceneData::placeAndCommit(std::size_t i, const gpu::InstanceRecord& record, const Aabb& box,
                               const glm::dmat4& brickToWorld, SceneDelta* delta) {
  if (i == instances.size()) {
    instances.push_back(record);
    instanceBounds.push_back(box);
    instanceTransforms.push_back(brickToWorld);
    instanceSlots.push_back(1);
  } else {
    instances[i] = record;
    instanceBounds[i] = box;
    instanceTransforms[i] = brickToWorld;
  }
  worldBounds = unionOf(instanceBounds);
  SceneDelta d;
  addRange(d, SceneArray::Instances, i * sizeof(gpu::InstanceRecord), sizeof(gpu::InstanceRecord));
  d.instances = true;
  deliver(delta, d);
  refreshBvh(delta);
}

SceneData::Placement SceneData::placeInstance(std::size_t i, const glm::dmat4& brickToWorld) const {
  if (i >= instances.size()) throwBadInput("moveInstance: instance " + std::to_string(i) + " out of range");
  if (!instanceActive(i)) throwBadInput("moveInstance: instance " + std::to_string(i) + " was removed");
  const std::uint32_t object = instances[i].info.x;
  Placement p;
  p.record = makeInstanceRecord(brickToWorld, voxelsOf(objects[object]), objectAnchors[object], object,
                                static_cast<std::uint32_t>(i), &p.box);
  p.brickToWorld = brickToWorld;
  for (std::size_t k = 0; k < instanceBounds.size(); ++k) {
    const Aabb& b = k == i ? p.box : instanceBounds[k];
    if (!b.empty()) p.worldBounds.extend(b);
  }
  return p;
}

void SceneData::applyPlacement(std::size_t i, const Placement& placement, SceneDelta* delta) {
  if (i >= instances.size()) throwBadInput("moveInstance: instance " + std::to_string(i) + " out of range");
  if (!instanceActive(i)) throwBadInput("moveInstance: instance " + std::to_string(i) + " was removed");
  instances[i] = placement.record;
  instanceBounds[i] = placement.box;
  instanceTransforms[i] = placement.brickToWorld;
  worldBounds = placement.worldBounds;
  SceneDelta d;
  addRange(d, SceneArray::Instances, i * sizeof(gpu::InstanceRecord), sizeof(gpu::InstanceRecord));
  d.instances = true;
  deliver(delta, d);
  refreshBvh(delta);
}

void SceneData::moveInstance(std::size_t i, const glm::dmat4& brickToWorld, SceneDelta* delta) {
  applyPlacement(i, placeInstance(i, brickToWorld), delta);
}

std::size_t SceneData::addInstance(const SceneInstance& instance, SceneDelta* delta) {
  if (instance.object >= objects.size())
    throwBadInput("addInstance: object " + std::to_string(instance.object) + " out of range (" +
                  std::to_string(objects.size()) + " objects)");
  std::size_t slot = 0;
  while (slot < instanceSlots.size() && instanceSlots[slot]) ++slot;
  if (slot > 0xffffffffull) throwBadInput("addInstance: more than 2^32 instances");
  Aabb box;
  const gpu::InstanceRecord record =
      makeInstanceRecord(instance.brickToWorld, voxelsOf(objects[instance.object]), objectAnchors[instance.object],
                         instance.object, static_cast<std::uint32_t>(slot), &box);
  if (slot < instanceSlots.size()) instanceSlots[slot] = 1;
  placeAndCommit(slot, record, box, instance.brickToWorld, delta);
  return slot;
}

void SceneData::removeInstance(std::size_t i, SceneDelta* delta) {
  if (i >= instances.size())
    throwBadInput("removeInstance: instance " + std::to_string(i) + " out of range (" +
                  std::to_string(instances.size()) + " slots)");
  if (!instanceActive(i)) throwBadInput("removeInstance: instance " + std::to_string(i) + " was already removed");
  Aabb box;
  const gpu::InstanceRecord record = emptySlotRecord(instances[i].info.x, static_cast<std::uint32_t>(i), &box);
  instanceSlots[i] = 0;
  placeAndCommit(i, record, box, glm::dmat4(1.0), delta);
}

void SceneData::setInstanceObject(std::size_t i, std::uint32_t object, const glm::dmat4& brickToWorld,
                                  SceneDelta* delta) {
  if (i >= instances.size())
    throwBadInput("setInstanceObject: instance " + std::to_string(i) + " out of range (" +
                  std::to_string(instances.size()) + " slots)");
  if (!instanceActive(i)) throwBadInput("setInstanceObject: instance " + std::to_string(i) + " was removed");
  if (object >= objects.size())
    throwBadInput("setInstanceObject: object " + std::to_string(object) + " out of range (" +
                  std::to_string(objects.size()) + " objects)");
  Aabb box;
  const gpu::InstanceRecord record = makeInstanceRecord(brickToWorld, voxelsOf(objects[object]), objectAnchors[object],
                                                        object, static_cast<std::uint32_t>(i), &box);
  placeAndCommit(i, record, box, brickToWorld, delta);
}

std::uint32_t SceneData::addObject(const Brickmap& brickmap, SceneDelta* delta) {
  const std::string call = "addObject";
  if (objects.size() >= 0xffffffffull) throwBadInput(call + ": more than 2^32 objects");
  VoxelArrays arrays(*this);
  const Sizes sizes = sizesOf(brickmap);
  Sizes totals{};
  for (int a = 0; a < kVoxelArrays; ++a) totals[a] = arrays.size(a) + sizes[a];
  checkIndexRange(totals, call);

  gpu::ObjectRecord rec = objectRecordOf(brickmap);
  SceneDelta d;
  for (int a = 0; a < kVoxelArrays; ++a) {
    const std::size_t base = arrays.size(a);
    setBase(rec, a, base);
    arrays.resize(a, totals[a]);
    const std::size_t bytes = sizes[a] * kElementBytes[a];
    if (bytes) std::memcpy(arrays.bytes(a) + base * kElementBytes[a], bytesOf(brickmap, a), bytes);
    addRange(d, SceneArray(a), base * kElementBytes[a], bytes);
  }
  const auto index = static_cast<std::uint32_t>(objects.size());
  objects.push_back(rec);
  objectAnchors.push_back(anchorPointOf(brickmap.bounds()));
  objectSizes.push_back(sizes);
  addRange(d, SceneArray::Objects, index * sizeof(gpu::ObjectRecord), sizeof(gpu::ObjectRecord));
  const glm::ivec3 regionBricks = glm::ivec3(rec.regionOrigin) * (1 << (gpu::VS_REGION_LOG2 - gpu::VS_BRICK_LOG2));
  const VoxelBox grid{regionBricks,
                      regionBricks + glm::ivec3(rec.regionDims) * (1 << (gpu::VS_REGION_LOG2 - gpu::VS_BRICK_LOG2))};
  if (!grid.empty()) d.editedBricks.push_back({index, grid});
  deliver(delta, d);
  return index;
}

int SceneData::boxHeadroom(const VoxelBox& box) {
  const glm::i64vec3 side = glm::i64vec3(box.max) - glm::i64vec3(box.min);
  const std::int64_t largest = std::max({side.x, side.y, side.z});
  // Coordinates lie within +-2^30 (Brickmap::kMaxCoordinate), so half a side fits an int.
  return int(std::max<std::int64_t>(kBoxHeadroomVoxels, largest / 2));
}

SceneDelta SceneData::updateObject(std::uint32_t object, std::span<const Brickmap* const> brickmaps,
                                   const EditResult& edit) {
  const std::string call = "updateObject(" + std::to_string(object) + ")";
  if (object >= objects.size())
    throwBadInput(call + ": object out of range (" + std::to_string(objects.size()) + " objects)");
  if (brickmaps.size() != objects.size())
    throwBadInput(call + ": " + std::to_string(brickmaps.size()) + " brickmaps for " +
                  std::to_string(objects.size()) + " objects (one per object expected)");
  if (objectSizes.size() != objects.size())
    throwBadInput(call + ": " + std::to_string(objectSizes.size()) + " objectSizes for " + std::to_string(objects.size()) +
                  " objects (a SceneData made by build and addObject holds one per object)");
  VoxelArrays arrays(*this);
  // The scene's slice of object o in array a: from its base to the next object's (or the array's end).
  auto sliceOf = [&](std::size_t o, int a) {
    const std::size_t end = o + 1 < objects.size() ? baseOf(objects[o + 1], a) : arrays.size(a);
    return end - baseOf(objects[o], a);
  };
  auto sameLayout = [&](std::size_t o, const Brickmap& bm) {
    return sizesOf(bm) == objectSizes[o] && bm.regionOrigin() == glm::ivec3(objects[o].regionOrigin) &&
           bm.regionDims() == glm::ivec3(objects[o].regionDims);
  };
  for (std::size_t o = 0; o < brickmaps.size(); ++o) {
    if (!brickmaps[o]) throwBadInput(call + ": brickmaps[" + std::to_string(o) + "] is null");
    if (o != object && !sameLayout(o, *brickmaps[o]))
      throwBadInput(call + ": brickmaps[" + std::to_string(o) + "] differs in layout from the scene's object " +
                    std::to_string(o) + "; update each edited object on its own");
  }
  const Brickmap& bm = *brickmaps[object];
  const Sizes sizes = sizesOf(bm);
  for (const DirtyRange& r : edit.dirty) {
    const int a = int(r.array);
    if (a < 0 || a >= kVoxelArrays || r.byteOffset > sizes[a] * kElementBytes[a] ||
        r.byteSize > sizes[a] * kElementBytes[a] - r.byteOffset)
      throwBadInput(call + ": the edit's dirty range (" +
                    std::string(a >= 0 && a < kVoxelArrays ? kArrayNames[a] : "?") + ", bytes " +
                    std::to_string(r.byteOffset) + " + " + std::to_string(r.byteSize) +
                    ") lies outside the brickmap's array");
  }

  const bool inPlace = !edit.layoutChanged && !edit.rebuilt && sameLayout(object, bm);
  const bool last = std::size_t(object) + 1 == objects.size();
  const Sizes used = objectSizes[object];
  // Arrays that fit the object's slice change in place; the last object's arrays end where the scene's do, so
  // they grow (or shrink) without moving any other object.
  bool fits = !edit.rebuilt;
  if (!last)
    for (int a = 0; a < kVoxelArrays; ++a) fits = fits && sizes[a] <= sliceOf(object, a);
  const bool extend = !inPlace && fits;
  gpu::ObjectRecord rec = objectRecordOf(bm);
  for (int a = 0; a < kVoxelArrays; ++a) setBase(rec, a, baseOf(objects[object], a));

  SceneDelta d;
  std::vector<gpu::ObjectRecord> relaid;  // every object's record, when the arrays are laid out again
  Sizes totals{};
  if (extend) {
    for (int a = 0; a < kVoxelArrays; ++a) totals[a] = last ? baseOf(rec, a) + sizes[a] : arrays.size(a);
    checkIndexRange(totals, call);
  } else if (!inPlace) {
    relaid = objects;
    relaid[object] = rec;
    for (std::size_t o = 0; o < brickmaps.size(); ++o) {
      const Sizes s = sizesOf(*brickmaps[o]);
      for (int a = 0; a < kVoxelArrays; ++a) {
        setBase(relaid[o], a, totals[a]);
        // The object that outgrew its slice gets headroom, so that its next edits grow in place; the others are
        // laid out densely (headroom kept for every object would add up past a device's binding limits).
        const std::size_t room = o == object && !edit.rebuilt && !last ? s[a] / 2 + 64 : 0;
        totals[a] += s[a] + room;
      }
    }
    checkIndexRange(totals, call);
    rec = relaid[object];
  }

  // The object's box (which rays are clipped to) and with it its instances' world boxes (where rays are
  // re-based, vsInstanceBaseT) decide the last bits of every hit's t on the object. So the box does not follow
  // each edit: it stays while the voxels fit in it (clears never shrink it), and a fill beyond it grows it by
  // boxHeadroom within the region table, so that an edit changes no texel away from itself except when the box
  // grows (then every ray through the instances changes, and the renderer redoes all they cover).
  const gpu::ObjectRecord old = objects[object];
  {
    const VoxelBox was = voxelsOf(old), now = voxelsOf(rec);
    if (!was.empty()) {
      VoxelBox box = was;
      if (!now.empty()) {
        const glm::ivec3 tableMin = glm::ivec3(rec.regionOrigin) * 128;
        const glm::ivec3 tableMax = tableMin + glm::ivec3(rec.regionDims) * 128;
        const int headroom = boxHeadroom(VoxelBox{glm::min(was.min, now.min), glm::max(was.max, now.max)});
        for (int a = 0; a < 3; ++a) {
          // In 64 bits: a coordinate near +-2^30 plus half a side would overflow an int before the clamp.
          if (now.min[a] < box.min[a])
            box.min[a] = int(std::max<std::int64_t>(tableMin[a], std::int64_t(now.min[a]) - headroom));
          if (now.max[a] > box.max[a])
            box.max[a] = int(std::min<std::int64_t>(tableMax[a], std::int64_t(now.max[a]) + headroom));
        }
      }
      rec.voxelMin = glm::ivec4(box.min, 0);
      rec.voxelMax = glm::ivec4(box.max, 0);
    }
  }
  const bool anchorMoves = voxelsOf(old).empty() && !voxelsOf(rec).empty();
  const glm::dvec3 anchorPoint = anchorMoves ? anchorPointOf(voxelsOf(rec)) : objectAnchors[object];
  std::vector<std::pair<std::size_t, gpu::InstanceRecord>> placed;
  std::vector<Aabb> placedBoxes;
  if (anchorMoves || !sameVoxels(old, rec)) {
    for (std::size_t k = 0; k < instances.size(); ++k) {
      if (!instanceActive(k) || instances[k].info.x != object) continue;
      Aabb box;
      placed.push_back({k, makeInstanceRecord(instanceTransforms[k], voxelsOf(rec), anchorPoint, object,
                                              static_cast<std::uint32_t>(k), &box)});
      placedBoxes.push_back(box);
    }
  }

  // Every check passed: from here on the scene changes.
  if (inPlace || extend) {
    if (extend)
      for (int a = 0; a < kVoxelArrays; ++a) {
        const std::size_t before = used[a];
        arrays.resize(a, totals[a]);
        // What the array gained is copied whatever the edit marked; what it lost in a slice is zeroed.
        if (sizes[a] != before && (sizes[a] > before || !last))
          addRange(d, SceneArray(a), (baseOf(rec, a) + std::min(before, sizes[a])) * kElementBytes[a],
                   (std::max(before, sizes[a]) - std::min(before, sizes[a])) * kElementBytes[a]);
      }
    // A grown region table moves the object's every brick code in a box table (and every code after it).
    if (extend &&
        (bm.regionOrigin() != glm::ivec3(old.regionOrigin) || bm.regionDims() != glm::ivec3(old.regionDims))) {
      addRange(d, SceneArray::RegionTable, baseOf(rec, 0) * kElementBytes[0], sizes[0] * kElementBytes[0]);
      d.voxelLayout = true;
    }
    for (const DirtyRange& r : edit.dirty)
      addRange(d, SceneArray(int(r.array)), baseOf(rec, int(r.array)) * kElementBytes[int(r.array)] + r.byteOffset,
               r.byteSize);
    normalizeRanges(d.ranges);
    for (const SceneDirtyRange& r : d.ranges) {
      const int a = int(r.array);
      const std::size_t objectStart = baseOf(rec, a) * kElementBytes[a];
      // The brickmap's bytes, and zeros past its end (a slice it shrank in).
      const std::size_t objectEnd = objectStart + sizes[a] * kElementBytes[a];
      const std::size_t copied = r.byteOffset < objectEnd ? std::min(r.byteSize, objectEnd - r.byteOffset) : 0;
      if (copied)
        std::memcpy(arrays.bytes(a) + r.byteOffset,
                    static_cast<const std::uint8_t*>(bytesOf(bm, a)) + (r.byteOffset - objectStart), copied);
      if (copied < r.byteSize) std::memset(arrays.bytes(a) + r.byteOffset + copied, 0, r.byteSize - copied);
    }
    if (std::memcmp(&old, &rec, sizeof rec) != 0)
      addRange(d, SceneArray::Objects, std::size_t(object) * sizeof(gpu::ObjectRecord), sizeof(gpu::ObjectRecord));
    objects[object] = rec;
  } else {
    relaid[object] = rec;
    for (int a = 0; a < kVoxelArrays; ++a) {
      arrays.resize(a, totals[a]);
      // Headroom holds zeros, not what the old layout left there.
      if (totals[a]) std::memset(arrays.bytes(a), 0, totals[a] * kElementBytes[a]);
      for (std::size_t o = 0; o < brickmaps.size(); ++o) {
        const std::size_t bytes = sizesOf(*brickmaps[o])[a] * kElementBytes[a];
        if (bytes)
          std::memcpy(arrays.bytes(a) + baseOf(relaid[o], a) * kElementBytes[a], bytesOf(*brickmaps[o], a), bytes);
      }
      addRange(d, SceneArray(a), 0, totals[a] * kElementBytes[a]);
    }
    objects = std::move(relaid);
    addRange(d, SceneArray::Objects, 0, objects.size() * sizeof(gpu::ObjectRecord));
    d.voxelLayout = true;
  }
  objectAnchors[object] = anchorPoint;
  if (!inPlace && !extend)
    for (std::size_t o = 0; o < brickmaps.size(); ++o) objectSizes[o] = sizesOf(*brickmaps[o]);
  objectSizes[object] = sizes;
  if (!edit.dirtyVoxels.empty()) d.editedBricks.push_back({object, bricksOf(edit.dirtyVoxels)});
  normalizeRanges(d.ranges);

  if (!placed.empty()) {
    for (std::size_t n = 0; n < placed.size(); ++n) {
      instances[placed[n].first] = placed[n].second;
      instanceBounds[placed[n].first] = placedBoxes[n];
      addRange(d, SceneArray::Instances, placed[n].first * sizeof(gpu::InstanceRecord), sizeof(gpu::InstanceRecord));
    }
    worldBounds = unionOf(instanceBounds);
    d.instances = true;
    normalizeRanges(d.ranges);
    refreshBvh(&d);
  }
  return d;
}

}  // namespace vs
