// vdb_info.h: what each grid of a .vdb file holds and what its brickmap would cost (`voxshadow info`).
#ifndef VOXSHADOW_VDB_INFO_H
#define VOXSHADOW_VDB_INFO_H

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "voxel/brickmap.h"
#include "voxel/voxel_object.h"

namespace vs {

struct GridInfo {
  std::string name;
  int index = -1;              // file order
  std::string valueType;       // OpenVDB value type name
  std::string gridClass;       // "level set", "fog volume", "unknown", ...
  glm::dvec3 voxelSize{0.0};
  std::uint64_t activeVoxelCount = 0;
  glm::ivec3 indexMin{0}, indexMax{0};  // active voxel bounds from the tree, inclusive; meaningless when no active voxel
  bool hasSolidRule = false;
  std::string rule;                  // the rule applied, empty when none
  std::uint64_t solidVoxelCount = 0; // under the rule
  BrickmapMemory brickmapMemory;
  double bytesPerSolidVoxel = 0.0;   // brickmap occupancy structure bytes / solid voxels (0 when none)
  std::uint64_t openvdbTreeBytes = 0;  // OpenVDB's own tree memUsage()
  std::string error;                 // why the rule could not be applied (bounds too large, ...), else empty
};

// Inspects every grid of a .vdb file, in file order; `options` gives the density threshold and colour used by
// the rules. Throws vs::Error(BadInput) naming the file when it cannot be read; a grid whose rule fails is
// listed with its `error` set.
std::vector<GridInfo> inspectVdb(const std::string& path, const LoadOptions& options = {});

}  // namespace vs

#endif
