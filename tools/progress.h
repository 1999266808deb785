// progress.h: a progress bar on stderr for long work, drawn only when stderr is a terminal.
#ifndef VOXSHADOW_TOOLS_PROGRESS_H
#define VOXSHADOW_TOOLS_PROGRESS_H

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace vs {

class Progress {
 public:
  // `label` prefixes the bar. enabled: draw at all; by default only when stderr is a terminal, so logs
  // and pipes never receive control characters.
  explicit Progress(std::string label, bool enabled = stderrIsTerminal());
  ~Progress();  // calls finish()
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // Thread-safe; callable from worker threads. Redraws at most every 100 ms (and on reaching total).
  // Preconditions: done <= total. Updates after finish() are ignored.
  void update(std::uint64_t done, std::uint64_t total);
  // Draws the final state and ends the line; idempotent.
  void finish();

  bool enabled() const { return enabled_; }
  static bool stderrIsTerminal();

 private:
  void draw(std::uint64_t done, std::uint64_t total);  // caller holds mutex_

  std::string label_;
  bool enabled_;
  bool finished_ = false;
  bool drawn_ = false;
  std::uint64_t lastDone_ = 0, lastTotal_ = 0;
  std::chrono::steady_clock::time_point lastDraw_{};
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
};

}  // namespace vs

#endif
