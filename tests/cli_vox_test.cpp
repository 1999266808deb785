// .vox assets end to end: info, convert, scenes that use them, and hostile files refused with exit 2.
#include <cstring>
#include <fstream>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <OpenImageIO/imageio.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "lighting/scene.h"
#include "support/test_paths.h"
#include "voxel/error.h"
#include "voxel/vox_reader.h"
#include "voxel/vox_scene.h"
#include "voxel/vox_writer.h"

namespace vs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::contains;
using test::quote;

int cli(const std::string& args, std::string& out) { return test::runCli(args, out); }

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

void writeBytes(const fs::path& p, const std::vector<std::uint8_t>& b) {
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

const char* kFiles[] = {"ogt_multiple_model_scene.vox", "ogt_groups.vox", "dotvox_axes.vox",
                        "dotvox_placeholder.vox", "vengi_transform.vox", "vengi_two_voxels.vox"};

json infoJson(const fs::path& file) {
  std::string out;
  int rc = cli("info --json " + quote(file) + " 2>/dev/null", out);
  EXPECT_EQ(rc, 0) << out;
  return json::parse(out).at(0);
}

TEST(CliVox, InfoListsModelsInstancesAndMemory) {
  const fs::path dir = test::sharedAssets() / "vox";
  for (const char* name : kFiles) {
    SCOPED_TRACE(name);
    VoxFile f = readVoxFile((dir / name).string());
    json j = infoJson(dir / name);
    EXPECT_EQ(j["kind"], "vox");
    ASSERT_EQ(j["models"].size(), f.models.size());
    EXPECT_EQ(j["instances"].size(), f.instances.size());
    for (std::size_t i = 0; i < f.models.size(); ++i) {
      EXPECT_EQ(j["models"][i]["size"][0], f.models[i].size.x);
      EXPECT_GT(j["models"][i]["brickmap"]["occupancyStructureBytes"].get<std::size_t>(), 0u);
    }
  }
  std::string out;
  EXPECT_EQ(cli("info " + quote(dir / "ogt_groups.vox"), out), 0) << out;
  EXPECT_TRUE(contains(out, "model 14: ")) << out;
  EXPECT_TRUE(contains(out, "world box [0, 0, -11] .. [20, 20, 10]")) << out;
  // ogt_groups.vox, node 9: the box worked out by hand in voxel_vox_test.
  json j = infoJson(dir / "ogt_groups.vox");
  bool found = false;
  for (const json& i : j["instances"])
    if (i["shapeNode"] == 9) {
      found = true;
      EXPECT_EQ(i["worldBox"]["min"], json({0.0, 0.0, -11.0}));
      EXPECT_EQ(i["worldBox"]["max"], json({20.0, 20.0, 10.0}));
    }
  EXPECT_TRUE(found);
}

TEST(CliVox, NotAVoxExitsTwo) {
  std::string out;
  const fs::path bad = test::sharedAssets() / "vox" / "dotvox_not_a_vox.vox";
  EXPECT_EQ(cli("info " + quote(bad), out), 2) << out;
  EXPECT_TRUE(contains(out, "dotvox_not_a_vox.vox: not a MagicaVoxel .vox file")) << out;
  const fs::path dir = test::scratchDir("cli_vox_notavox");
  EXPECT_EQ(cli("convert " + quote(bad) + " " + quote(dir / "o.vdb"), out), 2) << out;
  EXPECT_TRUE(test::leftovers(dir, "o").empty());
}

TEST(CliVox, ConvertRoundTripsEveryModel) {
  const fs::path src = test::sharedAssets() / "vox";
  const fs::path dir = test::scratchDir("cli_vox_convert");
  openvdb::initialize();
  for (const char* name : kFiles) {
    SCOPED_TRACE(name);
    const fs::path vdb = dir / (std::string(name) + ".vdb");
    std::string out;
    ASSERT_EQ(cli("convert " + quote(src / name) + " " + quote(vdb), out), 0) << out;
    VoxInfo vox = inspectVox((src / name).string());
    json v = infoJson(vdb);
    ASSERT_EQ(v["grids"].size(), vox.models.size());
    auto gridName = [&](std::size_t i) {
      std::string n = std::to_string(i), last = std::to_string(vox.models.size() - 1);
      return "model" + std::string(last.size() - n.size(), '0') + n;
    };
    for (std::size_t i = 0; i < vox.models.size(); ++i) {
      EXPECT_EQ(v["grids"][i]["name"], gridName(i));
      EXPECT_EQ(v["grids"][i]["type"], "int32");
      EXPECT_EQ(v["grids"][i]["solidVoxels"].get<std::uint64_t>(), vox.models[i].voxelCount) << "model " << i;
    }
    // What OpenVDB's own tools read (vdb_print opens files this way, and lists grids by name): grids,
    // palette metadata, transforms.
    openvdb::io::File file(vdb.string());
    file.open();
    openvdb::GridPtrVecPtr grids = file.getGrids();
    file.close();
    VoxFile f = readVoxFile((src / name).string());
    ASSERT_EQ(grids->size(), f.models.size());
    for (std::size_t i = 0; i < f.models.size(); ++i) {
      openvdb::GridBase::ConstPtr found;
      for (const auto& grid : *grids)
        if (grid->getName() == gridName(i)) found = grid;
      ASSERT_TRUE(found) << "model " << i;
      const openvdb::GridBase& g = *found;
      auto palette = g.getMetadata<openvdb::StringMetadata>("voxshadow:palette");
      ASSERT_TRUE(palette);
      EXPECT_EQ(palette->value().size(), 255u * 7 - 1);
      EXPECT_EQ(g.activeVoxelCount(), openvdb::Index64(f.models[i].voxels.size()));
      const VoxInstance* first = nullptr;
      for (const VoxInstance& inst : f.instances)
        if (!first && inst.model == int(i)) first = &inst;
      glm::dmat4 want = voxPlacementMatrix(f.models[i].size, first ? first->transform : VoxTransform{}, 1.0);
      // Index (x, y, z) is a voxel's centre: brick space + 0.5.
      openvdb::Vec3d w = g.transform().indexToWorld(openvdb::Vec3d(1, 2, 3));
      glm::dvec3 expect(want * glm::dvec4(1.5, 2.5, 3.5, 1.0));
      EXPECT_NEAR(w.x(), expect.x, 1e-9);
      EXPECT_NEAR(w.y(), expect.y, 1e-9);
      EXPECT_NEAR(w.z(), expect.z, 1e-9);
    }
    // And OpenVDB's own vdb_print (libopenvdb-tools, installed by tools/install-deps.sh) lists every grid
    // with its voxel count.
    ASSERT_EQ(test::runCommand("vdb_print -l " + quote(vdb), out), 0) << out;
    std::vector<std::string> counts;  // "Number of active voxels:   98,304", one per grid in its order
    const std::string label = "Number of active voxels:";
    for (std::size_t at = out.find(label); at != std::string::npos; at = out.find(label, at + 1)) {
      std::size_t b = out.find_first_not_of(' ', at + label.size()), e = out.find('\n', b);
      counts.push_back(out.substr(b, e - b));
    }
    ASSERT_EQ(counts.size(), f.models.size()) << out;
    for (std::size_t i = 0; i < f.models.size(); ++i) {
      EXPECT_TRUE(out.find("Name: " + gridName(i)) != std::string::npos) << out;
      const std::string digits = std::to_string(f.models[i].voxels.size());
      std::string count;  // with thousands separators, as vdb_print writes it
      for (std::size_t k = 0; k < digits.size(); ++k) {
        if (k > 0 && (digits.size() - k) % 3 == 0) count.push_back(',');
        count.push_back(digits[k]);
      }
      EXPECT_TRUE(std::find(counts.begin(), counts.end(), count) != counts.end())
          << "model " << i << " (" << count << " voxels): " << out;
    }
  }
}

TEST(CliVox, ConvertRefusesBadPaths) {
  const fs::path dir = test::scratchDir("cli_vox_paths");
  const fs::path vox = dir / "a.vox";
  fs::copy_file(test::sharedAssets() / "vox" / "vengi_two_voxels.vox", vox);
  std::string out;
  EXPECT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "a.exr"), out), 2) << out;
  EXPECT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "missing" / "a.vdb"), out), 2) << out;
  EXPECT_EQ(cli("convert " + quote(dir / "none.vox") + " " + quote(dir / "b.vdb"), out), 2) << out;
  EXPECT_TRUE(contains(out, "none.vox")) << out;
  EXPECT_FALSE(fs::exists(dir / "b.vdb"));
  // An output that is the input under another name.
  fs::create_symlink(vox, dir / "same.vdb");
  EXPECT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "same.vdb"), out), 2) << out;
  EXPECT_TRUE(contains(out, "would overwrite the input")) << out;
  EXPECT_EQ(fs::file_size(vox), fs::file_size(test::sharedAssets() / "vox" / "vengi_two_voxels.vox"));
}

VoxModel block(glm::ivec3 s, std::uint8_t colour) {
  VoxModel m;
  m.size = s;
  for (int z = 0; z < s.z; ++z)
    for (int y = 0; y < s.y; ++y)
      for (int x = 0; x < s.x; ++x)
        if ((x + y + z) % 3 != 0 || z == 0) m.voxels.push_back({std::uint8_t(x), std::uint8_t(y), std::uint8_t(z), colour});
  return m;
}

VoxWriteFile goodFile() {
  VoxWriteFile w;
  w.models = {block({5, 4, 3}, 10), block({2, 6, 7}, 20), block({8, 8, 1}, 30)};
  // One placement per model, in model order; a permutation, a mirror and a plain shift.
  w.nodes = voxSceneGraph({{0, 105, {0, 0, 4}, "first"}, {1, 49, {6, -3, 5}, "second"}, {2, 4, {0, 0, 0}, "base"}});
  return w;
}

std::vector<std::vector<std::uint8_t>> hostileFiles() {
  std::vector<std::vector<std::uint8_t>> out;
  std::vector<std::uint8_t> good = encodeVox(goodFile());
  for (std::size_t cut : {std::size_t(6), std::size_t(20), std::size_t(40), std::size_t(60), good.size() - 3})
    out.emplace_back(good.begin(), good.begin() + std::ptrdiff_t(cut));
  for (std::int32_t size : {0, std::int32_t(0x80000000u)}) {
    std::vector<std::uint8_t> b = good;
    std::memcpy(&b[32], &size, 4);  // SIZE of model 0: chunk at 20, x at 32
    out.push_back(b);
  }
  {
    std::vector<std::uint8_t> b = good;
    std::int32_t n = 1000000;
    std::memcpy(&b[56], &n, 4);  // XYZI count of model 0
    out.push_back(b);
  }
  {
    VoxWriteFile w = goodFile();
    w.models[0].voxels[0].x = 5;
    out.push_back(encodeVox(w));
  }
  {
    VoxWriteFile w = goodFile();
    w.nodes[2].child = 1;  // back to the group: a cycle
    out.push_back(encodeVox(w));
  }
  {
    VoxWriteFile w = goodFile();
    w.nodes[1].children.push_back(99);
    out.push_back(encodeVox(w));
  }
  {
    VoxWriteFile w;
    w.models = {block({1, 1, 1}, 1)};
    for (int i = 0; i < 10000; ++i) {
      VoxWriteNode t;
      t.id = i;
      t.child = i + 1;
      w.nodes.push_back(t);
    }
    VoxWriteNode s;
    s.kind = VoxWriteNode::Kind::Shape;
    s.id = 10000;
    s.models.push_back({0, {}});
    w.nodes.push_back(s);
    out.push_back(encodeVox(w));
  }
  return out;
}

TEST(CliVox, HostileFilesExitTwoAndWriteNothing) {
  const fs::path dir = test::scratchDir("cli_vox_hostile");
  std::vector<std::vector<std::uint8_t>> files = hostileFiles();
  for (std::size_t i = 0; i < files.size(); ++i) {
    SCOPED_TRACE("hostile file " + std::to_string(i));
    const fs::path vox = dir / ("bad" + std::to_string(i) + ".vox");
    writeBytes(vox, files[i]);
    std::string out;
    EXPECT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "out.vdb"), out), 2) << out;
    EXPECT_TRUE(contains(out, vox.string() + ": ")) << out;
    EXPECT_TRUE(test::leftovers(dir, "out").empty()) << out;
    // Every start of the CLI costs about a second: info and bake on every third file.
    if (i % 3 != 0) continue;
    EXPECT_EQ(cli("info " + quote(vox), out), 2) << out;
    EXPECT_TRUE(contains(out, vox.string() + ": ")) << out;
    writeText(dir / "s.json", R"({"version": 1, "assets": {"b": {"file": ")" + vox.filename().string() +
                                  R"("}}, "instances": [{"asset": "b"}], "lights": [{"name": "sun", "type": "directional", "direction": [0, -1, 0],
                                  "shadow": {"resolution": 16, "cascades": 1}}]})");
    EXPECT_EQ(cli("bake " + quote(dir / "s.json") + " -o " + quote(dir / "out.exr") + " --backend cpu", out), 2) << out;
    EXPECT_TRUE(contains(out, "assets.b: ")) << out;
    EXPECT_TRUE(test::leftovers(dir, "out").empty()) << out;
  }
}

std::vector<float> subimagePixels(const fs::path& exr, int s, int& width) {
  auto in = OIIO::ImageInput::open(exr.string());
  if (!in || !in->seek_subimage(s, 0)) return {};
  width = in->spec().width;
  std::vector<float> p(in->spec().image_pixels());
  if (!in->read_image(s, 0, 0, 1, OIIO::TypeDesc::FLOAT, p.data())) return {};
  return p;
}

const char* kLights = R"("lights": [
    { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3], "shadow": { "resolution": 64, "cascades": 1 } },
    { "name": "lamp", "type": "spot", "position": [2, 12, 3], "direction": [0, -1, 0], "range": 30,
      "outer_cone_deg": 50, "shadow": { "resolution": 32 } } ],
  "camera": { "position": [14, 12, 14], "target": [0, 2, 0], "far": 60 })";

TEST(CliVox, BakeOfVoxSceneEqualsBakeOfConvertedVdb) {
  const fs::path dir = test::scratchDir("cli_vox_bake");
  writeVoxFile(dir / "t.vox", goodFile());
  std::string out;
  ASSERT_EQ(cli("convert " + quote(dir / "t.vox") + " " + quote(dir / "t.vdb"), out), 0) << out;
  writeText(dir / "scene_vox.json", std::string(R"({ "version": 1, "assets": { "t": { "file": "t.vox" } },
  "instances": [ { "asset": "t", "translate": [1, 0, -2], "rotate_deg": [0, 30, 0] } ], )") + kLights + "}");
  std::string assets, instances;
  for (int i = 0; i < 3; ++i) {
    assets += std::string(i ? ", " : "") + "\"g" + std::to_string(i) + "\": { \"file\": \"t.vdb\", \"grid\": " + std::to_string(i) + " }";
    instances += std::string(i ? ", " : "") + "{ \"asset\": \"g" + std::to_string(i) +
                 "\", \"translate\": [1, 0, -2], \"rotate_deg\": [0, 30, 0] }";
  }
  writeText(dir / "scene_vdb.json", "{ \"version\": 1, \"assets\": { " + assets + " }, \"instances\": [ " + instances + " ], " +
                                  kLights + "}");
  ASSERT_EQ(cli("bake " + quote(dir / "scene_vox.json") + " -o " + quote(dir / "vox.exr") + " --backend cpu", out), 0) << out;
  ASSERT_EQ(cli("bake " + quote(dir / "scene_vdb.json") + " -o " + quote(dir / "vdb.exr") + " --backend cpu", out), 0) << out;

  Scene a = Scene::load(dir / "scene_vox.json"), b = Scene::load(dir / "scene_vdb.json");
  ASSERT_EQ(a.instances().size(), 3u);
  ASSERT_EQ(b.instances().size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(a.instances()[i].brickToWorld, b.instances()[i].brickToWorld) << i;

  std::size_t hits = 0, texels = 0;
  for (int s = 0; s < 2; ++s) {
    int wa = 0, wb = 0;
    std::vector<float> pa = subimagePixels(dir / "vox.exr", s, wa), pb = subimagePixels(dir / "vdb.exr", s, wb);
    ASSERT_FALSE(pa.empty());
    ASSERT_EQ(pa.size(), pb.size());
    ASSERT_EQ(wa, wb);
    const float miss = s == 0 ? 1.0f : 30.0f;
    for (std::size_t i = 0; i < pa.size(); ++i) {
      ASSERT_EQ(pa[i], pb[i]) << "subimage " << s << " texel " << i;
      hits += pa[i] < miss;
    }
    texels += pa.size();
  }
  EXPECT_GT(hits, 0u);
  EXPECT_LT(hits, texels);
}

TEST(CliVox, SceneFileKeysForVoxAssets) {
  const fs::path dir = test::scratchDir("cli_vox_scene");
  writeVoxFile(dir / "t.vox", goodFile());
  auto scene = [&](const std::string& asset) {
    writeText(dir / "s.json", R"({ "version": 1, "assets": { "t": )" + asset + R"( }, "instances": [ { "asset": "t" }, { "asset": "t", "translate": [20, 0, 0] } ] })");
    return dir / "s.json";
  };
  Scene whole = Scene::load(scene(R"({ "file": "t.vox", "voxel_size": 0.5 })"));
  EXPECT_EQ(whole.objects().size(), 3u);
  ASSERT_EQ(whole.instances().size(), 6u);  // two scene instances, three shapes each
  EXPECT_EQ(whole.instanceSources()[4], 1u);
  EXPECT_EQ(whole.assetObjects()[0].count, 3u);
  // Model 2 (8 x 8 x 1 at the origin, pivot (4 4 0)): y from 0 to 0.5 with voxel size 0.5.
  VoxAsset ref = loadVox((dir / "t.vox").string(), {.voxelSize = 0.5, .model = ""});
  EXPECT_EQ(whole.instances()[2].brickToWorld, ref.placements[2].brickToAsset);
  EXPECT_EQ(whole.instances()[5].brickToWorld,
            glm::translate(glm::dmat4(1.0), glm::dvec3(20, 0, 0)) * ref.placements[2].brickToAsset);

  Scene one = Scene::load(scene(R"({ "file": "t.vox", "model": 1 })"));
  EXPECT_EQ(one.objects().size(), 1u);
  EXPECT_EQ(one.instances().size(), 2u);
  Scene named = Scene::load(scene(R"({ "file": "t.vox", "model": "base" })"));
  EXPECT_EQ(named.objects()[0].brickmap.solidCount(), 64u);
  one.moveInstance(1, glm::translate(glm::dmat4(1.0), glm::dvec3(0, 5, 0)));
  EXPECT_EQ(one.desc().instances[1].transform[3].y, 5.0);

  struct Bad {
    const char* asset;
    const char* message;
  } bad[] = {
      {R"({ "file": "t.vox", "grid": 0 })", "assets.t.grid: unknown key for a .vox asset"},
      {R"({ "file": "t.vox", "voxel_size": 0 })", "assets.t.voxel_size: must be between"},
      {R"({ "file": "t.vox", "model": -1 })", "assets.t.model: a model index must not be negative"},
      {R"({ "file": "t.vox", "model": 3 })", "assets.t: " },
      {R"({ "file": "t.vox", "model": "nobody" })", "no visible shape named 'nobody'"},
      {R"({ "file": "t.vox", "frame": -2 })", "assets.t.frame: must be a whole number from 0 to 1000000, not -2"},
      {R"({ "file": "t.vox", "frame": 1e12 })", "assets.t.frame: must be a whole number from 0 to 1000000, not 1e+12"},
      {R"({ "file": "t.vox", "frame": 2.5 })", "assets.t.frame: must be a whole number from 0 to 1000000, not 2.5"},
      {R"({ "file": "t.vox", "frame": "3" })", "assets.t.frame: must be a whole number from 0 to 1000000, not a string"},
  };
  for (const Bad& b : bad) {
    try {
      Scene::load(scene(b.asset));
      ADD_FAILURE() << b.asset << ": accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput);
      EXPECT_TRUE(contains(e.what(), b.message)) << e.what();
      EXPECT_TRUE(contains(e.what(), "s.json: ")) << e.what();
    }
  }
  std::string out;
  EXPECT_EQ(cli("info " + quote(scene(R"({ "file": "t.vox" })")), out), 0) << out;
  EXPECT_TRUE(contains(out, "asset t: ")) << out;
  EXPECT_TRUE(contains(out, "3 objects")) << out;
}

// An animation as MagicaVoxel 0.98 and older store it: a PACK chunk, one model per frame, no scene graph.
VoxWriteFile packFile() {
  VoxWriteFile w;
  w.version = 150;
  w.pack = 3;
  w.models = {block({2, 2, 2}, 10), block({3, 3, 3}, 20), block({4, 4, 4}, 30)};
  return w;
}

std::size_t occurrences(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + 1)) ++n;
  return n;
}

TEST(CliVox, PackFramesInInfoConvertAndScenes) {
  const fs::path dir = test::scratchDir("cli_vox_pack");
  const fs::path vox = dir / "rex.vox";
  writeVoxFile(vox, packFile());
  const VoxFile f = readVoxFile(vox.string());
  std::string out;
  ASSERT_EQ(cli("info " + quote(vox), out), 0) << out;
  EXPECT_TRUE(contains(out, "3 models (PACK animation frames 0..2, frame 0 shown), 1 instance")) << out;
  EXPECT_TRUE(contains(out, "note: PACK animation: the 3 models are frames 0..2, frame 0 shown")) << out;
  json j = infoJson(vox);
  EXPECT_EQ(j["animation"]["frames"], 3);
  EXPECT_EQ(j["animation"]["frameShown"], 0);
  EXPECT_EQ(j["pack"], 3);
  ASSERT_EQ(j["instances"].size(), 1u);
  EXPECT_EQ(j["instances"][0]["model"], 0);

  ASSERT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "rex.vdb") + " --frame 2", out), 0) << out;
  EXPECT_TRUE(contains(out, "frame 2 of the PACK animation (the frame chosen)")) << out;
  EXPECT_TRUE(contains(out, "frame 2 shown")) << out;
  EXPECT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "past.vdb") + " --frame 3", out), 2) << out;
  EXPECT_TRUE(contains(out, "rex.vox: frame 3 is beyond the 3 frames of its PACK animation (0..2)")) << out;
  EXPECT_EQ(occurrences(out, "rex.vox"), 1u) << out;
  EXPECT_TRUE(test::leftovers(dir, "past").empty()) << out;
  // Bad values get one message, whatever CLI11 would make of them.
  for (const char* bad : {"-1", "99999999999", "1000001", "1.5", "x", "1e3"}) {
    SCOPED_TRACE(bad);
    EXPECT_EQ(cli("convert " + quote(vox) + " " + quote(dir / "bad.vdb") + " --frame " + bad, out), 2) << out;
    EXPECT_TRUE(contains(out, "--frame: must be a whole number from 0 to 1000000")) << out;
    EXPECT_FALSE(contains(out, "Could not convert")) << out;
    EXPECT_FALSE(contains(out, "not in range")) << out;
  }
  EXPECT_TRUE(test::leftovers(dir, "bad").empty());

  // Scene files: "frame" picks the pose; the default is frame 0.
  auto scene = [&](const std::string& asset) {
    writeText(dir / "s.json", R"({ "version": 1, "assets": { "rex": )" + asset + R"( }, "instances": [ { "asset": "rex" } ] })");
    return dir / "s.json";
  };
  Scene first = Scene::load(scene(R"({ "file": "rex.vox" })"));
  ASSERT_EQ(first.objects().size(), 1u);
  ASSERT_EQ(first.instances().size(), 1u);
  EXPECT_EQ(first.objects()[0].brickmap.solidCount(), f.models[0].voxels.size());
  Scene last = Scene::load(scene(R"({ "file": "rex.vox", "frame": 2 })"));
  ASSERT_EQ(last.objects().size(), 1u);
  EXPECT_EQ(last.objects()[0].brickmap.solidCount(), f.models[2].voxels.size());
  try {
    Scene::load(scene(R"({ "file": "rex.vox", "frame": 5 })"));
    ADD_FAILURE() << "frame 5 accepted";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "s.json: assets.rex: ")) << e.what();
    EXPECT_TRUE(contains(e.what(), "rex.vox: frame 5 is beyond the 3 frames of its PACK animation (0..2)")) << e.what();
    EXPECT_EQ(occurrences(e.what(), "rex.vox"), 1u) << e.what();
  }
}

}  // namespace
}  // namespace vs
