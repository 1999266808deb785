// deferred.cpp: shading records and the CPU lighting pass.
#include "lighting/deferred.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "lighting/cpu_shading.h"
#include "lighting/evsm.h"
#include "voxel/error.h"

namespace vs {

namespace {

int filterCode(ShadowFilter f) {
  switch (f) {
    case ShadowFilter::Hard: return gpu::VS_FILTER_HARD;
    case ShadowFilter::Pcf3: return gpu::VS_FILTER_PCF3;
    case ShadowFilter::Pcf5: return gpu::VS_FILTER_PCF5;
    case ShadowFilter::Poisson16: return gpu::VS_FILTER_POISSON16;
    case ShadowFilter::Pcss: return gpu::VS_FILTER_PCSS;
    case ShadowFilter::Evsm: return gpu::VS_FILTER_EVSM;
  }
  return gpu::VS_FILTER_HARD;
}

// The CPU pass reads the moments of EVSM views from inputs.moments (makeShadeInputs or the frame loop fill it).
void checkMomentStore(const ShadeInputs& inputs) {
  if (inputs.moments.size() != inputs.momentTexels)
    throwBadInput("lighting: the EVSM moment store holds " + std::to_string(inputs.moments.size()) + " texels, its views " +
                  std::to_string(inputs.momentTexels));
}

// How many pixels ahead the whole-frame pass asks for G-buffer texels (8 measured on the demo; not tuned).
constexpr std::size_t kShadePrefetch = 8;

int lightCode(LightType t) {
  switch (t) {
    case LightType::Directional: return gpu::VS_LIGHT_DIRECTIONAL;
    case LightType::Spot: return gpu::VS_LIGHT_SPOT;
    case LightType::Point: return gpu::VS_LIGHT_POINT;
  }
  return gpu::VS_LIGHT_DIRECTIONAL;
}

}  // namespace

ShadeInputs makeShadeInputs(const SceneDesc& scene, std::span<const LightView> views,
                            std::span<const ShadowLayer> layers, bool raytraced) {
  if (layers.size() != views.size()) throwBadInput("lighting: " + std::to_string(layers.size()) + " layers for " +
                                                   std::to_string(views.size()) + " views");
  for (std::size_t i = 0; i < views.size(); ++i)
    if (layers[i].width != views[i].resolution || layers[i].height != views[i].resolution)
      throwBadInput("lighting: layer " + views[i].name + " is " + std::to_string(layers[i].width) + "x" +
                    std::to_string(layers[i].height) + ", its view " + std::to_string(views[i].resolution) + " square");
  ShadeInputs in = makeShadeRecords(scene, views, raytraced);
  in.shadowTexels.resize(shadeStoreTexels(views));
  std::size_t at = 0;
  for (const ShadowLayer& layer : layers) {
    std::copy(layer.texels.begin(), layer.texels.end(), in.shadowTexels.begin() + std::ptrdiff_t(at));
    at += layer.texels.size();
  }
  computeMomentsOnCpu(in, momentWork(views, in, wholeMomentRects(in)), in.moments);
  return in;
}

ShadeInputs makeShadeRecords(const SceneDesc& scene, std::span<const LightView> views, bool raytraced) {
  ShadeInputs in;
  std::size_t texels = 0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const LightView& v = views[i];
    gpu::ShadeView sv{};
    sv.eyeToClip = glm::mat4(v.eyeToClip);
    sv.clipToEye = v.trace.clipToEye;
    sv.eye = glm::vec4(glm::vec3(v.trace.eyeHigh), float(v.texelWorld));
    sv.eyeLow = glm::vec4(glm::vec3(v.trace.eyeLow), float(1.0 / double(v.range)));
    const glm::ivec2 ring = ringOffset(v);
    const LightDesc& light = scene.lights[std::size_t(v.lightIndex)];
    int moments = -1;
    if (light.shadow && light.shadow->filter == ShadowFilter::Evsm && !raytraced) {
      moments = int(in.momentTexels);
      in.momentTexels += std::size_t(v.resolution) * std::size_t(v.resolution);
    }
    sv.trace = glm::ivec4(v.depthPoint, ring.x, ring.y, moments);
    // World units per unit of encoded depth: an orthographic view's NDC depth is linear in the distance along
    // the light, at the rate of its projection's z row.
    double depthScale = 1.0;
    if (v.encoding == gpu::VS_ENCODING_NDC_DEPTH) {
      const glm::dvec3 row(v.eyeToClip[0][2], v.eyeToClip[1][2], v.eyeToClip[2][2]);
      depthScale = 1.0 / glm::length(row);
    }
    sv.split = glm::vec4(float(v.splitNear), float(v.splitFar), v.range, float(depthScale));
    sv.info = glm::ivec4(int(texels), v.resolution, v.encoding, v.cascade);
    in.views.push_back(sv);
    texels += std::size_t(v.resolution) * std::size_t(v.resolution);
  }
  for (std::size_t li = 0; li < scene.lights.size(); ++li) {
    const LightDesc& l = scene.lights[li];
    gpu::ShadeLight sl{};
    sl.color = glm::vec4(l.enabled ? l.color * l.intensity : glm::vec3(0.0f), 0.0f);
    sl.position = glm::vec4(l.position, l.range);
    sl.direction = glm::vec4(l.direction, float(std::cos(glm::radians(double(l.outerConeDeg)))));
    int first = 0, count = 0;
    for (std::size_t i = 0; i < views.size(); ++i) {
      if (views[i].lightIndex != int(li)) continue;
      if (count == 0) first = int(i);
      ++count;
    }
    float contact = 0.0f;
    if (l.shadow && l.enabled) {
      sl.bias = glm::vec4(l.shadow->depthBias, l.shadow->normalBias, l.shadow->slopeBias, l.shadow->lightSize);
      contact = l.shadow->contactShadow;
      sl.extra = glm::vec4(float(std::cos(glm::radians(double(l.innerConeDeg)))), contact, l.shadow->cascadeBlend, 0.0f);
      sl.info = glm::ivec4(lightCode(l.type), count > 0 ? filterCode(l.shadow->filter) : gpu::VS_FILTER_NONE, first, count);
      if (l.shadow->filter == ShadowFilter::Evsm)
        sl.evsm = glm::vec4(l.shadow->evsmPositiveExponent, l.shadow->evsmNegativeExponent, l.shadow->lightBleedReduction,
                            float(l.shadow->evsmBlur));
    } else {
      sl.extra = glm::vec4(float(std::cos(glm::radians(double(l.innerConeDeg)))), 0.0f, 0.0f, 0.0f);
      sl.info = glm::ivec4(lightCode(l.type), gpu::VS_FILTER_NONE, 0, 0);
    }
    in.lights.push_back(sl);
    // A light without shadow casts none, in ray-traced shadows too.
    in.rayLength.push_back(!l.shadow || !l.enabled ? 0.0f : raytraced ? -1.0f : contact);
  }
  return in;
}

std::size_t shadeStoreTexels(std::span<const LightView> views) {
  std::size_t texels = 0;
  for (const LightView& v : views) texels += std::size_t(v.resolution) * std::size_t(v.resolution);
  return texels;
}

gpu::ShadePush makeShadePush(const SceneDesc& scene, int width, int height, int mode, bool raytraced) {
  gpu::ShadePush push{};
  push.ambient = glm::vec4(scene.ambient.color * scene.ambient.intensity, 0.0f);
  // A sky of the ambient light's hue, at a brightness that reads as sky beside lit surfaces.
  const glm::vec3 hue = scene.ambient.color / std::max(1e-6f, std::max(scene.ambient.color.x,
                                                       std::max(scene.ambient.color.y, scene.ambient.color.z)));
  push.sky = glm::vec4(hue * 0.75f, 0.0f);
  push.size = glm::ivec4(width, height, int(scene.lights.size()), mode);
  push.flags = glm::ivec4(raytraced ? 1 : 0, 0, 0, 0);
  return push;
}

std::span<const std::uint32_t> checkShadeSizes(const ShadeInputs& inputs, const gpu::ShadePush& push,
                                               const GBuffer& gbuffer, std::span<const std::uint32_t> rayVisibility,
                                               std::vector<std::uint32_t>& clear) {
  const std::size_t pixels = std::size_t(push.size.x) * std::size_t(push.size.y);
  const std::size_t lights = inputs.lights.size();
  if (gbuffer.texels.size() != pixels || std::size_t(push.size.z) != lights)
    throwBadInput("lighting: the G-buffer, the push block and the lights disagree on sizes");
  // Lights that need no ray read a clear answer.
  if (rayVisibility.empty()) {
    clear.assign(pixels * lights, 1u);
    rayVisibility = clear;
  }
  if (rayVisibility.size() != pixels * lights) throwBadInput("lighting: one visibility answer per pixel and light expected");
  return rayVisibility;
}

ShadeOutput shadeOnCpu(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                       std::span<const std::uint32_t> rayVisibility) {
  ShadeOutput out;
  shadeOnCpu(inputs, push, gbuffer, rayVisibility, out);
  return out;
}

void shadeOnCpu(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                std::span<const std::uint32_t> rayVisibility, ShadeOutput& out) {
  std::vector<std::uint32_t> clear;
  rayVisibility = checkShadeSizes(inputs, push, gbuffer, rayVisibility, clear);
  checkMomentStore(inputs);
  const std::size_t pixels = gbuffer.texels.size();
  const std::size_t lights = inputs.lights.size();
  // Every element is written below: a frame's buffers of last frame's size are reused as they are.
  out.color.resize(pixels);
  out.shadowTerms.resize(pixels * lights);
  gpu::CpuShading shading{inputs.shadowTexels.data(), inputs.views.data(), inputs.lights.data(), rayVisibility.data(),
                          out.shadowTerms.data(), inputs.moments.data()};
  tbb::parallel_for(0, push.size.y, [&](int y) {
    for (int x = 0; x < push.size.x; ++x) {
      const std::size_t pixel = std::size_t(y) * std::size_t(push.size.x) + std::size_t(x);
      // Without asking ahead, a third of the per-pixel time outside the filters was the wait for the pixel's
      // own G-buffer texel (64 bytes, a line each; perf on the demo frame).
      if (pixel + kShadePrefetch < pixels) __builtin_prefetch(&gbuffer.texels[pixel + kShadePrefetch]);
      out.color[pixel] = shading.vsShadePixel(push, int(pixel), gbuffer.texels[pixel]);
    }
  });
}

void shadeOnCpu(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                std::span<const std::uint32_t> rayVisibility, std::span<const std::uint32_t> pixels, ShadeOutput& out) {
  std::vector<std::uint32_t> clear;
  rayVisibility = checkShadeSizes(inputs, push, gbuffer, rayVisibility, clear);
  checkMomentStore(inputs);
  const std::size_t lights = inputs.lights.size();
  if (out.color.size() != gbuffer.texels.size() || out.shadowTerms.size() != gbuffer.texels.size() * lights)
    throwBadInput("lighting: the output to update is not sized for this frame");
  gpu::CpuShading shading{inputs.shadowTexels.data(), inputs.views.data(), inputs.lights.data(), rayVisibility.data(),
                          out.shadowTerms.data(), inputs.moments.data()};
  tbb::parallel_for(std::size_t(0), pixels.size(), [&](std::size_t k) {
    const std::uint32_t pixel = pixels[k];
    out.color[pixel] = shading.vsShadePixel(push, int(pixel), gbuffer.texels[pixel]);
  });
}

float shadowTermAt(const ShadeInputs& inputs, std::size_t light, const gpu::GBufferTexel& texel,
                   std::uint32_t visibility, bool raytraced) {
  if (light >= inputs.lights.size()) throwBadInput("lighting: no light " + std::to_string(light));
  checkMomentStore(inputs);
  gpu::CpuShading shading{inputs.shadowTexels.data(), inputs.views.data(), inputs.lights.data(), nullptr, nullptr,
                          inputs.moments.data()};
  return shading.vsShadowTerm(inputs.lights[light], texel, visibility, raytraced);
}

}  // namespace vs
