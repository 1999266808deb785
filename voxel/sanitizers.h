// sanitizers.h: whether this translation unit is built with AddressSanitizer (GCC and clang spell it apart),
// for the few places where an instrumented build must act differently: tests whose checks the runtime itself
// changes, and libraries that must stay loaded for LeakSanitizer to see their globals.
#ifndef VOXSHADOW_VOXEL_SANITIZERS_H
#define VOXSHADOW_VOXEL_SANITIZERS_H

namespace vs {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kAddressSanitized = true;
#else
inline constexpr bool kAddressSanitized = false;
#endif
#else
inline constexpr bool kAddressSanitized = false;
#endif

}  // namespace vs

#endif
