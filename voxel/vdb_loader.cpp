// loadVdb: one grid of a .vdb file to a VoxelObject (DESIGN.md §3).
#include <algorithm>
#include <cctype>

#include "voxel/error.h"
#include "voxel/vdb_rules.h"
#include "voxel/voxel_object.h"

namespace vs {

namespace {

std::string gridList(const openvdb::GridPtrVec& grids) {
  std::string s;
  for (std::size_t i = 0; i < grids.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(i) + ": '" + grids[i]->getName() + "' (" + grids[i]->valueType() + ")";
  }
  return s.empty() ? "none" : s;
}

}  // namespace

VoxelObject loadVdb(const std::string& path, const LoadOptions& options) {
  openvdb::GridPtrVec grids = readVdbGrids(path, options.checkInChildProcess);
  VoxelObject obj;
  obj.file = path;
  int chosen = -1;
  const std::string& want = options.grid;
  if (!want.empty() && std::all_of(want.begin(), want.end(), [](unsigned char c) { return std::isdigit(c); })) {
    if (want.size() > 9 || std::stoul(want) >= grids.size()) {
      throwBadInput(path + ": grid index " + want + " is out of range (grids: " + gridList(grids) + ")");
    }
    chosen = int(std::stoul(want));
  } else if (!want.empty()) {
    for (std::size_t i = 0; i < grids.size() && chosen < 0; ++i)
      if (grids[i]->getName() == want) chosen = int(i);
    if (chosen < 0) throwBadInput(path + ": no grid named '" + want + "' (grids: " + gridList(grids) + ")");
  } else {
    std::string skipped;
    for (std::size_t i = 0; i < grids.size() && chosen < 0; ++i) {
      if (!solidRuleOf(*grids[i]).empty()) chosen = int(i);
      else skipped += (skipped.empty() ? "" : ", ") + ("'" + grids[i]->getName() + "' (" + grids[i]->valueType() + ")");
    }
    if (chosen < 0) throwBadInput(path + ": no grid has a solid rule (grids: " + gridList(grids) + ")");
    obj.selectionNote = "grid " + std::to_string(chosen) + " '" + grids[std::size_t(chosen)]->getName() +
                        "' chosen: the first grid in file order with a solid rule";
    if (!skipped.empty()) obj.selectionNote += " (skipped: " + skipped + ")";
  }
  const openvdb::GridBase& grid = *grids[std::size_t(chosen)];
  obj.gridName = grid.getName();
  obj.gridIndex = chosen;
  obj.gridType = grid.valueType();
  obj.gridClass = openvdb::GridBase::gridClassToString(grid.getGridClass());
  obj.rule = solidRuleOf(grid);
  const std::string label = path + ": grid " + std::to_string(chosen) + " '" + obj.gridName + "'";
  if (obj.rule.empty()) throwBadInput(label + " of type " + obj.gridType + " has no solid rule");
  obj.brickToObject = brickToObjectOf(grid, path);
  SolidExtraction solid = extractSolid(grid, options, path);
  obj.palette = std::move(solid.palette);
  try {
    obj.brickmap = Brickmap::build(solid.voxels);
  } catch (const Error& e) {
    throwBadInput(label + ": " + e.what());
  }
  return obj;
}

}  // namespace vs
