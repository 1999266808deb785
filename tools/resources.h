// resources.h: the machine resources a command may use: thread counts, memory budgets, byte sizes.
#ifndef VOXSHADOW_TOOLS_RESOURCES_H
#define VOXSHADOW_TOOLS_RESOURCES_H

#include <cstdint>
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

}  // namespace vs::cli

#endif
