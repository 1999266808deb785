// deferred.h: the deferred lighting pass (DESIGN.md §7): the shading records built from a scene's lights and
// traced shadow layers, and the pass itself on the CPU, running lighting/shared/shading.h as C++ (the
// Vulkan pass runs the same source as GLSL: lighting/vulkan_lighting.h).
#ifndef VOXSHADOW_DEFERRED_H
#define VOXSHADOW_DEFERRED_H

#include <cstdint>
#include <span>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "lighting/gbuffer.h"
#include "lighting/light_views.h"
#include "lighting/scene_file.h"
#include "lighting/shared/shading_layout.h"

namespace vs {

// What the pass reads besides the G-buffer: one ShadeLight per scene light (scene order), one ShadeView per
// traced layer, and every layer's texels one after another.
struct ShadeInputs {
  std::vector<gpu::ShadeLight> lights;
  std::vector<gpu::ShadeView> views;
  std::vector<float> shadowTexels;
  // Per light: the length of its visibility rays (0: none needed; a contact-shadow length; or, for
  // ray-traced shadows, unbounded as -1).
  std::vector<float> rayLength;
  // EVSM (lighting/evsm.h): texels of the moment store that the views of EVSM lights index (ShadeView.trace.w),
  // and the store itself for the CPU pass (computeMomentsOnCpu fills it; the Vulkan pass keeps its own).
  std::size_t momentTexels = 0;
  std::vector<glm::vec4> moments;
};

// Preconditions: views as buildLightViews gave them for scene, layers[i] traced from views[i] and stored as
// FrameRenderer stores it (ring order for cascades: traceLayers in lighting/renderer.h).
// raytraced: every light gets a whole visibility ray instead of its shadow maps. The EVSM lights' moments are
// computed whole (on the CPU).
ShadeInputs makeShadeInputs(const SceneDesc& scene, std::span<const LightView> views,
                            std::span<const ShadowLayer> layers, bool raytraced);

// The same records with shadowTexels left empty: the views' layers take resolution^2 texels each, in view order,
// from views[i].info.x on, and a caller that keeps the layers in place sizes and fills the store itself
// (FrameRenderer: a frame whose layout did not move hands its kept store over instead of allocating one).
ShadeInputs makeShadeRecords(const SceneDesc& scene, std::span<const LightView> views, bool raytraced);

// Texels the views' layers take together: the store makeShadeRecords' views index into.
std::size_t shadeStoreTexels(std::span<const LightView> views);

// The push block of a frame: ambient, sky colour, size, light count, mode (VS_SHADE_*) and shadow source.
gpu::ShadePush makeShadePush(const SceneDesc& scene, int width, int height, int mode, bool raytraced);

struct ShadeOutput {
  std::vector<glm::vec4> color;    // per pixel, linear
  std::vector<float> shadowTerms;  // per pixel and light (pixel * lights + light)
};

// The pass on the CPU (TBB over rows). rayVisibility: per pixel and light, 1 where its visibility ray is clear
// (traceAny's answers inverted), or empty when no light needs rays. Preconditions: gbuffer and push agree on
// the size; inputs from makeShadeInputs for the same lights and shadow source as the push block.
ShadeOutput shadeOnCpu(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                       std::span<const std::uint32_t> rayVisibility);

// The same into `out`, resized to the frame: a frame loop hands last frame's buffers back, so that a frame
// touches no new page.
void shadeOnCpu(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                std::span<const std::uint32_t> rayVisibility, ShadeOutput& out);

// The same for the given pixels only (row-major indices, each at most once): their colours and shadow terms in
// `out`, sized for the frame (else vs::Error(BadInput)), are replaced; the others are left as they are.
void shadeOnCpu(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                std::span<const std::uint32_t> rayVisibility, std::span<const std::uint32_t> pixels, ShadeOutput& out);

// The checks both passes make: the G-buffer, the push block and the lights agree on sizes, and there is one
// visibility answer per pixel and light; returns those answers, or all-clear ones (kept in `clear`) when none
// were given. Throws vs::Error(BadInput) on a mismatch.
std::span<const std::uint32_t> checkShadeSizes(const ShadeInputs& inputs, const gpu::ShadePush& push,
                                               const GBuffer& gbuffer, std::span<const std::uint32_t> rayVisibility,
                                               std::vector<std::uint32_t>& clear);

// The shadow term of light `light` at one G-buffer texel, as the pass computes it (for tests and tools that
// probe fixed world points). visibility: that pixel's ray answer (1: clear).
float shadowTermAt(const ShadeInputs& inputs, std::size_t light, const gpu::GBufferTexel& texel,
                   std::uint32_t visibility = 1u, bool raytraced = false);

}  // namespace vs

#endif
