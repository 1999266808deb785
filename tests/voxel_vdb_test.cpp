// Loading .vdb files: solid rules against OpenVDB itself, world mapping, palettes and bad input.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"
#include "voxel/sanitizers.h"
#include "voxel/vdb_info.h"
#include "voxel/vdb_rules.h"
#include "voxel/voxel_object.h"

namespace fs = std::filesystem;

namespace {

// The rule of DESIGN.md §3, evaluated through OpenVDB's accessor: solid? and which material.
template <class GridT, class Rule>
void checkAgainstGrid(const GridT& grid, const vs::VoxelObject& obj, Rule rule) {
  auto acc = grid.getConstAccessor();
  const vs::Brickmap& bm = obj.brickmap;
  // Every brickmap voxel satisfies the rule with the right material.
  std::uint64_t seen = 0;
  bm.forEachSolid([&](glm::ivec3 v, std::uint8_t m) {
    int expected = rule(acc, openvdb::Coord(v.x, v.y, v.z));
    if (expected < 0 || expected != m) {
      ADD_FAILURE() << obj.file << " grid " << obj.gridIndex << ": brickmap voxel " << v.x << "," << v.y << ","
                    << v.z << " material " << int(m) << ", rule gives " << expected;
    }
    ++seen;
  });
  ASSERT_EQ(seen, bm.solidCount());
  // Every voxel that satisfies the rule is in the brickmap: exhaustive over the tree's bounds when small,
  // else every active voxel plus random samples.
  openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  if (grid.activeVoxelCount() == 0) return;
  box.expand(2);
  auto checkOne = [&](const openvdb::Coord& c) {
    int expected = rule(acc, c);
    glm::ivec3 v(c.x(), c.y(), c.z());
    if ((expected >= 0) != bm.isSolid(v) || (expected >= 0 && expected != bm.material(v))) {
      ADD_FAILURE() << obj.file << " grid " << obj.gridIndex << ": voxel " << v.x << "," << v.y << "," << v.z
                    << " rule " << expected << " brickmap " << bm.isSolid(v);
      return false;
    }
    return true;
  };
  std::uint64_t solid = 0;
  if (box.volume() <= 3000000) {
    for (auto it = box.begin(); it; ++it) {
      if (!checkOne(*it)) return;
      solid += rule(acc, *it) >= 0;
    }
    EXPECT_EQ(solid, bm.solidCount()) << obj.file;
  } else {
    for (auto it = grid.tree().cbeginValueOn(); it; ++it) {
      if (!it.isVoxelValue()) continue;
      if (!checkOne(it.getCoord())) return;
    }
    std::mt19937 rng(5);
    for (int i = 0; i < 1000000; ++i) {
      openvdb::Coord c(box.min().x() + int(rng() % unsigned(box.dim().x())),
                       box.min().y() + int(rng() % unsigned(box.dim().y())),
                       box.min().z() + int(rng() % unsigned(box.dim().z())));
      if (!checkOne(c)) return;
    }
  }
}

void roundTrip(const std::string& file, int index, const openvdb::GridBase::Ptr& grid) {
  vs::LoadOptions opt;
  opt.grid = std::to_string(index);
  vs::VoxelObject obj = vs::loadVdb(file, opt);
  ASSERT_EQ(obj.gridIndex, index);
  ASSERT_EQ(obj.gridName, grid->getName());
  obj.brickmap.checkConsistency();
  const bool levelSet = grid->getGridClass() == openvdb::GRID_LEVEL_SET;
  SCOPED_TRACE(file + " grid " + std::to_string(index) + " (" + grid->valueType() + ")");
  if (auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(grid)) {
    checkAgainstGrid(*g, obj, [&](auto& acc, const openvdb::Coord& c) {
      float v = acc.getValue(c);
      bool s = levelSet ? v < 0.0f : (acc.isValueOn(c) && v > 0.0f);
      return s ? 1 : -1;
    });
  } else if (auto g = openvdb::gridPtrCast<openvdb::DoubleGrid>(grid)) {
    checkAgainstGrid(*g, obj, [&](auto& acc, const openvdb::Coord& c) {
      double v = acc.getValue(c);
      return (levelSet ? v < 0.0 : (acc.isValueOn(c) && v > 0.0)) ? 1 : -1;
    });
  } else if (auto g = openvdb::gridPtrCast<openvdb::BoolGrid>(grid)) {
    checkAgainstGrid(*g, obj, [](auto& acc, const openvdb::Coord& c) { return acc.isValueOn(c) ? 1 : -1; });
  } else if (auto g = openvdb::gridPtrCast<openvdb::Int32Grid>(grid)) {
    checkAgainstGrid(*g, obj, [](auto& acc, const openvdb::Coord& c) {
      int v = acc.getValue(c);
      if (!acc.isValueOn(c) || v == 0) return -1;
      return 1 + (((v - 1) % 255) + 255) % 255;
    });
  } else if (auto g = openvdb::gridPtrCast<openvdb::Vec3SGrid>(grid)) {
    ASSERT_LE(obj.palette.size(), 256u);
    // Quantisation error is bounded by a fraction of the colours' extent (255 boxes over 3 channels).
    openvdb::Vec3f lo(1e30f), hi(-1e30f);
    for (auto it = g->cbeginValueOn(); it; ++it) {
      lo = openvdb::math::minComponent(lo, *it);
      hi = openvdb::math::maxComponent(hi, *it);
    }
    const float tol = 0.15f * std::max({hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z(), 1e-6f});
    checkAgainstGrid(*g, obj, [&](auto& acc, const openvdb::Coord& c) {
      if (!acc.isValueOn(c)) return -1;
      // With few colours the palette is exact: find the entry of this colour.
      openvdb::Vec3f col = acc.getValue(c);
      for (std::size_t i = 1; i < obj.palette.size(); ++i)
        if (obj.palette[i] == glm::vec3(col.x(), col.y(), col.z())) return int(i);
      // Quantised palette: the brickmap's entry must lie close to the voxel's colour.
      int got = obj.brickmap.material(glm::ivec3(c.x(), c.y(), c.z()));
      if (got < 1 || std::size_t(got) >= obj.palette.size()) return -2;
      float err = glm::length(obj.palette[std::size_t(got)] - glm::vec3(col.x(), col.y(), col.z()));
      if (err > tol) ADD_FAILURE() << "colour " << col << " entry " << got << " error " << err;
      return err <= tol ? got : -2;
    });
  } else {
    FAIL() << "grid type without a reference rule in this test";
  }
}

void roundTripFile(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  openvdb::io::Stream stream(in);  // file order, as the loader counts grids
  auto grids = stream.getGrids();
  ASSERT_FALSE(grids->empty()) << file;
  for (std::size_t i = 0; i < grids->size(); ++i) roundTrip(file, int(i), (*grids)[i]);
}

TEST(VdbLoad, ThirdPartyAssetsRoundTrip) {
  openvdb::initialize();
  int files = 0;
  for (const auto& e : fs::directory_iterator(vs::test::sharedAssets() / "vdb")) {
    if (e.path().extension() != ".vdb") continue;
    roundTripFile(e.path().string());
    ++files;
  }
  EXPECT_GE(files, 7);
}

TEST(VdbLoad, DemoWorldRoundTrip) {
  openvdb::initialize();
  auto dir = vs::test::scratchDir("voxel_demo_world");
  auto written = vs::writeDemoWorld(dir);
  ASSERT_GE(written.size(), 5u);
  EXPECT_EQ(fs::path(written.back()).filename(), "demo.json");
  std::ifstream scene(written.back());
  std::string text((std::istreambuf_iterator<char>(scene)), std::istreambuf_iterator<char>());
  for (const char* k : {"\"version\": 1", "directional", "spot", "point", "rotate_deg", "scale", "camera", "ambient"})
    EXPECT_NE(text.find(k), std::string::npos) << k;
  std::uint64_t total = 0;
  for (std::size_t i = 0; i + 1 < written.size(); ++i) {
    if (fs::path(written[i]).extension() != ".vdb") continue;  // the demo's .vox asset: voxel_vox_test
    roundTripFile(written[i]);
    total += vs::loadVdb(written[i]).brickmap.solidCount();
  }
  EXPECT_LT(total, 2000000u);
  // The blob is a level set: solid at its centre (index (0, 12, 0): centre (0, 6, 0) at voxel size 0.5).
  vs::VoxelObject blob = vs::loadVdb((dir / "blob.vdb").string());
  EXPECT_EQ(blob.gridClass, "level set");
  EXPECT_TRUE(blob.brickmap.isSolid(glm::ivec3(0, 12, 0)));
}

TEST(VdbLoad, LevelSetInteriorIsFilled) {
  openvdb::initialize();
  vs::VoxelObject ls = vs::loadVdb((vs::test::sharedAssets() / "vdb" / "gaffer_levelset_sphere.vdb").string());
  EXPECT_EQ(ls.gridClass, "level set");
  vs::VoxelBox b = ls.brickmap.bounds();
  ASSERT_FALSE(b.empty());
  glm::ivec3 centre = (b.min + b.max) / 2;
  EXPECT_TRUE(ls.brickmap.isSolid(centre));
  // Far more voxels than the narrow band's interior half: the inside is filled.
  auto file = vs::test::scratchDir("voxel_ls") / "sphere.vdb";
  auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(20.0f, openvdb::Vec3f(1, 2, 3), 1.0f);
  openvdb::io::File(file.string()).write({sphere});
  vs::VoxelObject gen = vs::loadVdb(file.string());
  EXPECT_TRUE(gen.brickmap.isSolid(glm::ivec3(1, 2, 3)));
  double volume = 4.0 / 3.0 * 3.14159265 * 20 * 20 * 20;
  EXPECT_NEAR(double(gen.brickmap.solidCount()), volume, volume * 0.05);
}

void checkMapping(const openvdb::math::Transform::Ptr& t, const std::string& name) {
  auto grid = openvdb::BoolGrid::create(false);
  grid->setTransform(t);
  grid->setName("mask");
  std::vector<openvdb::Coord> coords{{0, 0, 0}, {3, -7, 11}, {-40, 25, 9}};
  for (auto c : coords) grid->tree().setValueOn(c, true);
  auto file = vs::test::scratchDir("voxel_map_" + name) / "m.vdb";
  openvdb::io::File(file.string()).write({grid});
  vs::VoxelObject obj = vs::loadVdb(file.string());
  for (auto c : coords) {
    glm::ivec3 v(c.x(), c.y(), c.z());
    ASSERT_TRUE(obj.brickmap.isSolid(v));
    for (int corner = 0; corner < 8; ++corner) {
      glm::dvec3 off(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
      glm::dvec4 w = obj.brickToObject * glm::dvec4(glm::dvec3(v) + off, 1.0);
      openvdb::Vec3d ref = t->indexToWorld(openvdb::Vec3d(c.x() - 0.5 + off.x, c.y() - 0.5 + off.y, c.z() - 0.5 + off.z));
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(w[a], ref[a], 1e-9) << name << " corner " << corner;
    }
  }
}

TEST(VdbLoad, WorldMappingMatchesOpenVdb) {
  openvdb::initialize();
  checkMapping(openvdb::math::Transform::createLinearTransform(0.05), "scale");
  auto translated = openvdb::math::Transform::createLinearTransform(0.25);
  translated->postTranslate(openvdb::Vec3d(10.5, -3.25, 7.0));
  checkMapping(translated, "translate");
  openvdb::Mat4d m(0.9, 0.2, -0.1, 0.0,   // rotated and sheared, row-vector convention
                   -0.3, 0.8, 0.25, 0.0,  //
                   0.1, 0.15, 1.2, 0.0,   //
                   4.0, -2.0, 1.5, 1.0);
  checkMapping(openvdb::math::Transform::createLinearTransform(m), "affine");
}

void expectBadInput(const std::function<void()>& fn, const std::vector<std::string>& mentions) {
  try {
    fn();
    ADD_FAILURE() << "expected vs::Error";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput) << e.what();
    for (const auto& m : mentions) EXPECT_NE(std::string(e.what()).find(m), std::string::npos) << e.what() << " lacks " << m;
  }
}

TEST(VdbLoad, BadInputGivesClearErrors) {
  auto dir = vs::test::scratchDir("voxel_bad");
  std::string missing = (dir / "missing.vdb").string();
  expectBadInput([&] { vs::loadVdb(missing); }, {missing});
  std::string garbage = (dir / "garbage.vdb").string();
  std::ofstream(garbage) << "this is not a vdb file at all, just some text that goes on for a while\n";
  expectBadInput([&] { vs::loadVdb(garbage); }, {garbage});
  std::string fog = (vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string();
  vs::LoadOptions named;
  named.grid = "no_such_grid";
  expectBadInput([&] { vs::loadVdb(fog, named); }, {fog, "no_such_grid"});
  vs::LoadOptions index;
  index.grid = "7";
  expectBadInput([&] { vs::loadVdb(fog, index); }, {fog, "7", "density"});
  std::string truncated = (vs::test::sharedAssets() / "vdb" / "damaged" / "truncated.vdb").string();
  expectBadInput([&] { vs::loadVdb(truncated); }, {truncated});
  expectBadInput([&] { vs::inspectVdb(truncated); }, {truncated});
}

TEST(VdbLoad, DamagedFilesNeverCrash) {
  int handled = 0;
  for (const auto& e : fs::directory_iterator(vs::test::sharedAssets() / "vdb" / "damaged")) {
    std::string file = e.path().string();
    try {
      vs::VoxelObject obj = vs::loadVdb(file);
      obj.brickmap.checkConsistency();
      // Whatever loads is small: the hostile bounds live only in metadata.
      EXPECT_LT(obj.brickmap.memory().regionTableBytes, 1u << 20) << file;
      std::printf("%s: loaded, %llu solid voxels\n", e.path().filename().c_str(),
                  (unsigned long long)obj.brickmap.solidCount());
    } catch (const vs::Error& err) {
      EXPECT_EQ(err.kind(), vs::ErrorKind::BadInput);
      EXPECT_NE(std::string(err.what()).find(file), std::string::npos) << err.what();
      std::printf("%s: %s\n", e.path().filename().c_str(), err.what());
    }
    ++handled;
  }
  EXPECT_EQ(handled, 7);
}

TEST(VdbLoad, IntegerPaletteAndColourGrids) {
  openvdb::initialize();
  auto dir = vs::test::scratchDir("voxel_palette");
  auto ig = openvdb::Int32Grid::create(0);
  ig->setName("material");
  ig->tree().setValueOn({0, 0, 0}, 1);
  ig->tree().setValueOn({1, 0, 0}, 7);
  ig->tree().setValueOn({2, 0, 0}, 256);  // wraps to 1
  ig->tree().setValueOn({3, 0, 0}, -1);   // 1 + (-2 mod 255) = 254
  ig->tree().setValueOn({4, 0, 0}, 0);    // active but 0: empty
  ig->tree().setValueOff({5, 0, 0}, 9);   // inactive: empty
  auto cg = openvdb::Vec3SGrid::create();
  cg->setName("Cd");
  cg->tree().setValueOn({0, 0, 0}, openvdb::Vec3f(1, 0, 0));
  cg->tree().setValueOn({0, 1, 0}, openvdb::Vec3f(0, 0.5f, 0));
  cg->tree().setValueOn({0, 2, 0}, openvdb::Vec3f(1, 0, 0));
  auto file = (dir / "p.vdb").string();
  openvdb::io::File(file).write({ig, cg});

  vs::LoadOptions opt;
  opt.color = glm::vec3(0.1f, 0.2f, 0.3f);
  vs::VoxelObject first = vs::loadVdb(file, opt);
  // Both grids have a rule: the first in file order ("material", written first; io::File and a delay-loading
  // io::Stream list "Cd" first, sorted by name).
  EXPECT_EQ(first.gridName, ig->getName());
  EXPECT_FALSE(first.selectionNote.empty());
  opt.grid = "material";
  vs::VoxelObject io = vs::loadVdb(file, opt);
  EXPECT_EQ(io.gridName, "material");
  ASSERT_EQ(io.palette.size(), 256u);
  EXPECT_EQ(io.palette[1], opt.color);
  EXPECT_NE(io.palette[2], io.palette[3]);
  EXPECT_EQ(io.brickmap.material({0, 0, 0}), 1);
  EXPECT_EQ(io.brickmap.material({1, 0, 0}), 7);
  EXPECT_EQ(io.brickmap.material({2, 0, 0}), 1);
  EXPECT_EQ(io.brickmap.material({3, 0, 0}), 254);
  EXPECT_FALSE(io.brickmap.isSolid({4, 0, 0}));
  EXPECT_FALSE(io.brickmap.isSolid({5, 0, 0}));
  EXPECT_EQ(io.brickmap.solidCount(), 4u);

  opt.grid = "Cd";
  vs::VoxelObject co = vs::loadVdb(file, opt);
  EXPECT_TRUE(co.selectionNote.empty());
  ASSERT_EQ(co.palette.size(), 3u);  // entry 0 + two distinct colours, exact
  EXPECT_EQ(co.palette[co.brickmap.material({0, 0, 0})], glm::vec3(1, 0, 0));
  EXPECT_EQ(co.palette[co.brickmap.material({0, 1, 0})], glm::vec3(0, 0.5f, 0));
  EXPECT_EQ(co.brickmap.material({0, 2, 0}), co.brickmap.material({0, 0, 0}));

  // Many colours are quantised into at most 255 entries, each voxel near its colour.
  auto many = openvdb::Vec3SGrid::create();
  for (int i = 0; i < 2000; ++i)
    many->tree().setValueOn({i % 40, i / 40, 0}, openvdb::Vec3f(float(i % 13) / 12, float(i % 17) / 16, float(i % 7) / 6));
  auto mfile = (dir / "many.vdb").string();
  openvdb::io::File(mfile).write({many});
  vs::VoxelObject mo = vs::loadVdb(mfile);
  EXPECT_LE(mo.palette.size(), 256u);
  EXPECT_EQ(mo.brickmap.solidCount(), 2000u);
  for (int i = 0; i < 2000; ++i) {
    glm::vec3 want(float(i % 13) / 12, float(i % 17) / 16, float(i % 7) / 6);
    glm::vec3 got = mo.palette[mo.brickmap.material({i % 40, i / 40, 0})];
    EXPECT_LT(glm::length(got - want), 0.35f) << i;
  }

  // inspectVdb lists both grids with their rules and costs.
  auto infos = vs::inspectVdb(file);
  ASSERT_EQ(infos.size(), 2u);
  EXPECT_TRUE(infos[0].hasSolidRule);
  const auto& intInfo = infos[0].name == "material" ? infos[0] : infos[1];
  const auto& cdInfo = infos[0].name == "material" ? infos[1] : infos[0];
  EXPECT_EQ(intInfo.solidVoxelCount, 4u);
  EXPECT_EQ(intInfo.activeVoxelCount, 5u);
  EXPECT_EQ(cdInfo.solidVoxelCount, 3u);
  EXPECT_GT(infos[0].openvdbTreeBytes, 0u);
  EXPECT_GT(infos[0].bytesPerSolidVoxel, 0.0);
}

TEST(VdbLoad, NonLinearTransformIsRefused) {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("frustum_mask");
  grid->tree().setValueOn({1, 1, 1}, true);
  openvdb::BBoxd bbox(openvdb::Vec3d(0), openvdb::Vec3d(10));
  grid->setTransform(openvdb::math::Transform::createFrustumTransform(bbox, 0.5, 2.0, 1.0));
  auto file = (vs::test::scratchDir("voxel_frustum") / "f.vdb").string();
  openvdb::io::File(file).write({grid});
  expectBadInput([&] { vs::loadVdb(file); }, {file, "frustum_mask", "non-linear"});
}

}  // namespace

// Reading a .vdb (good or damaged) makes no temporary copy of it: OpenVDB's delayed loading from a stream
// copies the whole input to openvdb_temp_* files (and keeps them when reading fails). With the temporary
// directory pointing nowhere, such a copy would fail the load of every good file.
TEST(VdbLoad, ReadingMakesNoTemporaryCopies) {
  const fs::path tmp = vs::test::scratchDir("vdb_no_temp_copies");
  const fs::path nowhere = tmp / "missing";
  const char* old = std::getenv("TMPDIR");
  const std::string saved = old ? old : "";
  ::setenv("TMPDIR", nowhere.c_str(), 1);
  ::setenv("OPENVDB_TEMP_DIR", nowhere.c_str(), 1);
  int loaded = 0, refused = 0;
  for (const auto& e : fs::directory_iterator(vs::test::sharedAssets() / "vdb")) {
    if (!e.is_regular_file()) continue;
    EXPECT_NO_THROW((void)vs::loadVdb(e.path().string())) << e.path();
    ++loaded;
  }
  for (const auto& e : fs::directory_iterator(vs::test::sharedAssets() / "vdb" / "damaged")) {
    ::setenv("OPENVDB_TEMP_DIR", tmp.c_str(), 1);
    try {
      (void)vs::loadVdb(e.path().string());
    } catch (const vs::Error&) {
      ++refused;
    }
  }
  if (old) ::setenv("TMPDIR", saved.c_str(), 1);
  else ::unsetenv("TMPDIR");
  ::unsetenv("OPENVDB_TEMP_DIR");
  EXPECT_EQ(loaded, 7);
  EXPECT_GE(refused, 1);
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(tmp)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{}) << "temporary copies of damaged files were left behind";
}

// OpenVDB 10's reader itself overruns a heap buffer on this mutated file (io::bloscFromStream copies a
// block length read from the file into the value buffer unchecked): the process would die inside OpenVDB.
// The file is parsed in a child process first, whose death becomes a clear error; the CLI exits 2.
TEST(VdbLoad, ReaderCrashInsideOpenVdbIsAClearError) {
  const std::string file =
      (fs::path(VOXSHADOW_SOURCE_DIR) / "tests/fuzz/regressions/vdb/crash-blosc-uncompressed-length.vdb").string();
  ASSERT_TRUE(fs::is_regular_file(file)) << file;
  const std::vector<std::string> mentions{file, "damaged VDB file", "grid 0 'voxel_fog_density'", "not loaded"};
  expectBadInput([&] { vs::loadVdb(file); }, mentions);
  expectBadInput([&] { vs::inspectVdb(file); }, mentions);
  // The process that checked the file is gone and the next good file loads as before.
  EXPECT_GT(vs::loadVdb((vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string()).brickmap.solidCount(), 0u);
  std::string out;
  EXPECT_EQ(vs::test::runCli("info " + vs::test::quote(file), out), 2) << out;
  EXPECT_TRUE(vs::test::contains(out, file + ": damaged VDB file")) << out;
  EXPECT_FALSE(vs::test::contains(out, "[0]")) << "partial output: " << out;
}

// Without the checking process (trusted files) every asset loads to the same object as with it.
TEST(VdbLoad, InProcessReadingMatchesCheckedReading) {
  vs::LoadOptions trusted;
  trusted.checkInChildProcess = false;
  int compared = 0;
  for (const auto& e : fs::directory_iterator(vs::test::sharedAssets() / "vdb")) {
    if (!e.is_regular_file() || e.file_size() > 1000000) continue;
    const vs::VoxelObject checked = vs::loadVdb(e.path().string());
    const vs::VoxelObject direct = vs::loadVdb(e.path().string(), trusted);
    EXPECT_EQ(checked.gridName, direct.gridName) << e.path();
    EXPECT_EQ(checked.brickmap.solidCount(), direct.brickmap.solidCount()) << e.path();
    EXPECT_EQ(checked.palette, direct.palette) << e.path();
    ++compared;
  }
  EXPECT_GE(compared, 4);
}

// A .vdb cut short anywhere is refused, promptly: OpenVDB alone reads on past the end (a partial grid, a loop
// over a garbage count, a string sized from an unset length).
TEST(VdbLoad, TruncatedFilesAreRefused) {
  const fs::path dir = vs::test::scratchDir("vdb_truncated");
  for (const char* name : {"oiio_fog_sphere.vdb", "oiio_fog_sphere_Cd.vdb", "gaffer_levelset_sphere.vdb",
                           "arnold_fog_torus.vdb"}) {
    const fs::path source = vs::test::sharedAssets() / "vdb" / name;
    std::ifstream in(source, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_GT(bytes.size(), 4096u) << source;
    for (std::size_t cut : {std::size_t(100), std::size_t(1000), std::size_t(65536), bytes.size() / 2, bytes.size() - 1}) {
      if (cut >= bytes.size()) continue;
      SCOPED_TRACE(std::string(name) + " cut to " + std::to_string(cut));
      const fs::path file = dir / "cut.vdb";
      std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(cut));
      auto t0 = std::chrono::steady_clock::now();
      try {
        (void)vs::loadVdb(file.string());
        ADD_FAILURE() << "a truncated file loaded";
      } catch (const vs::Error& e) {
        EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput);
        EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
      }
      EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10.0);
    }
  }
}

namespace {

std::string readBytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeBytes(const fs::path& file, const std::string& bytes) {
  std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
}

// The bytes with the byte at `offset` from the start of `pattern`'s one occurrence set to `value`.
std::string patched(const std::string& bytes, const std::string& pattern, std::size_t offset, char value) {
  const std::size_t at = bytes.find(pattern);
  EXPECT_NE(at, std::string::npos) << "pattern not found";
  EXPECT_EQ(bytes.find(pattern, at + 1), std::string::npos) << "pattern found twice";
  if (at == std::string::npos) return bytes;
  std::string out = bytes;
  out[at + offset] = value;
  return out;
}

std::string int32Bytes(std::int32_t v) {
  std::string s(4, '\0');
  std::memcpy(s.data(), &v, 4);
  return s;
}


// The error of loading `file`: the same with and without the checking process, and from inspectVdb.
std::string refusalOf(const std::string& file) {
  std::string checked, direct, inspected;
  try {
    (void)vs::loadVdb(file);
    ADD_FAILURE() << file << " loaded";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput) << e.what();
    checked = e.what();
  }
  vs::LoadOptions trusted;
  trusted.checkInChildProcess = false;
  try {
    (void)vs::loadVdb(file, trusted);
    ADD_FAILURE() << file << " loaded without the checking process";
  } catch (const vs::Error& e) {
    direct = e.what();
  }
  try {
    (void)vs::inspectVdb(file);
    ADD_FAILURE() << file << " inspected";
  } catch (const vs::Error& e) {
    inspected = e.what();
  }
  EXPECT_EQ(checked, direct);
  EXPECT_EQ(checked, inspected);
  return checked;
}

// A file holding a bool (tile value, active flag, metadata) that is neither 0 nor 1 is refused with `message`. In the
// sanitized build this binary holds instrumented copies of OpenVDB's tree reading (header templates, which
// libopenvdb.so then calls too): OpenVDB copies the bool while reading it, and UBSan ends the checking
// process before the loader's check can run. The file is refused as damaged all the same, naming the grid;
// only the checked path is taken there (reading in this process would end the test).
void expectDamagedBool(const std::string& file, const std::string& grid, const std::string& message) {
  if (!vs::kAddressSanitized) {
    EXPECT_EQ(refusalOf(file), message);
    return;
  }
  try {
    (void)vs::loadVdb(file);
    ADD_FAILURE() << file << " loaded";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput) << e.what();
    const std::string died = file + ": damaged VDB file: OpenVDB's reader failed on grid 0 '" + grid +
                             "' (it exited with status 99 in a checking process); the file was not loaded";
    if (e.what() != message) {
      EXPECT_EQ(e.what(), died);
    }
  }
}

}  // namespace

// OpenVDB copies a bool tile value from the file into a bool without checking it: in this mutated file a
// bool grid's tile value (in an internal node) is the byte 2, which the loader's voxel count then loaded as a
// bool, undefined behaviour that UBSan reported in the vdb fuzz target. The file is refused as damaged before
// anything of the loader reads the value.
TEST(VdbLoad, BoolTileValueThatIsNotZeroOrOneIsRefused) {
  const std::string file =
      (fs::path(VOXSHADOW_SOURCE_DIR) / "tests/fuzz/regressions/vdb/ubsan-bool-tile-value.vdb").string();
  ASSERT_TRUE(fs::is_regular_file(file)) << file;
  expectDamagedBool(file, "b", file + ": damaged VDB file: grid 0 'b' has a tile value at (24, 120, 56) stored as the "
                                      "byte 2, not a bool (0 or 1)");
  std::string out;
  EXPECT_EQ(vs::test::runCli("info " + vs::test::quote(file), out), 2) << out;
  EXPECT_TRUE(vs::test::contains(out, file + ": damaged VDB file: ")) << out;
  EXPECT_TRUE(vs::test::contains(out, "grid 0 'b'")) << out;
}

// Every other bool OpenVDB copies from a file unchecked is read as a byte too: an internal node's tile value,
// a root tile's active flag (any grid type) and bool metadata. Each file loads before one byte is changed.
TEST(VdbLoad, EveryStoredBoolIsCheckedAsAByte) {
  openvdb::initialize();
  const fs::path dir = vs::test::scratchDir("vdb_stored_bools");

  // Tiles of 8^3 voxels in an internal node, at table offsets 0, 3 and 7: written uncompressed, the node's
  // values hold 1 0 0 1 0 0 0 1.
  auto mask = openvdb::BoolGrid::create(false);
  mask->setName("mask");
  for (int z : {0, 24, 56}) mask->tree().addTile(1, openvdb::Coord(0, 0, z), true, true);
  const fs::path maskFile = dir / "mask.vdb";
  {
    openvdb::io::File out(maskFile.string());
    out.setCompression(openvdb::io::COMPRESS_NONE);
    out.write({mask});
  }
  EXPECT_EQ(vs::loadVdb(maskFile.string()).brickmap.solidCount(), 3u * 512u);
  const std::string maskBytes = readBytes(maskFile);
  writeBytes(maskFile, patched(maskBytes, std::string("\1\0\0\1\0\0\0\1", 8), 3, '\2'));
  expectDamagedBool(maskFile.string(), "mask",
                   maskFile.string() + ": damaged VDB file: grid 0 'mask' has a tile value at (0, 0, 24) stored as "
                                       "the byte 2, not a bool (0 or 1)");

  // An inactive root tile of a fog grid: coordinates, value 0.5, active flag 0.
  auto fog = openvdb::FloatGrid::create(0.0f);
  fog->setName("density");
  fog->tree().setValueOn(openvdb::Coord(1, 2, 3), 1.0f);
  fog->tree().addTile(3, openvdb::Coord(8192, 0, 0), 0.5f, false);
  const fs::path fogFile = dir / "fog.vdb";
  openvdb::io::File(fogFile.string()).write({fog});
  EXPECT_EQ(vs::loadVdb(fogFile.string()).brickmap.solidCount(), 1u);
  const float half = 0.5f;
  std::string tile = int32Bytes(8192) + int32Bytes(0) + int32Bytes(0) + std::string(4, '\0') + std::string(1, '\0');
  std::memcpy(tile.data() + 12, &half, 4);
  writeBytes(fogFile, patched(readBytes(fogFile), tile, 16, '\3'));
  expectDamagedBool(fogFile.string(), "density",
                   fogFile.string() + ": damaged VDB file: grid 0 'density' has a tile at (8192, 0, 0) whose active "
                                      "flag is stored as the byte 3, not a bool (0 or 1)");

  // Bool metadata: name, type name "bool", size 1, the byte.
  auto meta = openvdb::BoolGrid::create(false);
  meta->setName("flagged");
  meta->tree().setValueOn(openvdb::Coord(0, 0, 0), true);
  meta->insertMeta("is_flagged", openvdb::BoolMetadata(true));
  const fs::path metaFile = dir / "meta.vdb";
  openvdb::io::File(metaFile.string()).write({meta});
  EXPECT_EQ(vs::loadVdb(metaFile.string()).brickmap.solidCount(), 1u);
  const std::string record = "is_flagged" + int32Bytes(4) + "bool" + int32Bytes(1) + "\1";
  writeBytes(metaFile, patched(readBytes(metaFile), record, record.size() - 1, '\xff'));
  expectDamagedBool(metaFile.string(), "flagged", metaFile.string() + ": damaged VDB file: grid 0 'flagged' has the metadata 'is_flagged' stored as "
                                       "the byte 255, not a bool (0 or 1)");
}

namespace {

// The outcome of loading a file: its grid and solid count, or its error message.
std::string outcomeOf(const std::string& file, const vs::LoadOptions& options = {}) {
  try {
    const vs::VoxelObject obj = vs::loadVdb(file, options);
    return "loaded " + obj.gridName + " " + std::to_string(obj.brickmap.solidCount());
  } catch (const vs::Error& e) {
    return std::string(e.kind() == vs::ErrorKind::BadInput ? "bad input: " : "runtime: ") + e.what();
  }
}

std::vector<pid_t> childrenOfThisThread() {
  std::ifstream in("/proc/self/task/" + std::to_string(::gettid()) + "/children");
  std::vector<pid_t> out;
  for (pid_t pid; in >> pid;) out.push_back(pid);
  return out;
}

}  // namespace

// One long-lived checking process (as the CLI and the fuzz target use) gives every file the verdict and message
// a fork per file gives, a file on which OpenVDB's reader crashes included; it is forked when turned on,
// outlives the readers that crash (it forks one per file and parses nothing itself) and keeps one thread, so
// that its forks never copy a lock held by another thread; one killed between two files is replaced without
// blaming the next; turning it off ends and reaps it.
// The crash file overruns a heap buffer inside OpenVDB: which signal ends the checking process (SIGSEGV, or
// SIGABRT from malloc's checks) depends on what the overrun hits, so verdicts are compared without it.
static std::string withoutSignal(std::string text) {
  const std::string marker = "(it crashed with SIG";
  if (std::size_t at = text.find(marker); at != std::string::npos) {
    const std::size_t end = text.find(' ', at + marker.size());
    text.replace(at, end - at, "(it crashed with a signal");
  }
  return text;
}

TEST(VdbLoad, PersistentCheckingProcessGivesTheSameVerdicts) {
  std::vector<std::string> files;
  for (const fs::path& dir : {vs::test::sharedAssets() / "vdb", vs::test::sharedAssets() / "vdb" / "damaged",
                              fs::path(VOXSHADOW_SOURCE_DIR) / "tests/fuzz/regressions/vdb",
                              fs::path(VOXSHADOW_SOURCE_DIR) / "tests/fuzz/seeds/vdb"})
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file() && e.file_size() < 1000000) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  const std::string crash =
      (fs::path(VOXSHADOW_SOURCE_DIR) / "tests/fuzz/regressions/vdb/crash-blosc-uncompressed-length.vdb").string();
  const std::string good = (vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string();
  // The crash twice more, between good files: each time the next check needs a new process.
  files.insert(files.end(), {good, crash, good, crash, crash, good});
  std::vector<std::string> forked;
  for (const std::string& f : files) forked.push_back(outcomeOf(f));
  ASSERT_TRUE(childrenOfThisThread().empty());

  vs::setPersistentCheckingProcess(true);
  const std::vector<pid_t> started = childrenOfThisThread();
  ASSERT_EQ(started.size(), 1u) << "the checking process starts when turned on";
  int crashes = 0;
  for (std::size_t i = 0; i < files.size(); ++i) {
    const std::string got = outcomeOf(files[i]);
    EXPECT_EQ(withoutSignal(got), withoutSignal(forked[i])) << files[i];
    if (files[i] == crash) {
      ++crashes;
      EXPECT_TRUE(vs::test::contains(got, crash + ": damaged VDB file: OpenVDB's reader failed on grid 0 "
                                                   "'voxel_fog_density' (")) << got;
    }
  }
  EXPECT_EQ(crashes, 4);
  const std::vector<pid_t> children = childrenOfThisThread();
  ASSERT_EQ(children.size(), 1u) << "one checking process, alive between files";
  EXPECT_EQ(children[0], started[0]) << "a reader's crash does not end the checking process";
  {
    std::ifstream status("/proc/" + std::to_string(children[0]) + "/status");
    std::string text((std::istreambuf_iterator<char>(status)), std::istreambuf_iterator<char>());
    EXPECT_TRUE(vs::test::contains(text, "\nThreads:\t1\n")) << text;
  }
  // Killed while idle: the next file is checked by a new process, not refused.
  ASSERT_EQ(::kill(children[0], SIGKILL), 0);
  for (int i = 0; i < 200 && fs::exists("/proc/" + std::to_string(children[0]) + "/status"); ++i) {
    std::ifstream status("/proc/" + std::to_string(children[0]) + "/status");
    std::string text((std::istreambuf_iterator<char>(status)), std::istreambuf_iterator<char>());
    if (vs::test::contains(text, "State:\tZ")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(outcomeOf(good), forked[files.size() - 1]);
  const std::vector<pid_t> after = childrenOfThisThread();
  ASSERT_EQ(after.size(), 1u);
  EXPECT_NE(after[0], children[0]);
  // Without the checking process at all the file is still read, in this process.
  vs::LoadOptions trusted;
  trusted.checkInChildProcess = false;
  EXPECT_EQ(outcomeOf(good, trusted), forked[files.size() - 1]);

  vs::setPersistentCheckingProcess(false);
  EXPECT_TRUE(childrenOfThisThread().empty());
  errno = 0;
  EXPECT_EQ(::waitpid(-1, nullptr, WNOHANG), -1) << "a checking process was left unreaped";
  EXPECT_EQ(errno, ECHILD);
  // Back to a fork per file, which leaves no process behind.
  EXPECT_EQ(withoutSignal(outcomeOf(crash)), withoutSignal(forked[files.size() - 2]));
  EXPECT_TRUE(childrenOfThisThread().empty());
}

// The voxel limit refuses a grid with more solid voxels than it allows, naming it, before extracting any;
// a grid at the limit loads.
TEST(VdbLoad, SolidVoxelLimitRefusesLargerGrids) {
  openvdb::initialize();
  auto mask = openvdb::BoolGrid::create(false);
  mask->setName("block");
  mask->tree().addTile(1, openvdb::Coord(0, 0, 0), true, true);  // 8^3 voxels
  mask->tree().setValueOn(openvdb::Coord(100, 0, 0), true);
  const fs::path file = vs::test::scratchDir("vdb_voxel_limit") / "block.vdb";
  openvdb::io::File(file.string()).write({mask});
  vs::LoadOptions options;
  EXPECT_EQ(vs::loadVdb(file.string(), options).brickmap.solidCount(), 513u);
  options.maxSolidVoxels = 513;
  EXPECT_EQ(vs::loadVdb(file.string(), options).brickmap.solidCount(), 513u);
  options.maxSolidVoxels = 512;
  expectBadInput([&] { vs::loadVdb(file.string(), options); },
                 {file.string() + ": grid 'block' has more than 512 solid voxels, more than the loader accepts"});
  const auto infos = vs::inspectVdb(file.string(), options);
  ASSERT_EQ(infos.size(), 1u);
  EXPECT_TRUE(vs::test::contains(infos[0].error, "more than 512 solid voxels")) << infos[0].error;
}

// The brickmap's region table has one slot per 128^3 region of the bounds, 2^24 at most: a grid whose bounds
// need more is refused by the loader before any voxel is extracted, also where each axis alone is within the
// limit and the product of the three does not fit in 64 bits (2^21 + 1 regions each, from a fuzzed file).
TEST(VdbLoad, BoundsBeyondTheRegionTableAreRefusedBeforeExtraction) {
  openvdb::initialize();
  const fs::path dir = vs::test::scratchDir("vdb_region_table");
  auto check = [&](int far, const std::string& name) {
    auto mask = openvdb::BoolGrid::create(false);
    mask->setName(name);
    mask->tree().setValueOn(openvdb::Coord(0, 0, 0), true);
    mask->tree().setValueOn(openvdb::Coord(far, far, far), true);
    const fs::path file = dir / (name + ".vdb");
    openvdb::io::File(file.string()).write({mask});
    expectBadInput([&] { vs::loadVdb(file.string()); },
                   {file.string() + ": grid '" + name + "' has index bounds too large for a brickmap (its region "
                                                        "table would need more than 16777216 slots)"});
  };
  check(256 * 128, "just_over");  // 257^3 slots
  check(1 << 28, "overflowing");  // (2^21 + 1)^3 slots
  // 256^3 slots fit: the grid loads.
  auto mask = openvdb::BoolGrid::create(false);
  mask->tree().setValueOn(openvdb::Coord(0, 0, 0), true);
  mask->tree().setValueOn(openvdb::Coord(256 * 128 - 1, 256 * 128 - 1, 256 * 128 - 1), true);
  const fs::path file = dir / "fits.vdb";
  openvdb::io::File(file.string()).write({mask});
  EXPECT_EQ(vs::loadVdb(file.string()).brickmap.solidCount(), 2u);
  // A caller's lower limit is honoured with the same message; one above the brickmap's own means that one.
  vs::LoadOptions lowered;
  lowered.maxRegionSlots = 256 * 256 * 256 - 1;
  expectBadInput([&] { vs::loadVdb(file.string(), lowered); },
                 {file.string() + ": ", "has index bounds too large for a brickmap (its region table would need "
                                         "more than 16777215 slots)"});
  vs::LoadOptions raised;
  raised.maxRegionSlots = std::int64_t(1) << 40;
  EXPECT_EQ(vs::loadVdb(file.string(), raised).brickmap.solidCount(), 2u);
  const fs::path over = dir / "just_over.vdb";
  expectBadInput([&] { vs::loadVdb(over.string(), raised); }, {"would need more than 16777216 slots"});
}

// A leaf stored with an origin near the end of the 32-bit coordinate range (found by fuzzing): OpenVDB
// computes its voxels' coordinates from that origin in ints, which overflowed inside its headers. The loader
// refuses the node first; a node that ends exactly at the last coordinate still loads as far as that check.
TEST(VdbLoad, NodeAtTheEndOfTheCoordinateRangeIsRefused) {
  openvdb::initialize();
  const std::string fuzzed =
      (fs::path(VOXSHADOW_SOURCE_DIR) / "tests/fuzz/regressions/vdb/ubsan-tile-bounds-overflow.vdb").string();
  expectBadInput([&] { vs::loadVdb(fuzzed); }, {fuzzed, "reaches beyond the 32-bit index coordinate range"});

  const fs::path dir = vs::test::scratchDir("vdb_coordinate_end");
  auto mask = openvdb::BoolGrid::create(false);
  mask->setName("edge");
  const int last = std::numeric_limits<int>::max();
  mask->tree().setValueOn(openvdb::Coord(last, last, last), true);
  const fs::path file = dir / "edge.vdb";
  openvdb::io::File(file.string()).write({mask});
  try {
    vs::loadVdb(file.string());
  } catch (const vs::Error& e) {
    // Whatever refuses it (the brickmap's coordinate range), it is not the node check.
    EXPECT_EQ(std::string(e.what()).find("reaches beyond"), std::string::npos) << e.what();
  }
}
