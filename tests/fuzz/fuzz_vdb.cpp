// Fuzz target: the .vdb loading path (vs::loadVdb: OpenVDB stream, grid choice, solid extraction, brickmap)
// on arbitrary bytes. A refusal is vs::Error (or std::bad_alloc); any other exception, crash or sanitizer
// report is a defect.
#include <cstddef>
#include <cstdint>
#include <new>

#include "fuzz/scratch.h"
#include "voxel/error.h"
#include "voxel/voxel_object.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // OpenVDB reads from files only.
  static const std::filesystem::path file = vs::fuzz::scratchDir() / "input.vdb";
  vs::fuzz::writeInput(file, data, size);
  try {
    vs::VoxelObject object = vs::loadVdb(file.string());
    (void)object;
  } catch (const vs::Error&) {
  } catch (const std::bad_alloc&) {
    // Asking for more memory than allocation_cap.cpp grants; the CLI reports it as a runtime failure.
  }
  return 0;
}
