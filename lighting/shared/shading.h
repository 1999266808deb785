// shading.h: the deferred lighting pass's per-pixel arithmetic (DESIGN.md §7): each light's shadow term
// (lighting/shared/shadow_lookup.h) and radiance summed into the lit colour. One source compiled as GLSL (the
// lighting shader, lighting/shaders/deferred_lighting.comp) and as C++ (lighting/deferred.cpp), so that the CPU
// path shades with exactly the shader's steps.
//
// The includer provides what shadow_lookup.h reads (shadowTexels, vsLoadView, vsLoadMoments), and, as arrays
// or buffer members of these names:
//   shadeLights[i] (ShadeLight)
//   rayVisibility[i] (uint): per pixel and light (pixel * lightCount + light), 1 where the exact visibility
//     ray toward the light (its whole length for ray-traced shadows, the contact length otherwise) is clear,
//     and where no ray was traced (a light without one, a receiver beyond its range: the term ignores it)
//   shadowTerms[i] (float, written): per pixel and light, the shadow term vsShadePixel used
//   with VS_LIGHTING_VARIANT defined (the shader build that pipeline variants specialise):
//     vsSpecializedLightCount, vsSpecializedMode, vsSpecializedRaytraced, vsSpecializedLight (see vsShadePixel)
// The includer includes lighting/shared/evsm.h first. C++ includes this inside a struct that holds those members (lighting/cpu_shading.h).
#ifndef VOXSHADOW_SHADING_H
#define VOXSHADOW_SHADING_H

#include "lighting/shared/shadow_lookup.h"

// Light l's share of pixel `pixel` (G-buffer texel g): its shadow term, written to shadowTerms and added to
// shadowSum, its radiance added to `radiance`, and, when `wantCascade`, the cascade of the first directional
// light with shadows.
void vsShadeLight(int pixel, int l, int lightCount, VS_IN(ShadeLight) light, VS_IN(GBufferTexel) g, bool raytraced,
                  bool wantCascade, VS_INOUT(vec3) radiance, VS_INOUT(float) shadowSum, VS_INOUT(int) cascade) {
  float s = vsShadowTerm(light, g, rayVisibility[pixel * lightCount + l], raytraced);
  shadowTerms[pixel * lightCount + l] = s;
  shadowSum += s;
  radiance += vsLightRadiance(light, g, s);
  if (wantCascade && cascade < 0 && light.info.x == VS_LIGHT_DIRECTIONAL && light.info.y != VS_FILTER_NONE)
    cascade = vsCascadeOf(light, vec3(g.position), g.position.w);
}

#ifndef VS_LIGHTING_VARIANT
// The general build (C++, and the general shader): every value as the records and the push block give it.
int vsSpecializedLightCount(int n) { return n; }
int vsSpecializedMode(int m) { return m; }
bool vsSpecializedRaytraced(bool r) { return r; }
#endif

// The colour of pixel `pixel` (G-buffer texel g) in the push block's mode, writing each light's shadow term
// to shadowTerms. push.flags.x: the exact visibility rays replace the shadow maps.
// The build that pipeline variants specialise (VS_LIGHTING_VARIANT; lighting/lighting_variant.h) has its
// includer provide the hooks vsSpecializedLightCount(n), vsSpecializedMode(m), vsSpecializedRaytraced(r) and
// vsSpecializedLight(l, light), which replace the dynamic values by the variant's constants, and shades each of
// the first VS_LIGHTING_SPECIALIZED_LIGHTS lights by its own call with a constant index, so that a variant holds
// only the code of each light's own kind, filter and view count: a CPU device (llvmpipe) runs every branch that
// any lane of a group takes, and the general build runs every filter of every light. The lights are summed in
// index order in both builds.
vec4 vsShadePixel(VS_IN(ShadePush) push, int pixel, VS_IN(GBufferTexel) g) {
  bool raytraced = vsSpecializedRaytraced(push.flags.x != 0);
  int lightCount = vsSpecializedLightCount(push.size.z);
  int mode = vsSpecializedMode(push.size.w);
  if (g.info.w == 0u) {
    for (int l = 0; l < lightCount; ++l) shadowTerms[pixel * lightCount + l] = 1.0f;
    return vec4(vec3(push.sky), 0.0f);
  }
  vec3 radiance = vec3(push.ambient);
  float shadowSum = 0.0f;
  int cascade = -1;
  bool wantCascade = mode == VS_SHADE_DEBUG_CASCADES;
#ifdef VS_LIGHTING_VARIANT
  // The specialised lights one call each (each index a constant), then a loop over any others.
  const int slots = min(lightCount, int(VS_LIGHTING_SPECIALIZED_LIGHTS));
  // (A macro, not a loop: the index must be a constant where the variant's constants are read.)
#define VS_SHADE_SLOT(k)                                                                                       \
  if (k < slots)                                                                                               \
    vsShadeLight(pixel, k, lightCount, vsSpecializedLight(k, shadeLights[k]), g, raytraced, wantCascade, radiance, \
                 shadowSum, cascade)
  VS_SHADE_SLOT(0); VS_SHADE_SLOT(1); VS_SHADE_SLOT(2); VS_SHADE_SLOT(3);
  VS_SHADE_SLOT(4); VS_SHADE_SLOT(5); VS_SHADE_SLOT(6); VS_SHADE_SLOT(7);
#undef VS_SHADE_SLOT
#else
  const int slots = 0;
#endif
  for (int l = slots; l < lightCount; ++l)
    vsShadeLight(pixel, l, lightCount, shadeLights[l], g, raytraced, wantCascade, radiance, shadowSum, cascade);
  vec3 lit = vec3(g.albedo) * radiance;
  if (mode == VS_SHADE_DEBUG_NORMALS) return vec4(vec3(g.normal) * 0.5f + vec3(0.5f), 1.0f);
  if (mode == VS_SHADE_DEBUG_SHADOW) return vec4(vec3(lightCount > 0 ? shadowSum / float(lightCount) : 1.0f), 1.0f);
  if (mode == VS_SHADE_DEBUG_CASCADES) {
    vec3 tint = vec3(1.0f);
    if (cascade == 0) tint = vec3(1.0f, 0.35f, 0.35f);
    if (cascade == 1) tint = vec3(0.35f, 1.0f, 0.35f);
    if (cascade == 2) tint = vec3(0.35f, 0.35f, 1.0f);
    if (cascade == 3) tint = vec3(1.0f, 1.0f, 0.35f);
    return vec4(lit * tint, 1.0f);
  }
  return vec4(lit, 1.0f);
}

#endif
