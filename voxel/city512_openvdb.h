// city512_openvdb.h: the city512 voxels as an OpenVDB BoolGrid (the peer of benchmarks and memory tests).
#ifndef VOXSHADOW_CITY512_OPENVDB_H
#define VOXSHADOW_CITY512_OPENVDB_H

#include <span>

#include <openvdb/openvdb.h>

#include "voxel/brickmap.h"

namespace vs {

// A BoolGrid (identity transform, index = brick-space coordinate) with every given voxel active and true,
// written through an accessor with setValueOn and not pruned. Precondition: openvdb::initialize() was called
// or the caller only uses the grid in memory.
openvdb::BoolGrid::Ptr boolGridFromVoxels(std::span<const SolidVoxel> voxels);

}  // namespace vs

#endif
