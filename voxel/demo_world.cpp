// The demo world: a few small assets and a scene that uses every light type with shadows.
#include "voxel/demo_world.h"

#include <cmath>
#include <fstream>

#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "voxel/demo_vox.h"
#include "voxel/error.h"
#include "voxel/vdb_rules.h"

namespace vs {

namespace {

void writeGrid(const std::filesystem::path& file, openvdb::GridBase::Ptr grid, std::vector<std::string>& written) {
  try {
    openvdb::io::File out(file.string());
    out.write(openvdb::GridPtrVec{grid});
    out.close();
  } catch (const std::exception& e) {
    throwRuntime(file.string() + ": cannot write (" + e.what() + ")");
  }
  written.push_back(file.string());
}

openvdb::Int32Grid::Ptr makeGround() {
  // 256 x 256 voxels of 0.5: rolling relief 3..12 voxels high; grass on top (1), soil below (2), rock deep (3).
  auto grid = openvdb::Int32Grid::create(0);
  grid->setName("material");
  grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
  grid->setGridClass(openvdb::GRID_UNKNOWN);
  auto acc = grid->getAccessor();
  for (int z = -128; z < 128; ++z)
    for (int x = -128; x < 128; ++x) {
      double h = 6.0 + 2.5 * std::sin(x * 0.06) * std::cos(z * 0.05) + 1.5 * std::sin((x + z) * 0.11);
      int top = std::max(3, int(std::lround(h)));
      for (int y = 0; y < top; ++y) acc.setValue(openvdb::Coord(x, y, z), y == top - 1 ? 1 : (y >= top - 3 ? 2 : 3));
    }
  return grid;
}

openvdb::Int32Grid::Ptr makeBuilding() {
  // A hollow block 16 x 32 x 12 with walls (1), window rows (2) and a roof slab (3).
  auto grid = openvdb::Int32Grid::create(0);
  grid->setName("material");
  auto acc = grid->getAccessor();
  const int sx = 16, sy = 32, sz = 12;
  for (int z = 0; z < sz; ++z)
    for (int y = 0; y < sy; ++y)
      for (int x = 0; x < sx; ++x) {
        bool wall = x == 0 || z == 0 || x == sx - 1 || z == sz - 1 || y == 0;
        bool roof = y >= sy - 2;
        if (!wall && !roof) continue;
        int m = roof ? 3 : 1;
        if (!roof && wall && y % 4 == 2 && ((x % 3 == 1 && (z == 0 || z == sz - 1)) || (z % 3 == 1 && (x == 0 || x == sx - 1))))
          m = 2;
        acc.setValue(openvdb::Coord(x, y, z), m);
      }
  return grid;
}

openvdb::BoolGrid::Ptr makeTower() {
  // A round tower, radius 5, 48 high, with a wider cap.
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("mask");
  auto acc = grid->getAccessor();
  for (int y = 0; y < 52; ++y) {
    int r = y < 46 ? 5 : 7;
    for (int z = -r; z <= r; ++z)
      for (int x = -r; x <= r; ++x)
        if (x * x + z * z <= r * r) acc.setValueOn(openvdb::Coord(x, y, z), true);
  }
  return grid;
}

openvdb::Vec3SGrid::Ptr makeTree() {
  // Trunk (brown) and a canopy of two greens.
  auto grid = openvdb::Vec3SGrid::create(openvdb::Vec3f(0.0f));
  grid->setName("Cd");
  auto acc = grid->getAccessor();
  for (int y = 0; y < 10; ++y)
    for (int z = -1; z <= 1; ++z)
      for (int x = -1; x <= 1; ++x) acc.setValueOn(openvdb::Coord(x, y, z), openvdb::Vec3f(0.35f, 0.22f, 0.1f));
  const int r = 7, cy = 14;
  for (int z = -r; z <= r; ++z)
    for (int y = -r; y <= r; ++y)
      for (int x = -r; x <= r; ++x)
        if (x * x + y * y + z * z <= r * r) {
          bool light = ((x + 2 * y + 3 * z) & 3) == 0;
          acc.setValueOn(openvdb::Coord(x, cy + y, z),
                         light ? openvdb::Vec3f(0.3f, 0.65f, 0.2f) : openvdb::Vec3f(0.15f, 0.45f, 0.12f));
        }
  return grid;
}

}  // namespace

std::vector<std::string> writeDemoWorld(const std::filesystem::path& dir) {
  ensureOpenVdbInitialized();
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throwRuntime(dir.string() + ": cannot create directory (" + ec.message() + ")");
  std::vector<std::string> written;
  writeGrid(dir / "ground.vdb", makeGround(), written);
  writeGrid(dir / "building.vdb", makeBuilding(), written);
  writeGrid(dir / "tower.vdb", makeTower(), written);
  writeGrid(dir / "tree.vdb", makeTree(), written);
  auto blob = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(6.0f, openvdb::Vec3f(0.0f, 6.0f, 0.0f), 0.5f);
  blob->setName("ls_blob");
  writeGrid(dir / "blob.vdb", blob, written);
  writeVoxFile(dir / "crates.vox", demoCratesVox());
  written.push_back((dir / "crates.vox").string());

  const std::filesystem::path scene = dir / "demo.json";
  std::ofstream out(scene);
  out << R"({
  "version": 1,
  "assets": {
    "ground": { "file": "ground.vdb", "color": [0.45, 0.6, 0.3] },
    "building": { "file": "building.vdb", "color": [0.75, 0.72, 0.68] },
    "tower": { "file": "tower.vdb", "color": [0.7, 0.65, 0.6] },
    "tree": { "file": "tree.vdb" },
    "blob": { "file": "blob.vdb", "color": [0.8, 0.3, 0.25] },
    "crates": { "file": "crates.vox", "voxel_size": 1.0 }
  },
  "instances": [
    { "asset": "ground", "translate": [0, -3, 0] },
    { "asset": "building", "translate": [-40, 0, -30] },
    { "asset": "building", "translate": [10, 0, -40], "rotate_deg": [0, 35, 0] },
    { "asset": "building", "translate": [-30, 0, 20], "scale": [1.5, 0.75, 1.5] },
    { "asset": "tower", "translate": [25, 0, 15] },
    { "asset": "tree", "translate": [0, 0, 10] },
    { "asset": "tree", "translate": [-12, 0, 30], "scale": 1.5 },
    { "asset": "tree", "translate": [35, 0, -12], "rotate_deg": [0, 60, 0] },
    { "asset": "blob", "translate": [-2, 0, 42] },
    { "asset": "crates", "translate": [30, 0, 36], "rotate_deg": [0, 20, 0] }
  ],
  "camera": { "position": [72, 40, 78], "target": [2, 14, 0], "up": [0, 1, 0], "fov_deg": 60,
              "near": 0.1, "far": 400, "width": 1280, "height": 720 },
  "ambient": { "color": [0.6, 0.7, 1.0], "intensity": 0.2 },
  "lights": [
    { "name": "sun", "type": "directional", "direction": [-0.8, -0.9, 0.2], "color": [1, 0.95, 0.9], "intensity": 2,
      "shadow": { "resolution": 2048, "cascades": 3, "lambda": 0.5, "max_distance": 200,
                  "filter": "pcf5", "contact_shadow": 0.5 } },
    { "name": "lamp", "type": "spot", "position": [6, 26, 36], "direction": [-0.1, -1, 0.05], "range": 50,
      "inner_cone_deg": 20, "outer_cone_deg": 30, "color": [1, 0.8, 0.6], "intensity": 2500,
      "shadow": { "resolution": 1024, "filter": "poisson16" } },
    { "name": "torch", "type": "point", "position": [36, 4, 44], "range": 25, "color": [1, 0.6, 0.3], "intensity": 120,
      "shadow": { "resolution": 512 } }
  ]
}
)";
  out.close();
  if (!out) throwRuntime(scene.string() + ": cannot write");
  written.push_back(scene.string());
  return written;
}

}  // namespace vs
