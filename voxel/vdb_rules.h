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

// Off by default. On: a checking process is forked now, and the checks of readVdbGrids go to it; it forks a
// reader per file (the reader parses the bytes and dies, if it dies, in place of a child of this process)
// and, never parsing anything itself, stays a one-thread process however many threads this one starts later.
// Verdicts and error messages are those of a fork per file. Two reasons to turn it on:
// - Precondition: call it before any other thread of this process works (at the top of main, before TBB,
//   OpenVDB or Vulkan start work; log4cplus, which OpenVDB links, starts a pool at load that waits idle). A fork per file forks whatever threads the process has by then, and a lock another
//   thread held at that moment (an allocator's) stays held in the child: with a C library that makes malloc
//   fork-safe this works, with clang 14's AddressSanitizer (no fork handlers) the child can wait forever.
//   The CLI turns it on first thing.
// - A process that checks many small untrusted files one after another (the vdb fuzz target): a fork of the
//   small checking process costs less than a fork of the large sanitized one.
// A checking process found dead (killed) is replaced at the next check, forked from this process as it is
// then (the hazard above, once), and a check it died in is asked again of the new one without blaming the
// file. It ends when this process ends or turns it off (the end of its socket), whichever thread started it.
// Checks from several threads take turns. The file's bytes are copied to it for the check and not kept.
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
