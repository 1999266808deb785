// lanes.h: the lane vocabulary of one ray, for GLSL and scalar C++.
//
// The walk pieces of compute/shared/lane_walk.h are written against this vocabulary: a float, an int and a
// bool of one lane (LFloat, LInt, LBool), conversions by constructor syntax (LFloat(i), LInt(f) truncates),
// the operators, and
//   vsSelect(c, a, b)  a where c, else b;
//   min, max, clamp    glm's operand order: min(x, y) = y < x ? y : x, max(x, y) = x < y ? y : x, which fixes
//                      the sign of a zero result when the operands are +0 and -0;
//   floor, abs;
//   vsLaneAny(b)       whether any lane of b is set (the lane itself here);
//   LVec3              three LFloat x, y, z with componentwise +, -, * (also by an LFloat), unary -, abs, and
//                      LVec3(s) / LVec3(vec3) / LVec3(x, y, z) construction;
//   vsMaskFloatBits(x, mask)  x with only the bits of mask kept.
// A shader invocation and a scalar C++ ray are one lane, so these are the plain types and built-ins.
// compute/cpu/lanes_avx2.h and lanes_avx512.h give the same vocabulary over 8 and 16 lanes, so that the same
// source runs as SIMD code with every lane performing the same IEEE operations in the same order.
#ifndef VOXSHADOW_LANES_H
#define VOXSHADOW_LANES_H

#include "voxel/exact_fp.h"
#include "voxel/portable.h"

#ifdef VS_GLSL
#define LFloat float
#define LInt int
#define LBool bool
#define LVec3 vec3
#define VS_LANE_INLINE
// A shader's lanes pay for any branch one of them takes: settling every coordinate is the cheaper way.
#define VS_SETTLE_ALWAYS true
#else
VS_NAMESPACE_BEGIN
using LFloat = float;
using LInt = int;
using LBool = bool;
using LVec3 = glm::vec3;
#define VS_LANE_INLINE inline
// One ray at a time, or lanes that rarely need it: settle only near a plane (compute/shared/lane_walk.h).
#define VS_SETTLE_ALWAYS false
#endif

// Division and square root rounded correctly on every device. Vulkan asks only addition, subtraction and
// multiplication to round correctly; a division may be 2.5 ulp off and a square root more, and NVIDIA's driver
// uses that room (a spot view's texel rays on an H200 differed from the CPU's in 16% of city512's texels). In
// the shader they go through double, whose result rounds to the correctly rounded float (53 >= 2 * 24 + 2
// bits, so rounding twice is harmless even with a few ulp of double error); C++ rounds correctly already.
// VS_DIV serves every lane type (the C++ lanes' operator/ is the IEEE division of each lane).
#ifdef VS_GLSL
// An orthographic view's points have w = 1 exactly: a branch that every lane of such a view takes alike
// skips their divisions through double, which cost lavapipe 15% of a sun view's speed.
float vsDivRounded(float a, float b) { return b == 1.0f ? a : float(double(a) / double(b)); }
float vsSqrtRounded(float x) { return float(sqrt(double(x))); }
#define VS_DIV(a, b) vsDivRounded(a, b)
#define VS_SQRT(x) vsSqrtRounded(x)
#else
#define VS_DIV(a, b) ((a) / (b))
#define VS_SQRT(x) sqrt(x)
#endif

VS_LANE_INLINE int vsSelect(bool c, int a, int b) { return c ? a : b; }
VS_LANE_INLINE float vsSelect(bool c, float a, float b) { return c ? a : b; }
VS_LANE_INLINE bool vsSelect(bool c, bool a, bool b) { return c ? a : b; }
VS_LANE_INLINE bool vsLaneAny(bool b) { return b; }
// x with only the bits of `mask` kept.
VS_LANE_INLINE float vsMaskFloatBits(float x, uint mask) { return uintBitsToFloat(floatBitsToUint(x) & mask); }

#ifndef VS_GLSL
VS_NAMESPACE_END
#endif

#endif
