// .vox reading: the third-party files against their own chunks, the placement rule against hand-computed
// boxes, and hostile files refused with clear messages.
#include <cstring>
#include <fstream>
#include <map>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "support/test_paths.h"
#include "voxel/error.h"
#include "voxel/vox_reader.h"
#include "voxel/vox_scene.h"
#include "voxel/vox_writer.h"

namespace vs {
namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<std::uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::int32_t le32(const std::vector<std::uint8_t>& b, std::size_t at) {
  return std::int32_t(std::uint32_t(b[at]) | std::uint32_t(b[at + 1]) << 8 | std::uint32_t(b[at + 2]) << 16 |
                      std::uint32_t(b[at + 3]) << 24);
}

// The file's own SIZE and XYZI chunks, walked without the reader.
struct RawModel {
  glm::ivec3 size;
  int count;
};
std::vector<RawModel> rawModels(const std::vector<std::uint8_t>& b, std::vector<std::size_t>* boundaries = nullptr) {
  std::vector<RawModel> out;
  std::size_t at = 20 + std::size_t(le32(b, 12)), end = at + std::size_t(le32(b, 16));
  if (boundaries) boundaries->assign({0, 8, 20});
  while (at < end) {
    std::string id(reinterpret_cast<const char*>(&b[at]), 4);
    std::size_t content = std::size_t(le32(b, at + 4)), children = std::size_t(le32(b, at + 8));
    if (id == "SIZE") out.push_back({{le32(b, at + 12), le32(b, at + 16), le32(b, at + 20)}, -1});
    if (id == "XYZI") out.back().count = le32(b, at + 12);
    at += 12 + content + children;
    if (boundaries) boundaries->push_back(at);
  }
  return out;
}

const char* kFiles[] = {"ogt_multiple_model_scene.vox", "ogt_groups.vox", "dotvox_axes.vox",
                        "dotvox_placeholder.vox", "vengi_transform.vox", "vengi_two_voxels.vox"};

TEST(VoxAssets, EveryFileLoadsWithItsOwnModelCounts) {
  const fs::path dir = test::sharedAssets() / "vox";
  for (const char* name : kFiles) {
    SCOPED_TRACE(name);
    std::vector<RawModel> raw = rawModels(fileBytes(dir / name));
    VoxFile f = readVoxFile((dir / name).string());
    ASSERT_EQ(f.models.size(), raw.size());
    for (std::size_t i = 0; i < raw.size(); ++i) {
      EXPECT_EQ(f.models[i].size, raw[i].size) << "model " << i;
      EXPECT_EQ(int(f.models[i].voxels.size()), raw[i].count) << "model " << i;
    }
    VoxAsset asset = buildVoxAsset(f);
    EXPECT_EQ(asset.placements.size(), f.instances.size());
    EXPECT_LE(asset.objects.size(), f.models.size());
    for (const VoxPlacement& p : asset.placements) {
      ASSERT_LT(p.object, asset.objects.size());
      EXPECT_EQ(asset.objects[p.object].brickmap.solidCount(), f.models[std::size_t(p.model)].voxels.size());
    }
  }
  // The documented figures of the two larger files.
  EXPECT_EQ(readVoxFile((dir / "ogt_multiple_model_scene.vox").string()).models.size(), 41u);
  EXPECT_EQ(readVoxFile((dir / "ogt_groups.vox").string()).models.size(), 15u);
  EXPECT_EQ(readVoxFile((dir / "dotvox_axes.vox").string()).version, 200);
}

TEST(VoxAssets, NotAVoxIsRefused) {
  const fs::path p = test::sharedAssets() / "vox" / "dotvox_not_a_vox.vox";
  try {
    readVoxFile(p.string());
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput);
    EXPECT_TRUE(test::contains(e.what(), "dotvox_not_a_vox.vox")) << e.what();
    EXPECT_TRUE(test::contains(e.what(), "not a MagicaVoxel .vox file")) << e.what();
  }
}

TEST(VoxAssets, SharedSubtreesAreInstancesAndIdenticalModelsShareObjects) {
  // vengi_transform.vox: one group (floor + a group of four shapes) under four transforms.
  VoxFile f = readVoxFile((test::sharedAssets() / "vox" / "vengi_transform.vox").string());
  EXPECT_EQ(f.instances.size(), 20u);
  VoxAsset a = buildVoxAsset(f);
  EXPECT_EQ(a.objects.size(), 3u);
  EXPECT_EQ(a.placements.size(), 20u);
}

struct Box {
  glm::dvec3 min, max;
};
Box worldBox(const glm::dmat4& brickToAsset, glm::ivec3 size) {
  glm::dvec3 a(brickToAsset * glm::dvec4(0, 0, 0, 1)), b(brickToAsset * glm::dvec4(glm::dvec3(size), 1));
  return {glm::min(a, b), glm::max(a, b)};
}

void expectBox(const VoxFile& f, const VoxInstance& inst, glm::dvec3 min, glm::dvec3 max) {
  Box b = worldBox(voxPlacementMatrix(f.models[std::size_t(inst.model)].size, inst.transform, 1.0),
                   f.models[std::size_t(inst.model)].size);
  EXPECT_EQ(b.min, min) << inst.name << " model " << inst.model;
  EXPECT_EQ(b.max, max) << inst.name << " model " << inst.model;
}

const VoxInstance& byNode(const VoxFile& f, int shapeNode, int nth = 0) {
  for (const VoxInstance& i : f.instances)
    if (i.shapeNode == shapeNode && nth-- == 0) return i;
  throw std::runtime_error("no such instance");
}

// Boxes worked out by hand from the files' chunks (MagicaVoxel Z-up: pivot floor(size/2), then the rotation,
// then the translations of every transform above, root last; then (x, y, z) -> (x, z, -y)).
TEST(VoxPlacement, HandComputedBoxesOfThirdPartyScenes) {
  const fs::path dir = test::sharedAssets() / "vox";
  {
    VoxFile f = readVoxFile((dir / "ogt_multiple_model_scene.vox").string());
    // node 2 _t (54 14 10), model 0 8^3: [50,58] x [10,18] x [6,14].
    expectBox(f, byNode(f, 3), {50, 6, -18}, {58, 14, -10});
    // node 4 _r 17 (a quarter turn about z), _t (62 14 10), model 1 8^3: symmetric about the pivot.
    expectBox(f, byNode(f, 5), {58, 6, -18}, {66, 14, -10});
  }
  {
    VoxFile f = readVoxFile((dir / "ogt_groups.vox").string());
    // (46 0 24) + (0 0 -14) + (-36 0 0), model 0 20x21x20, pivot (10 10 10): [0,20] x [-10,11] x [0,20].
    expectBox(f, byNode(f, 9), {0, 0, -11}, {20, 20, 10});
    // (46 0 24) + (-10 0 15) + (-28 0 5), model 4 5x1x8, pivot (2 0 4): [6,11] x [0,1] x [40,48].
    expectBox(f, byNode(f, 19), {6, 40, -1}, {11, 48, 0});
  }
  {
    VoxFile f = readVoxFile((dir / "vengi_transform.vox").string());
    // topLeft (_t -61 64 -6) > floor (_r 36 = mirror y, _t -4 0 0), model 0 128^3, pivot 64:
    // [-68,60] x [-64,64] x [-64,64] + topLeft = [-129,-1] x [0,128] x [-70,58].
    // Depth-first order: topLeft is the group's first child, floor the second child of group 3.
    expectBox(f, byNode(f, 5, 0), {-129, -70, -128}, {-1, 58, 0});
    // topRight (_r 20 = mirror x, _t 59 64 -6) > weird (_r 49, _t 33 -32 34) > front red (_r 41, _t 12 6 2),
    // model 1 39x40x40, pivot (19 20 20): local [-19,20] x [-20,20]^2;
    // _r 41 rows (0 1 0)(0 0 -1)(1 0 0): [-20,20] x [-20,20] x [-19,20], + (12 6 2): [-8,32] x [-14,26] x [-17,22];
    // _r 49 rows (0 -1 0)(-1 0 0)(0 0 1): [-26,14] x [-32,8] x [-17,22], + (33 -32 34): [7,47] x [-64,-24] x [17,56];
    // mirror x: [-47,-7], + (59 64 -6): [12,52] x [0,40] x [11,50].
    // Shape 9 is reached from front red (node 8) and top red (node 10) under each of the four corners:
    // topLeft, topRight, bottomLeft, bottomRight in the root group's order 16, 15, 14, 2.
    int seen = 0;
    for (const VoxInstance& i : f.instances)
      if (i.shapeNode == 9 && i.name == "front red" && seen++ == 1) expectBox(f, i, {12, 11, -40}, {52, 50, 0});
    EXPECT_EQ(seen, 4);
  }
}

// The columns and signs of a packed rotation byte, read per row as MagicaVoxel documents them.
struct RowForm {
  int col[3];
  int sign[3];
};
RowForm rows(int packed) {
  RowForm r;
  r.col[0] = packed & 3;
  r.col[1] = (packed >> 2) & 3;
  r.col[2] = 3 - r.col[0] - r.col[1];
  for (int i = 0; i < 3; ++i) r.sign[i] = (packed >> (4 + i)) & 1 ? -1 : 1;
  return r;
}

TEST(VoxPlacement, EveryRotationOddAndEvenSizes) {
  int valid = 0;
  for (int packed = 0; packed < 128; ++packed) {
    glm::imat3x3 m;
    RowForm r = rows(packed);
    bool ok = decodeVoxRotation(packed, m);
    EXPECT_EQ(ok, r.col[0] != 3 && r.col[1] != 3 && r.col[0] != r.col[1]) << packed;
    if (!ok) continue;
    ++valid;
    for (glm::ivec3 s : {glm::ivec3(3, 4, 5), glm::ivec3(2, 7, 1), glm::ivec3(6, 1, 9)}) {
      const glm::ivec3 t(10, -20, 7);
      const int f[3] = {s.x / 2, s.y / 2, s.z / 2};
      // Per axis: row i takes model axis c with sign g; the model spans [-f_c, s_c - f_c] about its pivot.
      int lo[3], hi[3];
      for (int i = 0; i < 3; ++i) {
        int c = r.col[i];
        lo[i] = t[i] + (r.sign[i] > 0 ? -f[c] : f[c] - s[c]);
        hi[i] = t[i] + (r.sign[i] > 0 ? s[c] - f[c] : f[c]);
      }
      VoxTransform vt{m, t};
      Box b = worldBox(voxPlacementMatrix(s, vt, 1.0), s);
      // Y-up world: (x, y, z) -> (x, z, -y).
      EXPECT_EQ(b.min, glm::dvec3(lo[0], lo[2], -hi[1])) << "rotation " << packed << " size " << s.x << s.y << s.z;
      EXPECT_EQ(b.max, glm::dvec3(hi[0], hi[2], -lo[1])) << "rotation " << packed << " size " << s.x << s.y << s.z;
      // One voxel: (1, 0, 2) of the model, centre T + R * ((1, 0, 2) + 0.5 - floor(s/2)).
      glm::dvec3 local(1.5 - f[0], 0.5 - f[1], 2.5 - f[2]);
      glm::dvec3 centre;
      for (int i = 0; i < 3; ++i) centre[i] = t[i] + r.sign[i] * local[r.col[i]];
      glm::dvec3 got(voxPlacementMatrix(s, vt, 1.0) * glm::dvec4(1.5, 0.5, 2.5, 1.0));
      EXPECT_EQ(got, glm::dvec3(centre.x, centre.z, -centre.y)) << packed;
    }
  }
  EXPECT_EQ(valid, 48);  // 6 permutations x 8 sign choices
}

TEST(VoxPlacement, LiteralCases) {
  // Identity, size 3x4x5 at (10 20 30): pivot (1 2 2), [9,12] x [18,22] x [28,33] in MagicaVoxel space.
  VoxTransform id{glm::imat3x3(1), {10, 20, 30}};
  Box b = worldBox(voxPlacementMatrix({3, 4, 5}, id, 1.0), {3, 4, 5});
  EXPECT_EQ(b.min, glm::dvec3(9, 28, -22));
  EXPECT_EQ(b.max, glm::dvec3(12, 33, -18));
  // The format's own example, rows (0 1 0)(0 0 -1)(-1 0 0) = byte 105: x' = y, y' = -z, z' = -x:
  // x' in [-2,2] + 10, y' in [-3,2] + 20, z' in [-2,1] + 30.
  glm::imat3x3 r;
  ASSERT_TRUE(decodeVoxRotation(105, r));
  EXPECT_EQ(r[1][0], 1);   // row 0, column 1
  EXPECT_EQ(r[2][1], -1);  // row 1, column 2
  EXPECT_EQ(r[0][2], -1);  // row 2, column 0
  b = worldBox(voxPlacementMatrix({3, 4, 5}, {r, {10, 20, 30}}, 1.0), {3, 4, 5});
  EXPECT_EQ(b.min, glm::dvec3(8, 28, -22));
  EXPECT_EQ(b.max, glm::dvec3(12, 31, -17));
  // Even and unit sizes at the origin: 2^3 straddles it, 1^3 sits in the positive octant (Z-up).
  b = worldBox(voxPlacementMatrix({2, 2, 2}, {}, 1.0), {2, 2, 2});
  EXPECT_EQ(b.min, glm::dvec3(-1, -1, -1));
  EXPECT_EQ(b.max, glm::dvec3(1, 1, 1));
  b = worldBox(voxPlacementMatrix({1, 1, 1}, {}, 0.5), {1, 1, 1});
  EXPECT_EQ(b.min, glm::dvec3(0, 0, -0.5));
  EXPECT_EQ(b.max, glm::dvec3(0.5, 0.5, 0));
  // Z-up to Y-up is a proper rotation.
  EXPECT_EQ(glm::determinant(glm::dmat3(voxZupToYup())), 1.0);
}

TEST(VoxPalette, DefaultPaletteAndColours) {
  const auto& p = voxDefaultPalette();
  EXPECT_EQ(p[1], 0xffffffffu);
  EXPECT_EQ(p[2], 0xffccffffu);    // blue steps first
  EXPECT_EQ(p[7], 0xffffccffu);    // then green
  EXPECT_EQ(p[215], 0xff330000u);  // the cube's last: R 00, G 00, B 33
  EXPECT_EQ(p[216], 0xff0000eeu);  // ramps: red
  EXPECT_EQ(p[255], 0xff111111u);  // grey
  EXPECT_FLOAT_EQ(srgbToLinear(255), 1.0f);
  EXPECT_FLOAT_EQ(srgbToLinear(0), 0.0f);
  EXPECT_NEAR(srgbToLinear(188), 0.5f, 0.005f);
  // Files saved with the untouched default palette store it in their RGBA chunk: every entry matches.
  for (const char* name : {"dotvox_placeholder.vox", "dotvox_axes.vox", "vengi_transform.vox"}) {
    VoxFile f = readVoxFile((test::sharedAssets() / "vox" / name).string());
    ASSERT_TRUE(f.hasPaletteChunk);
    int same = 0;
    for (int i = 1; i < 256; ++i) same += f.palette[std::size_t(i)] == p[std::size_t(i)];
    EXPECT_EQ(same, 255) << name;
  }
}

// --- files written here -----------------------------------------------------------------------------

VoxModel cube(int n, std::uint8_t colour = 1) {
  VoxModel m;
  m.size = {n, n, n};
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) m.voxels.push_back({std::uint8_t(x), std::uint8_t(y), std::uint8_t(z), colour});
  return m;
}

VoxWriteFile twoModelFile() {
  VoxWriteFile w;
  w.models = {cube(2, 3), cube(3, 5)};
  w.nodes = voxSceneGraph({{0, 4, {0, 0, 1}, "a"}, {1, 17, {5, 0, 0}, "b"}, {0, 4, {-5, 0, 0}, "c"}});
  return w;
}

void expectRefused(const std::vector<std::uint8_t>& bytes, const std::string& fragment, const std::string& what) {
  try {
    readVox(bytes, "bad.vox");
    ADD_FAILURE() << what << ": accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput) << what;
    EXPECT_EQ(std::string(e.what()).rfind("bad.vox: ", 0), 0u) << what << ": " << e.what();
    EXPECT_TRUE(test::contains(e.what(), fragment)) << what << ": " << e.what();
  }
}

TEST(VoxWritten, RoundTripAndSharing) {
  VoxFile f = readVox(encodeVox(twoModelFile()), "two.vox");
  ASSERT_EQ(f.models.size(), 2u);
  ASSERT_EQ(f.instances.size(), 3u);
  EXPECT_EQ(f.instances[1].name, "b");
  VoxAsset a = buildVoxAsset(f, {.voxelSize = 0.25, .model = ""});
  EXPECT_EQ(a.objects.size(), 2u);  // model 0 placed twice, one object
  EXPECT_EQ(a.placements[0].object, a.placements[2].object);
  Box b = worldBox(a.placements[0].brickToAsset, {2, 2, 2});
  EXPECT_EQ(b.min, glm::dvec3(-0.25, 0.0, -0.25));  // (0 0 1) + [-1,1]^3, times 0.25, Y-up
  EXPECT_EQ(b.max, glm::dvec3(0.25, 0.5, 0.25));
  // Two models with identical voxels share one object too.
  VoxWriteFile w = twoModelFile();
  w.models[1] = w.models[0];
  std::reverse(w.models[1].voxels.begin(), w.models[1].voxels.end());
  EXPECT_EQ(buildVoxAsset(readVox(encodeVox(w), "same.vox")).objects.size(), 1u);
  // Taking one model by index or a shape by name.
  VoxAsset one = buildVoxAsset(f, {.model = "1"});
  ASSERT_EQ(one.placements.size(), 1u);
  EXPECT_EQ(worldBox(one.placements[0].brickToAsset, {3, 3, 3}).min, glm::dvec3(-1, -1, -2));
  VoxAsset named = buildVoxAsset(f, {.model = "c"});
  ASSERT_EQ(named.placements.size(), 1u);
  EXPECT_EQ(worldBox(named.placements[0].brickToAsset, {2, 2, 2}).min, glm::dvec3(-6, -1, -1));
  EXPECT_THROW(buildVoxAsset(f, {.model = "2"}), Error);
  EXPECT_THROW(buildVoxAsset(f, {.model = "nobody"}), Error);
  EXPECT_THROW(buildVoxAsset(f, {.voxelSize = 0.0, .model = ""}), Error);
}

TEST(VoxWritten, NoSceneGraphNoPaletteVersion150) {
  VoxWriteFile w;
  w.version = 150;
  w.models = {cube(1, 9)};
  VoxFile f = readVox(encodeVox(w), "plain.vox");
  EXPECT_FALSE(f.hasSceneGraph);
  EXPECT_FALSE(f.hasPaletteChunk);
  EXPECT_EQ(f.palette, voxDefaultPalette());
  ASSERT_EQ(f.instances.size(), 1u);
  std::vector<glm::vec3> lin = voxLinearPalette(f.palette);
  EXPECT_EQ(lin.size(), 256u);
  EXPECT_EQ(lin[0], glm::vec3(0.0f));
  w.version = 201;
  expectRefused(encodeVox(w), "unsupported .vox version 201", "version");
}

TEST(VoxWritten, HiddenLayersAndNodesAndFrames) {
  VoxWriteFile w = twoModelFile();
  w.layers = {{0, "shown", false}, {1, "off", true}};
  w.nodes[2 + 2].layer = 1;                  // "b" in the hidden layer
  w.nodes[2 + 4].attributes["_hidden"] = "1"; // "c" hidden
  // "a" moves at frame 3.
  w.nodes[2].frames = {{{"_t", "0 0 1"}}, {{"_t", "0 0 9"}, {"_f", "3"}}};
  VoxFile f = readVox(encodeVox(w), "h.vox");
  ASSERT_EQ(f.instances.size(), 1u);
  EXPECT_EQ(f.instances[0].name, "a");
  EXPECT_EQ(f.instances[0].transform.translation, glm::ivec3(0, 0, 1));
  std::string notes;
  for (const std::string& n : f.notes) notes += n + "\n";
  EXPECT_TRUE(test::contains(notes, "hidden layer 1 'off' skipped (1 shape)")) << notes;
  EXPECT_TRUE(test::contains(notes, "hidden node 6 'c' skipped (1 shape)")) << notes;
  EXPECT_EQ(readVox(encodeVox(w), "h.vox", {.frame = 5}).instances[0].transform.translation, glm::ivec3(0, 0, 9));
  EXPECT_EQ(readVox(encodeVox(w), "h.vox", {.frame = 2}).instances[0].transform.translation, glm::ivec3(0, 0, 1));
}

TEST(VoxWritten, MaterialsAreReported) {
  VoxWriteFile w = twoModelFile();
  w.materials = {{3, {{"_type", "_emit"}, {"_emit", "0.5"}}}, {5, {{"_type", "_glass"}}}, {7, {{"_type", "_diffuse"}}}};
  VoxFile f = readVox(encodeVox(w), "m.vox");
  ASSERT_EQ(f.materials.size(), 3u);
  EXPECT_EQ(f.materials[0].type(), "emit");
  std::string notes;
  for (const std::string& n : f.notes) notes += n + "\n";
  EXPECT_TRUE(test::contains(notes, "emissive materials (palette 3)")) << notes;
  EXPECT_TRUE(test::contains(notes, "glass materials (palette 5)")) << notes;
}

// --- hostile files ------------------------------------------------------------------------------------

TEST(VoxBadInput, TruncatedAtEveryChunkBoundaryAndInside) {
  std::vector<std::uint8_t> good = encodeVox(twoModelFile());
  std::vector<std::size_t> cuts;
  rawModels(good, &cuts);
  ASSERT_GT(cuts.size(), 8u);
  for (std::size_t cut : cuts) {
    for (std::size_t c : {cut, cut + 5}) {
      if (c >= good.size()) continue;
      std::vector<std::uint8_t> t(good.begin(), good.begin() + std::ptrdiff_t(c));
      expectRefused(t, c < 8 ? "not a MagicaVoxel" : "truncated", "cut at " + std::to_string(c));
    }
  }
  // Every chunk's own sizes stay consistent when MAIN is patched to the shorter length: the chunk is named.
  for (std::size_t i = 2; i + 1 < cuts.size(); ++i) {
    std::vector<std::uint8_t> t(good.begin(), good.begin() + std::ptrdiff_t(cuts[i] + 14));
    std::uint32_t children = std::uint32_t(t.size() - 20);
    std::memcpy(&t[16], &children, 4);
    std::string id(reinterpret_cast<const char*>(&good[cuts[i]]), 4);
    expectRefused(t, id + " chunk at byte " + std::to_string(cuts[i]), "inner cut in " + id);
  }
}

std::vector<std::uint8_t> withSize(glm::ivec3 s) {
  VoxWriteFile w;
  w.models = {cube(1)};
  w.models[0].size = s;
  return encodeVox(w);
}

TEST(VoxBadInput, SizesCountsAndVoxels) {
  expectRefused(withSize({0, 1, 1}), "SIZE chunk at byte 20: model size 0 x 1 x 1 is outside 1..2048", "size 0");
  expectRefused(withSize({1, int(0x80000000u), 1}), "is outside 1..2048", "size 2^31");
  expectRefused(withSize({1, 1, 4096}), "is outside 1..2048", "size 4096");
  {
    std::vector<std::uint8_t> b = encodeVox(twoModelFile());
    std::int32_t huge = 1 << 30;
    // XYZI count of model 0 (SIZE at 20, XYZI at 44, count at 56).
    std::memcpy(&b[56], &huge, 4);
    expectRefused(b, "XYZI chunk at byte 44", "count");
    std::vector<std::uint8_t> c = encodeVox(twoModelFile());
    std::int32_t n = 9;  // 8 voxels written
    std::memcpy(&c[56], &n, 4);
    expectRefused(c, "the voxel count 9 is larger than the chunk", "count 9");
  }
  {
    VoxWriteFile w = twoModelFile();
    w.models[0].voxels[3].y = 2;
    expectRefused(encodeVox(w), "voxel 3 at (1, 2, 0) is outside the model size 2 x 2 x 2", "outside");
    w = twoModelFile();
    w.models[0].voxels[0].colorIndex = 0;
    expectRefused(encodeVox(w), "colour index 0", "index 0");
  }
  std::vector<std::uint8_t> junk = {'V', 'O', 'X', ' ', 200, 0, 0, 0, 'M', 'A', 'I', 'N', 0, 0, 0, 0, 0xff, 0xff, 0xff, 0x7f};
  expectRefused(junk, "MAIN chunk at byte 8: truncated", "huge MAIN");
}

TEST(VoxBadInput, SceneGraphs) {
  using K = VoxWriteNode::Kind;
  {
    VoxWriteFile w = twoModelFile();
    w.nodes[2].child = 0;  // transform "a" points back at the root
    expectRefused(encodeVox(w), "is its own ancestor (a cycle)", "cycle");
  }
  {
    VoxWriteFile w = twoModelFile();
    w.nodes[1].children.push_back(77);
    expectRefused(encodeVox(w), "child node 77 does not exist", "dangling");
  }
  {
    VoxWriteFile w = twoModelFile();
    w.nodes[3].models[0].first = 9;
    expectRefused(encodeVox(w), "model 9 does not exist", "missing model");
  }
  {
    VoxWriteFile w = twoModelFile();
    w.nodes[2].frames = {{{"_r", "15"}}};
    expectRefused(encodeVox(w), "not a valid packed rotation byte", "rotation");
    w.nodes[2].frames = {{{"_t", "1 2"}}};
    expectRefused(encodeVox(w), "translation", "translation");
  }
  {
    // A chain of 10,000 transforms.
    VoxWriteFile w;
    w.models = {cube(1)};
    for (int i = 0; i < 10000; ++i) {
      VoxWriteNode t;
      t.kind = K::Transform;
      t.id = i;
      t.child = i + 1;
      w.nodes.push_back(t);
    }
    VoxWriteNode s;
    s.kind = K::Shape;
    s.id = 10000;
    s.models.push_back({0, {}});
    w.nodes.push_back(s);
    expectRefused(encodeVox(w), "scene graph deeper than 256 nodes", "depth");
  }
  {
    // Shared subtrees doubling at every level: 2^40 paths.
    VoxWriteFile w;
    w.models = {cube(1)};
    for (int i = 0; i < 40; ++i) {
      VoxWriteNode g;
      g.kind = K::Group;
      g.id = i;
      g.children = {i + 1, i + 1};
      w.nodes.push_back(g);
    }
    VoxWriteNode s;
    s.kind = K::Shape;
    s.id = 40;
    s.models.push_back({0, {}});
    w.nodes.push_back(s);
    expectRefused(encodeVox(w), "more than", "blow-up");
  }
}

}  // namespace
}  // namespace vs

#include "voxel/demo_world.h"

namespace vs {
namespace {

TEST(VoxDemo, CratesAssetHasItsSceneGraph) {
  const auto dir = test::scratchDir("vox_demo");
  writeDemoWorld(dir);
  VoxFile f = readVoxFile((dir / "crates.vox").string());
  ASSERT_EQ(f.models.size(), 2u);
  ASSERT_EQ(f.instances.size(), 4u);
  EXPECT_TRUE(f.hasPaletteChunk);
  // "top": (3 0 7) over a nested transform _r 24 (rows (-1 0 0)(0 0 1)(0 1 0)), crate 5^3 with pivot (2 2 2):
  // local [-2,3]^3 -> x' = -x in [-3,2], y' = z, z' = y in [-2,3]; + (3 0 7): [0,5] x [-2,3] x [5,10],
  // resting on the two crates below (z in [0,5]).
  expectBox(f, f.instances[3], {0, 5, -3}, {5, 10, 2});
  EXPECT_EQ(f.instances[3].name, "top");
  VoxAsset a = buildVoxAsset(f);
  EXPECT_EQ(a.objects.size(), 2u);  // three crates share one object
}

}  // namespace
}  // namespace vs

// --- PACK animations (files of MagicaVoxel 0.98 and older) ----------------------------------------------

namespace vs {
namespace {

std::size_t occurrences(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + 1)) ++n;
  return n;
}

std::string joined(const std::vector<std::string>& notes) {
  std::string s;
  for (const std::string& n : notes) s += n + "\n";
  return s;
}

// Three poses of different sizes, so that the model shown can be told by its voxel count.
VoxWriteFile packFile() {
  VoxWriteFile w;
  w.version = 150;
  w.pack = 3;
  w.models = {cube(1, 2), cube(2, 3), cube(3, 4)};
  return w;
}

std::string refusal(const std::vector<std::uint8_t>& bytes, const std::string& name, const VoxReadOptions& options) {
  try {
    readVox(bytes, name, options);
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput);
    return e.what();
  }
  ADD_FAILURE() << "accepted";
  return "";
}

TEST(VoxPack, FramesAreShownOneAtATime) {
  const std::vector<std::uint8_t> bytes = encodeVox(packFile());
  VoxFile f = readVox(bytes, "rex.vox");
  EXPECT_FALSE(f.hasSceneGraph);
  EXPECT_TRUE(f.packFrames);
  EXPECT_EQ(f.packModels, 3);
  ASSERT_EQ(f.models.size(), 3u);
  ASSERT_EQ(f.instances.size(), 1u);  // not the three poses on top of each other
  EXPECT_EQ(f.instances[0].model, 0);
  EXPECT_TRUE(test::contains(joined(f.notes), "PACK animation: the 3 models are frames 0..2, frame 0 shown")) << joined(f.notes);
  EXPECT_FALSE(test::contains(joined(f.notes), "chunks skipped")) << joined(f.notes);

  VoxFile third = readVox(bytes, "rex.vox", {.frame = 2});
  ASSERT_EQ(third.instances.size(), 1u);
  EXPECT_EQ(third.instances[0].model, 2);
  EXPECT_TRUE(test::contains(joined(third.notes), "frame 2 shown")) << joined(third.notes);
  VoxAsset asset = buildVoxAsset(third);
  ASSERT_EQ(asset.placements.size(), 1u);
  ASSERT_EQ(asset.objects.size(), 1u);
  EXPECT_EQ(asset.objects[0].brickmap.solidCount(), 27u);
  EXPECT_TRUE(test::contains(joined(asset.notes), "frame 2 shown"));

  // From disk through loadVox and inspectVox, as scene files and `info` use them.
  const fs::path dir = test::scratchDir("vox_pack");
  writeVoxFile(dir / "rex.vox", packFile());
  VoxAsset second = loadVox((dir / "rex.vox").string(), {.frame = 1});
  ASSERT_EQ(second.objects.size(), 1u);
  EXPECT_EQ(second.objects[0].brickmap.solidCount(), 8u);
  VoxInfo info = inspectVox((dir / "rex.vox").string());
  EXPECT_TRUE(info.packFrames);
  EXPECT_EQ(info.frame, 0);
  ASSERT_EQ(info.instances.size(), 1u);
  EXPECT_EQ(info.models[0].instanceCount, 1);
  EXPECT_EQ(info.models[1].instanceCount, 0);

  // A frame the animation does not have is refused, naming the file once, the frame and the count.
  std::string e = refusal(bytes, "rex.vox", {.frame = 3});
  EXPECT_EQ(e.rfind("rex.vox: ", 0), 0u) << e;
  EXPECT_EQ(occurrences(e, "rex.vox"), 1u) << e;
  EXPECT_TRUE(test::contains(e, "frame 3 is beyond the 3 frames of its PACK animation (0..2)")) << e;
  e = refusal(bytes, "rex.vox", {.frame = -1});
  EXPECT_TRUE(test::contains(e, "rex.vox: frame -1 is outside 0..1000000")) << e;
}

TEST(VoxPack, ASceneGraphWinsOverPack) {
  VoxWriteFile w = twoModelFile();
  w.pack = 2;
  VoxFile f = readVox(encodeVox(w), "graph.vox");
  EXPECT_TRUE(f.hasSceneGraph);
  EXPECT_FALSE(f.packFrames);
  EXPECT_EQ(f.packModels, 2);
  EXPECT_EQ(f.instances.size(), 3u);  // the graph's three shapes, model 0 twice
  EXPECT_TRUE(test::contains(joined(f.notes), "chunks skipped: PACK x1")) << joined(f.notes);
  EXPECT_FALSE(test::contains(joined(f.notes), "PACK animation")) << joined(f.notes);
  // Frames are the graph's keyframes, not the models: a frame past the model count is fine.
  EXPECT_EQ(readVox(encodeVox(w), "graph.vox", {.frame = 7}).instances.size(), 3u);
  // Without PACK and without a graph every model is placed, as before.
  VoxWriteFile plain = packFile();
  plain.pack.reset();
  VoxFile p = readVox(encodeVox(plain), "plain.vox");
  EXPECT_FALSE(p.packFrames);
  EXPECT_EQ(p.instances.size(), 3u);
}

TEST(VoxPack, BadPackChunksAreRefused) {
  VoxWriteFile w = packFile();
  w.pack = 0;
  expectRefused(encodeVox(w), "PACK chunk at byte 20: model count 0 is not positive", "count 0");
  w.pack = 3;
  w.models.clear();
  expectRefused(encodeVox(w), "PACK chunk at byte 20: declares 3 models, the file has none", "no models");
  // A second PACK chunk: the first one (16 bytes at byte 20) twice.
  std::vector<std::uint8_t> b = encodeVox(packFile());
  b.insert(b.begin() + 36, b.begin() + 20, b.begin() + 36);
  std::uint32_t children = std::uint32_t(b.size() - 20);
  std::memcpy(&b[16], &children, 4);
  expectRefused(b, "PACK chunk at byte 36: a second PACK chunk", "two");
  // A count that disagrees with the models: the models are the frames, and the note says so.
  w = packFile();
  w.pack = 5;
  VoxFile f = readVox(encodeVox(w), "five.vox", {.frame = 2});
  EXPECT_EQ(f.instances.at(0).model, 2);
  EXPECT_TRUE(test::contains(joined(f.notes), "the PACK chunk declares 5 models")) << joined(f.notes);
}

// Chunk by chunk: MAIN's children are the given chunks.
std::vector<std::uint8_t> rawVox(const std::vector<std::pair<std::string, std::vector<std::int32_t>>>& chunks) {
  std::vector<std::uint8_t> b = {'V', 'O', 'X', ' ', 150, 0, 0, 0, 'M', 'A', 'I', 'N', 0, 0, 0, 0, 0, 0, 0, 0};
  auto put = [&b](std::int32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(std::uint32_t(v) >> (8 * i)));
  };
  for (const auto& [id, words] : chunks) {
    b.insert(b.end(), id.begin(), id.end());
    put(std::int32_t(4 * words.size()));
    put(0);
    for (std::int32_t w : words) put(w);
  }
  std::uint32_t children = std::uint32_t(b.size() - 20);
  std::memcpy(&b[16], &children, 4);
  return b;
}

TEST(VoxBadInput, EachMessageNamesTheFileOnce) {
  struct Case {
    std::vector<std::uint8_t> bytes;
    const char* fragment;
  } cases[] = {
      {rawVox({{"SIZE", {1, 1, 1}}}), "bad.vox: SIZE chunk at byte 20: no XYZI chunk follows it"},
      {rawVox({{"SIZE", {1, 1, 1}}, {"SIZE", {2, 2, 2}}}),
       "bad.vox: SIZE chunk at byte 44: a second SIZE without an XYZI chunk after the first (SIZE chunk at byte 20)"},
      {rawVox({{"XYZI", {0}}}), "bad.vox: XYZI chunk at byte 20: XYZI without a SIZE chunk"},
  };
  for (const Case& c : cases) {
    std::string e = refusal(c.bytes, "bad.vox", {});
    EXPECT_TRUE(test::contains(e, c.fragment)) << e;
    EXPECT_EQ(occurrences(e, "bad.vox"), 1u) << e;
  }
  // buildVoxAsset's own refusal gives the voxel size it was handed.
  try {
    buildVoxAsset(readVox(encodeVox(packFile()), "rex.vox"), {.voxelSize = -0.5});
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "rex.vox: voxel size must be a finite number greater than 0, not -0.5")) << e.what();
  }
}

}  // namespace
}  // namespace vs
