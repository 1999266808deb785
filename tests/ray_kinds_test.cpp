// The ray kinds (shadow texels, the closest-hit and any-hit rays of compute/shared/trace_rays.h, the camera
// rays of compute/shared/camera_rays.h and the visibility rays of compute/shared/visibility_rays.h) through
// every backend: the CPU reference (the box-table walk, one ray at a time), the CPU fast path in every lane width
// the processor runs (scalar, AVX2, AVX-512), the portable CPU tiles (the hierarchy walk) and the Vulkan shader
// give identical results bit for bit on a seeded battery of more than a
// million rays of each kind; any-hit agrees with
// "a closest hit exists" on every ray; and the records agree with the independent double-precision reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "compute/cpu/lane_tracer.h"
#include "compute/cpu/scene_arrays.h"
#include "compute/shared/visibility_rays.h"
#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "lighting/camera.h"
#include "support/exact_reference.h"
#include "support/test_scenes.h"
#include "voxel/error.h"

namespace vs {
namespace {

using test::TestScene;

// A lumpy 48^3 object whose voxels carry materials in every arrangement the payload has: bricks of one
// material, bricks with one byte per voxel, full bricks, and empty space between.
std::unique_ptr<Brickmap> materialObject(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<SolidVoxel> voxels;
  for (int z = 0; z < 48; ++z)
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 48; ++x) {
        glm::ivec3 v(x, y, z);
        bool ground = y < 6 + (x * 7 + z * 3) % 5;
        bool block = x >= 16 && x < 24 && z >= 16 && z < 24 && y < 24;  // one material, full bricks
        bool speckle = (rng() % 23u) == 0u && y < 40;
        if (!(ground || block || speckle)) continue;
        std::uint8_t material = block ? 7 : ground ? std::uint8_t(1 + (x + 3 * y + 5 * z) % 200) : std::uint8_t(250);
        voxels.push_back({v, material});
      }
  return std::make_unique<Brickmap>(Brickmap::build(voxels));
}

TestScene singleObjectScene(glm::dvec3 offset) {
  TestScene s;
  s.name = "single object";
  s.brickmaps.push_back(materialObject(3));
  s.instances.push_back({0u, glm::translate(glm::dmat4(1.0), offset)});
  s.finish();
  return s;
}

// Rotated, scaled and overlapping copies of two objects, moved by `offset`.
TestScene instancedScene(glm::dvec3 offset) {
  TestScene s;
  s.name = "instances";
  s.brickmaps.push_back(materialObject(5));
  s.brickmaps.push_back(test::boxObject({0, 0, 0}, {5, 9, 3}, 42));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 12; ++i) {
    glm::dmat4 m = glm::translate(glm::dmat4(1.0), offset + glm::dvec3((i % 4) * 20.0, unit(rng) * 6.0, (i / 4) * 20.0));
    if (i % 3 != 0)
      m = glm::rotate(m, unit(rng) * 6.283, glm::normalize(glm::dvec3(unit(rng) - 0.5, 1.0, unit(rng) - 0.5)));
    m = glm::scale(m, glm::dvec3(0.25 + unit(rng) * 0.5));
    s.instances.push_back({std::uint32_t(i % 5 == 4 ? 1 : 0), m});
  }
  s.finish();
  return s;
}

// A seeded battery around the scene's world box: axis-aligned, 45-degree, through voxel-lattice points (edges
// and corners), grazing, starting inside solid voxels, and general rays, with whole and partial segments.
std::vector<gpu::TraceRay> rayBattery(const TestScene& scene, std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const glm::dvec3 lo(scene.data.worldBounds.min), hi(scene.data.worldBounds.max);
  const glm::dvec3 centre = (lo + hi) * 0.5, extent = hi - lo;
  const double reach = glm::length(extent) * 1.5;
  auto inBox = [&](double grow) { return lo - extent * grow + (extent * (1.0 + 2.0 * grow)) * glm::dvec3(unit(rng), unit(rng), unit(rng)); };
  auto randomDir = [&] {
    glm::dvec3 d(unit(rng) * 2.0 - 1.0, unit(rng) * 2.0 - 1.0, unit(rng) * 2.0 - 1.0);
    return glm::length(d) < 1e-3 ? glm::dvec3(0.0, -1.0, 0.0) : glm::normalize(d);
  };
  // A point on the voxel lattice of some instance (a voxel corner, edge or face centre) in world space.
  auto latticePoint = [&] {
    const SceneInstance& inst = scene.instances[rng() % scene.instances.size()];
    const Brickmap& bm = *scene.brickmaps[inst.object];
    VoxelBox b = bm.bounds();
    glm::dvec3 p(b.min.x + int(rng() % unsigned(b.max.x - b.min.x + 1)), b.min.y + int(rng() % unsigned(b.max.y - b.min.y + 1)),
                 b.min.z + int(rng() % unsigned(b.max.z - b.min.z + 1)));
    if (rng() % 3u == 0u) p[rng() % 3u] += 0.5;
    return glm::dvec3(inst.brickToWorld * glm::dvec4(p, 1.0));
  };
  // The centre of a random solid voxel of some instance, in world space.
  auto solidCentre = [&] {
    for (;;) {
      const SceneInstance& inst = scene.instances[rng() % scene.instances.size()];
      const Brickmap& bm = *scene.brickmaps[inst.object];
      VoxelBox b = bm.bounds();
      glm::ivec3 v(b.min.x + int(rng() % unsigned(b.max.x - b.min.x)), b.min.y + int(rng() % unsigned(b.max.y - b.min.y)),
                   b.min.z + int(rng() % unsigned(b.max.z - b.min.z)));
      if (bm.isSolid(v)) return glm::dvec3(inst.brickToWorld * glm::dvec4(glm::dvec3(v) + 0.5, 1.0));
    }
  };
  std::vector<gpu::TraceRay> rays;
  rays.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    glm::dvec3 o, d;
    switch (i % 6) {
      case 0: {  // axis-aligned, into the box
        int axis = int(rng() % 3u);
        o = inBox(0.1);
        d = glm::dvec3(0.0);
        d[axis] = o[axis] > centre[axis] ? -1.0 : 1.0;
        break;
      }
      case 1:  // 45 degrees in a plane or along a space diagonal
        o = inBox(0.2);
        d = glm::dvec3(double(int(rng() % 3u) - 1), double(int(rng() % 3u) - 1), double(int(rng() % 3u) - 1));
        if (d == glm::dvec3(0.0)) d = glm::dvec3(1.0, -1.0, 0.0);
        d = glm::normalize(d);
        break;
      case 2:  // through lattice points: from one, or aimed at one
        if (rng() % 2u) {
          o = latticePoint();
          d = randomDir();
        } else {
          o = inBox(0.3);
          d = glm::normalize(latticePoint() - o);
        }
        break;
      case 3: {  // grazing: nearly parallel to a face
        o = inBox(0.1);
        d = randomDir();
        d[rng() % 3u] = (unit(rng) - 0.5) * std::pow(10.0, -2.0 - 5.0 * unit(rng));
        d = glm::normalize(d);
        break;
      }
      case 4:  // starting inside a solid voxel
        o = solidCentre();
        d = randomDir();
        break;
      default:  // general, from outside toward the box
        o = centre + randomDir() * reach * 0.5;
        d = glm::normalize(inBox(0.0) - o);
        break;
    }
    double tMin = 0.0, tMax = reach;
    switch (rng() % 4u) {
      case 0: tMin = unit(rng) * reach * 0.5; break;  // a segment starting part-way
      case 1: tMax = unit(rng) * reach * 0.25; break;  // a short segment (a visibility ray)
      default: break;
    }
    rays.push_back(gpu::makeTraceRay(o, d, float(tMin), float(tMax)));
  }
  return rays;
}

struct Results {
  std::vector<gpu::RayHit> hits;
  std::vector<std::uint32_t> occluded;
};

Results traceBoth(Tracer& tracer, std::span<const gpu::TraceRay> rays) {
  Results r;
  r.hits.resize(rays.size());
  r.occluded.resize(rays.size());
  tracer.traceClosest(rays, r.hits);
  tracer.traceAny(rays, r.occluded);
  return r;
}

// The first ray whose record differs, for the failure message.
std::string firstDifference(const std::vector<gpu::RayHit>& a, const std::vector<gpu::RayHit>& b) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::memcmp(&a[i], &b[i], sizeof(gpu::RayHit)) == 0) continue;
    char buf[256];
    std::snprintf(buf, sizeof buf, "ray %zu: hit %u/%u t %.9g/%.9g instance %u/%u voxel (%d %d %d)/(%d %d %d) face %d/%d material %u/%u",
                  i, a[i].hit, b[i].hit, a[i].t, b[i].t, a[i].instance, b[i].instance, a[i].voxel.x, a[i].voxel.y,
                  a[i].voxel.z, b[i].voxel.x, b[i].voxel.y, b[i].voxel.z, a[i].voxel.w, b[i].voxel.w, a[i].material,
                  b[i].material);
    return buf;
  }
  return "none";
}

std::size_t anyHitDisagreements(const Results& r) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < r.hits.size(); ++i) n += (r.hits[i].hit != 0u) != (r.occluded[i] != 0u);
  return n;
}

class RayKinds : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // A missing Vulkan device fails here, loudly: lavapipe is always installable.
    VulkanOptions options;
    options.validation = true;
    vulkan_ = makeVulkanTracer(options).release();
  }
  static void TearDownTestSuite() {
    delete vulkan_;
    vulkan_ = nullptr;
  }
  static Tracer* vulkan_;
};
Tracer* RayKinds::vulkan_ = nullptr;

// 4 scenes x 262,144 rays: 1,048,576 rays of each kind through each backend, and as many shadow texels.
TEST_F(RayKinds, EveryBackendGivesTheSameRecordsOnAMillionRays) {
  constexpr std::size_t kRaysPerScene = 262144;
  std::vector<TestScene> scenes;
  scenes.push_back(singleObjectScene(glm::dvec3(0.0)));
  scenes.push_back(instancedScene(glm::dvec3(0.0)));
  scenes.push_back(instancedScene(glm::dvec3(1.0e4, -3.0e3, 2.0e4)));
  scenes.push_back(singleObjectScene(glm::dvec3(-1.0e5, 2.0e3, 1.0e5)));
  // Every lane width this processor runs; the others are named as not compared.
  std::vector<CpuTracePath> lanePaths = {CpuTracePath::LanesScalar};
  for (auto [path, width] : {std::pair{CpuTracePath::LanesAvx2, LaneWidth::Avx2},
                             std::pair{CpuTracePath::LanesAvx512, LaneWidth::Avx512}}) {
    if (laneWidthSupported(width)) lanePaths.push_back(path);
    else std::printf("NOT COMPARED: this processor does not run the %s lane tracer\n", laneWidthName(width));
  }
  std::size_t total = 0, hits = 0, faces = 0, starts = 0, texels = 0, texelHits = 0;
  for (std::size_t s = 0; s < scenes.size(); ++s) {
    const TestScene& scene = scenes[s];
    SCOPED_TRACE("scene " + std::to_string(s) + " (" + scene.name + ")");
    std::vector<gpu::TraceRay> rays = rayBattery(scene, kRaysPerScene, std::uint32_t(100 + s));
    // The reference walks the box table, as the shader does; the portable tiles walk the hierarchy.
    auto reference = makeCpuTracer({CpuTracePath::Reference, 2});
    auto tiles = makeCpuTracer({CpuTracePath::PortableTiles, 2});
    std::vector<std::unique_ptr<Tracer>> laneTracers;
    for (CpuTracePath path : lanePaths) laneTracers.push_back(makeCpuTracer({path, 2}));
    std::vector<Tracer*> others = {tiles.get(), vulkan_};
    for (auto& t : laneTracers) others.push_back(t.get());
    reference->setScene(scene.data);
    for (Tracer* t : others) t->setScene(scene.data);
    ASSERT_TRUE(reference->cpu()->hasBoxTable());
    Results ref = traceBoth(*reference, rays);
    EXPECT_EQ(anyHitDisagreements(ref), 0u);
    for (std::size_t k = 0; k < others.size(); ++k) {
      Tracer* t = others[k];
      SCOPED_TRACE(t->backend() + " on " + t->deviceName() + " (tracer " + std::to_string(k) + ")");
      Results r = traceBoth(*t, rays);
      EXPECT_EQ(std::memcmp(r.hits.data(), ref.hits.data(), r.hits.size() * sizeof(gpu::RayHit)), 0)
          << "first difference from the reference: " << firstDifference(r.hits, ref.hits);
      EXPECT_EQ(r.occluded, ref.occluded);
      EXPECT_EQ(anyHitDisagreements(r), 0u);
    }
    // Shadow texels of four 256^2 views per scene: directional, and spot-like views from 1 to 90 degrees wide,
    // half of them with the depth at the voxel centre.
    std::mt19937 rng(std::uint32_t(500 + s));
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const Aabb& b = scene.data.worldBounds;
    const glm::vec3 centre = (b.min + b.max) * 0.5f;
    const float reach = glm::length(b.max - b.min);
    std::vector<gpu::TraceView> views;
    views.push_back(test::directionalView(b, glm::vec3(-0.4f, -1.0f, -0.3f), 256));
    for (int v = 0; v < 3; ++v) {
      glm::vec3 dir = glm::normalize(glm::vec3(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5));
      glm::vec3 position = centre - dir * reach * float(0.3 + unit(rng));
      views.push_back(test::distanceView(position, centre - position, reach * 3.0f, 256, float(1.0 + 89.0 * unit(rng))));
    }
    for (std::size_t v = 0; v < views.size(); v += 2) views[v].info.w = gpu::VS_DEPTH_POINT_VOXEL_CENTER;
    std::vector<ShadowLayer> refLayers;
    reference->traceShadow(views, refLayers);
    for (std::size_t k = 0; k < others.size(); ++k) {
      Tracer* t = others[k];
      SCOPED_TRACE(t->backend() + " shadow texels (tracer " + std::to_string(k) + ")");
      std::vector<ShadowLayer> layers;
      t->traceShadow(views, layers);
      for (std::size_t v = 0; v < views.size(); ++v)
        EXPECT_EQ(std::memcmp(layers[v].texels.data(), refLayers[v].texels.data(), layers[v].texels.size() * sizeof(float)), 0)
            << "view " << v;
    }
    for (std::size_t v = 0; v < views.size(); ++v) {
      const float miss = views[v].info.z == gpu::VS_ENCODING_NDC_DEPTH ? 1.0f : views[v].eyeHigh.w;
      texels += refLayers[v].texels.size();
      texelHits += std::size_t(std::count_if(refLayers[v].texels.begin(), refLayers[v].texels.end(),
                                             [&](float t) { return t < miss; }));
    }

    for (const gpu::RayHit& h : ref.hits) {
      hits += h.hit;
      faces += h.hit && h.voxel.w != int(gpu::VS_FACE_NONE);
      starts += h.hit && h.voxel.w == int(gpu::VS_FACE_NONE);
      if (h.hit) {
        EXPECT_GE(h.material, 1u);
        EXPECT_LE(h.voxel.w, int(gpu::VS_FACE_NONE));
      }
    }
    total += rays.size();
  }
  std::printf("%zu rays, %zu hits (%zu through a face, %zu starting inside a solid voxel); %zu shadow texels, %zu hit\n",
              total, hits, faces, starts, texels, texelHits);
  // The battery exercises what it claims to: most rays hit, and some start inside solids.
  EXPECT_GE(total, 1000000u);
  EXPECT_GE(texels, 1000000u);
  EXPECT_GT(texelHits, texels / 10);
  EXPECT_GT(hits, total / 4);
  EXPECT_GT(starts, total / 50);
  EXPECT_TRUE(vulkan_->vulkan()->validationMessages().empty());
}

// Hit records against the independent double-precision reference: the same hit or miss, instance, voxel, entry
// face and material, and t within 1e-3 voxel, wherever the ray is not an edge or corner contact (or a near tie
// between two voxels, which the test verifies as such).
TEST_F(RayKinds, ClosestHitsMatchTheExactReference) {
  for (glm::dvec3 offset : {glm::dvec3(0.0), glm::dvec3(1.0e4, -3.0e3, 2.0e4)}) {
    TestScene scene = instancedScene(offset);
    SCOPED_TRACE("offset " + std::to_string(offset.x));
    std::vector<gpu::TraceRay> rays = rayBattery(scene, 20000, 7);
    auto fast = makeCpuTracer();
    fast->setScene(scene.data);
    std::vector<gpu::RayHit> hits(rays.size());
    fast->traceClosest(rays, hits);
    test::ExactReference exact(scene.brickmapPointers(), scene.instances);
    std::size_t compared = 0, ties = 0, facesCompared = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const gpu::TraceRay& r = rays[i];
      test::ExactRay er;
      er.o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
      er.d = glm::dvec3(glm::vec3(r.direction));
      er.tMin = r.originHigh.w;
      er.tMax = r.originLow.w;
      test::ExactHit e = exact.trace(er);
      const gpu::RayHit& h = hits[i];
      if (bool(h.hit) != e.hit || (e.hit && (h.instance != e.instance || h.voxel.x != e.voxel.x ||
                                              h.voxel.y != e.voxel.y || h.voxel.z != e.voxel.z))) {
        // Two tracers may decide an edge or corner contact differently (where either of them hit); nothing else.
        bool contact = (h.hit && exact.grazesNear(er, double(h.t), 2.0, 1e-3)) ||
                       (e.hit && exact.grazesNear(er, e.t, 2.0, 1e-3));
        // Or two solid voxels the ray enters within 1e-3 voxel of each other, one chosen by each.
        if (h.hit && e.hit && !contact) {
          double tEnter = exact.entryT(er, h.instance, glm::ivec3(h.voxel));
          contact = tEnter >= 0.0 && std::abs(tEnter - e.t) * e.voxelsPerT <= 1e-3 &&
                    scene.brickmaps[scene.instances[h.instance].object]->isSolid(glm::ivec3(h.voxel));
        }
        EXPECT_TRUE(contact)
            << "ray " << i << ": hit " << h.hit << "/" << e.hit << " instance " << h.instance << "/" << e.instance
            << " voxel (" << h.voxel.x << " " << h.voxel.y << " " << h.voxel.z << ")/(" << e.voxel.x << " "
            << e.voxel.y << " " << e.voxel.z << ") t " << h.t << "/" << e.t;
        ++ties;
        continue;
      }
      ++compared;
      if (!e.hit) continue;
      EXPECT_NEAR(double(h.t) * e.voxelsPerT, e.t * e.voxelsPerT, 1e-3 + 1e-6 * std::abs(e.t * e.voxelsPerT))
          << "ray " << i;
      EXPECT_EQ(h.material, scene.brickmaps[scene.instances[e.instance].object]->material(e.voxel)) << "ray " << i;
      if (e.faceMargin > 1e-3) {
        EXPECT_EQ(unsigned(h.voxel.w), e.face) << "ray " << i;
        ++facesCompared;
      }
    }
    std::printf("%zu rays agree with the exact reference (%zu faces compared), %zu edge contacts\n", compared,
                facesCompared, ties);
    EXPECT_GT(facesCompared, rays.size() / 4);
    // Lattice-point rays (a sixth of the battery) are made to touch edges and corners.
    EXPECT_LT(ties, rays.size() / 20);
  }
}

// The shared pieces at exact ties: the entry face of a ray through a voxel corner follows the canonical order
// (z, then y, then x crossed: x last), a ray that starts inside its voxel has no face, and the material lookup
// reads uniform and per-voxel bricks alike.
TEST(RayKindsShared, EntryFaceAndMaterialAtTies) {
  gpu::SceneArrays arrays;
  const glm::vec3 diagonal(1.0f, 1.0f, 1.0f);
  const glm::vec3 invD(1.0f);
  // From (0.5, 0.5, 0.5) along the diagonal: the planes x = y = z = 1 are crossed at t = 0.5 together.
  EXPECT_EQ(arrays.vsEntryFace(glm::vec3(0.5f), diagonal, invD, glm::ivec3(1, 1, 1), 0.0f), gpu::VS_FACE_NEG_X);
  // A ray moving toward -z enters through the +z face.
  EXPECT_EQ(arrays.vsEntryFace(glm::vec3(0.5f, 0.5f, 3.5f), glm::vec3(0.0f, 0.0f, -1.0f),
                               glm::vec3(0.0f, 0.0f, -1.0f), glm::ivec3(0, 0, 2), 0.0f),
            gpu::VS_FACE_POS_Z);
  // Starting inside: every near plane lies before tStart.
  EXPECT_EQ(arrays.vsEntryFace(glm::vec3(1.5f, 1.5f, 1.5f), diagonal, invD, glm::ivec3(1, 1, 1), 0.0f),
            gpu::VS_FACE_NONE);
  // Starting exactly on the plane counts as entering through it.
  EXPECT_EQ(arrays.vsEntryFace(glm::vec3(1.0f, 1.5f, 1.5f), glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(1.0f, 0.0f, 0.0f),
                               glm::ivec3(1, 1, 1), 0.0f),
            gpu::VS_FACE_NEG_X);

  std::vector<SolidVoxel> voxels;
  for (int x = 0; x < 8; ++x)
    for (int y = 0; y < 8; ++y)
      for (int z = 0; z < 8; ++z) voxels.push_back({{x, y, z}, 9});  // one uniform brick
  voxels.push_back({{8, 0, 0}, 3});   // a brick with two materials
  voxels.push_back({{9, 1, 0}, 200});
  Brickmap bm = Brickmap::build(voxels);
  std::vector<const Brickmap*> maps{&bm};
  std::vector<SceneInstance> instances{{0u, glm::dmat4(1.0)}};
  SceneData scene = SceneData::build(maps, instances);
  gpu::SceneArrays sa(scene);
  EXPECT_EQ(sa.vsVoxelMaterial(0u, glm::ivec3(3, 4, 5)), 9u);
  EXPECT_EQ(sa.vsVoxelMaterial(0u, glm::ivec3(8, 0, 0)), 3u);
  EXPECT_EQ(sa.vsVoxelMaterial(0u, glm::ivec3(9, 1, 0)), 200u);
  EXPECT_EQ(sa.vsVoxelMaterial(0u, glm::ivec3(9, 0, 0)), 0u);    // empty voxel of a partial brick
  EXPECT_EQ(sa.vsVoxelMaterial(0u, glm::ivec3(40, 0, 0)), 0u);   // outside the object
  // A ray along +x from inside the uniform brick: no face, material 9; from outside: the -x face at t = 2.
  gpu::RayHit inside = sa.vsClosestHit(sa.vsTraceRayToWorld(gpu::makeTraceRay({2.5, 2.5, 2.5}, {1, 0, 0}, 0.0f, 50.0f)));
  EXPECT_EQ(inside.hit, 1u);
  EXPECT_EQ(inside.voxel.w, int(gpu::VS_FACE_NONE));
  EXPECT_EQ(inside.material, 9u);
  gpu::RayHit outside = sa.vsClosestHit(sa.vsTraceRayToWorld(gpu::makeTraceRay({-2.0, 0.5, 0.5}, {1, 0, 0}, 0.0f, 50.0f)));
  EXPECT_EQ(outside.hit, 1u);
  EXPECT_EQ(outside.t, 2.0f);
  EXPECT_EQ(outside.voxel.w, int(gpu::VS_FACE_NEG_X));
  // From +x toward the mixed brick: voxel (9, 1, 0) is entered through its +x face.
  gpu::RayHit back = sa.vsClosestHit(sa.vsTraceRayToWorld(gpu::makeTraceRay({20.0, 1.5, 0.5}, {-1, 0, 0}, 0.0f, 50.0f)));
  EXPECT_EQ(back.voxel, glm::ivec4(9, 1, 0, int(gpu::VS_FACE_POS_X)));
  EXPECT_EQ(back.material, 200u);
  // Any-hit over segments that stop short of the voxel and that reach it.
  EXPECT_FALSE(sa.vsAnyHit(sa.vsTraceRayToWorld(gpu::makeTraceRay({20.0, 1.5, 0.5}, {-1, 0, 0}, 0.0f, 9.5f))));
  EXPECT_TRUE(sa.vsAnyHit(sa.vsTraceRayToWorld(gpu::makeTraceRay({20.0, 1.5, 0.5}, {-1, 0, 0}, 0.0f, 10.5f))));
}

// The host's exact splits: a ray origin into high + low floats, and an instance's affines taken about its float
// anchor. Both subtract the rounded value from the double one, so the rounding must really happen (a compiler
// that keeps a float conversion at double precision makes the low part zero and the affines miss the anchor
// by up to half an ulp of the position: 5e-4 at 10^4 units).
TEST(RayKindsShared, HostSplitsRoundExactly) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-1.0e5, 1.0e5), unit(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    glm::dvec3 o(coord(rng), coord(rng), coord(rng));
    gpu::TraceRay r = gpu::makeTraceRay(o, {0.0, 0.0, 1.0}, 0.0f, 1.0f);
    for (int a = 0; a < 3; ++a) {
      const double high = r.originHigh[a], low = r.originLow[a];
      ASSERT_EQ(high, double(float(o[a]))) << "axis " << a;
      ASSERT_LE(std::abs(high + low - o[a]), std::abs(o[a]) * 1e-14) << "axis " << a;
    }
    glm::dmat4 m = glm::translate(glm::dmat4(1.0), o);
    m = glm::rotate(m, unit(rng) * 6.283, glm::normalize(glm::dvec3(unit(rng) - 0.5, 1.0, unit(rng) - 0.5)));
    m = glm::scale(m, glm::dvec3(0.25 + unit(rng)));
    const VoxelBox box{glm::ivec3(0), glm::ivec3(48, 40, 48)};
    gpu::InstanceRecord rec = makeInstanceRecord(m, box, 0u, 0u, nullptr);
    // The record's brickToWorld, in double, maps the box centre to its world position less the stored anchor.
    const glm::dvec3 centre(24.0, 20.0, 24.0);
    const glm::dvec3 world(m * glm::dvec4(centre, 1.0));
    const glm::dvec3 anchor(glm::vec3(rec.anchor));
    const gpu::Affine& b = rec.brickToWorld;
    const glm::dvec3 rel(glm::dot(glm::dvec4(b.row0), glm::dvec4(centre, 1.0)), glm::dot(glm::dvec4(b.row1), glm::dvec4(centre, 1.0)),
                         glm::dot(glm::dvec4(b.row2), glm::dvec4(centre, 1.0)));
    ASSERT_LE(glm::length(rel - (world - anchor)), 1e-4) << "instance at " << o.x << " " << o.y << " " << o.z;
  }
}

// FLT_MAX and infinity are how callers write "unbounded": such rays, and any tMax beyond the scene, give the
// records of a ray whose tMax is the end of the scene, bit for bit on every backend, and their hits are the
// exact reference's hits on the unbounded ray.
TEST_F(RayKinds, UnboundedRaysReachTheEndOfTheScene) {
  const float unbounded[] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::infinity(), 3.0e38f, 1.0e30f};
  for (glm::dvec3 offset : {glm::dvec3(0.0), glm::dvec3(1.0e4, -3.0e3, 2.0e4)}) {
    TestScene scene = instancedScene(offset);
    SCOPED_TRACE("offset " + std::to_string(offset.x));
    std::vector<gpu::TraceRay> bounded = rayBattery(scene, 20000, 23);
    const float sceneReach = 4.0f * glm::length(scene.data.worldBounds.max - scene.data.worldBounds.min) +
                             glm::length(glm::max(glm::abs(scene.data.worldBounds.min), glm::abs(scene.data.worldBounds.max)));
    for (gpu::TraceRay& r : bounded) r.originLow.w = sceneReach;  // past the scene from every start
    auto reference = makeCpuTracer({CpuTracePath::Reference, 2});
    auto fast = makeCpuTracer();
    for (Tracer* t : {reference.get(), fast.get(), vulkan_}) t->setScene(scene.data);
    const Results expected = traceBoth(*reference, bounded);
    std::size_t hits = 0;
    for (const gpu::RayHit& h : expected.hits) hits += h.hit;
    EXPECT_GT(hits, bounded.size() / 4);
    for (float tMax : unbounded) {
      std::vector<gpu::TraceRay> rays = bounded;
      for (gpu::TraceRay& r : rays) r.originLow.w = tMax;
      for (Tracer* t : {reference.get(), fast.get(), vulkan_}) {
        SCOPED_TRACE(t->backend() + " with tMax " + std::to_string(tMax));
        Results r = traceBoth(*t, rays);
        EXPECT_EQ(std::memcmp(r.hits.data(), expected.hits.data(), r.hits.size() * sizeof(gpu::RayHit)), 0)
            << "first difference: " << firstDifference(r.hits, expected.hits);
        EXPECT_EQ(r.occluded, expected.occluded);
      }
    }
    // The exact reference, given the ray in double to far past the scene: every hit it finds, the tracers find
    // at its t.
    test::ExactReference exact(scene.brickmapPointers(), scene.instances);
    std::size_t compared = 0;
    for (std::size_t i = 0; i < bounded.size(); ++i) {
      const gpu::TraceRay& r = bounded[i];
      test::ExactRay er;
      er.o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
      er.d = glm::dvec3(glm::vec3(r.direction));
      er.tMin = r.originHigh.w;
      er.tMax = 10.0 * double(sceneReach);  // far past the scene: the reference's own "unbounded"
      const test::ExactHit e = exact.trace(er);
      const gpu::RayHit& h = expected.hits[i];
      // Edge and corner contacts (at either tracer's t) may be decided either way, as in the test above.
      if (!e.hit || exact.grazesNear(er, e.t, 2.0, 1e-3) || (h.hit && exact.grazesNear(er, double(h.t), 2.0, 1e-3)))
        continue;
      ++compared;
      ASSERT_EQ(h.hit, 1u) << "ray " << i << ": the reference hits at " << e.t;
      EXPECT_NEAR(double(h.t) * e.voxelsPerT, e.t * e.voxelsPerT, 1e-3 + 1e-6 * std::abs(e.t * e.voxelsPerT)) << "ray " << i;
    }
    EXPECT_GT(compared, bounded.size() / 5);
  }
  // The plain case: a ray from outside along +x, unbounded, hits the first voxel at t = 2.
  TestScene box;
  box.brickmaps.push_back(test::boxObject({0, 0, 0}, {7, 7, 7}, 9));
  box.instances.push_back({0u, glm::dmat4(1.0)});
  box.finish();
  auto cpu = makeCpuTracer();
  cpu->setScene(box.data);
  vulkan_->setScene(box.data);
  for (float tMax : unbounded) {
    const std::vector<gpu::TraceRay> one = {gpu::makeTraceRay({-2.0, 0.5, 0.5}, {1, 0, 0}, 0.0f, tMax)};
    for (Tracer* t : {cpu.get(), vulkan_}) {
      Results r = traceBoth(*t, one);
      EXPECT_EQ(r.hits[0].hit, 1u) << t->backend() << " tMax " << tMax;
      EXPECT_EQ(r.hits[0].t, 2.0f) << t->backend() << " tMax " << tMax;
      EXPECT_EQ(r.occluded[0], 1u) << t->backend() << " tMax " << tMax;
    }
  }
  EXPECT_TRUE(vulkan_->vulkan()->validationMessages().empty());
}

// A camera looking at the scene's world box from outside it, up and to one side.
CameraFrame cameraOnto(const Aabb& box, int width, int height) {
  const glm::dvec3 lo(box.min), hi(box.max);
  const glm::dvec3 centre = (lo + hi) * 0.5;
  const double reach = glm::length(hi - lo);
  CameraDesc desc;
  desc.position = glm::vec3(centre + glm::dvec3(0.35, 0.3, 0.45) * reach);
  desc.target = glm::vec3(centre);
  desc.up = glm::vec3(0.0f, 1.0f, 0.0f);
  desc.fovDeg = 60.0f;
  desc.nearPlane = 0.05f * float(reach);
  desc.farPlane = 4.0f * float(reach);
  return cameraFrame(desc, width, height);
}

// Camera rays made where they are traced (the shader makes them on the device) give the hits of the same
// rays made on the host and traced one by one, bit for bit, for every pixel and for a listed subset; and the
// rays themselves follow an independent double-precision camera (position, basis, pixel centre, near and
// far planes) to float precision, near the origin and 10^4 units out.
TEST_F(RayKinds, CameraRaysMadeWhereTracedEqualTheHostsAndFollowTheCamera) {
  for (glm::dvec3 offset : {glm::dvec3(0.0), glm::dvec3(1.0e4, -3.0e3, 2.0e4)}) {
    SCOPED_TRACE("offset " + std::to_string(offset.x));
    TestScene scene = instancedScene(offset);
    const CameraFrame camera = cameraOnto(scene.data.worldBounds, 192, 108);
    const gpu::CameraRays record = cameraRaysOf(camera);
    const std::vector<gpu::TraceRay> rays = cameraRays(record);
    ASSERT_EQ(rays.size(), std::size_t(camera.width) * std::size_t(camera.height));

    // The rays against the camera in double, each from its own pixel centre.
    double worstAngle = 0.0, worstEnds = 0.0, worstOrigin = 0.0;
    for (int y = 0; y < camera.height; ++y)
      for (int x = 0; x < camera.width; ++x) {
        const gpu::TraceRay& r = rays[std::size_t(y) * std::size_t(camera.width) + std::size_t(x)];
        const double tanY = camera.tanHalfFovY, tanX = tanY * double(camera.width) / double(camera.height);
        const double u = ((x + 0.5) / camera.width * 2.0 - 1.0) * tanX, v = (1.0 - (y + 0.5) / camera.height * 2.0) * tanY;
        const glm::dvec3 exact = glm::normalize(camera.forward + camera.right * u + camera.up * v);
        const glm::dvec3 d(glm::vec3(r.direction));
        worstAngle = std::max(worstAngle, glm::length(glm::cross(d, exact)) + std::abs(glm::length(d) - 1.0));
        const double along = glm::dot(exact, camera.forward);
        worstEnds = std::max({worstEnds, std::abs(double(r.originHigh.w) * along / camera.nearPlane - 1.0),
                              std::abs(double(r.originLow.w) * along / camera.farPlane - 1.0)});
        const glm::dvec3 o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
        worstOrigin = std::max(worstOrigin, glm::length(o - camera.position) / glm::length(camera.position));
      }
    std::printf("camera rays against the double camera: direction %.3g rad, near/far %.3g, origin %.3g (relative)\n",
                worstAngle, worstEnds, worstOrigin);
    EXPECT_LT(worstAngle, 1e-6);
    EXPECT_LT(worstEnds, 1e-6);
    EXPECT_LT(worstOrigin, 1e-12);

    auto reference = makeCpuTracer({CpuTracePath::Reference, 2});
    auto fast = makeCpuTracer();
    reference->setScene(scene.data);
    fast->setScene(scene.data);
    vulkan_->setScene(scene.data);
    std::vector<gpu::RayHit> expected(rays.size());
    reference->traceClosest(rays, expected);
    std::size_t hitCount = 0;
    for (const gpu::RayHit& h : expected) hitCount += h.hit;
    EXPECT_GT(hitCount, rays.size() / 10) << "the camera sees the scene";
    // A listed subset, out of order and with a pixel twice, as a frame loop's marked pixels never are.
    std::vector<std::uint32_t> pixels;
    std::mt19937 rng(9);
    for (int k = 0; k < 5000; ++k) pixels.push_back(std::uint32_t(rng() % rays.size()));
    pixels.push_back(std::uint32_t(rays.size() - 1));
    pixels.push_back(0u);
    pixels.push_back(pixels.front());
    for (Tracer* t : {fast.get(), vulkan_}) {
      SCOPED_TRACE(t->backend());
      std::vector<gpu::RayHit> hits(rays.size());
      const TraceStats ts = t->traceCamera(record, {}, hits);
      EXPECT_EQ(ts.rays, rays.size());
      EXPECT_EQ(std::memcmp(hits.data(), expected.data(), hits.size() * sizeof(gpu::RayHit)), 0)
          << "first difference: " << firstDifference(hits, expected);
      std::vector<gpu::RayHit> listed(pixels.size());
      t->traceCamera(record, pixels, listed);
      std::vector<gpu::RayHit> want;
      for (std::uint32_t p : pixels) want.push_back(expected[p]);
      EXPECT_EQ(std::memcmp(listed.data(), want.data(), want.size() * sizeof(gpu::RayHit)), 0)
          << "first difference: " << firstDifference(listed, want);
    }
  }
  EXPECT_TRUE(vulkan_->vulkan()->validationMessages().empty());
}

TEST_F(RayKinds, BadCameraTracesAreRefused) {
  TestScene scene = singleObjectScene(glm::dvec3(0.0));
  auto cpu = makeCpuTracer();
  const gpu::CameraRays good = cameraRaysOf(cameraOnto(scene.data.worldBounds, 16, 8));
  std::vector<gpu::RayHit> hits(16 * 8);
  EXPECT_THROW(cpu->traceCamera(good, {}, hits), Error);  // before setScene
  cpu->setScene(scene.data);
  vulkan_->setScene(scene.data);
  for (Tracer* t : {cpu.get(), vulkan_}) {
    SCOPED_TRACE(t->backend());
    std::vector<gpu::RayHit> short_(16 * 8 - 1);
    EXPECT_THROW(t->traceCamera(good, {}, short_), Error);
    const std::uint32_t outside[] = {3u, 16u * 8u};
    std::vector<gpu::RayHit> two(2);
    try {
      t->traceCamera(good, outside, two);
      ADD_FAILURE() << "a pixel outside the frame was traced";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("pixels[1]"), std::string::npos) << e.what();
    }
    gpu::CameraRays empty = good;
    empty.size.y = 0;
    EXPECT_THROW(t->traceCamera(empty, {}, {}), Error);
    gpu::CameraRays huge = good;
    huge.size = glm::uvec4(70000u, 70000u, 0u, 0u);
    EXPECT_THROW(t->traceCamera(huge, {}, {}), Error);
    gpu::CameraRays nan = good;
    nan.forward.y = std::numeric_limits<float>::quiet_NaN();
    try {
      t->traceCamera(nan, {}, hits);
      ADD_FAILURE() << "a NaN camera was traced";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("CameraRays.forward"), std::string::npos) << e.what();
    }
    // The refusals wrote nothing into the outputs they were given.
    for (const gpu::RayHit& h : two) EXPECT_EQ(h.hit, 0u);
  }
  EXPECT_TRUE(vulkan_->vulkan()->validationMessages().empty());
}

// Lights around a scene's world box for visibility rays: a point above it, the sun, a point with short
// (contact) rays, one that needs no ray, a point inside the box, and one inside it whose range reaches part of
// the receivers.
std::vector<gpu::VisibilityLight> visibilityLights(const Aabb& box) {
  const glm::dvec3 lo(box.min), hi(box.max), centre = (lo + hi) * 0.5;
  const double reach = glm::length(hi - lo);
  auto light = [](glm::dvec3 target, float length, float kind, float range = 0.0f) {
    gpu::VisibilityLight l{};
    l.target = glm::vec4(glm::vec3(target), length);
    l.kind = glm::vec4(kind, range, 0.0f, 0.0f);
    return l;
  };
  return {light(centre + glm::dvec3(0.2, 0.9, -0.1) * reach, -1.0f, gpu::VS_VISIBILITY_TOWARD_POINT),
          light(glm::normalize(glm::dvec3(0.3, 1.0, 0.45)), -1.0f, gpu::VS_VISIBILITY_TOWARD_DIRECTION),
          light(centre + glm::dvec3(-0.6, 0.4, 0.3) * reach, float(0.05 * reach), gpu::VS_VISIBILITY_TOWARD_POINT),
          light(centre + glm::dvec3(0.0, 2.0, 0.0) * reach, 0.0f, gpu::VS_VISIBILITY_TOWARD_POINT),
          light(centre + glm::dvec3(0.05, 0.02, -0.03) * reach, -1.0f, gpu::VS_VISIBILITY_TOWARD_POINT),
          light(centre + glm::dvec3(-0.1, 0.1, 0.15) * reach, -1.0f, gpu::VS_VISIBILITY_TOWARD_POINT,
                float(0.4 * reach))};
}

// Receivers spread over a box grown by a tenth: surface points with unit normals, offsets of a thousandth of
// a voxel to a voxel, and every 17th without a surface.
std::vector<gpu::VisibilityReceiver> visibilityReceiversIn(const Aabb& box, std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0), side(-1.0, 1.0);
  const glm::dvec3 lo(box.min), hi(box.max), pad = (hi - lo) * 0.1;
  std::vector<gpu::VisibilityReceiver> receivers(count);
  for (std::size_t k = 0; k < count; ++k) {
    glm::dvec3 p = lo - pad + (hi - lo + 2.0 * pad) * glm::dvec3(unit(rng), unit(rng), unit(rng));
    glm::dvec3 n(side(rng), side(rng), side(rng));
    if (glm::length(n) < 1e-3) n = glm::dvec3(0.0, 1.0, 0.0);
    receivers[k].position = glm::vec4(glm::vec3(p), float(1e-3 + unit(rng)));
    receivers[k].normal = glm::vec4(glm::vec3(glm::normalize(n)), k % 17 == 5 ? 0.0f : 1.0f);
  }
  return receivers;
}

// Visibility rays made where they are traced (the shader makes them on the device from receivers and lights)
// give the answers of the same rays made on the host and traced by the reference, bit for bit; and the host's
// rays follow an independent double-precision construction (start off the face, toward the light, ending at
// it, at the world box's exit or at the light's longest ray) to float precision, near the origin and 10^4
// units out.
TEST_F(RayKinds, VisibilityRaysMadeWhereTracedEqualTheHostsAndReachTheLights) {
  for (glm::dvec3 offset : {glm::dvec3(0.0), glm::dvec3(1.0e4, -3.0e3, 2.0e4)}) {
    SCOPED_TRACE("offset " + std::to_string(offset.x));
    TestScene scene = instancedScene(offset);
    const Aabb& box = scene.data.worldBounds;
    gpu::VisibilityRays frame{};
    frame.boundsMin = glm::vec4(box.min, 0.0f);
    frame.boundsMax = glm::vec4(box.max, 0.0f);
    const std::vector<gpu::VisibilityLight> lights = visibilityLights(box);
    const std::vector<gpu::VisibilityReceiver> receivers = visibilityReceiversIn(box, 20000, 23);
    std::vector<gpu::TraceRay> rays;
    visibilityRays(frame, lights, receivers, rays);
    ASSERT_EQ(rays.size(), receivers.size() * lights.size());

    // Each ray against its own construction in double.
    double worstAngle = 0.0, worstLength = 0.0, worstOrigin = 0.0;
    std::size_t empty = 0, mismatchedEmpty = 0, beyondRange = 0;
    for (std::size_t k = 0; k < receivers.size(); ++k)
      for (std::size_t l = 0; l < lights.size(); ++l) {
        const gpu::TraceRay& r = rays[k * lights.size() + l];
        const gpu::VisibilityReceiver& rc = receivers[k];
        const gpu::VisibilityLight& li = lights[l];
        const glm::dvec3 n(glm::vec3(rc.normal));
        const glm::dvec3 origin = glm::dvec3(glm::vec3(rc.position)) + n * double(rc.position.w);
        bool wantEmpty = rc.normal.w == 0.0f || li.target.w == 0.0f;
        if (!wantEmpty && li.kind.x == gpu::VS_VISIBILITY_TOWARD_POINT && li.kind.y > 0.0f) {
          // Beyond the light's range (from the surface point, with the margin): no ray.
          const double distance = glm::length(glm::dvec3(glm::vec3(rc.position)) - glm::dvec3(glm::vec3(li.target)));
          const double limit = double(li.kind.y) * (1.0 + gpu::VS_VISIBILITY_REACH_MARGIN);
          if (std::abs(distance - limit) < 1e-9 * limit) continue;  // a tie that rounding may decide either way
          if (distance > limit) {
            ++beyondRange;
            wantEmpty = true;
          }
        }
        glm::dvec3 dir(0.0);
        double length = 0.0;
        if (!wantEmpty && li.kind.x == gpu::VS_VISIBILITY_TOWARD_DIRECTION) {
          dir = glm::dvec3(glm::vec3(li.target));
          double exit = std::numeric_limits<double>::infinity();
          for (int a = 0; a < 3; ++a)
            exit = std::min(exit, std::max((double(box.min[a]) - origin[a]) / dir[a],
                                           (double(box.max[a]) - origin[a]) / dir[a]));
          length = std::max(exit, 0.0);
        } else if (!wantEmpty) {
          const glm::dvec3 d = glm::dvec3(glm::vec3(li.target)) - origin;
          length = glm::length(d);
          dir = d / length;
        }
        const double facing = glm::dot(n, dir);
        if (!wantEmpty && std::abs(facing) < 1e-6) continue;  // a tie that rounding may decide either way
        wantEmpty = wantEmpty || facing <= 0.0;
        if (li.target.w > 0.0f) length = std::min(length, double(li.target.w));
        const bool isEmpty = r.originLow.w < r.originHigh.w;
        empty += isEmpty;
        if (isEmpty != wantEmpty) {
          ++mismatchedEmpty;
          continue;
        }
        if (isEmpty) continue;
        const glm::dvec3 d(glm::vec3(r.direction));
        worstAngle = std::max(worstAngle, glm::length(glm::cross(d, dir)) + std::abs(glm::length(d) - 1.0));
        worstLength = std::max(worstLength, std::abs(double(r.originLow.w) - length) / std::max(length, 1.0));
        const glm::dvec3 o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
        worstOrigin = std::max(worstOrigin, glm::length(o - origin) / std::max(glm::length(origin), 1.0));
      }
    std::printf("visibility rays against double: direction %.3g rad, length %.3g, origin %.3g (relative); "
                "%zu of %zu empty\n",
                worstAngle, worstLength, worstOrigin, empty, rays.size());
    EXPECT_EQ(mismatchedEmpty, 0u);
    EXPECT_GT(beyondRange, receivers.size() / 10) << "receivers beyond the ranged light's reach";
    EXPECT_LT(beyondRange, receivers.size() * 9 / 10) << "receivers within the ranged light's reach";
    EXPECT_LT(worstAngle, 1e-6);
    EXPECT_LT(worstLength, 1e-6);
    EXPECT_LT(worstOrigin, 1e-12);
    EXPECT_GT(empty, rays.size() / 5) << "receivers without a surface, facing away, a light without rays";
    EXPECT_LT(empty, rays.size() * 4 / 5);

    auto reference = makeCpuTracer({CpuTracePath::Reference, 2});
    auto fast = makeCpuTracer();
    reference->setScene(scene.data);
    fast->setScene(scene.data);
    vulkan_->setScene(scene.data);
    std::vector<std::uint32_t> expected(rays.size());
    reference->traceAny(rays, expected);
    const std::size_t occludedCount = std::size_t(std::count(expected.begin(), expected.end(), 1u));
    EXPECT_GT(occludedCount, rays.size() / 50) << "some rays meet the scene";
    EXPECT_LT(occludedCount, rays.size() - empty) << "some rays reach their light";
    for (Tracer* t : {fast.get(), vulkan_}) {
      SCOPED_TRACE(t->backend());
      std::vector<std::uint32_t> answers(rays.size(), 7u);
      const TraceStats ts = t->traceVisibility(frame, lights, receivers, answers);
      EXPECT_EQ(ts.rays, rays.size());
      std::size_t differ = 0, first = answers.size();
      for (std::size_t i = 0; i < answers.size(); ++i)
        if (answers[i] != expected[i]) {
          first = std::min(first, i);
          ++differ;
        }
      EXPECT_EQ(differ, 0u) << "first at ray " << first;
      // A subset of the receivers, as a frame that redoes some pixels traces them.
      const std::span<const gpu::VisibilityReceiver> some(receivers.data() + 101, 999);
      std::vector<std::uint32_t> part(some.size() * lights.size());
      t->traceVisibility(frame, lights, some, part);
      EXPECT_TRUE(std::equal(part.begin(), part.end(), expected.begin() + 101 * lights.size()));
    }
  }
  EXPECT_TRUE(vulkan_->vulkan()->validationMessages().empty());
}

TEST_F(RayKinds, BadVisibilityTracesAreRefused) {
  TestScene scene = singleObjectScene(glm::dvec3(0.0));
  const Aabb& box = scene.data.worldBounds;
  gpu::VisibilityRays frame{};
  frame.boundsMin = glm::vec4(box.min, 0.0f);
  frame.boundsMax = glm::vec4(box.max, 0.0f);
  const std::vector<gpu::VisibilityLight> lights = visibilityLights(box);
  const std::vector<gpu::VisibilityReceiver> receivers = visibilityReceiversIn(box, 10, 3);
  std::vector<std::uint32_t> answers(receivers.size() * lights.size(), 7u);
  auto cpu = makeCpuTracer();
  EXPECT_THROW(cpu->traceVisibility(frame, lights, receivers, answers), Error);  // before setScene
  cpu->setScene(scene.data);
  vulkan_->setScene(scene.data);
  auto refusal = [&](Tracer& t, const gpu::VisibilityRays& f, std::span<const gpu::VisibilityLight> l,
                     std::span<const gpu::VisibilityReceiver> r, std::span<std::uint32_t> out) -> std::string {
    try {
      t.traceVisibility(f, l, r, out);
    } catch (const Error& e) {
      return e.what();
    }
    return "(accepted)";
  };
  for (Tracer* t : {cpu.get(), vulkan_}) {
    SCOPED_TRACE(t->backend());
    EXPECT_NE(refusal(*t, frame, {}, receivers, {}).find("lights: none"), std::string::npos);
    std::vector<std::uint32_t> short_(answers.size() - 1);
    EXPECT_NE(refusal(*t, frame, lights, receivers, short_).find("answers"), std::string::npos);
    std::vector<gpu::VisibilityReceiver> nanReceiver = receivers;
    nanReceiver[3].position.y = std::numeric_limits<float>::quiet_NaN();
    EXPECT_NE(refusal(*t, frame, lights, nanReceiver, answers).find("receivers[3]"), std::string::npos);
    std::vector<gpu::VisibilityLight> badKind = lights;
    badKind[1].kind.x = 2.0f;
    EXPECT_NE(refusal(*t, frame, badKind, receivers, answers).find("lights[1].kind"), std::string::npos);
    for (float range : {-1.0f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
      std::vector<gpu::VisibilityLight> badRange = lights;
      badRange[4].kind.y = range;
      EXPECT_NE(refusal(*t, frame, badRange, receivers, answers).find("lights[4].kind.y"), std::string::npos) << range;
    }
    std::vector<gpu::VisibilityLight> nanLight = lights;
    nanLight[2].target.w = std::numeric_limits<float>::quiet_NaN();
    EXPECT_NE(refusal(*t, frame, nanLight, receivers, answers).find("lights[2].target"), std::string::npos);
    gpu::VisibilityRays infinite = frame;
    infinite.boundsMax.x = std::numeric_limits<float>::infinity();
    EXPECT_NE(refusal(*t, infinite, lights, receivers, answers).find("bounds"), std::string::npos);
    // The refusals wrote nothing into the answers they were given.
    for (std::uint32_t a : answers) EXPECT_EQ(a, 7u);
  }
  EXPECT_TRUE(vulkan_->vulkan()->validationMessages().empty());
}

TEST_F(RayKinds, MismatchedOutputsAreRefused) {
  TestScene scene = singleObjectScene(glm::dvec3(0.0));
  std::vector<gpu::TraceRay> rays = rayBattery(scene, 10, 1);
  std::vector<gpu::RayHit> hits(9);
  std::vector<std::uint32_t> occluded(11);
  auto cpu = makeCpuTracer();
  EXPECT_THROW(cpu->traceClosest(rays, hits), Error);  // before setScene
  cpu->setScene(scene.data);
  vulkan_->setScene(scene.data);
  for (Tracer* t : {cpu.get(), vulkan_}) {
    EXPECT_THROW(t->traceClosest(rays, hits), Error) << t->backend();
    EXPECT_THROW(t->traceAny(rays, occluded), Error) << t->backend();
  }
  // No rays: nothing traced, nothing written.
  EXPECT_NO_THROW(vulkan_->traceClosest({}, {}));
}

}  // namespace
}  // namespace vs
