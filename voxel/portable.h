// portable.h: the few words that let one header be read both as GLSL 4.50 and as C++20.
//
// GPU-visible records and the traversal are written once in this common subset. A GLSL includer
// defines VS_GLSL before including; C++ sees glm types under the GLSL names, inside namespace vs::gpu.
// Rules for portable code: float literals carry an `f` suffix (glm does not mix float and double),
// no implicit narrowing, no recursion, no pointers, arrays are read through buffer names.
#ifndef VOXSHADOW_PORTABLE_H
#define VOXSHADOW_PORTABLE_H

#ifdef VS_GLSL
#define VS_IN(T) T
#define VS_INOUT(T) inout T
#define VS_OUT(T) out T
#define VS_PRECISE precise
#define VS_INLINE
#define VS_ALWAYS_INLINE
#define VS_NAMESPACE_BEGIN
#define VS_NAMESPACE_END
#define VS_LAYOUT_CHECK(Type, size)
#define VS_OFFSET_CHECK(Type, member, offset)
#else
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/bitfield.hpp>
#include <glm/integer.hpp>
#define VS_IN(T) const T&
#define VS_INOUT(T) T&
#define VS_OUT(T) T&
#define VS_PRECISE
// A function defined in a shared header read at namespace scope (not inside an includer's struct).
#define VS_INLINE inline
// A small function of a ray's set-up that every walk runs: inlined whatever the caller's size (GCC otherwise
// keeps it out of line in the large lane drivers, and the calls showed as a third of a CPU frame's samples).
#define VS_ALWAYS_INLINE __attribute__((always_inline))
#define VS_NAMESPACE_BEGIN \
  namespace vs::gpu {      \
  using namespace glm;     \
  using uint = std::uint32_t;
#define VS_NAMESPACE_END }
// v rounded to float, component by component, with the rounding guaranteed to happen. The exact splits of the
// host (an eye or ray origin into high + low floats, an instance's anchor) subtract the rounded value from the
// double one; GCC 12's vectorizer was seen keeping a glm double-to-float conversion at double precision
// (-O2, and -O3 -march=native), which made such a low part zero and an anchor differ from the one stored.
// A volatile store cannot be elided.
// The host helpers of the shared headers are static inline: a consumer's translation unit, compiled with its
// own floating-point flags, keeps its own copy instead of lending it to voxshadow's code through the linker.
namespace vs::gpu {
static inline glm::vec3 roundedToFloat(const glm::dvec3& v) {
  volatile float x = static_cast<float>(v.x), y = static_cast<float>(v.y), z = static_cast<float>(v.z);
  return glm::vec3(x, y, z);
}
// v as high + low floats (their sum holds v to about 48 bits): high is v rounded, low the rest, rounded.
static inline void splitToFloats(const glm::dvec3& v, glm::vec3& high, glm::vec3& low) {
  high = roundedToFloat(v);
  low = glm::vec3(v - glm::dvec3(high));
}
}  // namespace vs::gpu
#define VS_LAYOUT_CHECK(Type, size) \
  static_assert(sizeof(Type) == (size), #Type " size must match std430 layout")
#define VS_OFFSET_CHECK(Type, member, offset) \
  static_assert(offsetof(Type, member) == (offset), #Type "." #member " offset must match std430")
#endif

#endif
