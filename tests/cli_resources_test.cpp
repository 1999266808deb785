// Memory budgets: bake and render refuse, before any trace, work that will not fit the memory available or the
// process's limits (ulimit -v, ulimit -d), naming the figure, the budget and what set it; sizes read in
// binary units.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <string>

#include "support/test_paths.h"
#include "tools/resources.h"

namespace fs = std::filesystem;

namespace {

using vs::test::contains;
using vs::test::quote;

void writeFile(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

// A camera over the fog sphere and one sun of `cascades` cascades at `resolution`^2.
std::string sunScene(int resolution, int cascades) {
  return R"({ "version": 1,
  "assets": { "ball": { "file": ")" + (vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string() + R"(" } },
  "instances": [ { "asset": "ball" } ],
  "camera": { "position": [3, 3, 3], "target": [0, 0, 0], "far": 20 },
  "lights": [ { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3],
                "shadow": { "resolution": )" + std::to_string(resolution) + R"(, "cascades": )" + std::to_string(cascades) + " } } ] }";
}

// Runs the CLI under a shell `ulimit` (e.g. "-v 650000"), returning its exit status and the seconds it took.
int cliUnderLimit(const std::string& limit, const std::string& args, std::string& out, double& seconds) {
  const auto t0 = std::chrono::steady_clock::now();
  const int status = vs::test::runCommand("ulimit " + limit + " && " + vs::test::cliPath() + " " + args, out);
  seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return status;
}

}  // namespace

TEST(CliResources, SizesArePrintedInAScaledUnit) {
  EXPECT_EQ(vs::cli::formatBytes(0), "0 B");
  EXPECT_EQ(vs::cli::formatBytes(1023), "1023 B");
  EXPECT_EQ(vs::cli::formatBytes(1024), "1.00 KiB");
  EXPECT_EQ(vs::cli::formatBytes(1536000), "1.46 MiB");
  EXPECT_EQ(vs::cli::formatBytes((1ull << 20) - 1), "1.00 MiB");  // not "1024.00 KiB"
  EXPECT_EQ(vs::cli::formatBytes(320ull << 20), "320.00 MiB");
  EXPECT_EQ(vs::cli::formatBytes(3ull << 30), "3.00 GiB");
  EXPECT_EQ(vs::cli::formatBytes(5ull << 40), "5.00 TiB");

  fs::path dir = vs::test::scratchDir("resources_units");
  writeFile(dir / "scene.json", sunScene(256, 1));
  std::string out;
  EXPECT_EQ(vs::test::runCli("bake " + quote(dir / "scene.json") + " -o " + quote(dir / "o.exr") +
                                 " --backend cpu --memory-budget 1K", out),
            2) << out;
  EXPECT_TRUE(contains(out, "need about 512.00 KiB of memory, more than the budget of 1.00 KiB (--memory-budget)")) << out;
  EXPECT_FALSE(contains(out, "0.00 GiB")) << out;
}

// The example of a 4096^2 sun in 4 cascades (320 MiB of layers) under ulimit -v 650000: the process maps
// most of that before any work (its libraries, and the Vulkan driver), so the bake cannot fit, and is refused
// up front, whichever the backend, instead of tracing and then failing for memory.
TEST(CliResources, BakeUnderAnAddressSpaceLimitIsRefusedBeforeTracing) {
  fs::path dir = vs::test::scratchDir("resources_ulimit_v");
  writeFile(dir / "scene.json", sunScene(4096, 4));
  for (const char* backend : {"cpu", "vulkan"}) {
    SCOPED_TRACE(backend);
    std::string out;
    double seconds = 0.0;
    EXPECT_EQ(cliUnderLimit("-v 650000", "bake " + quote(dir / "scene.json") + " -o " + quote(dir / "o.exr") +
                                             " --backend " + backend, out, seconds),
              2) << out;
    EXPECT_LT(seconds, 20.0) << "refused late";
    EXPECT_TRUE(contains(out, "4 shadow layers (67108864 texels) need about 320.00 MiB of memory")) << out;
    EXPECT_TRUE(contains(out, "the room left under ulimit -v (RLIMIT_AS) of 634.77 MiB, of which this process maps")) << out;
    EXPECT_FALSE(contains(out, "out of memory")) << out;
    EXPECT_FALSE(fs::exists(dir / "o.exr"));
  }
  // Room enough: the same limit that refuses the large bake lets a small one run.
  writeFile(dir / "small.json", sunScene(256, 1));
  std::string out;
  double seconds = 0.0;
  EXPECT_EQ(cliUnderLimit("-v 1500000", "bake " + quote(dir / "small.json") + " -o " + quote(dir / "s.exr") + " --backend cpu",
                          out, seconds),
            0) << out;
}

TEST(CliResources, ADataLimitSetsTheBudgetToo) {
  fs::path dir = vs::test::scratchDir("resources_ulimit_d");
  writeFile(dir / "scene.json", sunScene(4096, 4));
  std::string out;
  double seconds = 0.0;
  EXPECT_EQ(cliUnderLimit("-d 300000", "bake " + quote(dir / "scene.json") + " -o " + quote(dir / "o.exr") + " --backend cpu",
                          out, seconds),
            2) << out;
  EXPECT_LT(seconds, 20.0) << "refused late";
  EXPECT_TRUE(contains(out, "the room left under ulimit -d (RLIMIT_DATA) of 292.97 MiB, of which this process holds")) << out;
  // A larger --memory-budget does not lift the limit.
  EXPECT_EQ(cliUnderLimit("-d 300000", "bake " + quote(dir / "scene.json") + " -o " + quote(dir / "o.exr") +
                                           " --backend cpu --memory-budget 64G", out, seconds),
            2) << out;
  EXPECT_TRUE(contains(out, "ulimit -d (RLIMIT_DATA)")) << out;
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
}

TEST(CliResources, RenderChecksItsMemoryBeforeAnyWork) {
  fs::path dir = vs::test::scratchDir("resources_render");
  writeFile(dir / "scene.json", sunScene(512, 2));
  for (const char* backend : {"cpu", "vulkan"}) {
    SCOPED_TRACE(backend);
    std::string out;
    double seconds = 0.0;
    // 16384^2 pixels: some 33 GiB of G-buffer, rays and image.
    EXPECT_EQ(cliUnderLimit("-v 4000000", "render " + quote(dir / "scene.json") + " -o " + quote(dir / "o.png") +
                                              " --width 16384 --height 16384 --backend " + backend, out, seconds),
              2) << out;
    EXPECT_LT(seconds, 20.0) << "refused late";
    EXPECT_TRUE(contains(out, "a 16384x16384 frame (G-buffer, lit image, shadow layers and visibility rays) needs about ")) << out;
    EXPECT_TRUE(contains(out, " GiB of memory, more than the budget of ")) << out;
    EXPECT_TRUE(contains(out, "ulimit -v (RLIMIT_AS)")) << out;
    EXPECT_FALSE(fs::exists(dir / "o.png"));
  }
  std::string out;
  EXPECT_EQ(vs::test::runCli("render " + quote(dir / "scene.json") + " -o " + quote(dir / "o.exr") +
                                 " --backend cpu --memory-budget 20M", out),
            2) << out;
  EXPECT_TRUE(contains(out, "a 1280x720 frame")) << out;
  EXPECT_TRUE(contains(out, "the budget of 20.00 MiB (--memory-budget)")) << out;
  // A frame that fits renders.
  EXPECT_EQ(vs::test::runCli("render " + quote(dir / "scene.json") + " -o " + quote(dir / "o.png") +
                                 " --backend cpu --width 64 --height 48 --memory-budget 1G", out),
            0) << out;
  // A lighting buffer larger than the device binds is refused up front too, naming the limit.
  EXPECT_EQ(vs::test::runCli("render " + quote(dir / "scene.json") + " -o " + quote(dir / "big.png") +
                                 " --backend vulkan --width 16384 --height 16384 --memory-budget 1T", out),
            2) << out;
  EXPECT_TRUE(contains(out, "lighting buffer, more than maxStorageBufferRange")) << out;
}
