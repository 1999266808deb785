// Sharded bakes: the plan, the part files, merges that equal one machine's bake bit for bit, refusals of bad
// part sets, resumed bakes, and a Slurm job array on a single-node cluster (tools/bake_shards.h, tools/slurm/).
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <set>
#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include "lighting/scene.h"
#include "support/test_paths.h"
#include "tools/bake_shards.h"
#include "tools/sha256.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace fs = std::filesystem;
using vs::test::contains;
using vs::test::quote;
using vs::test::runCli;

namespace {

std::string fileBytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// The EXR and its sidecar of `a` equal those of `b`, byte for byte.
void expectSameBake(const fs::path& a, const fs::path& b) {
  ASSERT_TRUE(fs::is_regular_file(a)) << a;
  ASSERT_TRUE(fs::is_regular_file(b)) << b;
  const std::string ea = fileBytes(a), eb = fileBytes(b);
  EXPECT_EQ(ea.size(), eb.size()) << a << " against " << b;
  EXPECT_TRUE(ea == eb) << a << " differs from " << b;
  EXPECT_TRUE(fileBytes(vs::sidecarPath(a)) == fileBytes(vs::sidecarPath(b))) << vs::sidecarPath(a) << " differs";
}

int cli(const std::string& args, std::string& out) { return runCli(args, out); }

// The demo world in `dir` (demo.json and its assets).
fs::path writeDemo(const fs::path& dir) {
  vs::writeDemoWorld(dir);
  return dir / "demo.json";
}

// The demo's geometry under other lights: four cascades of 256 texels, two point lights whose faces (64 and 32
// texels) are smaller than a tile (one measured at voxel centres), and no spot light.
fs::path writePointsAndCascadesScene(const fs::path& demoScene) {
  nlohmann::json scene = nlohmann::json::parse(fileBytes(demoScene));
  nlohmann::json sun = scene["lights"][0], torch = scene["lights"][2];
  sun["shadow"]["resolution"] = 256;
  sun["shadow"]["cascades"] = 4;
  torch["shadow"]["resolution"] = 64;
  nlohmann::json second = torch;
  second["name"] = "ember";
  second["position"] = {20, 12, 30};
  second["shadow"]["resolution"] = 32;
  second["shadow"]["depth_point"] = "voxel_center";
  scene["lights"] = {sun, torch, second};
  const fs::path out = demoScene.parent_path() / "points_and_cascades.json";
  std::ofstream(out) << scene.dump(2);
  return out;
}

// A single-machine bake of `scene` on `backend` into `out`.
void bakeWhole(const fs::path& scene, const fs::path& out, const std::string& backend) {
  std::string log;
  ASSERT_EQ(cli("bake " + quote(scene) + " -o " + quote(out) + " --backend " + backend, log), 0) << log;
}

std::vector<fs::path> partPaths(const fs::path& dir, int n) {
  std::vector<fs::path> parts;
  for (int k = 0; k < n; ++k) parts.push_back(dir / vs::partFileName(k, n));
  return parts;
}

std::string quoted(const std::vector<fs::path>& paths) {
  std::string s;
  for (const fs::path& p : paths) s += " " + quote(p);
  return s;
}

}  // namespace

TEST(Farm, Sha256MatchesTheStandardsVectors) {
  auto hex = [](const std::string& s) {
    return vs::sha256Hex(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()));
  };
  EXPECT_EQ(hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  // A million 'a's fed in uneven pieces: the block boundary falls inside updates.
  vs::Sha256 h;
  const std::string piece(997, 'a');
  std::size_t fed = 0;
  while (fed < 1000000) {
    const std::size_t n = std::min<std::size_t>(piece.size() - fed % 7, 1000000 - fed);
    h.update(piece.data(), n);
    fed += n;
  }
  EXPECT_EQ(vs::toHex(h.digest()), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Farm, PlansPutEveryTexelInExactlyOneShardOfAboutEqualCost) {
  const fs::path dir = vs::test::scratchDir("farm_plan");
  const vs::Scene scene = vs::Scene::load(vs::parseSceneFile(writeDemo(dir)));
  const std::vector<vs::LightView> views = scene.lightViews();
  const std::vector<vs::Aabb> boxes = scene.data().instanceBounds;
  for (int n : {1, 2, 3, 7, 16, 100, 4096}) {
    SCOPED_TRACE("shards " + std::to_string(n));
    const vs::ShardPlan plan = vs::planShards(views, boxes, n);
    const vs::ShardPlan again = vs::planShards(views, boxes, n);
    EXPECT_EQ(plan.tiles, again.tiles);
    EXPECT_EQ(plan.first, again.first);
    ASSERT_EQ(plan.first.size(), std::size_t(n) + 1);
    EXPECT_EQ(plan.first.front(), 0u);
    EXPECT_EQ(plan.first.back(), plan.tiles.size());
    for (int k = 0; k < n; ++k) EXPECT_LE(plan.first[k], plan.first[k + 1]);
    // Every texel of every layer exactly once.
    std::vector<std::vector<std::uint8_t>> seen(views.size());
    for (std::size_t v = 0; v < views.size(); ++v)
      seen[v].assign(std::size_t(views[v].trace.info.x) * views[v].trace.info.y, 0);
    for (const vs::ShardTile& t : plan.tiles)
      for (int y = t.y0; y < t.y1; ++y)
        for (int x = t.x0; x < t.x1; ++x) ++seen[t.view][std::size_t(y) * views[t.view].trace.info.x + x];
    for (std::size_t v = 0; v < views.size(); ++v)
      EXPECT_TRUE(std::all_of(seen[v].begin(), seen[v].end(), [](std::uint8_t c) { return c == 1; })) << views[v].name;
    // Each shard's cost is within one tile's cost of an equal share (the split is at tile granularity).
    std::uint64_t total = 0, largestTile = 0;
    for (std::uint64_t c : plan.costs) {
      total += c;
      largestTile = std::max(largestTile, c);
    }
    for (int k = 0; k < n; ++k) {
      std::uint64_t cost = 0;
      for (std::size_t i = plan.first[k]; i < plan.first[k + 1]; ++i) cost += plan.costs[i];
      EXPECT_LE(std::llabs(std::int64_t(cost) - std::int64_t(total / n)), std::int64_t(largestTile)) << "shard " << k;
    }
  }
  // Tiles over more caster boxes weigh more: the demo's nearest cascade is not all of one weight.
  const vs::ShardPlan one = vs::planShards(views, boxes, 1);
  std::set<std::uint64_t> weights;
  for (std::size_t i = 0; i < one.tiles.size(); ++i)
    if (one.tiles[i].view == 0) weights.insert(one.costs[i] / one.tiles[i].texels());
  EXPECT_GT(weights.size(), 2u);
  EXPECT_THROW(vs::planShards(views, boxes, 0), vs::Error);
  EXPECT_THROW(vs::planShards(views, boxes, vs::kMaxShards + 1), vs::Error);
}

// N shards baked on this machine (bake --shards N --parts DIR) merge into the single bake's very files.
void expectLocalMergesEqualTheBake(const std::string& backend) {
  const fs::path dir = vs::test::scratchDir("farm_local_" + backend);
  const fs::path demo = writeDemo(dir);
  const fs::path other = writePointsAndCascadesScene(demo);
  for (const fs::path& scene : {demo, other}) {
    const std::string stem = scene.stem().string();
    const fs::path whole = dir / (stem + "_whole.exr");
    bakeWhole(scene, whole, backend);
    const std::vector<int> counts = scene == demo ? std::vector<int>{1, 2, 3, 7, 16} : std::vector<int>{2, 7};
    for (int n : counts) {
      SCOPED_TRACE(stem + ", " + std::to_string(n) + " shards on " + backend);
      const fs::path parts = dir / (stem + "_parts" + std::to_string(n));
      const fs::path merged = dir / (stem + "_merged" + std::to_string(n) + ".exr");
      std::string log;
      ASSERT_EQ(cli("bake " + quote(scene) + " --shards " + std::to_string(n) + " --parts " + quote(parts) + " -o " +
                        quote(merged) + " --backend " + backend,
                    log),
                0)
          << log;
      EXPECT_TRUE(contains(log, std::to_string(n) + " of " + std::to_string(n) + " shard")) << log;
      expectSameBake(merged, whole);
      // The standalone merge of the same parts writes the same files too.
      const fs::path again = dir / (stem + "_again" + std::to_string(n) + ".exr");
      ASSERT_EQ(cli("merge" + quoted(partPaths(parts, n)) + " -o " + quote(again), log), 0) << log;
      expectSameBake(again, whole);
    }
  }
}

TEST(Farm, CpuShardsMergeIntoTheSingleBake) { expectLocalMergesEqualTheBake("cpu"); }

TEST(Farm, VulkanShardsMergeIntoTheSingleBake) { expectLocalMergesEqualTheBake("vulkan"); }

TEST(Farm, CpuAndVulkanShardsMixedMergeIntoTheSingleBake) {
  const fs::path dir = vs::test::scratchDir("farm_mixed");
  const fs::path demo = writeDemo(dir);
  const fs::path cpuWhole = dir / "cpu.exr", vulkanWhole = dir / "vulkan.exr";
  bakeWhole(demo, cpuWhole, "cpu");
  bakeWhole(demo, vulkanWhole, "vulkan");
  expectSameBake(vulkanWhole, cpuWhole);
  const int n = 5;
  const std::vector<fs::path> parts = partPaths(dir / "parts", n);
  fs::create_directories(dir / "parts");
  for (int k = 0; k < n; ++k) {
    std::string log;
    const std::string backend = k % 2 ? "vulkan" : "cpu";
    ASSERT_EQ(cli("bake " + quote(demo) + " --shard " + std::to_string(k) + "/" + std::to_string(n) + " -o " +
                      quote(parts[k]) + " --backend " + backend,
                  log),
              0)
        << log;
    EXPECT_TRUE(contains(log, "baked shard " + std::to_string(k) + " of 5")) << log;
    const vs::BakePart part = vs::readBakePart(parts[k]);
    EXPECT_TRUE(contains(part.manifest["producer"]["backend"].get<std::string>(), backend));
  }
  std::string log;
  // Parts given in any order.
  std::vector<fs::path> shuffled = {parts[3], parts[0], parts[4], parts[2], parts[1]};
  ASSERT_EQ(cli("merge" + quoted(shuffled) + " -o " + quote(dir / "merged.exr") + " --preview " + quote(dir / "merged.png"), log), 0)
      << log;
  expectSameBake(dir / "merged.exr", cpuWhole);
  EXPECT_TRUE(fs::is_regular_file(dir / "merged.png"));
}

TEST(Farm, BadPartSetsExitTwoNamingThePartAndWriteNothing) {
  const fs::path dir = vs::test::scratchDir("farm_bad_parts");
  const fs::path demo = writeDemo(dir);
  const fs::path other = writePointsAndCascadesScene(demo);
  const fs::path partsDir = dir / "parts";
  std::string log;
  ASSERT_EQ(cli("bake " + quote(demo) + " --shards 4 --parts " + quote(partsDir) + " -o " + quote(dir / "good.exr") +
                    " --backend cpu",
                log),
            0)
      << log;
  const std::vector<fs::path> parts = partPaths(partsDir, 4);
  // The other scene's shard 1 of 4, and the demo's shard 1 of 3.
  const fs::path foreign = dir / "foreign.vspart", otherCount = dir / "of3.vspart";
  ASSERT_EQ(cli("bake " + quote(other) + " --shard 1/4 -o " + quote(foreign) + " --backend cpu", log), 0) << log;
  ASSERT_EQ(cli("bake " + quote(demo) + " --shard 1/3 -o " + quote(otherCount) + " --backend cpu", log), 0) << log;
  // Shard 3 as another version of the tool would have written it (a valid file with another tool string).
  const fs::path otherVersion = dir / "old.vspart";
  {
    vs::BakePart p = vs::readBakePart(parts[3]);
    p.manifest["bake"]["tool"] = "voxshadow 0.0.9";
    vs::writeBakePart(otherVersion, p.manifest, p.texels);
  }
  const fs::path truncated = dir / "truncated.vspart", damaged = dir / "damaged.vspart", copy = dir / "copy.vspart";
  {
    const std::string bytes = fileBytes(parts[2]);
    std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    std::string flipped = bytes;
    flipped[flipped.size() / 2] ^= 0x10;
    std::ofstream(damaged, std::ios::binary) << flipped;
    fs::copy_file(parts[1], copy);
  }
  // Valid files whose tiles are wrong: one moved off the tile grid, and shard 0 holding shard 1's first tile too.
  const fs::path offGrid = dir / "offgrid.vspart", overlapping = dir / "overlapping.vspart";
  {
    vs::BakePart p = vs::readBakePart(parts[2]);
    p.manifest["tiles"][0][1] = p.manifest["tiles"][0][1].get<int>() + 1;
    p.manifest["tiles"][0][3] = p.manifest["tiles"][0][3].get<int>() + 1;
    vs::writeBakePart(offGrid, p.manifest, p.texels);
    vs::BakePart zero = vs::readBakePart(parts[0]);
    const vs::BakePart one = vs::readBakePart(parts[1]);
    zero.manifest["tiles"].push_back(one.manifest["tiles"][0]);
    zero.texels.insert(zero.texels.end(), one.texels.begin(), one.texels.begin() + std::ptrdiff_t(one.tiles[0].texels()));
    vs::writeBakePart(overlapping, zero.manifest, zero.texels);
  }
  const fs::path exr = dir / "good.exr";  // an unrelated EXR (the merged bake itself)

  struct Case {
    std::string what;
    std::vector<fs::path> parts;
    fs::path named;       // the part the message must name ("" for a missing one)
    std::string message;  // what it must say
  };
  const std::vector<Case> cases = {
      {"one missing", {parts[0], parts[1], parts[3]}, "", "shard 2 of 4 missing"},
      {"one twice", {parts[0], parts[1], parts[2], parts[3], copy}, copy, "given twice"},
      {"one from another scene", {parts[0], foreign, parts[2], parts[3]}, foreign, "another scene"},
      {"one of another shard count", {parts[0], otherCount, parts[2], parts[3]}, otherCount, "a part of 3 shards"},
      {"one from another version", {parts[0], parts[1], parts[2], otherVersion}, otherVersion, "voxshadow 0.0.9"},
      {"a truncated part", {parts[0], parts[1], truncated, parts[3]}, truncated, "truncated ("},
      {"a damaged part", {parts[0], parts[1], damaged, parts[3]}, damaged, "damaged: its sha256 does not match"},
      {"tiles off the grid", {parts[0], parts[1], offGrid, parts[3]}, offGrid, "is not a tile of the 128-texel grid"},
      {"a tile in two parts", {overlapping, parts[1], parts[2], parts[3]}, overlapping, "is also in"},
      {"an unrelated EXR", {parts[0], parts[1], parts[2], exr}, exr, "not a voxshadow part file"},
      {"a missing file", {parts[0], parts[1], parts[2], dir / "nowhere.vspart"}, dir / "nowhere.vspart", "no such part file"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const fs::path out = dir / "out.exr";
    EXPECT_EQ(cli("merge" + quoted(c.parts) + " -o " + quote(out) + " --preview " + quote(dir / "out.png"), log), 2) << log;
    if (!c.named.empty()) {
      EXPECT_TRUE(contains(log, c.named.string())) << log;
    }
    EXPECT_TRUE(contains(log, c.message)) << log;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(vs::sidecarPath(out)));
    EXPECT_FALSE(fs::exists(dir / "out.png"));
    EXPECT_TRUE(vs::test::leftovers(dir, "out.").empty());
  }
  // A merge never writes over one of its parts.
  EXPECT_EQ(cli("merge" + quoted(parts) + " -o " + quote(parts[0]), log), 2) << log;
  const fs::path asExr = dir / "part.exr";
  fs::copy_file(parts[0], asExr);
  const std::string before = fileBytes(asExr);
  EXPECT_EQ(cli("merge " + quote(asExr) + quoted({parts[1], parts[2], parts[3]}) + " -o " + quote(asExr), log), 2) << log;
  EXPECT_TRUE(contains(log, "would overwrite")) << log;
  EXPECT_TRUE(fileBytes(asExr) == before);
}

TEST(Farm, BadShardOptionsAreRefusedBeforeAnyWork) {
  const fs::path dir = vs::test::scratchDir("farm_bad_options");
  const fs::path demo = writeDemo(dir);
  const std::string scene = quote(demo);
  const std::string part = quote(dir / "p.vspart");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--shard 4/4 -o " + part, "--shard: expected K/N"},
      {"--shard 1/0 -o " + part, "--shard: expected K/N"},
      {"--shard x/2 -o " + part, "--shard: expected K/N"},
      {"--shard 1/5000 -o " + part, "--shard: expected K/N"},
      {"--shard -1/2 -o " + part, "--shard"},
      {"--shard 1/2 -o " + quote(dir / "p.exr"), "must be a .vspart part file"},
      {"--shard 1/2", "--shard needs -o"},
      {"--shard 1/2 -o " + part + " --preview " + quote(dir / "p.png"), "a shard writes no preview"},
      {"--shard 1/2 --shards 2 --parts " + quote(dir / "d") + " -o " + part, "cannot be combined"},
      {"--shards 2 -o " + quote(dir / "o.exr"), "--shards needs --parts"},
      {"--parts " + quote(dir / "d") + " -o " + quote(dir / "o.exr"), "--parts needs --shards"},
      {"--shards 0 --parts " + quote(dir / "d") + " -o " + quote(dir / "o.exr"), "--shards: must be between 1 and 4096"},
      {"--shards 4097 --parts " + quote(dir / "d") + " -o " + quote(dir / "o.exr"), "--shards: must be between 1 and 4096"},
      {"--shards 2 --parts " + quote(demo) + " -o " + quote(dir / "o.exr"), "--parts must be a directory"},
      {"--shards 2 --parts " + quote(dir / "d"), "-o,--output is required"},
      {"--shards 2 --parts " + quote(dir / "d") + " -o " + quote(dir / "o.png"), "must be an .exr file"},
  };
  for (const auto& [args, message] : cases) {
    SCOPED_TRACE(args);
    std::string log;
    EXPECT_EQ(cli("bake " + scene + " " + args + " --backend cpu", log), 2) << log;
    EXPECT_TRUE(contains(log, message)) << log;
  }
  EXPECT_FALSE(fs::exists(dir / "p.vspart"));
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
  EXPECT_FALSE(fs::exists(dir / "d"));
  std::string log;
  EXPECT_EQ(cli("merge -o " + quote(dir / "o.exr"), log), 2) << log;
}

TEST(Farm, ARerunBakesOnlyTheMissingOrStaleShards) {
  const fs::path dir = vs::test::scratchDir("farm_resume");
  const fs::path demo = writeDemo(dir);
  const fs::path whole = dir / "whole.exr";
  bakeWhole(demo, whole, "cpu");
  const fs::path partsDir = dir / "parts";
  const std::string bake = "bake " + quote(demo) + " --shards 4 --parts " + quote(partsDir) + " --backend cpu";
  std::string log;
  ASSERT_EQ(cli(bake + " --missing-shards", log), 0) << log;
  EXPECT_EQ(log, "0,1,2,3\n");
  EXPECT_FALSE(fs::exists(partsDir)) << "--missing-shards only reads";
  ASSERT_EQ(cli(bake + " -o " + quote(dir / "first.exr"), log), 0) << log;
  expectSameBake(dir / "first.exr", whole);
  ASSERT_EQ(cli(bake + " --missing-shards", log), 0) << log;
  EXPECT_EQ(log, "\n");

  const std::vector<fs::path> parts = partPaths(partsDir, 4);
  struct stat kept0 {}, kept3 {};
  ASSERT_EQ(stat(parts[0].c_str(), &kept0), 0);
  ASSERT_EQ(stat(parts[3].c_str(), &kept3), 0);
  fs::remove(parts[1]);
  {
    std::string bytes = fileBytes(parts[2]);
    bytes[bytes.size() - 100] ^= 1;
    std::ofstream(parts[2], std::ios::binary | std::ios::trunc) << bytes;
  }
  ASSERT_EQ(cli(bake + " --missing-shards", log), 0) << log;
  EXPECT_EQ(log, "1,2\n");
  ASSERT_EQ(cli(bake + " -o " + quote(dir / "second.exr"), log), 0) << log;
  EXPECT_TRUE(contains(log, "2 of 4 shards to bake, 2 up to date")) << log;
  EXPECT_TRUE(contains(log, "baked shard 1 of 4") && contains(log, "baked shard 2 of 4")) << log;
  EXPECT_FALSE(contains(log, "baked shard 0 of 4") || contains(log, "baked shard 3 of 4")) << log;
  expectSameBake(dir / "second.exr", whole);
  struct stat now0 {}, now3 {};
  ASSERT_EQ(stat(parts[0].c_str(), &now0), 0);
  ASSERT_EQ(stat(parts[3].c_str(), &now3), 0);
  EXPECT_EQ(now0.st_ino, kept0.st_ino);
  EXPECT_EQ(now3.st_ino, kept3.st_ino);
  EXPECT_EQ(now0.st_mtim.tv_nsec, kept0.st_mtim.tv_nsec);

  // One shard by itself: kept when up to date, baked again when its scene changed.
  ASSERT_EQ(cli("bake " + quote(demo) + " --shard 3/4 -o " + quote(parts[3]) + " --backend cpu", log), 0) << log;
  EXPECT_TRUE(contains(log, "up to date: " + parts[3].string())) << log;
  {
    nlohmann::json scene = nlohmann::json::parse(fileBytes(demo));
    scene["lights"][0]["intensity"] = 3;  // moves no texel, yet it is another scene file
    std::ofstream(demo, std::ios::trunc) << scene.dump(2);
  }
  ASSERT_EQ(cli(bake + " --missing-shards", log), 0) << log;
  EXPECT_EQ(log, "0,1,2,3\n");
  ASSERT_EQ(cli("bake " + quote(demo) + " --shard 3/4 -o " + quote(parts[3]) + " --backend cpu", log), 0) << log;
  EXPECT_TRUE(contains(log, "baked shard 3 of 4")) << log;
  // A merge of old and new parts is refused: they saw different scene files.
  EXPECT_EQ(cli("merge" + quoted(parts) + " -o " + quote(dir / "mixed.exr"), log), 2) << log;
  EXPECT_TRUE(contains(log, "another scene")) << log;
}

TEST(Farm, SlurmArrayWithARequeuedShardEqualsTheLocalBake) {
  const fs::path dir = vs::test::scratchDir("farm_slurm");
  const fs::path demo = writeDemo(dir);
  const fs::path whole = dir / "whole.exr";
  bakeWhole(demo, whole, "cpu");
  std::string log;
  const fs::path script = fs::path(VOXSHADOW_SOURCE_DIR) / "tests" / "farm" / "slurm_farm_check.sh";
  const int status = vs::test::runCommand("bash " + quote(script) + " " + quote(vs::test::cliPath()) + " " + quote(demo) +
                                              " " + quote(whole) + " " + quote(dir / "work") + " 2>&1",
                                          log);
  EXPECT_EQ(status, 0) << log;
  expectSameBake(dir / "work" / "farm.exr", whole);
}
