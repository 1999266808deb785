// Fuzz target: the .vdb loading path (vs::loadVdb: OpenVDB stream, grid choice, solid extraction, brickmap)
// on arbitrary bytes. A refusal is vs::Error (or std::bad_alloc); any other exception, crash or sanitizer
// report is a defect.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>

#include <unistd.h>

#include "fuzz/scratch.h"
#include "voxel/error.h"
#include "voxel/vdb_rules.h"
#include "voxel/voxel_object.h"

namespace {


// The seeds expand to at most a few thousand solid voxels (2,450: arnold_fog_torus.vdb); a mutation that
// turns a leaf into a tile of 32^3 voxels or more is refused by the loader's voxel limit (the check and
// message the default limit has), instead of extracting and sorting tens of thousands of voxels (under
// coverage instrumentation, most of an execution) that exercise nothing new.
constexpr std::uint64_t kMaxSolidVoxels = std::uint64_t(1) << 13;
// Likewise a mutation that moves one leaf far away: within the brickmap's limit (2^24 slots, a 64 MiB table
// to allocate and clear for every such input, most of the fuzzing time) it exercises nothing a 32^3-region
// table does not, and the refusal is the same check.
constexpr std::int64_t kMaxRegionSlots = std::int64_t(1) << 15;

const pid_t fuzzingProcess = ::getpid();

// The value of `name=` in ASAN_OPTIONS, last one first, as AddressSanitizer reads it; `otherwise` if absent.
long asanOption(const char* name, long otherwise) {
  const char* options = std::getenv("ASAN_OPTIONS");
  if (!options) return otherwise;
  const std::size_t length = std::strlen(name);
  long value = otherwise;
  for (const char* p = options; *p;) {
    if (std::strncmp(p, name, length) == 0 && p[length] == '=') value = std::strtol(p + length + 1, nullptr, 10);
    p += std::strcspn(p, ":, ");
    if (*p) ++p;
  }
  return value;
}

}  // namespace

// AddressSanitizer calls this before it prints a report. In a reader (its report goes nowhere, and only how
// the reader ended decides the verdict) the report's symbolization started llvm-symbolizer over this
// binary's debug information for every input OpenVDB's reader overran: about half a second each, an eighth
// of the fuzzing time. The child ends as AddressSanitizer would end it after the report, at once.
extern "C" void __asan_on_error() {
  if (::getpid() == fuzzingProcess || asanOption("halt_on_error", 1) == 0) return;
  if (asanOption("abort_on_error", 0) != 0) std::abort();
  ::_exit(int(asanOption("exitcode", 1)));
}

// Forking the sanitized process for every input cost more than the rest of an execution: one small checking
// process, forked before fuzzing starts (after every static initializer ran), forks the reader of each input
// (vs::setPersistentCheckingProcess), with the same verdicts and messages.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vs::setPersistentCheckingProcess(true);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // OpenVDB reads from files only.
  static const std::filesystem::path file = vs::fuzz::scratchDir() / "input.vdb";
  vs::fuzz::writeInput(file, data, size);
  vs::LoadOptions options;
  options.maxSolidVoxels = kMaxSolidVoxels;
  options.maxRegionSlots = kMaxRegionSlots;
  try {
    vs::VoxelObject object = vs::loadVdb(file.string(), options);
    (void)object;
  } catch (const vs::Error&) {
  } catch (const std::bad_alloc&) {
    // Asking for more memory than allocation_cap.cpp grants; the CLI reports it as a runtime failure.
  }
  return 0;
}
