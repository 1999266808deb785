// resources.h: the machine resources a command may use: thread counts, memory budgets, byte sizes.
#ifndef VOXSHADOW_TOOLS_RESOURCES_H
#define VOXSHADOW_TOOLS_RESOURCES_H

#include <cstdint>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

namespace vs::cli {

// More threads than this gains nothing on any machine voxshadow runs on, and TBB fails on far larger counts.
inline constexpr int kMaxThreads = 1024;

// Adds `--threads N` to `app`, storing into `threads`: a whole number from `minimum` to kMaxThreads, with an
// error that says so (and nothing of CLI11's numeric limits) otherwise.
void addThreadsOption(CLI::App* app, int& threads, const std::string& help, int minimum);

// Parses "1234", "512K", "512M", "8G", "1.5G" or "1T" (binary units, optional "B" or "iB") to bytes.
// Throws vs::Error(BadInput) naming `what` for anything else, zero, or more than 2^60 bytes.
std::uint64_t parseByteSize(const std::string& text, const std::string& what);

// The memory this process may still use: MemAvailable from /proc/meminfo, lowered to the room left under a
// cgroup memory limit when there is one. Falls back to the physical memory when neither can be read.
std::uint64_t availableMemoryBytes();

// What a CPU Vulkan device (lavapipe) allocates in host memory while it works, beside the images and buffers
// a command asks for (compiled pipelines, command and descriptor memory), as measured on lavapipe.
inline constexpr std::uint64_t kCpuVulkanDeviceWorkingBytes = 64ull << 20;

// A size as people read it, in the largest binary unit that keeps it at 1 or more: "512 B", "1.50 KiB",
// "3.25 MiB", "2.00 GiB".
std::string formatBytes(std::uint64_t bytes);

// What a command may still allocate, and what set that figure.
struct MemoryBudget {
  std::uint64_t bytes = 0;
  std::string setBy;  // "--memory-budget", "the memory available now ...", "ulimit -v (RLIMIT_AS) of ..."
};

// The least of: `requested` (--memory-budget) or else availableMemoryBytes(); the soft RLIMIT_AS (ulimit -v)
// less the address space this process maps now (VmSize) and what the threads it has yet to start will map
// (each a stack and a malloc arena); the soft RLIMIT_DATA (ulimit -d) less its data now (VmData) and those
// threads' stacks. `peakThreads`: how many threads the command will have at most (its libraries' pools
// included); those beyond the ones running now are the threads yet to start.
MemoryBudget memoryBudget(const std::optional<std::uint64_t>& requested, unsigned peakThreads);

// The threads a command that traces with TBB and writes images with OpenImageIO has at its peak, pools
// included: TBB's workers, OpenImageIO's and OpenEXR's pools (one per hardware thread each), and the main thread.
unsigned tracingCommandThreads(int threadsOption);

// Throws vs::Error(BadInput) "<what> about <need> of memory, more than the budget of <budget> (<setBy>);
// <advice>" when need exceeds the budget; `what` ends in its verb ("... shadow layers need").
void checkMemoryNeed(std::uint64_t need, const MemoryBudget& budget, const std::string& what, const std::string& advice);

}  // namespace vs::cli

#endif
