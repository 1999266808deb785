// The Vulkan compute tracer against the CPU reference traversal, texel by texel, on every scene the CPU tests
// use (hostile scenes, many instances, city512, the third-party assets, the demo scene), plus split bindings
// on a real scene, the refusal of an over-limit scene and partial re-traces.
//
// Both sides run the same portable traversal (compute/shared/traverse.h) with `precise` arithmetic in GLSL and
// -ffp-contract=off in C++, so every texel must be bit-identical (memcmp), in the normal build and in
// vulkan_trace_native_test, built with -march=native (FMA available); the largest depth difference is printed
// as well, to show how far a mismatch is. By default the shader walks objects through the box table, the CPU
// reference through the brickmap hierarchy: the canonical voxel order makes them agree bit for bit, and the
// shader's hierarchy walk is checked too (HierarchyWalkMatchesCpu).
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtx/component_wise.hpp>
#include <gtest/gtest.h>

#include "compute/cpu/cpu_tracer.h"
#include "compute/cpu/scene_arrays.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/scene.h"
#include "support/test_paths.h"
#include "support/hostile_views.h"
#include "support/test_scenes.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"
#include "voxel/voxel_object.h"

namespace vs {
namespace {


// One tracer (one pipeline JIT) for the whole file; each test uploads its scene.
class VulkanTrace : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { tracer_ = std::make_unique<VulkanTracer>(); }
  static void TearDownTestSuite() { tracer_.reset(); }
  void SetUp() override {
    // ctest sets VOXSHADOW_VALIDATION=1: the checks below then see every validation message.
    const char* v = std::getenv("VOXSHADOW_VALIDATION");
    if (v && std::string(v) == "1") {
      EXPECT_TRUE(tracer_->context().validationEnabled());
    }
  }
  void TearDown() override {
    std::vector<std::string> messages = tracer_->validationMessages();
    for (const std::string& m : messages) ADD_FAILURE() << "validation: " << m;
  }
  static std::unique_ptr<VulkanTracer> tracer_;
};
std::unique_ptr<VulkanTracer> VulkanTrace::tracer_;

template <class T>
std::uint64_t bytesOf(const std::vector<T>& v) {
  return std::uint64_t(v.size()) * sizeof(T);
}

// Length of one unit of t in voxels of the hit instance.
double voxelsPerT(const SceneData& scene, std::uint32_t instance, glm::vec3 d) {
  const gpu::Affine& m = scene.instances[instance].worldToBrick;
  glm::dvec3 ld(glm::dot(glm::dvec3(glm::vec3(m.row0)), glm::dvec3(d)),
                glm::dot(glm::dvec3(glm::vec3(m.row1)), glm::dvec3(d)),
                glm::dot(glm::dvec3(glm::vec3(m.row2)), glm::dvec3(d)));
  return glm::length(ld);
}

struct Comparison {
  std::size_t texels = 0, hits = 0, hitMismatch = 0, bitDifferent = 0;
  double maxDepthVoxels = 0.0;
};

// Compares the texels inside each view's rectangle.
Comparison compareLayers(const SceneData& scene, std::span<const gpu::TraceView> views,
                         const std::vector<ShadowLayer>& gpuLayers, const std::vector<ShadowLayer>& cpuLayers) {
  gpu::SceneArrays arrays(scene);
  Comparison c;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const gpu::TraceView& view = views[i];
    for (int y = view.rect.y; y < view.rect.w; ++y)
      for (int x = view.rect.x; x < view.rect.z; ++x) {
        std::size_t k = std::size_t(y) * std::size_t(view.info.x) + std::size_t(x);
        float g = gpuLayers[i].texels[k], r = cpuLayers[i].texels[k];
        ++c.texels;
        if (std::memcmp(&g, &r, sizeof g) != 0) ++c.bitDifferent;
        gpu::SceneArrays::WorldRay ray;
        arrays.vsViewRay(view, {x, y}, ray);
        const glm::vec3 d = ray.d;
        const float tMax = ray.tMax;
        bool gHit = g < tMax, rHit = r < tMax;
        if (gHit != rHit) {
          if (++c.hitMismatch <= 3)
            std::printf("  view %zu texel (%d %d): gpu %.9g cpu %.9g\n", i, x, y, double(g), double(r));
          continue;
        }
        if (!rHit) continue;
        ++c.hits;
        float t = 0;
        std::uint32_t inst = 0;
        glm::ivec3 voxel(0);
        arrays.vsTraceClosest(ray, t, inst, voxel);
        double err = std::abs(double(g) - double(r)) * voxelsPerT(scene, inst, d);
        c.maxDepthVoxels = std::max(c.maxDepthVoxels, err);
      }
  }
  return c;
}

// Traces `views` in one call on both backends and expects every texel bit-identical.
Comparison expectGpuMatchesCpu(VulkanTracer& tracer, const std::string& name, const SceneData& scene,
                               const std::vector<gpu::TraceView>& views, bool expectHits = true) {
  tracer.upload(scene);
  std::vector<ShadowLayer> gpuLayers, cpuLayers;
  TraceStats stats = tracer.trace(views, gpuLayers);
  auto t0 = std::chrono::steady_clock::now();
  traceCpu(scene, views, cpuLayers, CpuTracePath::Reference, 0);
  double cpuMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  Comparison c = compareLayers(scene, views, gpuLayers, cpuLayers);
  std::printf("%s: %zu views, %zu texels (%zu hits), %zu hit/miss mismatches, %zu texels not bit-identical, "
              "max |delta depth| %.3e voxel (gpu %.1f ms, cpu reference %.1f ms)\n",
              name.c_str(), views.size(), c.texels, c.hits, c.hitMismatch, c.bitDifferent, c.maxDepthVoxels,
              stats.gpuMs, cpuMs);
  EXPECT_EQ(stats.rays, c.texels) << name;
  EXPECT_EQ(c.hitMismatch, 0u) << name;
  EXPECT_EQ(c.bitDifferent, 0u) << name;
  if (expectHits) {
    EXPECT_GT(c.hits, 0u) << name;
  }
  return c;
}

// The CPU tests' views (directional, spot, six cube faces), then the same views again with the voxel_center
// depth point and a partial rectangle that is not a multiple of the 8x8 workgroup.
std::vector<gpu::TraceView> standardViews(const Aabb& bounds, int res) {
  Aabb b = bounds.empty() ? Aabb{{-8, -8, -8}, {8, 8, 8}} : bounds;
  glm::vec3 c = (b.min + b.max) * 0.5f;
  float r = glm::length(b.max - b.min);
  std::vector<gpu::TraceView> views = {test::directionalView(b, {-0.4f, -1.0f, -0.3f}, res),
                                       test::directionalView(b, {0.0f, -1.0f, 0.0f}, res),
                                       test::directionalView(b, {1.0f, -1.0f, 1.0f}, res),
                                       test::distanceView(c + glm::vec3(0, r * 0.4f, 0), {0.2f, -1, 0.1f}, r * 2, res)};
  const glm::vec3 faces[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (const auto& f : faces) views.push_back(test::distanceView(c + glm::vec3(0.3f, 0.2f, 0.1f), f, r, res / 2));
  test::appendVoxelCenterCopies(views, {5, 3, 7, 2});
  return views;
}

TEST_F(VulkanTrace, HostileScenesMatchCpu) {
  std::vector<test::TestScene> scenes;
  scenes.push_back(test::floorScene());
  scenes.push_back(test::singleVoxelScene());
  scenes.push_back(test::longObjectScene());
  for (const auto& scene : scenes)
    expectGpuMatchesCpu(*tracer_, scene.name, scene.data, standardViews(scene.data.worldBounds, 96));
}

// Axis-aligned orthographic views with half-voxel texels whose window is offset by a quarter texel, so
// texel centres fall on integer and half-integer coordinates (to the rounding of the unprojection): every
// other ray runs along a voxel face plane, and one in four along a voxel edge.
gpu::TraceView boundaryView(const Aabb& b, glm::vec3 d) {
  glm::vec3 center = glm::round((b.min + b.max) * 0.5f);
  float half = std::ceil(glm::compMax(b.max - b.min) * 0.5f) + 2.0f;
  float depth = glm::length(b.max - b.min) + 4.0f;
  glm::vec3 up = std::abs(d.y) > 0.99f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
  glm::mat4 view = glm::lookAtRH(center - d * depth, center, up);
  glm::mat4 proj = glm::orthoRH_ZO(-half - 0.25f, half - 0.25f, -half - 0.25f, half - 0.25f, 1.0f, 2.0f * depth);
  int res = int(half * 4.0f);
  return gpu::makeTraceView(glm::dmat4(proj * view), res, res, gpu::VS_ENCODING_NDC_DEPTH, gpu::VS_DEPTH_POINT_ENTRY);
}

TEST_F(VulkanTrace, RaysAlongVoxelBoundariesMatchCpu) {
  auto scene = test::floorScene();
  std::vector<gpu::TraceView> views;
  for (const glm::vec3& d : {glm::vec3(0, -1, 0), glm::vec3(1, 0, 0), glm::vec3(0, 0, -1)}) {
    views.push_back(boundaryView(scene.data.worldBounds, d));
    gpu::TraceView center = views.back();
    center.info.w = gpu::VS_DEPTH_POINT_VOXEL_CENTER;
    views.push_back(center);
  }
  expectGpuMatchesCpu(*tracer_, "floor, boundary rays", scene.data, views);
}

TEST_F(VulkanTrace, EmptyScenesNeverHit) {
  std::vector<test::TestScene> scenes;
  scenes.push_back(test::emptyScene());
  scenes.push_back(test::emptyObjectScene());
  for (const auto& scene : scenes) {
    auto views = standardViews(scene.data.worldBounds, 32);
    Comparison c = expectGpuMatchesCpu(*tracer_, scene.name, scene.data, views, false);
    EXPECT_EQ(c.hits, 0u);
  }
}

// The shader treats a ray with a NaN or infinite component as a miss, as the CPU does, bit for bit.
TEST_F(VulkanTrace, NonFiniteRaysAreMisses) {
  for (const test::TestScene& scene : test::hostileViewScenes()) {
    SCOPED_TRACE(scene.name);
    std::vector<test::HostileView> hostile = test::hostileViews(scene.data.worldBounds);
    std::vector<gpu::TraceView> views = test::traceViewsOf(hostile);
    tracer_->upload(scene.data);
    std::vector<ShadowLayer> gpu, cpu;
    tracer_->trace(views, gpu);
    traceCpu(scene.data, views, cpu, CpuTracePath::Reference, 2);
    ASSERT_EQ(gpu.size(), cpu.size());
    for (std::size_t i = 0; i < views.size(); ++i) {
      ASSERT_EQ(gpu[i].texels.size(), cpu[i].texels.size());
      EXPECT_EQ(std::memcmp(gpu[i].texels.data(), cpu[i].texels.data(), gpu[i].texels.size() * sizeof(float)), 0)
          << "view " << i;
    }
    test::expectAllMisses(hostile, gpu);
  }
}

TEST_F(VulkanTrace, ManyInstancesMatchCpu) {
  for (int count : {2000, 10000}) {
    auto scene = test::manyInstancesScene(count);
    expectGpuMatchesCpu(*tracer_, scene.name + " (" + std::to_string(count) + ")", scene.data,
                        standardViews(scene.data.worldBounds, 64));
  }
}

// A frame in which only instances moved: uploadInstances() keeps the voxel arrays and the box table on the
// device, and the trace equals the CPU reference of the moved scene, bit for bit.
TEST_F(VulkanTrace, MovedInstancesNeedOnlyTheInstanceUpload) {
  auto scene = test::manyInstancesScene(300);
  auto views = standardViews(scene.data.worldBounds, 64);
  expectGpuMatchesCpu(*tracer_, scene.name + " (before the move)", scene.data, views);
  ASSERT_TRUE(tracer_->boxTableInUse());
  std::vector<ShadowLayer> before;
  tracer_->trace(views, before);

  const glm::vec3 lo = scene.data.worldBounds.min, size = scene.data.worldBounds.max - lo;
  for (std::size_t i = 0; i < scene.data.instances.size(); i += 3) {
    glm::dvec3 to = glm::dvec3(lo) + glm::dvec3(size) * glm::dvec3(double(i % 7) / 7.0, 0.5, double(i % 5) / 5.0);
    scene.data.moveInstance(i, glm::translate(glm::dmat4(1.0), to));
  }
  tracer_->uploadInstances(scene.data);
  EXPECT_TRUE(tracer_->boxTableInUse());
  std::vector<ShadowLayer> gpuLayers, cpuLayers;
  tracer_->trace(views, gpuLayers);
  traceCpu(scene.data, views, cpuLayers, CpuTracePath::Reference, 0);
  Comparison c = compareLayers(scene.data, views, gpuLayers, cpuLayers);
  EXPECT_EQ(c.bitDifferent, 0u);
  EXPECT_GT(c.hits, 0u);
  std::size_t changed = 0;
  for (std::size_t i = 0; i < views.size(); ++i)
    for (std::size_t k = 0; k < before[i].texels.size(); ++k) changed += before[i].texels[k] != gpuLayers[i].texels[k];
  EXPECT_GT(changed, 0u) << "the move should change the shadows";

  // Another scene's voxel arrays cannot be kept: refused, naming the call to make.
  auto other = test::floorScene();
  try {
    tracer_->uploadInstances(other.data);
    FAIL() << "uploadInstances accepted a scene with other voxel arrays";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput);
    EXPECT_NE(std::string(e.what()).find("upload()"), std::string::npos) << e.what();
  }
  for (const std::string& m : tracer_->validationMessages()) ADD_FAILURE() << "validation: " << m;
}

TEST_F(VulkanTrace, City512MatchesCpu) {
  auto scene = test::city512Scene();
  expectGpuMatchesCpu(*tracer_, scene.name, scene.data, standardViews(scene.data.worldBounds, 128));
  EXPECT_TRUE(tracer_->boxTableInUse());  // the default walk: the box table
}

// The shader's other walk, through the brickmap hierarchy as the CPU reference walks it (taken when no box
// table can be built), on the hostile floor scene and city512.
TEST_F(VulkanTrace, HierarchyWalkMatchesCpu) {
  VulkanOptions options;
  options.boxTable = false;
  VulkanTracer hierarchy(options);
  std::vector<test::TestScene> scenes;
  scenes.push_back(test::floorScene());
  scenes.push_back(test::city512Scene());
  for (const auto& scene : scenes) {
    Comparison c = expectGpuMatchesCpu(hierarchy, scene.name + " (hierarchy walk)", scene.data,
                                       standardViews(scene.data.worldBounds, 96));
    EXPECT_FALSE(hierarchy.boxTableInUse());
    EXPECT_EQ(c.bitDifferent, 0u) << scene.name;
  }
  for (const std::string& m : hierarchy.validationMessages()) ADD_FAILURE() << "validation: " << m;
}

// Instances of every third-party asset, rotated and scaled non-uniformly (as in trace_cpu_test.cpp).
TEST_F(VulkanTrace, ThirdPartyAssetsMatchCpu) {
  auto scene = test::thirdPartyAssetsScene();
  expectGpuMatchesCpu(*tracer_, scene.name, scene.data, standardViews(scene.data.worldBounds, 128));
}

// The demo scene's own light views (directional, spot, point faces), each traced at a reduced size: the
// same view-projection with fewer texels, which keeps the comparison fast.
std::vector<gpu::TraceView> demoViews(const Scene& scene, int maxRes) {
  std::vector<gpu::TraceView> views;
  for (const LightView& lv : scene.lightViews()) {
    gpu::TraceView v = lv.trace;
    int w = std::min(v.info.x, maxRes), h = std::min(v.info.y, maxRes);
    v.info.x = w;
    v.info.y = h;
    v.rect = glm::ivec4(0, 0, w, h);
    views.push_back(v);
  }
  return views;
}

// Scenes far from the world origin, and a narrow spot cone 10^5 units from 0.01-unit voxels: the re-based rays
// of both backends agree bit for bit there too (tests/exact_rays_test.cpp checks the CPU against a
// double-precision reference on the same kind of scenes).
TEST_F(VulkanTrace, FarFromTheOriginMatchesCpu) {
  for (double offset : {1e4, 1e5}) {
    auto scene = test::floorScene();
    for (SceneInstance& inst : scene.instances)
      inst.brickToWorld = glm::translate(glm::dmat4(1.0), glm::dvec3(offset, 0.37 * offset, -0.61 * offset)) *
                          inst.brickToWorld;
    scene.finish();
    expectGpuMatchesCpu(*tracer_, "floor +" + std::to_string(int(offset)), scene.data,
                        standardViews(scene.data.worldBounds, 64));
  }
  auto plate = test::boxObject({0, 0, 0}, {512, 2, 512});
  test::TestScene scene;
  scene.name = "fine plate";
  scene.brickmaps.push_back(std::move(plate));
  scene.instances.push_back({0u, glm::rotate(glm::dmat4(1.0), glm::radians(30.0), {1, 0, 0}) *
                                     glm::scale(glm::dmat4(1.0), glm::dvec3(0.01)) *
                                     glm::translate(glm::dmat4(1.0), {-256, -1, -256})});
  scene.finish();
  std::vector<gpu::TraceView> views;
  for (double distance : {100.0, 1e4, 1e5}) {
    glm::dvec3 eye = glm::normalize(glm::dvec3(0.3, 1.0, 0.2)) * distance;
    glm::dmat4 proj = glm::perspectiveRH_ZO(2.0 * std::atan(3.0 / distance), 1.0, distance * 1e-3, distance * 1.5);
    glm::dmat4 view = glm::lookAtRH(eye, glm::dvec3(0.0), glm::dvec3(0, 1, 0));
    views.push_back(gpu::makeTraceView(proj * view, eye, 64, 64, gpu::VS_ENCODING_LINEAR_DISTANCE,
                                       gpu::VS_DEPTH_POINT_ENTRY, float(distance * 1.5)));
    views.push_back(gpu::makeTraceView(proj * view, eye, 64, 64, gpu::VS_ENCODING_LINEAR_DISTANCE,
                                       gpu::VS_DEPTH_POINT_VOXEL_CENTER, float(distance * 1.5)));
  }
  expectGpuMatchesCpu(*tracer_, "fine plate, far spot cones", scene.data, views);
}

TEST_F(VulkanTrace, DemoSceneMatchesCpu) {
  auto dir = test::scratchDir("vulkan_trace_demo");
  writeDemoWorld(dir);
  Scene scene = Scene::load(dir / "demo.json");
  auto views = demoViews(scene, 192);
  ASSERT_FALSE(views.empty());
  expectGpuMatchesCpu(*tracer_, "demo", scene.data(), views);
}

// Rectangles traced into a device buffer (a layer store read in place) land where their places say, equal
// to the texels read back, and touch nothing else; places that would land outside the buffer are refused
// before anything is traced.
TEST_F(VulkanTrace, TracedIntoADeviceBufferEqualsTheReadBack) {
  auto dir = test::scratchDir("vulkan_trace_into");
  writeDemoWorld(dir);
  Scene scene = Scene::load(dir / "demo.json");
  std::vector<gpu::TraceView> views = demoViews(scene, 64);
  ASSERT_GE(views.size(), 2u);
  views.resize(2);
  tracer_->upload(scene.data());
  std::vector<ShadowLayer> full;
  tracer_->trace(views, full);
  // Each view's rectangle (off the workgroup grid) into a store of rows 80 wide: view i's texel (x, y) at
  // 7 + i * 64 * 80 + (y - 5) * 80 + x, so the rectangle's first row starts at a row's texel 7 + x0.
  const std::uint32_t row = 80;
  const std::uint64_t storeTexels = 2ull * 64 * row + 64;
  std::vector<gpu::TraceView> part = views;
  std::vector<DeviceTexelPlace> places(views.size());
  for (std::size_t i = 0; i < views.size(); ++i) {
    part[i].rect = glm::ivec4(5 + int(i), 5, 50, 61);
    places[i] = {7 + std::int64_t(i) * 64 * row - 5 * std::int64_t(row), row};
  }
  vk::Buffer store = tracer_->context().createHostBuffer(storeTexels * sizeof(float),
                                                         VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  const float marker = -12345.0f;
  std::fill_n(static_cast<float*>(store.mapped), storeTexels, marker);
  const TraceStats stats = tracer_->traceInto(part, {store.get(), storeTexels, places});
  EXPECT_EQ(stats.rays, 2u * 45u * 56u - 56u);
  const auto* texels = static_cast<const float*>(store.mapped);
  std::size_t written = 0;
  for (std::uint64_t e = 0; e < storeTexels; ++e) written += texels[e] != marker ? 1 : 0;
  EXPECT_EQ(written, std::size_t(stats.rays)) << "texels outside the rectangles were written";
  for (std::size_t i = 0; i < views.size(); ++i) {
    ASSERT_EQ(views[i].info.x, 64);
    ASSERT_EQ(views[i].info.y, 64);
    const glm::ivec4 r = part[i].rect;
    float nearest = INFINITY, farthest = -INFINITY;  // the rectangle holds geometry: not all one value
    for (int y = r.y; y < r.w; ++y)
      for (int x = r.x; x < r.z; ++x) {
        const float got = texels[places[i].origin + std::int64_t(y) * row + x];
        const float want = full[i].texels[std::size_t(y) * 64 + std::size_t(x)];
        ASSERT_EQ(std::bit_cast<std::uint32_t>(got), std::bit_cast<std::uint32_t>(want))
            << "view " << i << " texel (" << x << ", " << y << ")";
        nearest = std::min(nearest, want);
        farthest = std::max(farthest, want);
      }
    EXPECT_LT(nearest, farthest) << "view " << i;
  }

  // Refused: a place that reaches past the end, one that starts before the buffer, a row narrower than the rectangle,
  // a place count that is not the view count; the buffer keeps its texels.
  std::vector<float> before(texels, texels + storeTexels);
  for (int bad = 0; bad < 4; ++bad) {
    std::vector<DeviceTexelPlace> wrong = places;
    if (bad == 0) wrong[1].origin = std::int64_t(storeTexels);
    if (bad == 1) wrong[0].origin = -5 * std::int64_t(row) - 6;  // the rectangle's first texel at -1
    if (bad == 2) wrong[0].rowLength = 20;
    if (bad == 3) wrong.pop_back();
    EXPECT_THROW(tracer_->traceInto(part, {store.get(), storeTexels, wrong}), Error) << "case " << bad;
  }
  EXPECT_EQ(std::memcmp(before.data(), texels, storeTexels * sizeof(float)), 0);
}

// Four rectangles traced one after another into the same layers equal one full dispatch, bit for bit.
TEST_F(VulkanTrace, FourRectanglesEqualOneDispatchOnCity512) {
  auto scene = test::city512Scene();
  auto views = standardViews(scene.data.worldBounds, 96);
  views.resize(10);  // the full-size views
  tracer_->upload(scene.data);
  std::vector<ShadowLayer> full, pieces;
  tracer_->trace(views, full);
  // Split points off the 8x8 grid, so rectangles start mid-workgroup.
  std::vector<gpu::TraceView> part = views;
  for (int piece = 0; piece < 4; ++piece) {
    for (std::size_t i = 0; i < views.size(); ++i) {
      int w = views[i].info.x, h = views[i].info.y;
      int sx = w / 2 + 3, sy = h / 3 + 1;
      glm::ivec4 rects[4] = {{0, 0, sx, sy}, {sx, 0, w, sy}, {0, sy, sx, h}, {sx, sy, w, h}};
      part[i].rect = rects[piece];
    }
    tracer_->trace(part, pieces);
  }
  std::size_t hits = 0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    ASSERT_EQ(full[i].texels.size(), pieces[i].texels.size());
    EXPECT_EQ(std::memcmp(full[i].texels.data(), pieces[i].texels.data(), full[i].texels.size() * sizeof(float)), 0)
        << "view " << i;
    for (float t : full[i].texels) hits += (i < 4 ? t < 1.0f : t < views[i].eyeHigh.w) ? 1 : 0;
  }
  EXPECT_GT(hits, 0u);
}

// A scene whose occupancy array really exceeds the device's maxStorageBufferRange (128 MiB on lavapipe).
// Building one from voxels would need over two million partial bricks (several GB of source voxels and
// minutes), so the brickmap arrays are written directly: a 1152 x 1024 x 1024 object of 9 x 8 x 8 full
// regions whose every brick is partial and holds one voxel at a hashed position. Its occupancy is 144 MiB
// (RAM in all < 1 GB, a few seconds); the trace spans two bindings and must equal the CPU reference.
TEST_F(VulkanTrace, SceneBeyondOneBindingMatchesCpu) {
  const glm::ivec3 regionDims(9, 8, 8);
  const glm::ivec3 voxelMax = regionDims * 128;
  // The real builder fixes the instance, BVH and object records for the object's bounds (two corner voxels).
  std::vector<SolidVoxel> corners = {{{0, 0, 0}, 1}, {voxelMax - 1, 1}};
  Brickmap frame = Brickmap::build(corners);
  const Brickmap* objects[] = {&frame};
  SceneInstance instance{0u, glm::dmat4(1.0)};
  SceneData scene = SceneData::build(objects, std::span<const SceneInstance>(&instance, 1));

  const std::uint32_t regionCount = std::uint32_t(regionDims.x * regionDims.y * regionDims.z);
  const std::uint32_t sectorCount = regionCount * 64u, brickCount = sectorCount * 64u;
  scene.regionTable.resize(regionCount);
  scene.regions.resize(regionCount);
  scene.sectors.resize(sectorCount);
  scene.bricks.resize(brickCount);
  scene.occupancy.assign(std::size_t(brickCount) * gpu::VS_OCCUPANCY_WORDS, 0u);
  const glm::uvec2 all(~0u, ~0u);
  for (std::uint32_t r = 0; r < regionCount; ++r) {
    scene.regionTable[r] = r;
    scene.regions[r] = gpu::Region{all, r * 64u, 0u};
  }
  for (std::uint32_t s = 0; s < sectorCount; ++s) scene.sectors[s] = gpu::Sector{all, s * 64u, 0u};
  for (std::uint32_t b = 0; b < brickCount; ++b) {
    std::uint32_t h = b * 2654435761u;
    std::uint32_t bit = (h ^ (h >> 15)) & 511u;  // cell = bit / 8, voxel in the cell = bit % 8
    gpu::Brick brick{glm::uvec2(0u), b, gpu::VS_UNIFORM_PAYLOAD | 1u};
    std::uint32_t cell = bit >> 3;
    if (cell < 32u) brick.cellMask.x = 1u << cell;
    else brick.cellMask.y = 1u << (cell - 32u);
    scene.bricks[b] = brick;
    scene.occupancy[std::size_t(b) * gpu::VS_OCCUPANCY_WORDS + (bit >> 5)] = 1u << (bit & 31u);
  }
  gpu::ObjectRecord& obj = scene.objects[0];
  obj.regionOrigin = glm::ivec4(0);
  obj.regionDims = glm::ivec4(regionDims, 0);
  obj.voxelMin = glm::ivec4(0);
  obj.voxelMax = glm::ivec4(voxelMax, 0);
  obj.bases = glm::uvec4(0u);
  obj.bases2.x = 0u;

  const std::uint64_t limit = tracer_->device().maxStorageBufferRange;
  std::printf("big scene: occupancy %.1f MiB, bricks %.1f MiB, binding limit %.1f MiB\n",
              scene.occupancy.size() * 4.0 / 1048576.0, scene.bricks.size() * 16.0 / 1048576.0, limit / 1048576.0);
  ASSERT_GT(scene.occupancy.size() * sizeof(std::uint32_t), limit);
  auto views = standardViews(scene.worldBounds, 48);
  expectGpuMatchesCpu(*tracer_, "big scene (beyond one binding)", scene, views);
  EXPECT_GE(tracer_->bufferCount(SplitArray::Occupancy), 2);
  // Free the device copy before the next test.
  tracer_->upload(test::emptyScene().data);
}

// The split path on a realistic scene: maxBindingBytes forces city512's arrays over up to four bindings; the
// trace must equal the unsplit one bit for bit, and the CPU.
TEST_F(VulkanTrace, City512SplitAcrossBindingsMatchesCpu) {
  auto scene = test::city512Scene();
  auto views = standardViews(scene.data.worldBounds, 96);
  tracer_->upload(scene.data);
  EXPECT_TRUE(tracer_->boxTableInUse());
  std::vector<ShadowLayer> whole;
  tracer_->trace(views, whole);

  std::uint64_t largest = 0;
  largest = std::max<std::uint64_t>(largest, bytesOf(scene.data.regionTable));
  largest = std::max<std::uint64_t>(largest, bytesOf(scene.data.regions));
  largest = std::max<std::uint64_t>(largest, bytesOf(scene.data.sectors));
  largest = std::max<std::uint64_t>(largest, bytesOf(scene.data.bricks));
  largest = std::max<std::uint64_t>(largest, bytesOf(scene.data.occupancy));
  VulkanOptions options;
  // A power of two at or above a quarter of the largest array: it splits into 3 or 4 bindings.
  options.maxBindingBytes = std::bit_ceil((largest + 3) / 4);
  VulkanTracer split(options);
  split.upload(scene.data);
  int maxBuffers = 0;
  for (int a = 0; a < kSplitArrayCount; ++a) maxBuffers = std::max(maxBuffers, split.bufferCount(SplitArray(a)));
  std::printf("city512 split: binding limit %llu bytes, largest array %llu bytes, bricks in %d buffers, occupancy "
              "in %d buffers\n",
              static_cast<unsigned long long>(options.maxBindingBytes), static_cast<unsigned long long>(largest),
              split.bufferCount(SplitArray::Bricks), split.bufferCount(SplitArray::Occupancy));
  EXPECT_GE(maxBuffers, 3);
  EXPECT_GE(split.bufferCount(SplitArray::Occupancy), 2);
  EXPECT_GE(split.bufferCount(SplitArray::Bricks), 2);
  // The box table (one texel buffer, held to the same byte limit here) does not fit: the hierarchy is walked.
  EXPECT_FALSE(split.boxTableInUse());
  std::vector<ShadowLayer> pieces;
  split.trace(views, pieces);
  for (std::size_t i = 0; i < views.size(); ++i)
    EXPECT_EQ(std::memcmp(whole[i].texels.data(), pieces[i].texels.data(), whole[i].texels.size() * sizeof(float)),
              0)
        << "view " << i;
  expectGpuMatchesCpu(split, "city512 (split bindings)", scene.data, views);
  for (const std::string& m : split.validationMessages()) ADD_FAILURE() << "validation: " << m;
}

// A scene that would need more than four bindings of the limit for one array is refused before any
// allocation, and the message names the array and the limit.
TEST_F(VulkanTrace, OverLimitSceneIsRefusedNamingTheLimit) {
  auto scene = test::city512Scene();
  VulkanOptions options;
  options.maxBindingBytes = std::bit_ceil(bytesOf(scene.data.occupancy) / 8);
  VulkanTracer small(options);
  try {
    small.upload(scene.data);
    FAIL() << "upload of an over-limit scene succeeded";
  } catch (const Error& e) {
    std::string what = e.what();
    EXPECT_EQ(e.kind(), ErrorKind::Runtime);
    EXPECT_NE(what.find("maxStorageBufferRange"), std::string::npos) << what;
    EXPECT_NE(what.find("occupancy"), std::string::npos) << what;
  }
  for (const std::string& m : small.validationMessages()) ADD_FAILURE() << "validation: " << m;
}

}  // namespace
}  // namespace vs
