// The Vulkan backend: device listing and choice, validation capture, a hand-built scene traced with
// hand-computed expectations, partial re-trace by rectangles, split buffers, and the disk pipeline cache.
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "compute/vulkan/vulkan_tracer.h"
#include "support/test_paths.h"
#include "voxel/error.h"

namespace {

using vs::gpu::TraceView;

// A one-brick object (voxels inside [0, 8)^3, brick space = world space) assembled record by record, as the
// layout in voxel/brickmap_layout.h describes, so the trace is checked independently of the builders.
struct TinyScene {
  std::vector<std::uint32_t> regionTable{0};
  std::vector<vs::gpu::Region> regions;
  std::vector<vs::gpu::Sector> sectors;
  std::vector<vs::gpu::Brick> bricks;
  std::vector<std::uint32_t> occupancy;
  std::vector<std::uint32_t> payload;  // empty: its one brick has a uniform material
  std::vector<vs::gpu::ObjectRecord> objects;
  std::vector<vs::gpu::InstanceRecord> instances;
  std::vector<vs::gpu::BvhNode> nodes;
  std::vector<std::uint32_t> instanceIndices{0};
  std::vector<std::uint32_t> nodeEscapes{1};  // one leaf: its subtree ends at node 1

  vs::SceneArrays arrays() const {
    return {regionTable, regions,   sectors,         bricks,     occupancy, payload,
            objects,     instances, nodes,           instanceIndices, nodeEscapes};
  }
};

void setBit(glm::uvec2& mask, unsigned bit) {
  if (bit < 32) mask.x |= 1u << bit;
  else mask.y |= 1u << (bit - 32);
}

TinyScene makeScene(const std::function<bool(glm::ivec3)>& solid) {
  TinyScene s;
  vs::gpu::Brick brick{};
  s.occupancy.assign(vs::gpu::VS_OCCUPANCY_WORDS, 0u);
  glm::ivec3 lo(8), hi(0);
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) {
        if (!solid({x, y, z})) continue;
        unsigned cell = unsigned((x >> 1) + 4 * (y >> 1) + 16 * (z >> 1));
        unsigned bit = cell * 8 + unsigned((x & 1) + 2 * (y & 1) + 4 * (z & 1));
        s.occupancy[bit >> 5] |= 1u << (bit & 31);
        setBit(brick.cellMask, cell);
        lo = glm::min(lo, glm::ivec3(x, y, z));
        hi = glm::max(hi, glm::ivec3(x, y, z) + 1);
      }
  brick.occupancy = 0;
  brick.payload = vs::gpu::VS_UNIFORM_PAYLOAD | 1u;
  s.bricks.push_back(brick);
  vs::gpu::Sector sector{};
  setBit(sector.brickMask, 0);
  s.sectors.push_back(sector);
  vs::gpu::Region region{};
  setBit(region.sectorMask, 0);
  s.regions.push_back(region);
  vs::gpu::ObjectRecord object{};
  object.regionDims = glm::ivec4(1, 1, 1, 0);
  object.voxelMin = glm::ivec4(lo, 0);
  object.voxelMax = glm::ivec4(hi, 0);
  s.objects.push_back(object);
  vs::gpu::InstanceRecord inst{};
  inst.worldToBrick = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
  inst.brickToWorld = inst.worldToBrick;
  inst.boundsMin = glm::vec4(glm::vec3(lo), 0.0f);
  inst.boundsMax = glm::vec4(glm::vec3(hi), 0.0f);
  s.instances.push_back(inst);
  vs::gpu::BvhNode node{};
  node.boundsMin = glm::vec3(lo);
  node.boundsMax = glm::vec3(hi);
  node.rightOrFirst = 0;
  node.count = 1;
  s.nodes.push_back(node);
  return s;
}

// Column heights: a 4x4x4 block in the corner, a tall column and a single voxel.
int columnHeight(int x, int z) {
  if (x < 4 && z < 4) return 4;
  if (x == 6 && z == 1) return 7;
  if (x == 2 && z == 6) return 1;
  return 0;
}

TinyScene heightScene() {
  return makeScene([](glm::ivec3 v) { return v.y < columnHeight(v.x, v.z); });
}

TraceView makeView(const glm::mat4& viewProj, int width, int height, int encoding, int depthPoint,
                   glm::vec4 origin = glm::vec4(0.0f)) {
  return vs::gpu::makeTraceView(glm::dmat4(viewProj), width, height, encoding, depthPoint, origin);
}

// Looking straight down from y = 10 onto the 8x8 footprint; near at y = 10, far at y = -10.
// Texel (x, y) covers column x, z = 7 - y (the up vector is -z, and row 0 is the bottom of NDC).
TraceView topDownView(int depthPoint) {
  glm::mat4 view = glm::lookAt(glm::vec3(4, 10, 4), glm::vec3(4, 0, 4), glm::vec3(0, 0, -1));
  glm::mat4 proj = glm::orthoRH_ZO(-4.0f, 4.0f, -4.0f, 4.0f, 0.0f, 20.0f);
  return makeView(proj * view, 8, 8, vs::gpu::VS_ENCODING_NDC_DEPTH, depthPoint);
}

// An oblique directional view of the whole scene, with an odd size so rectangles cut through workgroups.
TraceView obliqueView() {
  glm::vec3 d = glm::normalize(glm::vec3(-0.4f, -1.0f, -0.3f));
  glm::vec3 c(4, 4, 4);
  glm::mat4 view = glm::lookAt(c - d * 20.0f, c, glm::vec3(0, 0, 1));
  glm::mat4 proj = glm::orthoRH_ZO(-7.0f, 7.0f, -6.0f, 6.0f, 0.0f, 40.0f);
  return makeView(proj * view, 37, 29, vs::gpu::VS_ENCODING_NDC_DEPTH, vs::gpu::VS_DEPTH_POINT_ENTRY);
}

vs::VulkanOptions validatedOptions() {
  vs::VulkanOptions o;
  o.validation = true;
  // One cache folder per test, so parallel test processes never clear each other's.
  o.cacheDir = vs::test::scratchDir(std::string("vulkan_cache_") +
                                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
  return o;
}

void expectNoValidationMessages(const vs::VulkanTracer& tracer) {
  std::vector<std::string> messages = tracer.validationMessages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages; first: " << messages.front();
}

TEST(VulkanDevices, ListsAtLeastOneDevice) {
  std::vector<vs::VulkanDeviceInfo> devices = vs::listVulkanDevices();
  ASSERT_FALSE(devices.empty()) << "no Vulkan device found (install mesa-vulkan-drivers for lavapipe)";
  for (const auto& d : devices) {
    EXPECT_FALSE(d.name.empty());
    EXPECT_GT(d.maxStorageBufferRange, 0u) << d.name;
  }
  std::size_t best = vs::chooseVulkanDevice(devices, -1, "");
  EXPECT_TRUE(devices[best].hasComputeQueue);
  EXPECT_TRUE(devices[best].shaderFloat64);
  for (const auto& d : devices) {
    if (!d.hasComputeQueue || !d.shaderFloat64) continue;
    EXPECT_LE(int(devices[best].type), int(d.type)) << "a better device type was passed over";
  }
}

// A GPU without shaderFloat64 (Intel Xe and Arc) is passed over for one that has it, lavapipe say; a device
// named by index is taken as named; a list with no such device is refused naming the feature.
TEST(VulkanDevices, AutomaticChoiceNeedsShaderFloat64) {
  vs::VulkanDeviceInfo gpu, cpu;
  gpu.name = "Integrated GPU without fp64";
  gpu.type = vs::VulkanDeviceType::Integrated;
  gpu.hasComputeQueue = true;
  cpu.index = 1;
  cpu.name = "llvmpipe";
  cpu.type = vs::VulkanDeviceType::Cpu;
  cpu.hasComputeQueue = true;
  cpu.shaderFloat64 = true;
  EXPECT_EQ(vs::chooseVulkanDevice({gpu, cpu}, -1, ""), 1u);
  EXPECT_EQ(vs::chooseVulkanDevice({gpu, cpu}, 0, ""), 0u);
  cpu.shaderFloat64 = false;
  try {
    vs::chooseVulkanDevice({gpu, cpu}, -1, "");
    FAIL() << "devices without shaderFloat64 were chosen";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::Runtime);
    EXPECT_NE(std::string(e.what()).find("shaderFloat64"), std::string::npos) << e.what();
  }
}

TEST(VulkanDevices, ChoiceByIndexAndName) {
  std::vector<vs::VulkanDeviceInfo> devices = vs::listVulkanDevices();
  ASSERT_FALSE(devices.empty());
  std::size_t best = vs::chooseVulkanDevice(devices, -1, "");
  EXPECT_EQ(vs::chooseVulkanDevice(devices, int(best), ""), best);
  // A name substring in another case picks a device whose name contains it.
  std::string part = devices[best].name.substr(0, 4);
  for (char& c : part) c = char(std::toupper(static_cast<unsigned char>(c)));
  std::size_t byName = vs::chooseVulkanDevice(devices, -1, part);
  EXPECT_EQ(devices[byName].name.substr(0, 4), devices[best].name.substr(0, 4));
  try {
    vs::chooseVulkanDevice(devices, -1, "no such device xyz");
    FAIL() << "an unknown device name was accepted";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput);
    EXPECT_NE(std::string(e.what()).find(devices[0].name), std::string::npos) << "message lists devices";
  }
  EXPECT_THROW(vs::chooseVulkanDevice(devices, int(devices.size()), ""), vs::Error);
  try {
    vs::chooseVulkanDevice({}, -1, "");
    FAIL() << "an empty device list was accepted";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::Runtime);
    EXPECT_NE(std::string(e.what()).find("no Vulkan device found"), std::string::npos);
  }
}

TEST(VulkanContext, ValidationCapturesErrors) {
  vs::VulkanContextOptions o;
  o.validation = true;
  vs::VulkanContext context(o);
  ASSERT_TRUE(context.validationEnabled());
  EXPECT_TRUE(context.validationMessages().empty());
  // A zero-sized buffer is invalid usage: the messenger must record it, or "no messages" would prove nothing.
  auto info = vs::vk::make<VkBufferCreateInfo>(VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO);
  info.size = 0;
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  VkBuffer buffer = VK_NULL_HANDLE;
  if (vkCreateBuffer(context.device(), &info, nullptr, &buffer) == VK_SUCCESS && buffer != VK_NULL_HANDLE)
    vkDestroyBuffer(context.device(), buffer, nullptr);
  std::vector<std::string> messages = context.validationMessages();
  ASSERT_FALSE(messages.empty());
  EXPECT_NE(messages.front().find("error"), std::string::npos) << messages.front();
}

// Objects shared per device: one per key, kept while the context lives (a renderer made for one frame finds
// the pipelines the last one compiled), destroyed with the context.
TEST(VulkanContext, SharedObjectsAreMadeOncePerKeyAndLiveWithTheContext) {
  std::weak_ptr<void> watched;
  {
    vs::VulkanContext context;
    int made = 0;
    auto make = [&] {
      ++made;
      return std::static_pointer_cast<void>(std::make_shared<int>(made));
    };
    std::shared_ptr<void> a = context.shared("a", make);
    std::shared_ptr<void> again = context.shared("a", make);
    std::shared_ptr<void> b = context.shared("b", make);
    EXPECT_EQ(made, 2);
    EXPECT_EQ(a, again);
    EXPECT_NE(a, b);
    watched = a;
    a.reset();
    again.reset();
    std::shared_ptr<void> kept = context.shared("a", make);
    EXPECT_EQ(made, 2) << "no holder left, yet the context kept it";
    EXPECT_EQ(*std::static_pointer_cast<int>(kept), 1);
    EXPECT_FALSE(watched.expired());
  }
  EXPECT_TRUE(watched.expired()) << "the context destroys what it shares";
}

TEST(VulkanTracer, HandComputedHits) {
  vs::VulkanTracer tracer(validatedOptions());
  TinyScene scene = heightScene();
  tracer.upload(scene.arrays());

  const float range = 30.0f;
  glm::vec3 light(1.5f, 12.0f, 1.5f);
  glm::mat4 spotView = glm::lookAt(light, light - glm::vec3(0, 1, 0), glm::vec3(0, 0, -1));
  glm::mat4 spotProj = glm::perspectiveRH_ZO(glm::radians(60.0f), 1.0f, 0.1f, range);
  std::vector<TraceView> views = {
      topDownView(vs::gpu::VS_DEPTH_POINT_ENTRY),
      topDownView(vs::gpu::VS_DEPTH_POINT_VOXEL_CENTER),
      makeView(spotProj * spotView, 3, 3, vs::gpu::VS_ENCODING_LINEAR_DISTANCE, vs::gpu::VS_DEPTH_POINT_ENTRY,
               glm::vec4(light, range)),
  };
  std::vector<vs::ShadowLayer> layers;
  vs::TraceStats stats = tracer.trace(views, layers);
  ASSERT_EQ(layers.size(), 3u);
  EXPECT_EQ(stats.rays, 8u * 8u * 2u + 9u);

  for (int layer = 0; layer < 2; ++layer) {
    ASSERT_EQ(layers[layer].width, 8);
    ASSERT_EQ(layers[layer].height, 8);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) {
        int h = columnHeight(x, 7 - y);
        // Entry: the top face at y = h; voxel centre: y = h - 0.5. NDC depth is (10 - y_hit) / 20.
        float hitY = layer == 0 ? float(h) : float(h) - 0.5f;
        float expected = h == 0 ? 1.0f : (10.0f - hitY) / 20.0f;
        EXPECT_NEAR(layers[layer].texels[y * 8 + x], expected, 1e-6f) << "layer " << layer << " texel " << x << "," << y;
      }
  }
  // The centre texel of the spot looks straight down onto the block top (y = 4), 8 below the light;
  // the corner texel (0, 0) leans towards -x, where there is no voxel.
  EXPECT_NEAR(layers[2].texels[1 * 3 + 1], 8.0f, 1e-5f);
  EXPECT_EQ(layers[2].texels[0], range);
  expectNoValidationMessages(tracer);
}

TEST(VulkanTracer, FourRectanglesEqualOneDispatch) {
  vs::VulkanTracer tracer(validatedOptions());
  TinyScene scene = heightScene();
  tracer.upload(scene.arrays());
  TraceView full = obliqueView();
  std::vector<vs::ShadowLayer> whole;
  tracer.trace(std::span<const TraceView>(&full, 1), whole);
  ASSERT_EQ(whole.size(), 1u);
  int hits = 0, misses = 0;
  for (float t : whole[0].texels) (t < 1.0f ? hits : misses)++;
  ASSERT_GT(hits, 20) << "the oblique view must see the scene";
  ASSERT_GT(misses, 20) << "and empty space around it";

  std::vector<vs::ShadowLayer> parts(1);
  parts[0].width = 37;
  parts[0].height = 29;
  parts[0].texels.assign(37 * 29, -7.0f);
  const glm::ivec4 rects[4] = {{0, 0, 13, 17}, {13, 0, 37, 17}, {0, 17, 13, 29}, {13, 17, 37, 29}};
  for (int i = 0; i < 4; ++i) {
    TraceView v = full;
    v.rect = rects[i];
    tracer.trace(std::span<const TraceView>(&v, 1), parts);
    // Texels in rectangles not traced yet keep the caller's values.
    for (int j = i + 1; j < 4; ++j)
      for (int y = rects[j].y; y < rects[j].w; ++y)
        for (int x = rects[j].x; x < rects[j].z; ++x)
          ASSERT_EQ(parts[0].texels[y * 37 + x], -7.0f) << "rect " << i << " wrote outside itself at " << x << "," << y;
  }
  EXPECT_EQ(parts[0].texels, whole[0].texels);
  expectNoValidationMessages(tracer);
}

TEST(VulkanTracer, SplitBuffersGiveTheSameImage) {
  TinyScene scene = heightScene();
  TraceView view = obliqueView();
  std::vector<vs::ShadowLayer> unsplit, split;
  {
    vs::VulkanTracer tracer(validatedOptions());
    tracer.upload(scene.arrays());
    EXPECT_EQ(tracer.bufferCount(vs::SplitArray::Occupancy), 1);
    tracer.trace(std::span<const TraceView>(&view, 1), unsplit);
    expectNoValidationMessages(tracer);
  }
  vs::VulkanOptions o = validatedOptions();
  o.maxBindingBytes = 16;  // one brick record, four occupancy words per binding
  vs::VulkanTracer tracer(o);
  tracer.upload(scene.arrays());
  EXPECT_EQ(tracer.bufferCount(vs::SplitArray::Occupancy), 4);
  tracer.trace(std::span<const TraceView>(&view, 1), split);
  EXPECT_EQ(split[0].texels, unsplit[0].texels);
  expectNoValidationMessages(tracer);
}

// Expects upload() of the scene to fail with an error of `kind` whose message names each of `words`, and the
// tracer to stay free of validation messages.
void expectUploadRefused(vs::VulkanTracer& tracer, const TinyScene& scene, vs::ErrorKind kind,
                         std::initializer_list<const char*> words) {
  try {
    tracer.upload(scene.arrays());
    ADD_FAILURE() << "the upload was accepted";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), kind);
    std::string what = e.what();
    for (const char* word : words) EXPECT_NE(what.find(word), std::string::npos) << what;
  }
  expectNoValidationMessages(tracer);
}

TEST(VulkanTracer, RefusesArraysBeyondTheBindingLimit) {
  vs::VulkanOptions o = validatedOptions();
  o.maxBindingBytes = 64;
  vs::VulkanTracer tracer(o);
  TinyScene scene = heightScene();
  scene.occupancy.assign(1000, 0u);  // 4000 bytes: 63 bindings of 64 bytes, more than the shader has
  expectUploadRefused(tracer, scene, vs::ErrorKind::Runtime, {"occupancy", "maxStorageBufferRange"});
}

// Arrays assembled by hand must carry one node escape per BVH node; a mismatch is bad input, named.
TEST(VulkanTracer, RefusesMissingNodeEscapes) {
  vs::VulkanTracer tracer(validatedOptions());
  TinyScene scene = heightScene();
  scene.nodeEscapes.clear();
  expectUploadRefused(tracer, scene, vs::ErrorKind::BadInput, {"node escapes"});
}

TEST(VulkanTracer, PipelineCacheIsWrittenAndReused) {
  vs::VulkanOptions o = validatedOptions();
  o.cacheDir = vs::test::scratchDir("vulkan_pipeline_cache");
  {
    vs::VulkanTracer cold(o);
    EXPECT_FALSE(cold.pipelineStats().warmCache) << "the cache directory was fresh";
    EXPECT_TRUE(cold.pipelineStats().cacheSaved) << cold.pipelineStats().cacheError;
    ASSERT_TRUE(std::filesystem::exists(cold.pipelineStats().cacheFile));
    // At least the cache header (16 bytes + UUID); lavapipe keeps no pipeline binaries beyond it.
    EXPECT_GE(std::filesystem::file_size(cold.pipelineStats().cacheFile), 32u);
    EXPECT_EQ(cold.pipelineStats().cacheFile.parent_path(), o.cacheDir);
    expectNoValidationMessages(cold);
  }
  vs::VulkanTracer warm(o);
  // A driver that caches pipelines gives a warm cache; one that keeps only the header (lavapipe) an empty one.
  const bool headerOnly = std::filesystem::file_size(warm.pipelineStats().cacheFile) <= 32u;
  EXPECT_EQ(warm.pipelineStats().warmCache, !headerOnly);
  EXPECT_EQ(warm.pipelineStats().cacheEmpty, headerOnly);
  EXPECT_GE(warm.pipelineStats().createMs, 0.0);
  // Leftover temporary files would mean the write was not atomic.
  for (const auto& entry : std::filesystem::directory_iterator(o.cacheDir))
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
  expectNoValidationMessages(warm);
}

}  // namespace
