// The voxshadow CLI end to end: exit codes, messages and outputs, run as a user would run it.
#include <gtest/gtest.h>

#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include <OpenImageIO/imageio.h>

#include "support/test_paths.h"

namespace fs = std::filesystem;

namespace {

using vs::test::contains;
using vs::test::quote;
int cli(const std::string& args, std::string& out) { return vs::test::runCli(args, out); }

void writeFile(const fs::path& p, const std::string& text) {
  std::ofstream f(p);
  f << text;
}

// A valid scene over a third-party asset, so bake tests do not depend on the demo writer.
std::string sceneText(const fs::path& vdb, const std::string& extraAsset = "") {
  return R"({ "version": 1,
  "assets": { "ball": { "file": ")" + vdb.string() + R"(")" + extraAsset + R"( } },
  "instances": [ { "asset": "ball" } ],
  "camera": { "position": [3, 3, 3], "target": [0, 0, 0], "far": 20 },
  "lights": [ { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3],
                "shadow": { "resolution": 32, "cascades": 1 } } ] })";
}

std::vector<std::string> subimageNames(const fs::path& exr) {
  std::vector<std::string> names;
  auto in = OIIO::ImageInput::open(exr.string());
  if (!in) return names;
  for (int s = 0; in->seek_subimage(s, 0); ++s) names.push_back(in->spec().get_string_attribute("oiio:subimagename"));
  return names;
}



}  // namespace

TEST(Cli, HelpOfEverySubcommandExitsZero) {
  std::string out;
  EXPECT_EQ(cli("--help", out), 0) << out;
  for (const char* sub : {"info", "demo", "bake"}) EXPECT_TRUE(contains(out, sub)) << sub << " missing:\n" << out;
  for (const char* sub : {"info", "demo", "bake"}) {
    EXPECT_EQ(cli(std::string(sub) + " --help", out), 0) << sub << ":\n" << out;
    EXPECT_TRUE(contains(out, sub)) << out;
  }
  EXPECT_EQ(cli("bake --help", out), 0);
  EXPECT_TRUE(contains(out, "--backend")) << out;
  EXPECT_TRUE(contains(out, "--preview")) << out;
}

TEST(Cli, BadUsageExitsTwo) {
  std::string out;
  EXPECT_EQ(cli("", out), 2) << out;
  EXPECT_EQ(cli("frobnicate", out), 2) << out;
  EXPECT_TRUE(contains(out, "voxshadow: ")) << out;
  EXPECT_EQ(cli("info --no-such-option x.vdb", out), 2) << out;
  EXPECT_EQ(cli("info", out), 2) << out;  // FILE is required
  EXPECT_EQ(cli("bake", out), 2) << out;
  EXPECT_EQ(cli("bake scene.json -o out.exr --backend opengl", out), 2) << out;
  EXPECT_EQ(cli("bake scene.json -o out.exr --threads -3", out), 2) << out;
}

TEST(Cli, InfoOnEveryThirdPartyVdb) {
  const fs::path vdb = vs::test::sharedAssets() / "vdb";
  struct Case {
    const char* file;
    std::vector<const char*> grids;
  };
  const std::vector<Case> cases = {
      {"oiio_fog_sphere.vdb", {"density"}},
      {"oiio_fog_sphere_Cd.vdb", {"Cd"}},
      {"arnold_smoke_v222.vdb", {"density"}},
      {"arnold_fog_torus.vdb", {"voxel_fog_density"}},
      {"arnold_three_density_grids.vdb", {"density"}},
      {"gaffer_levelset_sphere.vdb", {"ls_sphere"}},
      {"scivis_dense_posdensity.vdb", {"posdensity"}},
  };
  for (const Case& c : cases) {
    std::string out;
    EXPECT_EQ(cli("info " + quote(vdb / c.file), out), 0) << c.file << ":\n" << out;
    EXPECT_TRUE(contains(out, c.file)) << out;
    for (const char* grid : c.grids) EXPECT_TRUE(contains(out, grid)) << c.file << " lacks grid " << grid << ":\n" << out;
  }
  // Several files at once, machine-readable.
  std::string out;
  ASSERT_EQ(cli("info --json " + quote(vdb / "arnold_three_density_grids.vdb") + " " +
                    quote(vdb / "gaffer_levelset_sphere.vdb"),
                out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "\"ls_sphere\"")) << out;
}

TEST(Cli, InfoOnDamagedFilesNeverCrashes) {
  const fs::path damaged = vs::test::sharedAssets() / "vdb" / "damaged";
  for (const auto& entry : fs::directory_iterator(damaged)) {
    std::string out;
    int status = cli("info " + quote(entry.path()), out);
    const std::string name = entry.path().filename().string();
    SCOPED_TRACE(name + ":\n" + out);
    EXPECT_TRUE(status == 0 || status == 2) << "status " << status;
    if (status == 2) {
      EXPECT_TRUE(contains(out, "voxshadow: "));
      EXPECT_TRUE(contains(out, name));
    }
    if (name == "truncated.vdb") {
      EXPECT_EQ(status, 2);
    }
    if (name == "bad-bbox-empty.vdb") {
      EXPECT_EQ(status, 0);
    }
  }
}

TEST(Cli, InfoOnMissingOrForeignFilesExitsTwoNamingTheFile) {
  const fs::path dir = vs::test::scratchDir("cli_info_bad");
  std::string out;
  EXPECT_EQ(cli("info " + quote(dir / "missing.vdb"), out), 2) << out;
  EXPECT_TRUE(contains(out, "missing.vdb")) << out;

  const fs::path notVdb = dir / "not_a.vdb";
  writeFile(notVdb, "this is plain text, not an OpenVDB file\n");
  EXPECT_EQ(cli("info " + quote(notVdb), out), 2) << out;
  EXPECT_TRUE(contains(out, "not_a.vdb")) << out;

  // The third-party non-.vox file under a .vdb name is not a VDB either.
  const fs::path foreign = vs::test::sharedAssets() / "vox" / "dotvox_not_a_vox.vox";
  EXPECT_EQ(cli("info " + quote(foreign), out), 2) << out;
  EXPECT_TRUE(contains(out, "dotvox_not_a_vox.vox")) << out;
}

TEST(Cli, InfoOfSceneWithUnknownGridExitsTwoNamingFileAndGrid) {
  const fs::path dir = vs::test::scratchDir("cli_info_grid");
  const fs::path vdb = vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb";
  const fs::path scene = dir / "scene.json";
  writeFile(scene, sceneText(vdb, R"(, "grid": "no_such_grid")"));
  std::string out;
  EXPECT_EQ(cli("info " + quote(scene), out), 2) << out;
  EXPECT_TRUE(contains(out, "no_such_grid")) << out;
  EXPECT_TRUE(contains(out, "oiio_fog_sphere.vdb")) << out;
}

TEST(Cli, InfoOfSceneListsInstancesAndLights) {
  const fs::path dir = vs::test::scratchDir("cli_info_scene");
  const fs::path scene = dir / "scene.json";
  writeFile(scene, sceneText(vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb"));
  std::string out;
  ASSERT_EQ(cli("info " + quote(scene), out), 0) << out;
  EXPECT_TRUE(contains(out, "sun")) << out;
  EXPECT_TRUE(contains(out, "ball")) << out;
}

TEST(Cli, BakeOfBrokenSceneExitsTwoAndWritesNothing) {
  const fs::path dir = vs::test::scratchDir("cli_bake_bad");
  const fs::path vdb = vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb";
  struct Case {
    const char* name;
    std::string text;
    const char* jsonPath;  // what the message must name
  };
  const std::vector<Case> cases = {
      {"syntax.json", "{ \"version\": 1, \"assets\": { ", "line"},
      {"unknown_key.json", R"({ "version": 1, "assets": {}, "instances": [], "colour": 1 })", "colour"},
      {"bad_resolution.json",
       R"({ "version": 1, "assets": {}, "instances": [], "lights": [ { "type": "directional",
          "direction": [0, -1, 0], "shadow": { "resolution": 1000 } } ] })",
       "lights[0].shadow.resolution"},
      {"bad_version.json", R"({ "version": 7, "assets": {}, "instances": [] })", "version"},
  };
  for (const Case& c : cases) {
    const fs::path scene = dir / c.name;
    writeFile(scene, c.text);
    const fs::path exr = dir / (std::string(c.name) + ".exr");
    std::string out;
    EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(exr) + " --backend cpu", out), 2) << c.name << ":\n" << out;
    EXPECT_TRUE(contains(out, c.name)) << out;
    EXPECT_TRUE(contains(out, c.jsonPath)) << out;
    EXPECT_FALSE(fs::exists(exr));
    EXPECT_FALSE(fs::exists(fs::path(exr.string() + ".json")));
  }
  // A scene naming a grid its file lacks.
  const fs::path scene = dir / "unknown_grid.json";
  writeFile(scene, sceneText(vdb, R"(, "grid": "no_such_grid")"));
  std::string out;
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "g.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "no_such_grid")) << out;
  EXPECT_FALSE(fs::exists(dir / "g.exr"));
  // A scene whose asset is a damaged file.
  const fs::path damagedScene = dir / "damaged_asset.json";
  writeFile(damagedScene, sceneText(vs::test::sharedAssets() / "vdb" / "damaged" / "truncated.vdb"));
  EXPECT_EQ(cli("bake " + quote(damagedScene) + " -o " + quote(dir / "d.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "damaged_asset.json")) << out;
  EXPECT_TRUE(contains(out, "assets.ball")) << out;
  EXPECT_TRUE(contains(out, "truncated.vdb")) << out;
  EXPECT_FALSE(fs::exists(dir / "d.exr"));
  EXPECT_FALSE(fs::exists(dir / "d.exr.json"));
}

TEST(Cli, BakeToUnusableOutputExitsTwoAndWritesNothing) {
  const fs::path dir = vs::test::scratchDir("cli_bake_output");
  const fs::path scene = dir / "scene.json";
  writeFile(scene, sceneText(vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb"));
  std::string out;
  // Wrong extension.
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "out.png") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, ".exr")) << out;
  // Missing directory.
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "nope" / "out.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "nope")) << out;
  // A directory that refuses new files.
  const fs::path locked = dir / "locked";
  fs::create_directory(locked);
  const fs::path target = vs::test::unwritableDir(locked);
  EXPECT_EQ(cli("bake " + quote(scene) + " -o " + quote(target / "vs_out.exr") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "not writable")) << out;
  EXPECT_TRUE(vs::test::leftovers(target, "vs_out").empty());
  fs::permissions(locked, fs::perms::owner_all);
  EXPECT_FALSE(fs::exists(dir / "out.png"));
}

TEST(Cli, BakeWritesExrSidecarAndPreview) {
  const fs::path dir = vs::test::scratchDir("cli_bake_ok");
  const fs::path scene = dir / "scene.json";
  writeFile(scene, sceneText(vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb"));
  std::string out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "out.exr") + " --backend cpu --threads 2 --preview " +
                    quote(dir / "out.png") + " --stats",
                out),
            0)
      << out;
  // The scene has a camera: its sun is baked as cascades (one here).
  EXPECT_EQ(subimageNames(dir / "out.exr"), std::vector<std::string>{"sun.cascade0"});
  EXPECT_TRUE(fs::is_regular_file(dir / "out.exr.json"));
  EXPECT_TRUE(fs::is_regular_file(dir / "out.png"));
}

TEST(Cli, DemoWritesAssetsAndBakedShadows) {
  const fs::path dir = vs::test::scratchDir("cli_demo");
  std::string out;
  ASSERT_EQ(cli("demo --backend cpu --out " + quote(dir / "demo"), out), 0) << out;
  const fs::path exr = dir / "demo" / "demo_shadows.exr";
  ASSERT_TRUE(fs::is_regular_file(exr)) << out;
  EXPECT_TRUE(fs::is_regular_file(dir / "demo" / "demo_shadows.exr.json"));
  EXPECT_TRUE(fs::is_regular_file(dir / "demo" / "demo_shadows.png"));
  // The lit image (README's picture): the camera's size, not one flat colour.
  {
    auto png = OIIO::ImageInput::open((dir / "demo" / "demo.png").string());
    ASSERT_TRUE(png) << out;
    EXPECT_EQ(png->spec().width, 1280);
    EXPECT_EQ(png->spec().height, 720);
    std::vector<unsigned char> rgb(std::size_t(1280) * 720 * 3);
    ASSERT_TRUE(png->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, rgb.data()));
    std::set<unsigned char> greys(rgb.begin(), rgb.end());
    EXPECT_GT(greys.size(), 100u);
  }
  EXPECT_TRUE(contains(out, ".vdb")) << out;  // the assets' info was printed

  // Expected subimages from the demo scene itself: every shadowed light has its views (six for a point
  // light, one for a spot light, one per cascade or one for a directional light) and nothing else appears.
  std::ifstream sceneFile(dir / "demo" / "demo.json");
  nlohmann::json scene = nlohmann::json::parse(sceneFile);
  auto names = subimageNames(exr);
  std::set<std::string> remaining(names.begin(), names.end());
  EXPECT_EQ(remaining.size(), names.size()) << "duplicate subimage names";
  for (const auto& light : scene.at("lights")) {
    if (!light.contains("shadow")) continue;
    const std::string name = light.at("name");
    const std::string type = light.at("type");
    std::vector<std::string> expected;
    if (type == "point") {
      for (const char* f : {"+x", "-x", "+y", "-y", "+z", "-z"}) expected.push_back(name + ".face" + f);
    } else if (type == "spot" || !remaining.count(name + ".cascade0")) {
      expected.push_back(name);
    } else {
      for (int i = 0; remaining.count(name + ".cascade" + std::to_string(i)); ++i)
        expected.push_back(name + ".cascade" + std::to_string(i));
    }
    for (const auto& e : expected) EXPECT_EQ(remaining.erase(e), 1u) << "missing subimage " << e;
  }
  EXPECT_TRUE(remaining.empty()) << "unexpected subimage " << *remaining.begin();
}

// DESIGN.md §9: the two backends bake files that agree texel by texel.
TEST(Cli, CpuAndVulkanBakesAgree) {
  const fs::path dir = vs::test::scratchDir("cli_bake_backends");
  const fs::path scene = dir / "scene.json";
  writeFile(scene, sceneText(vs::test::sharedAssets() / "vdb" / "gaffer_levelset_sphere.vdb"));
  std::string out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "cpu.exr") + " --backend cpu", out), 0) << out;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(dir / "vk.exr") + " --backend vulkan", out), 0) << out;
  auto a = OIIO::ImageInput::open((dir / "cpu.exr").string());
  auto b = OIIO::ImageInput::open((dir / "vk.exr").string());
  ASSERT_TRUE(a && b);
  std::size_t hits = 0;
  for (int s = 0; a->seek_subimage(s, 0); ++s) {
    ASSERT_TRUE(b->seek_subimage(s, 0));
    ASSERT_EQ(a->spec().width, b->spec().width);
    ASSERT_EQ(a->spec().height, b->spec().height);
    std::vector<float> pa(a->spec().image_pixels()), pb(b->spec().image_pixels());
    ASSERT_TRUE(a->read_image(s, 0, 0, 1, OIIO::TypeDesc::FLOAT, pa.data()));
    ASSERT_TRUE(b->read_image(s, 0, 0, 1, OIIO::TypeDesc::FLOAT, pb.data()));
    for (std::size_t i = 0; i < pa.size(); ++i) {
      ASSERT_EQ(pa[i], pb[i]) << "subimage " << s << " texel " << i;
      hits += pa[i] < 1.0f;
    }
  }
  EXPECT_GT(hits, 0u) << "the sphere casts no shadow: the comparison would be vacuous";
}
