// city512: the brickmap's occupancy structure against OpenVDB's BoolGrid for the same voxels (DESIGN.md §4).
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include "voxel/brickmap.h"
#include "voxel/city512.h"
#include "voxel/city512_openvdb.h"

namespace {

TEST(VoxelMemory, City512OccupancyIsAtMostHalfOfBoolGrid) {
  openvdb::initialize();
  auto voxels = vs::city512Voxels();
  ASSERT_EQ(voxels.size(), vs::kCity512SolidVoxels);

  vs::Brickmap bm = vs::Brickmap::build(voxels);
  EXPECT_EQ(bm.solidCount(), vs::kCity512SolidVoxels);
  bm.checkConsistency();

  auto grid = vs::boolGridFromVoxels(voxels);
  ASSERT_EQ(grid->activeVoxelCount(), openvdb::Index64(vs::kCity512SolidVoxels));
  const double vdbBytes = double(grid->tree().memUsage());
  const double ours = double(bm.memory().occupancyStructureBytes());
  std::printf("city512: brickmap occupancy structure %.3f MiB, OpenVDB BoolGrid tree %.3f MiB, ratio %.3f\n",
              ours / 1048576.0, vdbBytes / 1048576.0, ours / vdbBytes);
  EXPECT_LE(ours, 0.5 * vdbBytes);

  // Bounds equal the BoolGrid's active bounding box (brick space = index space here).
  openvdb::CoordBBox bbox = grid->evalActiveVoxelBoundingBox();
  vs::VoxelBox b = bm.bounds();
  EXPECT_EQ(b.min, glm::ivec3(bbox.min().x(), bbox.min().y(), bbox.min().z()));
  EXPECT_EQ(b.max, glm::ivec3(bbox.max().x() + 1, bbox.max().y() + 1, bbox.max().z() + 1));

  auto acc = grid->getConstAccessor();
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> coord(-4, 515);
  int solid = 0;
  for (int i = 0; i < 300000; ++i) {
    glm::ivec3 v(coord(rng), coord(rng), coord(rng));
    bool expected = acc.isValueOn(openvdb::Coord(v.x, v.y, v.z));
    solid += expected;
    ASSERT_EQ(bm.isSolid(v), expected) << v.x << "," << v.y << "," << v.z;
    ASSERT_EQ(bm.material(v), expected ? 1 : 0);
  }
  EXPECT_GT(solid, 1000);  // the sample reaches solid voxels, not only empty space
}

}  // namespace
