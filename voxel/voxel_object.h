// voxel_object.h: a voxel asset loaded from a file: its brickmap, palette and index-to-world map.
#ifndef VOXSHADOW_VOXEL_OBJECT_H
#define VOXSHADOW_VOXEL_OBJECT_H

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "voxel/brickmap.h"

namespace vs {

struct LoadOptions {
  // Grid to use: a name (first grid of that name in file order) or a 0-based index in file order, written
  // as decimal digits. Empty: the first grid in file order that has a solid rule (the choice is logged).
  std::string grid;
  float densityThreshold = 0.0f;       // fog and other scalar float grids: solid where value > this
  glm::vec3 color{0.8f, 0.8f, 0.8f};  // default colour (palette entry 1) for grids without their own
  // .vdb files only. OpenVDB 10's reader does not check everything it reads: on some damaged files it
  // writes past a buffer (a compressed block longer than the values it is read into) and the process dies.
  // With this set, the file's bytes (read into memory once) are parsed first in a forked child process, and
  // a child that dies becomes a vs::Error(BadInput) naming the file and grid. A file the child refuses
  // with OpenVDB's exception is refused with the child's message (so the tree nodes OpenVDB leaks when it
  // throws stay in the child); only a file the child read to its end is parsed again, from the same bytes,
  // by this process. The cost: one fork and a second parse of every grid (about as long again as OpenVDB's
  // reading; the brickmap building that follows is not repeated), and the child's memory while it runs.
  // Turn it off only for files that are trusted (written by this process or a known tool).
  bool checkInChildProcess = true;
  // Most solid voxels (tiles counted by their volume) the chosen grid may expand to. A grid with more is
  // refused, naming the file, the grid and this limit, after its tree is counted and before any voxel is
  // extracted. The default bounds what a hostile or absurd file can make the loader allocate (about 16 bytes
  // a voxel while extracting, then the brickmap); a caller that only needs small assets, such as the fuzz
  // target, lowers it to refuse large grids early.
  std::uint64_t maxSolidVoxels = std::uint64_t(1) << 26;
  // Most region-table slots (one per 128^3 region of the grid's index bounds) the brickmap may need; values
  // above the brickmap's own limit (Brickmap::kMaxRegionSlots, 2^24) mean that limit. A grid needing more is
  // refused before extraction. The fuzz target lowers it: a mutation that moves a leaf far away otherwise
  // allocates and clears a 64 MiB table for every such input.
  std::int64_t maxRegionSlots = std::int64_t(1) << 24;
};

struct VoxelObject {
  std::string file;      // path as given
  std::string gridName;  // the chosen grid's name
  int gridIndex = -1;    // its index in file order
  std::string gridType;  // OpenVDB value type name, e.g. "float", "vec3s", "bool", "int32"
  std::string gridClass; // "level set", "fog volume", "unknown", ...
  std::string rule;      // human-readable solid rule applied, e.g. "level set: value < 0 (interior filled)"
  std::string selectionNote;  // why this grid was chosen when no grid was named; empty otherwise
  // Palette: entry 0 is unused (empty), entries 1..255 are linear RGB colours.
  std::vector<glm::vec3> palette;
  // Maps brick space (index + 0.5) to the asset's world space: grid transform * translate(-0.5).
  glm::dmat4 brickToObject{1.0};
  Brickmap brickmap;
};

// Loads one grid of a .vdb file and builds its brickmap under the solid rules of DESIGN.md §3.
// Preconditions: none on the file; every failure is a vs::Error naming the file (and grid):
// missing/unreadable file, not a VDB, truncated, unknown grid name or index, grid without a solid rule,
// non-linear (frustum) transform, bounds too large for the brickmap, and (see checkInChildProcess) damaged
// data on which OpenVDB's reader crashes. An empty grid loads as an empty object.
VoxelObject loadVdb(const std::string& path, const LoadOptions& options = {});

// Forks, now, the process that checks .vdb files for every later load with checkInChildProcess, so that
// checks never fork this process once it has threads (a fork copies a lock another thread held, and the
// child can then wait on it forever; see setPersistentCheckingProcess in vdb_rules.h). Precondition: no other
// thread of this process is working yet: call it at the top of main. Without it each check forks this process. Throws
// vs::Error(Runtime) when the process cannot be started; later checks then fork per file.
void startVdbCheckingProcess();

}  // namespace vs

#endif
