// scratch.h: scratch space shared by the fuzz targets and their replay driver.
#ifndef VOXSHADOW_FUZZ_SCRATCH_H
#define VOXSHADOW_FUZZ_SCRATCH_H

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace vs::fuzz {

// A directory of this process's own under $TMPDIR (fuzz jobs run in parallel processes), created on first use
// and removed at normal exit.
const std::filesystem::path& scratchDir();

// Writes the input to `file` (truncating it): the .vdb path reads files only.
void writeInput(const std::filesystem::path& file, const std::uint8_t* data, std::size_t size);

}  // namespace vs::fuzz

#endif
