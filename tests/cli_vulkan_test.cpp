// The CLI's Vulkan options: info --devices, bake --device (by index and by name), one trace call per view
// size, the Vulkan --stats lines, and a Vulkan bake equal to a CPU bake texel by texel.
#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "compute/vulkan/vulkan_context.h"
#include "support/test_paths.h"

namespace fs = std::filesystem;

namespace {

using vs::test::contains;
using vs::test::quote;
int cli(const std::string& args, std::string& out) { return vs::test::runCli(args, out); }

// A sun (32 texels), a spot (64) and a point light (six 16-texel faces): eight views of three sizes.
fs::path writeScene(const fs::path& dir) {
  fs::path scene = dir / "scene.json";
  std::ofstream f(scene);
  f << R"({ "version": 1,
  "assets": { "ball": { "file": ")" << (vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string() << R"(" } },
  "instances": [ { "asset": "ball" }, { "asset": "ball", "translate": [1.5, 0, 0.5], "scale": [1, 0.5, 1.5] } ],
  "camera": { "position": [3, 3, 3], "target": [0, 0, 0], "far": 20 },
  "lights": [ { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3],
                "shadow": { "resolution": 32, "cascades": 2 } },
              { "name": "lamp", "type": "spot", "position": [0, 4, 0], "direction": [0.1, -1, 0], "range": 10,
                "outer_cone_deg": 40, "shadow": { "resolution": 64 } },
              { "name": "torch", "type": "point", "position": [2, 1, 2], "range": 8,
                "shadow": { "resolution": 16 } } ] })";
  return scene;
}

// Every subimage's Z channel, in file order.
std::vector<std::vector<float>> readLayers(const fs::path& exr) {
  std::vector<std::vector<float>> layers;
  auto in = OIIO::ImageInput::open(exr.string());
  if (!in) return layers;
  for (int s = 0; in->seek_subimage(s, 0); ++s) {
    const OIIO::ImageSpec& spec = in->spec();
    std::vector<float> texels(std::size_t(spec.width) * spec.height * spec.nchannels);
    if (!in->read_image(s, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, texels.data())) return {};
    layers.push_back(std::move(texels));
  }
  return layers;
}

TEST(CliVulkan, InfoDevicesListsEveryDevice) {
  auto devices = vs::listVulkanDevices();
  ASSERT_FALSE(devices.empty());
  std::string out;
  ASSERT_EQ(cli("info --devices", out), 0) << out;
  for (const auto& d : devices) {
    EXPECT_TRUE(contains(out, "device " + std::to_string(d.index) + ": " + d.name)) << out;
    if (!d.driverName.empty()) {
      EXPECT_TRUE(contains(out, d.driverName)) << out;
    }
  }
  EXPECT_TRUE(contains(out, "maxStorageBufferRange")) << out;
  EXPECT_TRUE(contains(out, "maxTexelBufferElements")) << out;
  EXPECT_TRUE(contains(out, "(default)")) << out;

  ASSERT_EQ(cli("info --devices --json", out), 0) << out;
  auto j = nlohmann::json::parse(out);
  ASSERT_EQ(j.size(), devices.size());
  for (std::size_t i = 0; i < devices.size(); ++i) {
    EXPECT_EQ(j[i]["name"], devices[i].name);
    EXPECT_EQ(j[i]["type"], vs::toString(devices[i].type));
    EXPECT_EQ(j[i]["maxStorageBufferRange"].get<std::uint64_t>(), devices[i].maxStorageBufferRange);
    EXPECT_EQ(j[i]["maxTexelBufferElements"].get<std::uint64_t>(), devices[i].maxTexelBufferElements);
  }
  EXPECT_EQ(cli("info --devices " + quote("x.vdb"), out), 2) << out;
}

TEST(CliVulkan, BakeOnAChosenDeviceEqualsTheCpuBake) {
  auto devices = vs::listVulkanDevices();
  ASSERT_FALSE(devices.empty());
  const fs::path dir = vs::test::scratchDir("cli_vulkan_bake");
  const fs::path scene = writeScene(dir);
  std::string out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "cpu.exr") + " --backend cpu --threads 2", out), 0)
      << out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "by_index.exr") + " --backend vulkan --device 0 --stats",
                out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "device " + devices[0].name)) << out;
  EXPECT_TRUE(contains(out, "3 trace calls")) << out;  // three view sizes, eight views
  EXPECT_TRUE(contains(out, "walk through the box table")) << out;
  EXPECT_TRUE(contains(out, "pipeline creation")) << out;
  EXPECT_TRUE(contains(out, "view torch.face-z")) << out;
  EXPECT_TRUE(contains(out, "Mrays/s")) << out;

  // By name: a lower-case piece of the device's name.
  std::string part = devices[0].name.substr(0, std::min<std::size_t>(6, devices[0].name.size()));
  std::transform(part.begin(), part.end(), part.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "by_name.exr") + " --device " + quote(part), out), 0)
      << out;

  auto cpu = readLayers(dir / "cpu.exr");
  ASSERT_EQ(cpu.size(), 9u);  // two sun cascades (the scene has a camera), the lamp, six torch faces
  for (const char* name : {"by_index.exr", "by_name.exr"}) {
    auto gpu = readLayers(dir / name);
    ASSERT_EQ(gpu.size(), cpu.size()) << name;
    for (std::size_t i = 0; i < cpu.size(); ++i) {
      ASSERT_EQ(gpu[i].size(), cpu[i].size()) << name << " layer " << i;
      EXPECT_EQ(std::memcmp(gpu[i].data(), cpu[i].data(), cpu[i].size() * sizeof(float)), 0)
          << name << " layer " << i;
    }
  }
}

TEST(CliVulkan, UnknownDeviceExitsTwoAndWritesNothing) {
  const fs::path dir = vs::test::scratchDir("cli_vulkan_bad_device");
  const fs::path scene = writeScene(dir);
  std::string out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "a.exr") + " --device 99", out), 2) << out;
  EXPECT_TRUE(contains(out, "99")) << out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "b.exr") + " --device no-such-gpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "no-such-gpu")) << out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "c.exr") + " --backend cpu --device 0", out), 2)
      << out;
  EXPECT_TRUE(contains(out, "--device")) << out;
  for (const char* name : {"a.exr", "b.exr", "c.exr"}) EXPECT_FALSE(fs::exists(dir / name)) << name;
}

}  // namespace
