// portable.h: the few words that let one header be read both as GLSL 4.50 and as C++20.
//
// GPU-visible records and the traversal are written once in this common subset. A GLSL includer
// defines VS_GLSL before including; C++ sees glm types under the GLSL names, inside namespace vs::gpu.
// Rules for portable code: float literals carry an `f` suffix (glm does not mix float and double),
// no implicit narrowing, no recursion, no pointers, arrays are read through buffer names.
#ifndef VOXSHADOW_PORTABLE_H
#define VOXSHADOW_PORTABLE_H

#ifdef VS_GLSL
#define VS_INOUT(T) inout T
#define VS_OUT(T) out T
#define VS_PRECISE precise
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
#define VS_INOUT(T) T&
#define VS_OUT(T) T&
#define VS_PRECISE
#define VS_NAMESPACE_BEGIN \
  namespace vs::gpu {      \
  using namespace glm;     \
  using uint = std::uint32_t;
#define VS_NAMESPACE_END }
#define VS_LAYOUT_CHECK(Type, size) \
  static_assert(sizeof(Type) == (size), #Type " size must match std430 layout")
#define VS_OFFSET_CHECK(Type, member, offset) \
  static_assert(offsetof(Type, member) == (offset), #Type "." #member " offset must match std430")
#endif

#endif
