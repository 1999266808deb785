#include "tools/progress.h"

#include <cstdio>
#include <unistd.h>

namespace vs {

namespace {
constexpr auto kRedrawInterval = std::chrono::milliseconds(100);
constexpr int kBarWidth = 30;
}  // namespace

Progress::Progress(std::string label, bool enabled)
    : label_(std::move(label)), enabled_(enabled), start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() { finish(); }

bool Progress::stderrIsTerminal() { return ::isatty(STDERR_FILENO) == 1; }

void Progress::update(std::uint64_t done, std::uint64_t total) {
  if (!enabled_) return;
  std::lock_guard lock(mutex_);
  if (finished_) return;
  lastDone_ = done;
  lastTotal_ = total;
  auto now = std::chrono::steady_clock::now();
  if (drawn_ && done < total && now - lastDraw_ < kRedrawInterval) return;
  lastDraw_ = now;
  draw(done, total);
}

void Progress::finish() {
  if (!enabled_) return;
  std::lock_guard lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (!drawn_) return;  // nothing on screen: leave the terminal alone
  draw(lastDone_, lastTotal_);
  std::fputc('\n', stderr);
  std::fflush(stderr);
}

void Progress::draw(std::uint64_t done, std::uint64_t total) {
  drawn_ = true;
  double fraction = total ? double(done) / double(total) : 1.0;
  if (fraction > 1.0) fraction = 1.0;
  int filled = int(fraction * kBarWidth);
  std::string bar(std::size_t(filled), '#');
  bar.append(std::size_t(kBarWidth - filled), '-');
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  // \r and clear-to-end-of-line keep the bar on one line however the label or counts change width.
  std::fprintf(stderr, "\r%s [%s] %3d%% %llu/%llu %.1fs\x1b[K", label_.c_str(), bar.c_str(), int(fraction * 100.0),
               static_cast<unsigned long long>(done), static_cast<unsigned long long>(total), seconds);
  std::fflush(stderr);
}

}  // namespace vs
