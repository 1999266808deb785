// lighting_variant.h: the lighting shader's pipeline variants, named by what they specialise (the frame's
// lights' kinds, filters and view counts, the debug mode, ray-traced shadows), and their specialisation
// constants (lighting/shared/lighting_interface.h, VS_LIGHTING_SPEC_*).
//
// Why variants: a CPU device (llvmpipe) runs every branch that any lane of a group takes, so the one shader
// that serves every filter of every light ran all of them for each light of each pixel (1.6x the time of the
// specialised shader on the demo frame on lavapipe). A variant whose constants say which code each light runs holds only
// that code. The constants are the same values the records carry, so a variant shades exactly as the general
// shader (and the CPU pass) does.
#ifndef VOXSHADOW_LIGHTING_VARIANT_H
#define VOXSHADOW_LIGHTING_VARIANT_H

#include <array>
#include <compare>
#include <cstdint>
#include <span>

#include "lighting/shared/lighting_interface.h"
#include "lighting/shared/shading_layout.h"

namespace vs {

// deferred_lighting.comp declares the constants of this many lights and shading.h gives as many their own call.
static_assert(gpu::VS_LIGHTING_SPECIALIZED_LIGHTS == 8, "the lighting shader's light slots are written out for 8");

struct LightingVariant {
  // -1 in any field: not specialised (the shader reads the records).
  struct Light {
    std::int32_t kind = -1;     // VS_LIGHT_*
    std::int32_t filter = -1;   // VS_FILTER_*
    std::int32_t views = -1;    // its view count
    auto operator<=>(const Light&) const = default;
  };
  std::int32_t lightCount = -1;
  std::int32_t mode = -1;       // VS_SHADE_*
  std::int32_t raytraced = -1;  // 0 or 1
  std::array<Light, gpu::VS_LIGHTING_SPECIALIZED_LIGHTS> lights{};

  auto operator<=>(const LightingVariant&) const = default;

  // The variant for a frame of these lights and push block: fully specialised when the lights fit the
  // shader's slots, else the general one (every field -1).
  static LightingVariant of(std::span<const gpu::ShadeLight> frameLights, const gpu::ShadePush& push) {
    LightingVariant v;
    if (frameLights.size() > gpu::VS_LIGHTING_SPECIALIZED_LIGHTS) return v;
    v.lightCount = std::int32_t(frameLights.size());
    v.mode = push.size.w;
    v.raytraced = push.flags.x != 0 ? 1 : 0;
    for (std::size_t l = 0; l < frameLights.size(); ++l)
      v.lights[l] = {frameLights[l].info.x, frameLights[l].info.y, frameLights[l].info.w};
    return v;
  }

  // The constants in constant_id order (VS_LIGHTING_SPEC_*).
  std::array<std::int32_t, gpu::VS_LIGHTING_SPEC_COUNT> constants() const {
    std::array<std::int32_t, gpu::VS_LIGHTING_SPEC_COUNT> c{};
    c[gpu::VS_LIGHTING_SPEC_LIGHT_COUNT] = lightCount;
    c[gpu::VS_LIGHTING_SPEC_MODE] = mode;
    c[gpu::VS_LIGHTING_SPEC_RAYTRACED] = raytraced;
    for (std::size_t l = 0; l < lights.size(); ++l) {
      const std::size_t first = gpu::VS_LIGHTING_SPEC_FIRST_LIGHT + 3 * l;
      c[first] = lights[l].kind;
      c[first + 1] = lights[l].filter;
      c[first + 2] = lights[l].views;
    }
    return c;
  }
};

}  // namespace vs

#endif
