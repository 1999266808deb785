// evsm.h: exponential variance shadow maps (DESIGN.md §7), one source compiled as GLSL (the lighting shader and
// the moment pass, lighting/shaders/evsm_moments.comp) and as C++ (lighting/evsm.cpp, lighting/deferred.cpp).
//
// A layer's depth d maps to t = 2 clamp(d / miss value, 0, 1) - 1 and warps to p = e^(c+ t) and n = -e^(-c- t);
// its moments are (p, p^2, n, n^2), box-blurred over (2r + 1)^2 texels, and a receiver of warped depths (p', n')
// is lit with the smaller of the two one-tailed Chebyshev bounds. Every step of the moments is a sum or a
// product that IEEE rounds alike on every Vulkan device that rounds to nearest even (as the trace core also
// assumes; Vulkan 1.0 leaves the mode to the device) and on the CPU (no fused multiply-add: VS_PRECISE), so
// both backends produce the same moment bits; the bounds divide, and are compared as the lighting is.
#ifndef VOXSHADOW_EVSM_H
#define VOXSHADOW_EVSM_H

#include "voxel/exact_fp.h"
#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// ln 2 in two parts, the first with 15 significant bits, so that k * VS_EXP_LN2_HIGH is exact for |k| < 2^9.
const float VS_EXP_LN2_HIGH = 0.693145751953125f;
const float VS_EXP_LN2_LOW = 1.4286068e-06f;
const float VS_EXP_LOG2E = 1.442695f;
// 1/7! .. 1/3!, written as the floats they round to (no constant folding to differ between compilers).
const float VS_EXP_C7 = 1.984127e-04f;
const float VS_EXP_C6 = 1.3888889e-03f;
const float VS_EXP_C5 = 8.333334e-03f;
const float VS_EXP_C4 = 4.1666668e-02f;
const float VS_EXP_C3 = 1.6666667e-01f;

// The narrowest depth spread the bounds assume (a share of the warped range [-1, 1]): a flat lit surface has
// no variance, and the rounding of p^2 - p * p would otherwise decide its light.
const float VS_EVSM_MIN_SPREAD = 0.0002f;

// e^x for |x| <= 84 (the moments' range), from +, -, * and an exponent set in the bits. GLSL's exp has the
// device's precision, so the moments would differ by backend; this one rounds the same everywhere. Relative
// error below 2.5e-7, the test's bound (9.9e-8 measured).
VS_INLINE float vsExpExact(float x) {
  VS_PRECISE float k = floor(x * VS_EXP_LOG2E + 0.5f);
  VS_PRECISE float r = (x - k * VS_EXP_LN2_HIGH) - k * VS_EXP_LN2_LOW;
  // e^r for |r| <= 0.347, Taylor to r^7 (the r^8 term is below 5e-9), by Horner.
  VS_PRECISE float q = r * VS_EXP_C7 + VS_EXP_C6;
  q = q * r + VS_EXP_C5;
  q = q * r + VS_EXP_C4;
  q = q * r + VS_EXP_C3;
  q = q * r + 0.5f;
  q = q * r + 1.0f;
  q = q * r + 1.0f;
  VS_PRECISE float scaled = q * intBitsToFloat((int(k) + 127) << 23);
  return scaled;
}

// A stored or receiver depth's moments: (p, p^2, n, n^2). scale: 1 / the layer's miss value; exponents: (c+, c-).
VS_INLINE vec4 vsEvsmWarp(float depth, float scale, vec2 exponents) {
  VS_PRECISE float t = clamp(depth * scale, 0.0f, 1.0f) * 2.0f - 1.0f;
  VS_PRECISE float p = vsExpExact(exponents.x * t);
  VS_PRECISE float n = -vsExpExact(-exponents.y * t);
  VS_PRECISE vec4 m = vec4(p, p * p, n, n * n);
  return m;
}

// The one-tailed Chebyshev bound on the share of a region's occluders at or behind warped depth w, from the
// region's mean and mean square: 1 when w is at most the mean.
VS_INLINE float vsChebyshev(vec2 moments, float w, float minVariance) {
  if (w <= moments.x) return 1.0f;
  float variance = max(moments.y - moments.x * moments.x, minVariance);
  float d = w - moments.x;
  return variance / (variance + d * d);
}

// The EVSM shadow term of a receiver at `depth` (the layer's encoding) from the (filtered) moments at its
// texel. evsm: ShadeLight.evsm. The smaller bound of the two warps, with the light-bleeding reduction: bounds
// at or below evsm.z read as shadow and the rest is stretched to [0, 1].
VS_INLINE float vsEvsmShadow(vec4 moments, float depth, float scale, vec4 evsm) {
  vec4 w = vsEvsmWarp(depth, scale, vec2(evsm.x, evsm.y));
  // The least variance: VS_EVSM_MIN_SPREAD of depth through each warp's slope there (c e^(c t)).
  float spreadP = VS_EVSM_MIN_SPREAD * evsm.x * w.x;
  float spreadN = VS_EVSM_MIN_SPREAD * evsm.y * w.z;
  float positive = vsChebyshev(vec2(moments.x, moments.y), w.x, spreadP * spreadP);
  float negative = vsChebyshev(vec2(moments.z, moments.w), w.z, spreadN * spreadN);
  float s = min(positive, negative);
  return clamp((s - evsm.z) / (1.0f - evsm.z), 0.0f, 1.0f);
}

VS_NAMESPACE_END

#endif
