// vdb_rules.h: the solid rules of DESIGN.md §3 applied to one OpenVDB grid, and VDB file reading.
// Internal to the voxel module (its interface names OpenVDB types).
#ifndef VOXSHADOW_VDB_RULES_H
#define VOXSHADOW_VDB_RULES_H

#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <openvdb/openvdb.h>

#include "voxel/brickmap.h"
#include "voxel/voxel_object.h"

namespace vs {

// Calls openvdb::initialize() once per process; safe from any thread.
void ensureOpenVdbInitialized();

// Reads every grid of a .vdb file, in file order. Throws vs::Error(BadInput) naming the file when it is
// missing, unreadable, not a VDB or damaged (OpenVDB's exceptions are caught and rethrown). The file is read
// into memory once; with `checkInChild` (LoadOptions::checkInChildProcess) a forked child parses those bytes
// first: a child that dies (OpenVDB overruns a buffer on some damaged files) becomes an error naming the
// file and the grid being read, one that OpenVDB refused with an exception gives its message, and only a
// file the child read to its end is parsed by this process, from the same bytes. A file holding a bool
// whose byte is neither 0 nor 1 (OpenVDB copies tile values, active flags and bool metadata from the file
// unchecked) is refused as damaged, naming the grid and the value.
openvdb::GridPtrVec readVdbGrids(const std::string& path, bool checkInChild = true);

// Off by default. On: the checks of readVdbGrids go to one long-lived child process, forked at the first
// check and again after one dies or retires (after 2,048 files or 512 MiB of growth: it never frees what it
// read), instead of a fork per file; verdicts and error messages stay the same, a child that dies while
// reading a file included, and a child found dead before it took a file is replaced without blaming the file.
// For a process that checks many small untrusted files one after another, such as the vdb fuzz target, where
// forking the large sanitized process cost more than the check. Not for the CLI or a long-running
// application: the child keeps, copy-on-write, the memory the process had when it forked (memory freed later
// stays resident in the child), and PR_SET_PDEATHSIG ends it with the thread that forked it (a check running
// for another thread at that moment would be refused as a crash). Checks from several threads take turns;
// at exit, or when turned off, the child is ended and waited for.
void setPersistentCheckingProcess(bool on);

// The human-readable solid rule for a grid, or an empty string when its type has none.
std::string solidRuleOf(const openvdb::GridBase& grid);

struct SolidExtraction {
  std::vector<SolidVoxel> voxels;   // brick-space coordinates (= index coordinates) and palette indices
  std::vector<glm::vec3> palette;   // entry 0 unused
};

// Applies the grid's solid rule. Preconditions: solidRuleOf(grid) is not empty. Throws vs::Error(BadInput)
// naming `file` and the grid when the grid would expand to more than options.maxSolidVoxels voxels or its
// bounds exceed the brickmap's region-table limit.
SolidExtraction extractSolid(const openvdb::GridBase& grid, const LoadOptions& options, const std::string& file);

// The grid's index-to-world map times translate(-0.5), as a GLM column-major matrix. Throws
// vs::Error(BadInput) naming file and grid when the transform is not linear.
glm::dmat4 brickToObjectOf(const openvdb::GridBase& grid, const std::string& file);

// The deterministic palette of integer grids: entry 1 is `color`, the rest spread over hues.
std::vector<glm::vec3> integerPalette(glm::vec3 color);

// Maps an integer grid value (non-zero) to a palette index 1..255: 1 + (v - 1) mod 255.
std::uint8_t integerMaterial(std::int64_t v);

}  // namespace vs

#endif
