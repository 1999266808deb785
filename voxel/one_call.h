// one_call.h: the guard of objects that serve one call at a time (FrameRenderer, VulkanTracer).
#ifndef VOXSHADOW_ONE_CALL_H
#define VOXSHADOW_ONE_CALL_H

#include <atomic>
#include <string>

#include "voxel/error.h"

namespace vs {

// Holds `busy` for one call's length. A call that finds it held (another thread is inside the same object) is
// refused with vs::Error(Runtime) "<object>::<call>: another thread is using this <noun>; <advice>" before it
// touches anything; the holder is not disturbed. Detects overlap, not order: calls from several threads one
// after another are fine.
class OneCallAtATime {
 public:
  OneCallAtATime(std::atomic<bool>& busy, const char* object, const char* call, const char* noun, const char* advice)
      : busy_(busy) {
    bool idle = false;
    if (!busy_.compare_exchange_strong(idle, true, std::memory_order_acquire))
      throwRuntime(std::string(object) + "::" + call + ": another thread is using this " + noun + "; " + advice);
  }
  ~OneCallAtATime() { busy_.store(false, std::memory_order_release); }
  OneCallAtATime(const OneCallAtATime&) = delete;
  OneCallAtATime& operator=(const OneCallAtATime&) = delete;

 private:
  std::atomic<bool>& busy_;
};

}  // namespace vs

#endif
