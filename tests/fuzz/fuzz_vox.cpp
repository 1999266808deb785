// libFuzzer target: arbitrary bytes through the .vox reader and on to objects and placements. Refusals are
// vs::Error; anything else (a crash, a sanitizer report, another exception) is a finding.
#include <cstddef>
#include <cstdint>
#include <span>

#include "voxel/error.h"
#include "voxel/vox_reader.h"
#include "voxel/vox_scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    vs::VoxFile file = vs::readVox(std::span<const std::uint8_t>(data, size), "fuzz.vox");
    // Building brickmaps is bounded by the voxels read, which are bounded by the input's length.
    vs::buildVoxAsset(file);
  } catch (const vs::Error&) {
  }
  return 0;
}
