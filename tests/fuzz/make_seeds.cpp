// make_seeds: writes the small generated seed files of tests/fuzz/seeds/vdb/ and tests/fuzz/seeds/vox/.
//   make_fuzz_seeds OUT_DIR     writes OUT_DIR/vdb/*.vdb and OUT_DIR/vox/*.vox
// Each file holds a few voxels, so that one fuzz execution takes well under a millisecond, and together they
// reach every grid type with a solid rule, every compression OpenVDB writes (none, zip, blosc, active mask,
// half floats; uncompressed only for a mask grid, which stores no values), tiles, instanced grids, metadata and a non-linear transform; and for .vox: models, palettes,
// scene graphs, layers, materials and animation frames. The committed seeds are this program's output;
// regenerate them with `build/tests/fuzz/make_fuzz_seeds tests/fuzz/seeds` after changing it.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include "voxel/vox_writer.h"

namespace fs = std::filesystem;

namespace {

void writeVdb(const fs::path& file, const openvdb::GridPtrVec& grids, std::uint32_t compression,
              const openvdb::MetaMap& meta = {}) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  openvdb::io::Stream stream(out);
  stream.setCompression(compression);
  stream.write(grids, meta);
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

template <class GridT>
typename GridT::Ptr smallGrid(const std::string& name, typename GridT::ValueType a, typename GridT::ValueType b,
                              typename GridT::ValueType background = {}) {
  typename GridT::Ptr grid = GridT::create(background);
  grid->setName(name);
  auto acc = grid->getAccessor();
  // Two leaves, a few voxels each, one of them inactive with a value; all under one root child (each
  // further top-level node would add 8 KiB of masks to the file).
  acc.setValue(openvdb::Coord(0, 0, 0), a);
  acc.setValue(openvdb::Coord(1, 0, 0), b);
  acc.setValue(openvdb::Coord(0, 2, 1), a);
  acc.setValue(openvdb::Coord(9, 3, 4), b);
  acc.setValueOff(openvdb::Coord(10, 3, 4), a);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
  return grid;
}

void vdbSeeds(const fs::path& dir) {
  using namespace openvdb;
  fs::create_directories(dir);
  const std::uint32_t none = io::COMPRESS_NONE, zip = io::COMPRESS_ZIP, blosc = io::COMPRESS_BLOSC,
                      mask = io::COMPRESS_ACTIVE_MASK;

  // A level set: a tiny sphere (narrow band, inactive interior below the background).
  FloatGrid::Ptr ls = FloatGrid::create(0.3f);
  ls->setName("surface");
  ls->setGridClass(GRID_LEVEL_SET);
  for (int z = 0; z <= 4; ++z)
    for (int y = 0; y <= 4; ++y)
      for (int x = 0; x <= 4; ++x) {
        const float d = 0.1f * float((x - 2) * (x - 2) + (y - 2) * (y - 2) + (z - 2) * (z - 2)) - 0.5f;
        if (d < -0.2f) ls->tree().setValueOff(Coord(x, y, z), -0.3f);
        else if (d < 0.3f) ls->tree().setValue(Coord(x, y, z), d);
      }
  ls->setTransform(math::Transform::createLinearTransform(0.25));
  writeVdb(dir / "levelset-zip-mask.vdb", {ls}, zip | mask);
  writeVdb(dir / "levelset-blosc-mask.vdb", {ls}, blosc | mask);
  ls->setSaveFloatAsHalf(true);
  writeVdb(dir / "levelset-half-blosc.vdb", {ls}, blosc | mask);

  FloatGrid::Ptr fog = smallGrid<FloatGrid>("density", 0.75f, 0.25f);
  fog->setGridClass(GRID_FOG_VOLUME);
  writeVdb(dir / "fog-mask.vdb", {fog}, mask);
  writeVdb(dir / "fog-zip-mask.vdb", {fog}, zip | mask);
  writeVdb(dir / "fog-blosc.vdb", {fog}, blosc);
  // An active tile (a whole 8^3 leaf's worth at level 1) beside the voxels.
  FloatGrid::Ptr tiled = fog->deepCopy();
  tiled->tree().addTile(1, Coord(64, 0, 0), 1.0f, true);
  writeVdb(dir / "fog-tile.vdb", {tiled}, mask);

  writeVdb(dir / "double.vdb", {smallGrid<DoubleGrid>("d", 2.0, -1.0)}, zip | mask);
  writeVdb(dir / "bool.vdb", {smallGrid<BoolGrid>("b", true, true)}, mask);
  MaskGrid::Ptr mk = MaskGrid::create();
  mk->setName("m");
  mk->tree().setValueOn(Coord(0, 0, 0));
  mk->tree().setValueOn(Coord(5, 9, 3));
  writeVdb(dir / "mask-blosc.vdb", {mk}, blosc | mask);
  // Uncompressed: a mask grid stores no values, so the file stays small.
  writeVdb(dir / "mask-none.vdb", {mk}, none);
  Int32Grid::Ptr ints = smallGrid<Int32Grid>("palette", 3, 300);
  std::string words;
  for (int i = 1; i <= 255; ++i) {
    char w[8];
    std::snprintf(w, sizeof w, "%02x%02x%02x", i, 255 - i, (i * 7) & 255);
    if (i > 1) words += ' ';
    words += w;
  }
  ints->insertMeta("voxshadow:palette", StringMetadata(words));
  writeVdb(dir / "int32-palette.vdb", {ints}, zip | mask);
  writeVdb(dir / "int64.vdb", {smallGrid<Int64Grid>("i64", 5, -7)}, zip | mask);
  writeVdb(dir / "vec3s.vdb", {smallGrid<Vec3SGrid>("Cd", Vec3s(1, 0.5f, 0), Vec3s(0, 0, 1))}, blosc | mask);
  writeVdb(dir / "vec3d.vdb", {smallGrid<Vec3DGrid>("Cd", Vec3d(0.2, 0.4, 0.6), Vec3d(1, 1, 1))}, zip | mask);
  writeVdb(dir / "vec3i.vdb", {smallGrid<Vec3IGrid>("rgb", Vec3i(255, 0, 0), Vec3i(0, 128, 255))}, mask);

  // Several grids in one file: one without a solid rule first, an instance sharing the fog's tree, file
  // metadata, and a frustum transform (refused by the loader).
  FloatGrid::Ptr instance = fog->copy();
  instance->setName("density_instance");
  MetaMap meta;
  meta.insertMeta("creator", StringMetadata("make_fuzz_seeds"));
  writeVdb(dir / "multi.vdb", {smallGrid<Vec3IGrid>("rgb", Vec3i(1, 2, 3), Vec3i(4, 5, 6)), fog, instance}, zip | mask,
           meta);
  BoolGrid::Ptr frustum = smallGrid<BoolGrid>("frustum", true, true);
  frustum->setTransform(math::Transform::createFrustumTransform(BBoxd(Vec3d(0), Vec3d(8)), 0.5, 2.0, 0.5));
  writeVdb(dir / "frustum.vdb", {frustum}, mask);
  FloatGrid::Ptr empty = FloatGrid::create(0.0f);
  empty->setName("empty");
  writeVdb(dir / "empty.vdb", {empty}, mask);
}

void voxSeeds(const fs::path& dir) {
  using namespace vs;
  fs::create_directories(dir);
  VoxModel a;
  a.size = {2, 2, 1};
  a.voxels = {{0, 0, 0, 1}, {1, 1, 0, 200}};
  VoxModel b;
  b.size = {3, 1, 2};
  b.voxels = {{0, 0, 0, 7}, {2, 0, 1, 255}, {1, 0, 0, 7}};
  std::array<std::uint32_t, 256> palette{};
  for (int i = 0; i < 256; ++i) palette[std::size_t(i)] = 0xff000000u | std::uint32_t(i * 0x010305);

  VoxWriteFile plain;
  plain.version = 150;
  plain.models = {a};
  writeVoxFile(dir / "one-model.vox", plain);

  VoxWriteFile coloured;
  coloured.models = {a, b};
  coloured.palette = palette;
  writeVoxFile(dir / "two-models-palette.vox", coloured);

  VoxWriteFile scene = coloured;
  scene.nodes = voxSceneGraph({{0, 4, {0, 0, 0}, "first"}, {1, 17, {5, -2, 3}, "second"}, {0, 40, {-4, 1, 0}, ""}});
  scene.layers = {{0, "visible", false}, {1, "hidden", true}};
  VoxMaterial glass;
  glass.id = 200;
  glass.props = {{"_type", "_glass"}, {"_ior", "0.3"}};
  VoxMaterial emit;
  emit.id = 7;
  emit.props = {{"_type", "_emit"}, {"_emit", "1.0"}};
  scene.materials = {glass, emit};
  writeVoxFile(dir / "scene-graph.vox", scene);

  // Keyframes: a transform with two frames, a hidden shape on a hidden layer.
  VoxWriteFile anim = coloured;
  anim.nodes = voxSceneGraph({{0, 4, {0, 0, 0}, "moving"}, {1, 4, {2, 2, 2}, "still"}});
  for (VoxWriteNode& n : anim.nodes) {
    if (n.kind == VoxWriteNode::Kind::Transform && n.attributes.count("_name") && n.attributes["_name"] == "moving") {
      n.frames = {{{"_f", "0"}, {"_t", "0 0 0"}}, {{"_f", "5"}, {"_t", "3 0 -1"}, {"_r", "20"}}};
      n.layer = 1;
    }
  }
  anim.layers = {{0, "base", false}, {1, "hidden", true}};
  writeVoxFile(dir / "keyframes-layers.vox", anim);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_fuzz_seeds OUT_DIR (writes OUT_DIR/vdb and OUT_DIR/vox)\n");
    return 2;
  }
  try {
    openvdb::initialize();
    vdbSeeds(fs::path(argv[1]) / "vdb");
    voxSeeds(fs::path(argv[1]) / "vox");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
