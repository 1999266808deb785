// bench_loop.h: `voxshadow bench --loop`, a scripted game loop over the demo scene (DESIGN.md §11): five
// phases of frames that change the scene a little each (still, camera pan, a walking actor, digging, a setting
// sun), each frame's time and what it did beside a forced full frame of the same state.
#ifndef VOXSHADOW_TOOLS_BENCH_LOOP_H
#define VOXSHADOW_TOOLS_BENCH_LOOP_H

#include <filesystem>
#include <optional>

namespace vs::cli {

struct LoopBenchOptions {
  bool vulkan = false;   // the Vulkan backend after the CPU backend
  int frames = 100;      // per phase, 1..100000
  int fullEvery = 1;     // a forced full frame after every fullEvery-th frame of a phase, >= 1
  int threads = 2;       // CPU tracer threads
  int width = 1280, height = 720;
  int shadowDivisor = 1;  // every shadow resolution divided by this power of two (at least 16): quick runs
  std::optional<std::filesystem::path> csv;   // one row per frame
  std::optional<std::filesystem::path> plot;  // .png: frame times drawn by tools/plot_loop.py
};

// Runs every phase on each backend and prints a table and one `loop ...` line per backend and phase.
// Bad options and output paths throw vs::Error(BadInput) before any work; a missing plotting tool is
// vs::Error(Runtime), also before any work.
void runLoopBench(const LoopBenchOptions& options);

}  // namespace vs::cli

#endif
