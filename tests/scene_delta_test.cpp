// Incremental scene changes (compute/scene_data.h): random edits, added objects and instance changes on a small
// scene, each checked for what its SceneDelta says (every changed byte inside a reported range; the voxel
// arrays still the brickmaps' dense concatenation), for the box table updated around the edit against a whole
// build, and for traced texels: a CpuTracer kept across the changes (sceneChanged) and a VulkanTracer kept
// across them (update), with and without split bindings, against tracers given the scene anew, bit for bit.
// Also the removed-slot rule (no hit on an empty slot, the lowest slot reused), kept anchors, the one BVH
// rule, and refusals that change nothing.
#include <algorithm>
#include <bit>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "compute/box_table.h"
#include "compute/cpu/cpu_tracer.h"
#include "compute/cpu/scene_arrays.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "support/test_scenes.h"
#include "voxel/error.h"

namespace vs {
namespace {

using Bytes = std::vector<std::uint8_t>;

template <class T>
Bytes bytesOf(const std::vector<T>& v) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
  return Bytes(p, p + v.size() * sizeof(T));
}
template <class T>
Bytes bytesOf(std::span<const T> v) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
  return Bytes(p, p + v.size() * sizeof(T));
}

// The bytes of one scene array as SceneDelta names them.
Bytes arrayBytes(const SceneData& s, SceneArray a) {
  switch (a) {
    case SceneArray::RegionTable: return bytesOf(s.regionTable);
    case SceneArray::Regions: return bytesOf(s.regions);
    case SceneArray::Sectors: return bytesOf(s.sectors);
    case SceneArray::Bricks: return bytesOf(s.bricks);
    case SceneArray::Occupancy: return bytesOf(s.occupancy);
    case SceneArray::Payload: return bytesOf(s.payload);
    case SceneArray::Objects: return bytesOf(s.objects);
    case SceneArray::Instances: return bytesOf(s.instances);
    case SceneArray::Bvh: {
      Bytes b = bytesOf(s.bvh.nodes());
      Bytes i = bytesOf(s.bvh.instanceIndices()), e = bytesOf(s.bvh.nodeEscapes());
      b.insert(b.end(), i.begin(), i.end());
      b.insert(b.end(), e.begin(), e.end());
      return b;
    }
  }
  return {};
}
constexpr SceneArray kArrays[] = {SceneArray::RegionTable, SceneArray::Regions,   SceneArray::Sectors,
                                  SceneArray::Bricks,      SceneArray::Occupancy, SceneArray::Payload,
                                  SceneArray::Objects,     SceneArray::Instances, SceneArray::Bvh};
bool isVoxelArray(SceneArray a) { return int(a) <= int(SceneArray::Payload); }

struct Snapshot {
  std::vector<Bytes> arrays;
  explicit Snapshot(const SceneData& s) {
    for (SceneArray a : kArrays) arrays.push_back(arrayBytes(s, a));
  }
};

// Every byte that differs from `before` (or is new) lies in one of the delta's ranges, unless the delta says the
// whole array must be copied (voxelLayout for the voxel arrays and objects).
void expectDeltaCovers(const Snapshot& before, const SceneData& after, const SceneDelta& delta,
                       const std::string& what) {
  for (std::size_t k = 0; k < std::size(kArrays); ++k) {
    const SceneArray a = kArrays[k];
    if (delta.voxelLayout && (isVoxelArray(a) || a == SceneArray::Objects)) continue;
    const Bytes now = arrayBytes(after, a);
    const Bytes& old = before.arrays[k];
    std::vector<std::uint8_t> covered(now.size(), 0);
    for (const SceneDirtyRange& r : delta.ranges)
      if (r.array == a)
        for (std::size_t i = r.byteOffset; i < std::min(now.size(), r.byteOffset + r.byteSize); ++i) covered[i] = 1;
    std::size_t missed = 0;
    for (std::size_t i = 0; i < now.size(); ++i)
      if ((i >= old.size() || old[i] != now[i]) && !covered[i]) ++missed;
    EXPECT_EQ(missed, 0u) << what << ": " << missed << " changed bytes of array " << int(a) << " outside the delta";
    if (!isVoxelArray(a) && a != SceneArray::Objects && old != now) {
      EXPECT_TRUE(delta.instances) << what << ": instance arrays changed without delta.instances";
    }
  }
}

// The voxel arrays hold each brickmap's arrays at its object's bases (SceneData::objectSizes of them), in
// object order without overlap, and zeros in any headroom after them; the object records are a fresh build's
// but for the bases.
void expectConcatenation(const SceneData& s, const std::vector<const Brickmap*>& brickmaps, const std::string& what) {
  SceneData fresh = SceneData::build(brickmaps, {});
  ASSERT_EQ(s.objectSizes.size(), brickmaps.size()) << what;
  auto expectSlices = [&](const auto& array, auto member, int a, const char* name) {
    const std::size_t elementBytes = sizeof(array[0]);
    std::vector<std::uint8_t> expected(array.size() * elementBytes, 0);
    std::size_t end = 0;
    for (std::size_t o = 0; o < brickmaps.size(); ++o) {
      const auto source = ((*brickmaps[o]).*member)();
      const std::size_t base = a < 4 ? s.objects[o].bases[a] : s.objects[o].bases2[a - 4];
      EXPECT_EQ(s.objectSizes[o][std::size_t(a)], source.size()) << what << ": " << name << " of object " << o;
      EXPECT_GE(base, end) << what << ": " << name << " of object " << o << " overlaps the one before";
      ASSERT_LE((base + source.size()) * elementBytes, expected.size()) << what << ": " << name;
      if (!source.empty()) std::memcpy(expected.data() + base * elementBytes, source.data(), source.size() * elementBytes);
      end = base + source.size();
    }
    EXPECT_TRUE(bytesOf(array) == expected) << what << ": " << name;
  };
  expectSlices(s.regionTable, &Brickmap::regionTable, 0, "regionTable");
  expectSlices(s.regions, &Brickmap::regions, 1, "regions");
  expectSlices(s.sectors, &Brickmap::sectors, 2, "sectors");
  expectSlices(s.bricks, &Brickmap::bricks, 3, "bricks");
  expectSlices(s.occupancy, &Brickmap::occupancyWords, 4, "occupancy");
  expectSlices(s.payload, &Brickmap::payloadWords, 5, "payload");
  ASSERT_EQ(s.objects.size(), fresh.objects.size()) << what;
  // The kept voxel box may be larger than a fresh build's tight one (SceneData::boxHeadroom): it holds
  // every voxel and stays inside the object's region table; every other field is the fresh record's.
  for (std::size_t o = 0; o < s.objects.size(); ++o) {
    gpu::ObjectRecord kept = s.objects[o];
    const gpu::ObjectRecord& tight = fresh.objects[o];
    const bool freshEmpty = glm::any(glm::greaterThanEqual(glm::ivec3(tight.voxelMin), glm::ivec3(tight.voxelMax)));
    if (!freshEmpty) {
      const glm::ivec3 tableMin = glm::ivec3(kept.regionOrigin) * 128;
      const glm::ivec3 tableMax = tableMin + glm::ivec3(kept.regionDims) * 128;
      EXPECT_TRUE(glm::all(glm::lessThanEqual(glm::ivec3(kept.voxelMin), glm::ivec3(tight.voxelMin))) &&
                  glm::all(glm::greaterThanEqual(glm::ivec3(kept.voxelMax), glm::ivec3(tight.voxelMax))))
          << what << ": object " << o << "'s box does not hold its voxels";
      EXPECT_TRUE(glm::all(glm::greaterThanEqual(glm::ivec3(kept.voxelMin), tableMin)) &&
                  glm::all(glm::lessThanEqual(glm::ivec3(kept.voxelMax), tableMax)))
          << what << ": object " << o << "'s box leaves its region table";
    }
    kept.voxelMin = tight.voxelMin;
    kept.voxelMax = tight.voxelMax;
    kept.bases = tight.bases;
    kept.bases2 = tight.bases2;
    EXPECT_EQ(std::memcmp(&kept, &tight, sizeof(gpu::ObjectRecord)), 0) << what << ": object " << o;
  }
}

// Instance records, boxes, world bounds and BVH as the slots say: active slots placed about their kept anchor,
// empty slots with empty boxes, the BVH listing exactly the active instances with a box.
void expectInstances(const SceneData& s, const std::string& what) {
  ASSERT_EQ(s.instances.size(), s.instanceSlots.size()) << what;
  ASSERT_EQ(s.instances.size(), s.instanceBounds.size()) << what;
  ASSERT_EQ(s.instances.size(), s.instanceTransforms.size()) << what;
  Aabb world;
  std::vector<std::uint32_t> expectedLeaves;
  for (std::size_t i = 0; i < s.instances.size(); ++i) {
    EXPECT_EQ(s.instances[i].info.y, i) << what << ": instance id of slot " << i;
    if (!s.instanceActive(i)) {
      EXPECT_TRUE(s.instanceBounds[i].empty()) << what << ": empty slot " << i << " has a box";
      continue;
    }
    const std::uint32_t o = s.instances[i].info.x;
    ASSERT_LT(o, s.objects.size());
    Aabb box;
    gpu::InstanceRecord rec = makeInstanceRecord(
        s.instanceTransforms[i], VoxelBox{glm::ivec3(s.objects[o].voxelMin), glm::ivec3(s.objects[o].voxelMax)},
        s.objectAnchors[o], o, std::uint32_t(i), &box);
    EXPECT_EQ(std::memcmp(&rec, &s.instances[i], sizeof rec), 0) << what << ": record of instance " << i;
    if (!box.empty()) {
      world.extend(box);
      expectedLeaves.push_back(std::uint32_t(i));
    }
  }
  EXPECT_EQ(world.empty(), s.worldBounds.empty()) << what;
  if (!world.empty()) {
    EXPECT_EQ(world.min, s.worldBounds.min) << what;
    EXPECT_EQ(world.max, s.worldBounds.max) << what;
  }
  std::vector<std::uint32_t> leaves(s.bvh.instanceIndices().begin(), s.bvh.instanceIndices().end());
  std::sort(leaves.begin(), leaves.end());
  // A refit tree may still list an active instance whose object lost every voxel; never an empty slot.
  for (std::uint32_t l : leaves) EXPECT_TRUE(s.instanceActive(l)) << what << ": the BVH lists empty slot " << l;
  for (std::uint32_t l : expectedLeaves)
    EXPECT_TRUE(std::binary_search(leaves.begin(), leaves.end(), l)) << what << ": the BVH misses instance " << l;
}

// A fixed box all the test's instances stay inside, so that views do not follow the world's bounds.
const Aabb kViewBox{glm::vec3(-70.0f), glm::vec3(70.0f)};

std::vector<gpu::TraceView> testViews() {
  std::vector<gpu::TraceView> views;
  views.push_back(test::directionalView(kViewBox, {-0.35f, -1.0f, -0.25f}, 40));
  views.push_back(test::directionalView(kViewBox, {0.6f, -0.3f, 0.7f}, 40));
  views.push_back(test::distanceView({5.0f, 60.0f, -8.0f}, {0.0f, -1.0f, 0.1f}, 200.0f, 32, 100.0f));
  return views;
}

std::size_t texelMismatches(const std::vector<ShadowLayer>& a, const std::vector<ShadowLayer>& b) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t t = 0; t < a[i].texels.size(); ++t)
      if (std::memcmp(&a[i].texels[t], &b[i].texels[t], sizeof(float)) != 0) ++n;
  return n;
}

std::size_t hits(const std::vector<ShadowLayer>& layers, const std::vector<gpu::TraceView>& views) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const float miss = views[i].info.z == gpu::VS_ENCODING_NDC_DEPTH ? 1.0f : views[i].eyeHigh.w;
    for (float t : layers[i].texels) n += t < miss ? 1 : 0;
  }
  return n;
}

Brickmap randomObject(std::mt19937& rng, int size) {
  std::vector<SolidVoxel> voxels;
  std::uniform_int_distribution<int> coord(0, size - 1), material(1, 255);
  // A floor, a few boxes, and scattered voxels.
  for (int z = 0; z < size; ++z)
    for (int x = 0; x < size; ++x) voxels.push_back({{x, 0, z}, std::uint8_t(1 + (x + z) % 3)});
  for (int b = 0; b < 4; ++b) {
    glm::ivec3 lo(coord(rng), coord(rng) / 2, coord(rng)),
        ext(1 + coord(rng) / 4, 1 + coord(rng) / 3, 1 + coord(rng) / 4);
    glm::ivec3 hi = glm::min(lo + ext, glm::ivec3(size));
    std::uint8_t m = std::uint8_t(material(rng));
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) voxels.push_back({{x, y, z}, m});
  }
  for (int i = 0; i < 200; ++i) voxels.push_back({{coord(rng), coord(rng), coord(rng)}, std::uint8_t(material(rng))});
  return Brickmap::build(voxels);
}

glm::dmat4 randomPlacement(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  glm::dmat4 m = glm::translate(glm::dmat4(1.0), glm::dvec3(25.0 * u(rng), 10.0 * u(rng), 25.0 * u(rng)));
  m = glm::rotate(m, 3.0 * u(rng), glm::normalize(glm::dvec3(u(rng), 1.0 + u(rng) * 0.5, u(rng))));
  m = glm::scale(m, glm::dvec3(0.3 + 0.05 * u(rng), 0.3 + 0.05 * u(rng), 0.3 + 0.05 * u(rng)));
  return m;
}

bool validationOn() {
  const char* v = std::getenv("VOXSHADOW_VALIDATION");
  return v && std::string(v) == "1";
}

void expectNoValidationMessages(const VulkanTracer& tracer) {
  for (const std::string& m : tracer.validationMessages()) ADD_FAILURE() << "validation: " << m;
}

// The scene of the random sequence: its brickmaps (edited in place) and the SceneData kept across changes.
struct World {
  std::vector<std::unique_ptr<Brickmap>> brickmaps;
  SceneData data;
  std::vector<const Brickmap*> pointers() const {
    std::vector<const Brickmap*> p;
    for (const auto& b : brickmaps) p.push_back(b.get());
    return p;
  }
};

TEST(SceneDelta, RandomChangesKeepArraysTablesAndTexelsExact) {
  std::mt19937 rng(20240611);
  World world;
  world.brickmaps.push_back(std::make_unique<Brickmap>(randomObject(rng, 48)));
  world.brickmaps.push_back(std::make_unique<Brickmap>(randomObject(rng, 32)));
  world.brickmaps.push_back(std::make_unique<Brickmap>(randomObject(rng, 64)));
  std::vector<SceneInstance> placed;
  for (int i = 0; i < 5; ++i) placed.push_back({std::uint32_t(i % 3), randomPlacement(rng)});
  const std::vector<const Brickmap*> initial = world.pointers();
  world.data = SceneData::build(initial, placed);
  expectInstances(world.data, "built");

  const std::vector<gpu::TraceView> views = testViews();
  CpuTracer keptCpu(world.data);
  std::vector<std::int32_t> table = buildBoxTable(world.data);
  ASSERT_FALSE(table.empty());

  std::unique_ptr<VulkanTracer> kept, fresh, keptSplit;
  try {
    kept = std::make_unique<VulkanTracer>();
  } catch (const Error& e) {
    ADD_FAILURE() << "no Vulkan device: " << e.what();
  }
  if (kept) {
    if (validationOn()) {
      EXPECT_TRUE(kept->context().validationEnabled());
    }
    fresh = std::make_unique<VulkanTracer>();
    VulkanOptions splitOptions;
    // The largest voxel arrays over two bindings at first (and up to four as they grow).
    splitOptions.maxBindingBytes =
        std::bit_ceil(std::max(world.data.occupancy.size(), world.data.payload.size()) * sizeof(std::uint32_t)) / 2;
    keptSplit = std::make_unique<VulkanTracer>(splitOptions);
    kept->upload(world.data);
    keptSplit->upload(world.data);
    EXPECT_TRUE(kept->boxTableInUse());
  }
  std::vector<ShadowLayer> warm;
  keptCpu.trace(views, warm);

  std::uniform_int_distribution<int> pick(0, 99), material(0, 255), small(1, 12);
  int inPlaceEdits = 0, relaidEdits = 0, localTables = 0, checkedUploads = 0, steps = 0, traced = 0;
  for (int step = 0; step < 70; ++step) {
    const Snapshot before(world.data);
    const SceneData previous = world.data;
    SceneDelta delta;
    std::string what = "step " + std::to_string(step);
    const int op = pick(rng);
    const std::uint32_t objects = std::uint32_t(world.brickmaps.size());
    bool voxelEdit = false;
    if (op < 55) {
      // A voxel edit of one object: boxes and single voxels, fills and clears, material 0, and now and then a
      // box beyond the object's region table (which grows it).
      const std::uint32_t o = std::uniform_int_distribution<std::uint32_t>(0, objects - 1)(rng);
      Brickmap& bm = *world.brickmaps[o];
      const VoxelBox b = bm.bounds();
      const glm::ivec3 lo = b.empty() ? glm::ivec3(0) : b.min, hi = b.empty() ? glm::ivec3(16) : b.max;
      glm::ivec3 at(std::uniform_int_distribution<int>(lo.x - 4, hi.x + 4)(rng),
                    std::uniform_int_distribution<int>(lo.y - 4, hi.y + 4)(rng),
                    std::uniform_int_distribution<int>(lo.z - 4, hi.z + 4)(rng));
      if (pick(rng) < 8) at[pick(rng) % 3] += 130;  // outside the region table
      EditResult edit;
      const int kind = pick(rng) % 5;
      if (kind == 0) {
        edit = bm.setVoxel(at, std::uint8_t(material(rng)));
        what += ": setVoxel";
      } else if (kind == 1) {
        edit = bm.fillBox({at, at + glm::ivec3(small(rng), small(rng), small(rng))},
                          std::uint8_t(1 + material(rng) % 255));
        what += ": fillBox";
      } else if (kind == 2) {
        edit = bm.clearBox({at - glm::ivec3(small(rng)), at + glm::ivec3(small(rng), small(rng), small(rng))});
        what += ": clearBox";
      } else if (kind == 3) {
        edit = bm.fillBox({at, at + glm::ivec3(small(rng), 2, small(rng))}, 0);
        what += ": fillBox material 0";
      } else {
        if (pick(rng) < 10) {
          edit = bm.compact();
          what += ": compact";
        } else {
          edit = bm.clearVoxel(at);
          what += ": clearVoxel";
        }
      }
      bm.checkConsistency();
      delta = world.data.updateObject(o, world.pointers(), edit);
      voxelEdit = true;
      (delta.voxelLayout ? relaidEdits : inPlaceEdits) += 1;
    } else if (op < 60 && objects < 5) {
      world.brickmaps.push_back(std::make_unique<Brickmap>(randomObject(rng, 32)));
      const std::uint32_t o = world.data.addObject(*world.brickmaps.back(), &delta);
      EXPECT_EQ(o, objects) << what;
      EXPECT_FALSE(delta.voxelLayout) << what << ": addObject moved no object";
      what += ": addObject";
    } else if (op < 70) {
      const std::uint32_t o = std::uniform_int_distribution<std::uint32_t>(0, objects - 1)(rng);
      std::size_t expectedSlot = 0;
      while (expectedSlot < world.data.instanceSlots.size() && world.data.instanceActive(expectedSlot)) ++expectedSlot;
      EXPECT_EQ(world.data.addInstance({o, randomPlacement(rng)}, &delta), expectedSlot) << what;
      what += ": addInstance";
    } else {
      std::vector<std::size_t> active;
      for (std::size_t i = 0; i < world.data.instances.size(); ++i)
        if (world.data.instanceActive(i)) active.push_back(i);
      if (active.empty()) continue;
      const std::size_t i = active[std::size_t(pick(rng)) % active.size()];
      if (op < 78 && active.size() > 1) {
        world.data.removeInstance(i, &delta);
        EXPECT_FALSE(world.data.instanceActive(i));
        what += ": removeInstance";
      } else if (op < 88) {
        const std::uint32_t o = std::uniform_int_distribution<std::uint32_t>(0, objects - 1)(rng);
        world.data.setInstanceObject(i, o, world.data.instanceTransforms[i], &delta);
        what += ": setInstanceObject";
      } else {
        world.data.moveInstance(i, randomPlacement(rng), &delta);
        what += ": moveInstance";
      }
    }
    ++steps;
    SCOPED_TRACE(what);

    // (a) the arrays: every change inside the delta; the voxel arrays the brickmaps' concatenation.
    expectDeltaCovers(before, world.data, delta, what);
    expectConcatenation(world.data, world.pointers(), what);
    expectInstances(world.data, what);
    if (voxelEdit) {
      // Edits keep every anchor (an object without voxels before takes one from its first voxels).
      for (std::size_t i = 0; i < world.data.instances.size(); ++i) {
        if (!world.data.instanceActive(i) || !previous.instanceActive(i)) continue;
        const gpu::ObjectRecord& was = previous.objects[previous.instances[i].info.x];
        if (VoxelBox{glm::ivec3(was.voxelMin), glm::ivec3(was.voxelMax)}.empty()) continue;
        EXPECT_EQ(std::memcmp(&world.data.instances[i].anchor, &previous.instances[i].anchor, sizeof(glm::vec4)), 0)
            << what << ": the anchor of instance " << i << " moved";
        EXPECT_EQ(std::memcmp(&world.data.instances[i].worldToBrick, &previous.instances[i].worldToBrick,
                              sizeof(gpu::Affine)),
                  0)
            << what << ": the affine of instance " << i << " changed";
      }
    }

    // (b) the box table updated around the edit equals a whole build.
    const BoxTableUpdate update = updateBoxTable(table, world.data, delta);
    const std::vector<std::int32_t> full = buildBoxTable(world.data);
    ASSERT_EQ(table.size(), full.size()) << what;
    std::size_t differ = 0;
    for (std::size_t e = 0; e < full.size(); ++e) differ += table[e] != full[e] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << what << ": box table elements differ from a whole build (local: " << !update.rebuilt
                          << ")";
    if (!update.rebuilt && (!delta.editedBricks.empty())) ++localTables;
    if (voxelEdit && !delta.voxelLayout) {
      EXPECT_FALSE(update.rebuilt) << what << ": an in-place edit rebuilt the table";
    }

    // (c) traced texels: the tracers kept across changes against tracers given the scene anew.
    keptCpu.sceneChanged(delta);
    if (step % 2 == 1 || voxelEdit) {
      ++traced;
      std::vector<ShadowLayer> keptLayers = warm, freshLayers;
      keptCpu.trace(views, keptLayers);
      CpuTracer(world.data).trace(views, freshLayers);
      EXPECT_EQ(texelMismatches(keptLayers, freshLayers), 0u) << what << ": kept CpuTracer";
      warm = keptLayers;
      if (kept) {
        const std::uint64_t uploadedBefore = kept->bytesUploaded();
        const int growthsBefore = kept->bufferGrowths();
        kept->update(world.data, delta);
        const std::uint64_t uploaded = kept->bytesUploaded() - uploadedBefore;
        // A growth copies its array whole (and is counted); otherwise an edit copies its ranges only.
        if (voxelEdit && !delta.voxelLayout && kept->bufferGrowths() == growthsBefore) {
          std::uint64_t bound = delta.rangeBytes();
          for (const auto& r : update.rewritten) bound += r.second * sizeof(std::int32_t);
          EXPECT_LE(uploaded, bound) << what << ": uploaded more than the delta and the rewritten table";
          ++checkedUploads;
        }
        keptSplit->update(world.data, delta);
        fresh->upload(world.data);
        std::vector<ShadowLayer> gpuKept, gpuFresh, gpuSplit;
        kept->trace(views, gpuKept);
        fresh->trace(views, gpuFresh);
        keptSplit->trace(views, gpuSplit);
        EXPECT_EQ(kept->boxTableInUse(), fresh->boxTableInUse()) << what;
        EXPECT_EQ(texelMismatches(gpuKept, gpuFresh), 0u) << what << ": kept VulkanTracer";
        EXPECT_EQ(texelMismatches(gpuSplit, gpuFresh), 0u) << what << ": kept VulkanTracer, split bindings";
        EXPECT_EQ(texelMismatches(gpuFresh, freshLayers), 0u) << what << ": Vulkan against CPU";
      }
    } else if (kept) {
      // Deltas of untraced steps are handed over one by one as well.
      kept->update(world.data, delta);
      keptSplit->update(world.data, delta);
    }
  }
  std::printf("  %d changes: %d in-place edits, %d relaid, %d local tables, %d traced, %d upload bounds checked\n",
              steps, inPlaceEdits, relaidEdits, localTables, traced, checkedUploads);
  std::vector<ShadowLayer> last;
  keptCpu.trace(views, last);
  EXPECT_GT(hits(last, views), 100u) << "the views must see the scene";
  EXPECT_GT(inPlaceEdits, 10) << "steps " << steps;
  EXPECT_GT(relaidEdits, 2);
  EXPECT_GT(localTables, 10);
  EXPECT_GT(traced, 20);
  if (kept) {
    EXPECT_GT(checkedUploads, 5);
    EXPECT_GE(std::max(keptSplit->bufferCount(SplitArray::Occupancy), keptSplit->bufferCount(SplitArray::Payload)), 2)
        << "the split tracer must split";
    EXPECT_GT(kept->bufferGrowths(), 0) << "appends must have grown some buffer";
    expectNoValidationMessages(*kept);
    expectNoValidationMessages(*fresh);
    expectNoValidationMessages(*keptSplit);
  }
}

// Box tables of a larger object (several regions) under small edits, so that the updated window lies strictly
// inside the object's brick grid: element for element equal to a whole build after every edit.
TEST(SceneDelta, LocalBoxTableEqualsWholeBuildInsideLargeObjects) {
  std::mt19937 rng(7);
  std::vector<SolidVoxel> voxels;
  std::uniform_int_distribution<int> x(0, 383), y(0, 255), z(0, 255), m(1, 255);
  for (int i = 0; i < 3000; ++i) voxels.push_back({{x(rng), y(rng) / 4, z(rng)}, std::uint8_t(m(rng))});
  for (int i = 0; i < 40; ++i) {
    glm::ivec3 lo(x(rng), y(rng) / 2, z(rng));
    for (int k = 0; k < 64; ++k) voxels.push_back({lo + glm::ivec3(k % 4, k / 16, (k / 4) % 4), 7});
  }
  // The large object last, so that its arrays grow in place (another object's growth lays the arrays out again).
  Brickmap small = randomObject(rng, 40), large = Brickmap::build(voxels);
  std::vector<const Brickmap*> ptrs{&small, &large};
  SceneData scene = SceneData::build(ptrs, std::vector<SceneInstance>{{0, glm::dmat4(1.0)}, {1, glm::dmat4(1.0)}});
  std::vector<std::int32_t> table = buildBoxTable(scene);
  ASSERT_FALSE(table.empty());
  ASSERT_GE(large.regionDims().x * large.regionDims().y * large.regionDims().z, 8);
  // Edits stay inside the region table, which then does not grow.
  const glm::ivec3 tableLo = large.regionOrigin() * 128, tableHi = (large.regionOrigin() + large.regionDims()) * 128;
  std::uniform_int_distribution<int> pick(0, 3), len(1, 20), ax(tableLo.x + 20, tableHi.x - 41),
      ay(tableLo.y + 20, tableHi.y - 41), az(tableLo.z + 20, tableHi.z - 41);
  for (int step = 0; step < 40; ++step) {
    glm::ivec3 at(ax(rng), ay(rng), az(rng));
    EditResult edit;
    switch (pick(rng)) {
      case 0: edit = large.setVoxel(at, std::uint8_t(m(rng))); break;
      case 1: edit = large.fillBox({at, at + glm::ivec3(len(rng), len(rng), len(rng))}, 3); break;
      case 2: edit = large.clearBox({at - glm::ivec3(len(rng)), at + glm::ivec3(len(rng) * 2)}); break;
      default: edit = large.clearBox({tableLo, tableHi}); break;
    }
    SceneDelta delta = scene.updateObject(1, ptrs, edit);
    ASSERT_FALSE(delta.voxelLayout) << step;
    const std::vector<std::int32_t> before = table;
    const BoxTableUpdate u = updateBoxTable(table, scene, delta);
    EXPECT_FALSE(u.rebuilt) << step;
    const std::vector<std::int32_t> full = buildBoxTable(scene);
    ASSERT_EQ(table.size(), full.size()) << step;
    EXPECT_TRUE(table == full) << "step " << step;
    // Every element that changed lies in a reported range (a device copy updated by those ranges alone equals
    // the table), and the ranges report little that did not change.
    std::vector<std::uint8_t> reported(table.size(), 0);
    for (const auto& [first, count] : u.rewritten) std::fill_n(reported.begin() + std::ptrdiff_t(first), count, 1);
    std::size_t missed = 0, unchanged = 0, changed = 0;
    for (std::size_t i = 0; i < table.size(); ++i) {
      const bool differs = i >= before.size() || before[i] != table[i];
      changed += differs;
      missed += differs && !reported[i];
      unchanged += !differs && reported[i];
    }
    EXPECT_EQ(missed, 0u) << "step " << step;
    EXPECT_LE(unchanged, 8 * changed + 64) << "step " << step;
    // Only the codes within kMaxBoxExtent bricks of the edit, and the occupancy words the edit wrote.
    std::size_t rewritten = 0, bound = 0;
    for (const auto& r : u.rewritten) rewritten += r.second;
    for (const ObjectBricks& e : delta.editedBricks) {
      const glm::ivec3 gridLo = glm::ivec3(scene.objects[1].regionOrigin) * 16;
      const glm::ivec3 gridHi = gridLo + glm::ivec3(scene.objects[1].regionDims) * 16;
      const glm::ivec3 lo = glm::max(e.bricks.min - kMaxBoxExtent, gridLo),
                       hi = glm::min(e.bricks.max + kMaxBoxExtent, gridHi);
      bound += std::size_t(hi.x - lo.x) * std::size_t(hi.y - lo.y) * std::size_t(hi.z - lo.z);
    }
    for (const SceneDirtyRange& r : delta.ranges)
      if (r.array == SceneArray::Occupancy) bound += r.byteSize / sizeof(std::uint32_t);
    EXPECT_LE(rewritten, bound) << "step " << step;
    if (step % 10 == 9) {
      // Everything cleared now and then, and the scene refilled.
      SceneDelta refill = scene.updateObject(1, ptrs, large.fillBox({at, at + glm::ivec3(9)}, 5));
      updateBoxTable(table, scene, refill);
      EXPECT_TRUE(table == buildBoxTable(scene)) << "step " << step << ", refilled";
    }
  }
}

// A removed instance leaves an empty slot: no ray hits it (on every path), the BVH leaves it out, and the
// next addInstance takes the lowest empty slot, its id the slot.
TEST(SceneDelta, RemovedSlotsAreNeverHitAndAreReused) {
  std::vector<std::unique_ptr<Brickmap>> bms;
  bms.push_back(test::boxObject({0, 0, 0}, {16, 16, 16}));
  std::vector<const Brickmap*> ptrs{bms[0].get()};
  // Four cubes in a column under the ray: y = 0, 10, 20, 30 (world units, one voxel = 0.5).
  std::vector<SceneInstance> inst;
  for (int i = 0; i < 4; ++i)
    inst.push_back({0, glm::scale(glm::translate(glm::dmat4(1.0), glm::dvec3(-4.0, 10.0 * i, -4.0)), glm::dvec3(0.5))});
  SceneData scene = SceneData::build(ptrs, inst);
  const gpu::TraceRay down = gpu::makeTraceRay(glm::dvec3(0.0, 100.0, 0.0), glm::vec3(0, -1, 0), 0.0f, 1000.0f);
  auto closest = [&](CpuTracePath path) {
    std::vector<gpu::RayHit> h(1);
    CpuTracer(scene).traceClosest(std::span<const gpu::TraceRay>(&down, 1), h, path);
    return h[0];
  };
  auto expectTop = [&](std::uint32_t instance, const char* what) {
    for (CpuTracePath path : {CpuTracePath::Reference, CpuTracePath::Interleaved, CpuTracePath::PortableTiles}) {
      gpu::RayHit h = closest(path);
      EXPECT_EQ(h.hit, 1u) << what << ", path " << int(path);
      EXPECT_EQ(h.instance, instance) << what << ", path " << int(path);
    }
  };
  expectTop(3, "all four");
  SceneDelta d;
  scene.removeInstance(3, &d);
  EXPECT_TRUE(d.instances);
  EXPECT_FALSE(scene.instanceActive(3));
  expectTop(2, "top removed");
  scene.removeInstance(1, &d);
  expectTop(2, "two removed");
  // The empty slot's record cannot hit even when walked directly.
  {
    gpu::SceneArrays arrays(scene);
    gpu::SceneArrays::WorldRay ray = arrays.vsTraceRayToWorld(down);
    float t = 0.0f;
    glm::ivec3 v(0);
    EXPECT_FALSE(arrays.vsTraceInstance(ray, 3u, false, ray.tMax, t, v));
    EXPECT_TRUE(arrays.vsTraceInstance(ray, 2u, false, ray.tMax, t, v));
  }
  for (std::uint32_t leaf : scene.bvh.instanceIndices()) EXPECT_TRUE(leaf == 0u || leaf == 2u) << leaf;
  EXPECT_THROW(scene.removeInstance(3, &d), Error);
  EXPECT_THROW(scene.moveInstance(3, glm::dmat4(1.0)), Error);
  EXPECT_THROW(scene.setInstanceObject(1, 0, glm::dmat4(1.0)), Error);
  // Lowest empty slot first, then a new one.
  const glm::dmat4 high = glm::scale(glm::translate(glm::dmat4(1.0), glm::dvec3(-4.0, 40.0, -4.0)), glm::dvec3(0.5));
  EXPECT_EQ(scene.addInstance({0, high}, &d), 1u);
  EXPECT_EQ(scene.instances[1].info.y, 1u);
  expectTop(1, "slot 1 reused, highest");
  EXPECT_EQ(scene.addInstance({0, glm::dmat4(1.0)}, &d), 3u);
  EXPECT_EQ(scene.addInstance({0, glm::dmat4(1.0)}, &d), 4u);
  expectInstances(scene, "reused");
  // Everything removed: a miss.
  for (std::size_t i = 0; i < scene.instances.size(); ++i) scene.removeInstance(i, &d);
  EXPECT_TRUE(scene.bvh.nodes().empty());
  EXPECT_TRUE(scene.worldBounds.empty());
  EXPECT_EQ(closest(CpuTracePath::Reference).hit, 0u);
  EXPECT_EQ(closest(CpuTracePath::Interleaved).hit, 0u);
  EXPECT_EQ(scene.addInstance({0, glm::dmat4(1.0)}, &d), 0u);
  EXPECT_EQ(closest(CpuTracePath::Reference).hit, 1u);
}

// An edit that grows an object keeps its instances' anchors (and so their affines), where a scene built anew
// from the edited brickmap centres them on the grown box.
TEST(SceneDelta, EditsKeepAnchors) {
  std::vector<std::unique_ptr<Brickmap>> bms;
  bms.push_back(test::boxObject({0, 0, 0}, {20, 20, 20}));
  std::vector<const Brickmap*> ptrs{bms[0].get()};
  const glm::dmat4 m =
      glm::rotate(glm::translate(glm::dmat4(1.0), glm::dvec3(1000.25, 3.0, -7.5)), 0.7, glm::dvec3(0, 1, 0));
  SceneData scene = SceneData::build(ptrs, std::vector<SceneInstance>{{0, m}});
  const gpu::InstanceRecord before = scene.instances[0];
  SceneDelta d = scene.updateObject(0, ptrs, bms[0]->setVoxel({40, 3, 3}, 9));
  EXPECT_TRUE(d.instances);
  const gpu::InstanceRecord after = scene.instances[0];
  EXPECT_EQ(std::memcmp(&before.worldToBrick, &after.worldToBrick, sizeof(gpu::Affine)), 0);
  EXPECT_EQ(std::memcmp(&before.brickToWorld, &after.brickToWorld, sizeof(gpu::Affine)), 0);
  EXPECT_EQ(std::memcmp(&before.anchor, &after.anchor, sizeof before.anchor), 0);
  EXPECT_NE(before.boundsMax.x, after.boundsMax.x);
  const SceneData rebuilt = SceneData::build(ptrs, std::vector<SceneInstance>{{0, m}});
  EXPECT_NE(std::memcmp(&rebuilt.instances[0].anchor, &after.anchor, sizeof after.anchor), 0)
      << "a scene built anew centres the anchor on the grown box";
  // A move places the anchor anew, at the image of the kept point.
  scene.moveInstance(0, m);
  EXPECT_EQ(std::memcmp(&scene.instances[0].anchor, &before.anchor, sizeof before.anchor), 0);
}

// Refused calls throw BadInput and leave every array as it was.
TEST(SceneDelta, RefusalsChangeNothing) {
  std::vector<std::unique_ptr<Brickmap>> bms;
  bms.push_back(test::boxObject({0, 0, 0}, {20, 20, 20}));
  bms.push_back(test::boxObject({0, 0, 0}, {8, 8, 8}));
  std::vector<const Brickmap*> ptrs{bms[0].get(), bms[1].get()};
  SceneData scene = SceneData::build(ptrs, std::vector<SceneInstance>{{0, glm::dmat4(1.0)}, {1, glm::dmat4(1.0)}});
  auto expectRefused = [&](const std::function<void()>& change, const char* what) {
    const Snapshot before(scene);
    try {
      change();
      ADD_FAILURE() << what << ": not refused";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput) << what;
      EXPECT_FALSE(std::string(e.what()).empty());
    }
    const Snapshot after(scene);
    EXPECT_TRUE(before.arrays == after.arrays) << what << ": changed the scene";
  };
  glm::dmat4 singular(1.0);
  singular[1] = glm::dvec4(0.0);
  expectRefused([&] { scene.addInstance({5, glm::dmat4(1.0)}); }, "addInstance of a missing object");
  expectRefused([&] { scene.addInstance({0, singular}); }, "addInstance singular");
  expectRefused([&] { scene.setInstanceObject(0, 9, glm::dmat4(1.0)); }, "setInstanceObject missing object");
  expectRefused([&] { scene.setInstanceObject(0, 1, singular); }, "setInstanceObject singular");
  expectRefused([&] { scene.removeInstance(7); }, "removeInstance out of range");
  expectRefused([&] { scene.moveInstance(0, singular); }, "moveInstance singular");
  expectRefused([&] { scene.updateObject(2, ptrs, EditResult{}); }, "updateObject out of range");
  expectRefused([&] { scene.updateObject(0, std::span<const Brickmap* const>(ptrs.data(), 1), EditResult{}); },
                "updateObject with too few brickmaps");
  EditResult outside;
  outside.dirty.push_back({DirtyRange::Array::Bricks, 1u << 20, 16});
  expectRefused([&] { scene.updateObject(0, ptrs, outside); }, "updateObject with a range outside the array");
  // Object 1 grown behind the scene's back: updating object 0 must not lay it out silently.
  Brickmap grown = *bms[1];
  grown.fillBox({{0, 0, 0}, {200, 4, 4}}, 2);
  std::vector<const Brickmap*> stale{bms[0].get(), &grown};
  expectRefused([&] { scene.updateObject(0, stale, EditResult{}); }, "updateObject with another object changed");
}

// The BVH's one rule (Bvh::update): refit while the boxes' emptiness is as at build and the cost holds, else
// rebuild; a box that empties leaves the tree.
TEST(SceneDelta, BvhUpdateRule) {
  std::vector<Aabb> boxes;
  for (int i = 0; i < 12; ++i) boxes.push_back(Aabb{glm::vec3(float(i) * 3.0f), glm::vec3(float(i) * 3.0f + 1.0f)});
  Bvh bvh = Bvh::build(boxes);
  boxes[3].min += 0.1f;
  boxes[3].max += 0.1f;
  EXPECT_FALSE(bvh.update(boxes)) << "a small move refits";
  boxes[5] = Aabb{};
  EXPECT_TRUE(bvh.update(boxes)) << "an emptied box rebuilds";
  for (std::uint32_t i : bvh.instanceIndices()) EXPECT_NE(i, 5u);
  boxes[5] = Aabb{glm::vec3(0.0f), glm::vec3(1.0f)};
  EXPECT_TRUE(bvh.update(boxes)) << "a box that gains voxels rebuilds";
  boxes.push_back(Aabb{glm::vec3(2.0f), glm::vec3(3.0f)});
  EXPECT_TRUE(bvh.update(boxes)) << "another box count rebuilds";
  EXPECT_EQ(bvh.instanceIndices().size(), boxes.size());
}

}  // namespace
}  // namespace vs
