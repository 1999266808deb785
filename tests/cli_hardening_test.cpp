// Hostile use of the CLI: outputs over inputs, absurd numbers, non-regular files, flags out of range, resource
// limits, many views, a missing Vulkan driver. Each case exits with a clear message and leaves no output.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include "support/test_paths.h"

namespace fs = std::filesystem;

namespace {

using vs::test::contains;
using vs::test::quote;
int cli(const std::string& args, std::string& out) { return vs::test::runCli(args, out); }

void writeFile(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

// Concatenation by appending (GCC 12 warns falsely on chains of string operator+).
std::string cat(std::initializer_list<std::string_view> parts) {
  std::string s;
  for (std::string_view p : parts) s.append(p);
  return s;
}

std::string readFile(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

fs::path fogSphere() { return vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb"; }

// A scene over the third-party fog sphere; `lights` is the JSON array of lights.
std::string sceneWith(const std::string& lights, const fs::path& asset = fogSphere(), const std::string& instance = "") {
  return R"({ "version": 1, "assets": { "ball": { "file": ")" + asset.string() + R"(" } },
  "instances": [ { "asset": "ball")" + instance + R"( } ], "lights": )" + lights + " }";
}

const char* kSun = R"([ { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3],
                          "shadow": { "resolution": 32 } } ])";

// Files in dir other than the given ones: outputs or temporaries a failed command must not leave.
std::vector<std::string> extraFiles(const fs::path& dir, const std::vector<std::string>& expected) {
  std::vector<std::string> extra;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::string name = e.path().filename().string();
    if (std::find(expected.begin(), expected.end(), name) == expected.end()) extra.push_back(name);
  }
  return extra;
}

std::string pointLights(int count, int resolution) {
  std::string lights = "[";
  for (int i = 0; i < count; ++i)
    lights += std::string(i ? "," : "") + R"({ "name": "p)" + std::to_string(i) + R"(", "type": "point", "position": [)" +
              std::to_string(-2.0 + 0.01 * i) + R"(, 2, 1], "range": 9, "shadow": { "resolution": )" +
              std::to_string(resolution) + " } }";
  return lights + "]";
}

}  // namespace

TEST(CliHardening, SidecarNeverReplacesTheSceneBesideIt) {
  fs::path dir = vs::test::scratchDir("hardening_sidecar");
  fs::path scene = dir / "demo.json";
  writeFile(scene, sceneWith(kSun));
  const std::string before = readFile(scene);
  std::string out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "demo.exr") + " --backend cpu", out), 0) << out;
  EXPECT_EQ(readFile(scene), before) << "the bake changed its own scene file";
  EXPECT_TRUE(fs::is_regular_file(dir / "demo.exr.json"));
  auto sidecar = nlohmann::json::parse(readFile(dir / "demo.exr.json"));
  EXPECT_EQ(sidecar["views"][0]["name"], "sun");
}

TEST(CliHardening, OutputsResolvingToAnInputAreRefusedBeforeAnyWork) {
  fs::path dir = vs::test::scratchDir("hardening_over_inputs");
  fs::path asset = dir / "ball.vdb";
  fs::copy_file(fogSphere(), asset);
  fs::path scene = dir / "scene.json";
  writeFile(scene, sceneWith(kSun, asset));
  const std::string sceneBefore = readFile(scene), assetBefore = readFile(asset);
  fs::create_symlink(scene, dir / "link.exr");           // the EXR itself through a symlink
  fs::create_symlink(asset, dir / "asset.png");          // the preview through a symlink
  fs::create_hard_link(scene, dir / "hard.exr.json");    // the sidecar as a hard link
  fs::create_symlink(dir / "scene.json", dir / "x.exr.json");
  struct Case {
    std::string args;
    std::string named;
  };
  const std::vector<Case> cases = {
      {"-o " + quote(dir / "link.exr"), "scene"},
      {"-o " + quote(dir / "out.exr") + " --preview " + quote(dir / "asset.png"), "asset 'ball'"},
      {"-o " + quote(dir / "hard.exr"), "scene"},
      {"-o " + quote(dir / "x.exr"), "scene"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args);
    std::string out;
    EXPECT_EQ(cli("bake " + quote(scene) + " " + c.args + " --backend cpu", out), 2) << out;
    EXPECT_TRUE(contains(out, "would overwrite the input " + c.named)) << out;
    EXPECT_FALSE(contains(out, "baked")) << out;
  }
  EXPECT_EQ(readFile(scene), sceneBefore);
  EXPECT_EQ(readFile(asset), assetBefore);
  EXPECT_FALSE(fs::exists(dir / "out.exr"));
}

TEST(CliHardening, NumbersOutsideTheValidRangeAreRefusedNamingTheField) {
  fs::path dir = vs::test::scratchDir("hardening_numbers");
  struct Case {
    std::string lights;
    std::string instance;
    std::string field;
  };
  const std::vector<Case> cases = {
      {R"([ { "type": "point", "position": [1e16, 2, 0], "range": 10, "shadow": {} } ])", "", "lights[0].position[0]"},
      {R"([ { "type": "point", "position": [1, 2, 0], "range": 1e39, "shadow": {} } ])", "", "lights[0].range"},
      {R"([ { "type": "directional", "direction": [1e39, -1, 0], "shadow": {} } ])", "", "lights[0].direction[0]"},
      {R"([ { "type": "spot", "position": [0, 5, 0], "direction": [0, -1, 0], "range": 1e7, "outer_cone_deg": 20,
             "shadow": {} } ])", "", "lights[0].range"},
      {kSun, R"(, "translate": [0, 2e5, 0])", "instances[0].translate[1]"},
      {kSun, R"(, "scale": 1e-30)", "instances[0].scale"},
      {kSun, R"(, "scale": [1, 1, 1e6])", "instances[0].scale"},
      {kSun, R"(, "rotate_deg": [0, 1e9, 0])", "instances[0].rotate_deg[1]"},
      {R"([ { "type": "directional", "direction": [0, -1, 0], "intensity": 1e30, "shadow": {} } ])", "", "lights[0].intensity"},
      {R"([ { "type": "directional", "direction": [0, -1, 0], "shadow": { "depth_bias": 1e20 } } ])", "", "lights[0].shadow.depth_bias"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].field);
    fs::path scene = dir / ("s" + std::to_string(i) + ".json");
    writeFile(scene, sceneWith(cases[i].lights, fogSphere(), cases[i].instance));
    for (const char* backend : {"cpu", "vulkan"}) {
      std::string out;
      EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend " + backend, out), 2) << out;
      EXPECT_TRUE(contains(out, scene.string() + ": " + cases[i].field)) << out;
    }
  }
  EXPECT_TRUE(extraFiles(dir, {}).size() == cases.size()) << "outputs were written";
}

TEST(CliHardening, AVoxelSizeOutsideTheValidRangeIsRefusedAtLoad) {
  openvdb::initialize();
  fs::path dir = vs::test::scratchDir("hardening_voxel_size");
  for (double size : {1e30, 5e-5}) {
    auto grid = openvdb::BoolGrid::create(false);
    grid->setName("mask");
    grid->tree().setValueOn({0, 0, 0}, true);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(size));
    fs::path vdb = dir / "huge.vdb";
    openvdb::io::File(vdb.string()).write({grid});
    fs::path scene = dir / "scene.json";
    writeFile(scene, sceneWith(kSun, vdb));
    std::string out;
    EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2) << out;
    EXPECT_TRUE(contains(out, "assets.ball")) << out;
    EXPECT_TRUE(contains(out, "voxel size")) << out;
  }
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
}

TEST(CliHardening, ALightTooFarFromFineVoxelsIsRefused) {
  fs::path dir = vs::test::scratchDir("hardening_far_light");
  fs::path scene = dir / "scene.json";
  // Voxels of 0.1 * 1e-3 = 1e-4 units; a spot 1e4 units away is 1e8 of them, beyond 2^26.
  writeFile(scene, sceneWith(R"([ { "type": "spot", "position": [0, 10000, 0], "direction": [0, -1, 0], "range": 12000,
                                   "outer_cone_deg": 1, "shadow": { "resolution": 16 } } ])",
                             fogSphere(), R"(, "scale": 1e-3)"));
  std::string out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "lights[0].position")) << out;
  EXPECT_TRUE(contains(out, "6.71089e+07 voxels")) << out;
  // The same light 100 units away (1e6 voxels) is within the range and bakes.
  writeFile(scene, sceneWith(R"([ { "type": "spot", "position": [0, 100, 0], "direction": [0, -1, 0], "range": 200,
                                   "outer_cone_deg": 1, "shadow": { "resolution": 16 } } ])",
                             fogSphere(), R"(, "scale": 1e-3)"));
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 0) << out;
}

TEST(CliHardening, DuplicateKeysNulsAndLayerNamesAreErrorsBeforeTracing) {
  fs::path dir = vs::test::scratchDir("hardening_duplicates");
  const std::string asset = fogSphere().string();
  struct Case {
    std::string text;
    std::string field;
  };
  const std::vector<Case> cases = {
      {R"({ "version": 1, "version": 1, "assets": {} })", "version: duplicate key"},
      {cat({R"({ "version": 1, "assets": { "a": { "file": ")", asset, R"(" }, "a": { "file": ")", asset,
            R"(" } }, "instances": [ { "asset": "a" } ] })"}),
       "assets.a: duplicate key"},
      {cat({R"({ "version": 1, "assets": { "a": { "file": ")", asset, R"(", "color": [1, 1, 1], "color": [0, 0, 0] } } })"}),
       "assets.a.color: duplicate key"},
      {R"({ "version": 1, "assets": {}, "lights": [ { "type": "point", "name": "a\u0000b", "position": [0, 0, 0],
           "range": 3 } ] })",
       "lights[0].name: must not contain a NUL"},
      {R"({ "version": 1, "assets": { "a\u0000": { "file": "x.vdb" } } })", "assets.a\\u0000: a key must not contain a NUL"},
      {cat({R"({ "version": 1, "assets": { "a": { "file": ")", asset, R"(\u0000.png" } } })"}),
       "assets.a.file: must not contain a NUL"},
      {R"({ "version": 1, "assets": {}, "lights": [
           { "name": "lamp", "type": "point", "position": [0, 0, 0], "range": 3, "shadow": {} },
           { "name": "lamp.face+x", "type": "directional", "direction": [0, -1, 0], "shadow": {} } ] })",
       "lights[1].name: its shadow layer \"lamp.face+x\" has the same name as a layer of lights[0]"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].field);
    fs::path scene = dir / cat({"s", std::to_string(i), ".json"});
    writeFile(scene, cases[i].text);
    std::string out;
    EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2) << out;
    EXPECT_TRUE(contains(out, scene.string() + ": " + cases[i].field)) << out;
  }
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
}

TEST(CliHardening, OnlyRegularFilesAreRead) {
  fs::path dir = vs::test::scratchDir("hardening_file_kinds");
  fs::create_directory(dir / "adir.vdb");
  ASSERT_EQ(::mkfifo((dir / "fifo.vdb").c_str(), 0600), 0);
  ASSERT_EQ(::mkfifo((dir / "fifo.json").c_str(), 0600), 0);
  struct Case {
    std::string scene;
    std::string message;
  };
  std::vector<Case> cases = {
      {"/dev/zero", "/dev/zero: is a device, not a regular file"},
      {(dir / "fifo.json").string(), "fifo.json: is a FIFO, not a regular file"},
      {(dir / "adir.vdb").string(), "adir.vdb: is a directory"},
  };
  for (const char* asset : {"adir.vdb", "fifo.vdb", "/dev/zero"}) {
    fs::path scene = dir / (std::string("uses_") + fs::path(asset).filename().string() + ".json");
    writeFile(scene, sceneWith(kSun, asset[0] == '/' ? fs::path(asset) : dir / asset));
    cases.push_back({scene.string(), std::string("assets.ball.file: ") + (asset[0] == '/' ? "" : dir.string() + "/") + asset +
                                         (asset == std::string("adir.vdb") ? ": is a directory, not a file"
                                          : asset == std::string("fifo.vdb") ? ": is a FIFO, not a regular file"
                                                                             : ": is a device, not a regular file")});
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.scene);
    std::string out;
    // `timeout` turns a hang (a FIFO opened for reading) into a failure instead of a stuck suite.
    EXPECT_EQ(vs::test::runCommand("timeout 20 " + vs::test::cliPath() + " bake " + quote(c.scene) + " -o " +
                                       quote(dir / "o.exr") + " --backend cpu",
                                   out),
              2)
        << out;
    EXPECT_TRUE(contains(out, c.message)) << out;
  }
  // A scene file far larger than any scene is refused by its size, without reading it.
  fs::path big = dir / "big.json";
  { std::ofstream(big) << "{"; }
  fs::resize_file(big, 65ull << 20);
  std::string out;
  EXPECT_EQ(cli("bake " + quote(big) + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "a scene file may have at most")) << out;
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
}

TEST(CliHardening, ThreadCountsAreCheckedWithAPlainMessage) {
  fs::path dir = vs::test::scratchDir("hardening_threads");
  fs::path scene = dir / "scene.json";
  writeFile(scene, sceneWith(kSun));
  for (const char* bad : {"70000", "abc", "-1", "1e3", "99999999999999999999"}) {
    SCOPED_TRACE(bad);
    std::string out;
    EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu --threads " + bad, out), 2) << out;
    EXPECT_TRUE(contains(out, "--threads: '" + std::string(bad) + "' is not a whole number from 0 to 1024")) << out;
    EXPECT_LT(out.size(), 300u) << out;
  }
  std::string out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu --threads 1024", out), 0) << out;
  EXPECT_EQ(cli("bench --threads 70000", out), 2) << out;
  EXPECT_TRUE(contains(out, "is not a whole number from 1 to 1024")) << out;
}

TEST(CliHardening, LongOutputNamesFitOrAreRefusedClearly) {
  fs::path dir = vs::test::scratchDir("hardening_long_names");
  fs::path scene = dir / "scene.json";
  writeFile(scene, sceneWith(kSun));
  std::string out;
  // 250 bytes: the sidecar (+".json") is 255, the longest name a file system takes.
  const std::string longest = std::string(246, 'n') + ".exr";
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / longest) + " --backend cpu --preview " +
                    quote(dir / (std::string(251, 'p') + ".png")),
                out),
            0)
      << out;
  EXPECT_TRUE(fs::is_regular_file(dir / longest));
  EXPECT_TRUE(fs::is_regular_file(dir / (longest + ".json")));
  EXPECT_TRUE(fs::is_regular_file(dir / (std::string(251, 'p') + ".png")));
  EXPECT_EQ(extraFiles(dir, {"scene.json", longest, longest + ".json", std::string(251, 'p') + ".png"}),
            std::vector<std::string>{});
  const std::string tooLong = std::string(248, 'm') + ".exr";
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / tooLong) + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "the file name is 252 bytes long; at most 250 are allowed here")) << out;
  EXPECT_FALSE(contains(out, "not writable")) << out;
}

TEST(CliHardening, MemoryIsCheckedBeforeTracing) {
  fs::path dir = vs::test::scratchDir("hardening_memory");
  fs::path scene = dir / "scene.json";
  // Four point lights at 16384^2: 24 GiB of layers.
  writeFile(scene, sceneWith(pointLights(4, 16384)));
  for (const char* backend : {"cpu", "vulkan"}) {
    SCOPED_TRACE(backend);
    std::string out;
    auto t0 = std::chrono::steady_clock::now();
    EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --memory-budget 2G --backend " + backend, out), 2)
        << out;
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0) << "refused late";
    EXPECT_TRUE(contains(out, "24 shadow layers")) << out;
    EXPECT_TRUE(contains(out, "the budget of 2.00 GiB (--memory-budget)")) << out;
  }
  // Without a budget: the memory available now, which no machine has for 64 such lights (384 GiB).
  writeFile(scene, sceneWith(pointLights(64, 16384)));
  std::string out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "the memory available now")) << out;
  for (const char* bad : {"0", "lots", "8X", "-1G"}) {
    EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --memory-budget " + bad, out), 2) << out;
    EXPECT_TRUE(contains(out, "--memory-budget: '")) << out;
  }
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
}

// 2052 views of one size: more than lavapipe's 2048 image layers, traced in batches; a preview of them all
// stays within 4096 pixels a side. The Vulkan file equals the CPU file texel for texel.
TEST(CliHardening, ThousandsOfViewsAreBatchedAndPreviewed) {
  fs::path dir = vs::test::scratchDir("hardening_many_views");
  fs::path scene = dir / "scene.json";
  writeFile(scene, sceneWith(pointLights(342, 16)));
  std::string out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "cpu.exr") + " --backend cpu --preview " +
                    quote(dir / "cpu.png"),
                out),
            0)
      << out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "gpu.exr") + " --backend vulkan --stats", out), 0) << out;
  EXPECT_TRUE(contains(out, "2 trace calls")) << out;
  auto png = OIIO::ImageInput::open((dir / "cpu.png").string());
  ASSERT_TRUE(png);
  EXPECT_LE(png->spec().width, 4096);
  EXPECT_LE(png->spec().height, 4096);
  auto a = OIIO::ImageInput::open((dir / "cpu.exr").string()), b = OIIO::ImageInput::open((dir / "gpu.exr").string());
  ASSERT_TRUE(a && b);
  int s = 0;
  for (; a->seek_subimage(s, 0); ++s) {
    ASSERT_TRUE(b->seek_subimage(s, 0)) << s;
    std::vector<float> ta(16 * 16), tb(16 * 16);
    ASSERT_TRUE(a->read_image(s, 0, 0, 1, OIIO::TypeDesc::FLOAT, ta.data()));
    ASSERT_TRUE(b->read_image(s, 0, 0, 1, OIIO::TypeDesc::FLOAT, tb.data()));
    ASSERT_EQ(std::memcmp(ta.data(), tb.data(), ta.size() * sizeof(float)), 0) << "subimage " << s;
  }
  EXPECT_EQ(s, 2052);
}

TEST(CliHardening, PipelineCachePathThatIsNotAFileIsIgnoredWithAWarning) {
  fs::path dir = vs::test::scratchDir("hardening_cache");
  fs::path scene = dir / "scene.json";
  writeFile(scene, sceneWith(kSun));
  fs::path cache = dir / "cache";
  const std::string env = "VOXSHADOW_CACHE_DIR=" + quote(cache) + " ";
  std::string out;
  ASSERT_EQ(vs::test::runCommand(env + vs::test::cliPath() + " bake " + quote(scene) + " -o " + quote(dir / "o.exr") +
                                     " --stats",
                                 out),
            0)
      << out;
  ASSERT_EQ(std::distance(fs::directory_iterator(cache), fs::directory_iterator()), 1);
  const fs::path file = fs::directory_iterator(cache)->path();
  ASSERT_EQ(vs::test::runCommand(env + vs::test::cliPath() + " bake " + quote(scene) + " -o " + quote(dir / "o.exr") +
                                     " --stats",
                                 out),
            0)
      << out;
  // lavapipe keeps no pipelines: its header-only cache is no warm cache.
  if (fs::file_size(file) <= 32) EXPECT_TRUE(contains(out, "empty (the driver caches nothing) cache")) << out;
  else EXPECT_TRUE(contains(out, "warm cache")) << out;
  for (const char* kind : {"fifo", "directory"}) {
    SCOPED_TRACE(kind);
    fs::remove_all(file);
    if (kind == std::string("fifo")) ASSERT_EQ(::mkfifo(file.c_str(), 0600), 0);
    else fs::create_directory(file);
    EXPECT_EQ(vs::test::runCommand("timeout 60 env " + env + vs::test::cliPath() + " bake " + quote(scene) + " -o " +
                                       quote(dir / "o.exr"),
                                   out),
              0)
        << out;
    EXPECT_TRUE(contains(out, "warning: pipeline cache: " + file.string() + ": is not a regular file")) << out;
  }
}

TEST(CliHardening, WithoutAVulkanDriverBakeSuggestsTheCpuBackend) {
  fs::path dir = vs::test::scratchDir("hardening_no_device");
  fs::path scene = dir / "scene.json";
  writeFile(scene, sceneWith(kSun));
  const std::string hide = "env VK_DRIVER_FILES=/nonexistent VK_ICD_FILENAMES=/nonexistent ";
  std::string out;
  EXPECT_EQ(vs::test::runCommand(hide + vs::test::cliPath() + " bake " + quote(scene) + " -o " + quote(dir / "o.exr"), out), 1)
      << out;
  EXPECT_TRUE(contains(out, "use --backend cpu")) << out;
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
  EXPECT_EQ(vs::test::runCommand(hide + vs::test::cliPath() + " bake " + quote(scene) + " -o " + quote(dir / "o.exr") +
                                     " --backend cpu",
                                 out),
            0)
      << out;
  EXPECT_TRUE(fs::is_regular_file(dir / "o.exr"));
}

TEST(CliHardening, OpenVdbMessagesCarryNoColourCodesOffATerminal) {
  fs::path dir = vs::test::scratchDir("hardening_colour");
  for (const auto& e : fs::directory_iterator(vs::test::sharedAssets() / "vdb" / "damaged")) {
    std::string out;
    fs::path scene = dir / "scene.json";
    writeFile(scene, sceneWith(kSun, e.path()));
    vs::test::runCommand(vs::test::cliPath() + " bake " + quote(scene) + " -o " + quote(dir / "o.exr") + " --backend cpu", out);
    EXPECT_FALSE(contains(out, "\x1b[")) << e.path() << ": " << out;
  }
}

TEST(CliHardening, VersionFlag) {
  std::string out;
  EXPECT_EQ(cli("--version", out), 0) << out;
  EXPECT_TRUE(contains(out, "voxshadow 0.")) << out;
}
