#include "voxel/city512_openvdb.h"

namespace vs {

openvdb::BoolGrid::Ptr boolGridFromVoxels(std::span<const SolidVoxel> voxels) {
  auto grid = openvdb::BoolGrid::create(false);
  auto acc = grid->getAccessor();
  for (const auto& v : voxels) acc.setValueOn(openvdb::Coord(v.coord.x, v.coord.y, v.coord.z), true);
  return grid;
}

}  // namespace vs
