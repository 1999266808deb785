// inspectVdb: per-grid facts and brickmap cost of a .vdb file.
#include "voxel/vdb_info.h"

#include "voxel/error.h"
#include "voxel/vdb_rules.h"

namespace vs {

std::vector<GridInfo> inspectVdb(const std::string& path, const LoadOptions& options) {
  openvdb::GridPtrVec grids = readVdbGrids(path, options.checkInChildProcess);
  std::vector<GridInfo> out;
  for (std::size_t i = 0; i < grids.size(); ++i) {
    const openvdb::GridBase& g = *grids[i];
    GridInfo info;
    info.name = g.getName();
    info.index = int(i);
    info.valueType = g.valueType();
    info.gridClass = openvdb::GridBase::gridClassToString(g.getGridClass());
    openvdb::Vec3d vs = g.voxelSize();
    info.voxelSize = glm::dvec3(vs.x(), vs.y(), vs.z());
    info.activeVoxelCount = g.activeVoxelCount();
    openvdb::CoordBBox box = g.evalActiveVoxelBoundingBox();
    info.indexMin = glm::ivec3(box.min().x(), box.min().y(), box.min().z());
    info.indexMax = glm::ivec3(box.max().x(), box.max().y(), box.max().z());
    info.openvdbTreeBytes = g.baseTree().memUsage();
    info.rule = solidRuleOf(g);
    info.hasSolidRule = !info.rule.empty();
    if (info.hasSolidRule) {
      try {
        SolidExtraction solid = extractSolid(g, options, path);
        Brickmap bm = Brickmap::build(solid.voxels);
        info.solidVoxelCount = bm.solidCount();
        info.brickmapMemory = bm.memory();
        if (info.solidVoxelCount)
          info.bytesPerSolidVoxel = double(info.brickmapMemory.occupancyStructureBytes()) / double(info.solidVoxelCount);
      } catch (const Error& e) {
        info.error = e.what();
      }
    }
    out.push_back(std::move(info));
  }
  return out;
}

}  // namespace vs
