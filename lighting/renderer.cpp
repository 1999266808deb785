// renderer.cpp: the frame: trace shadow layers, trace the G-buffer, trace visibility rays, shade.
#include "lighting/renderer.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <utility>

#include "lighting/vulkan_lighting.h"
#include "voxel/error.h"
#include "voxel/valid_range.h"

namespace vs {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

int shadeMode(DebugView d) {
  switch (d) {
    case DebugView::Cascades: return gpu::VS_SHADE_DEBUG_CASCADES;
    case DebugView::Shadow: return gpu::VS_SHADE_DEBUG_SHADOW;
    case DebugView::Normals: return gpu::VS_SHADE_DEBUG_NORMALS;
    default: return gpu::VS_SHADE_LIT;
  }
}

}  // namespace

void checkRenderOptions(const RenderOptions& options) {
  for (auto [name, side] : {std::pair{"width", options.width}, std::pair{"height", options.height}})
    if (side < 0 || side > limits::kMaxImageSide)
      throwBadInput(std::string("RenderOptions.") + name + ": must be 0 (the camera's) or 1.." +
                    std::to_string(limits::kMaxImageSide) + ", not " + std::to_string(side));
  if (options.shadows != ShadowSource::Maps && options.shadows != ShadowSource::Raytraced)
    throwBadInput("RenderOptions.shadows: " + std::to_string(int(options.shadows)) +
                  " is no ShadowSource (Maps or Raytraced)");
  switch (options.debug) {
    case DebugView::None:
    case DebugView::Cascades:
    case DebugView::Shadow:
    case DebugView::Normals:
    case DebugView::Layer: break;
    default:
      throwBadInput("RenderOptions.debug: " + std::to_string(int(options.debug)) +
                    " is no DebugView (None, Cascades, Shadow, Normals or Layer)");
  }
  if (options.debug == DebugView::Layer && options.debugLayer < 0)
    throwBadInput("RenderOptions.debugLayer: must be 0 or more, not " + std::to_string(options.debugLayer));
}

struct FrameRenderer::VulkanPass {
  explicit VulkanPass(VulkanContext& context) : lighting(context) {}
  VulkanLighting lighting;
};

FrameRenderer::FrameRenderer(Tracer& tracer) : tracer_(tracer) {}
FrameRenderer::~FrameRenderer() = default;

int FrameRenderer::traceChangedLayers(const std::vector<LightView>& views) {
  // A layer holds while the bound scene and its view's record (matrices, eye, size, encoding, depth point:
  // everything its rays and texel values are made from) stay the same, bit for bit.
  const bool sameScene = tracer_.sceneVersion() == tracedVersion_;
  std::vector<std::size_t> changed;
  for (std::size_t i = 0; i < views.size(); ++i)
    if (!sameScene || i >= tracedViews_.size() ||
        std::memcmp(&views[i].trace, &tracedViews_[i], sizeof(gpu::TraceView)) != 0)
      changed.push_back(i);
  layers_.resize(views.size());
  tracedViews_.resize(views.size());
  if (changed.empty()) return 0;
  // The changed layers are traced as one batch (one submission on Vulkan); moving them in and out copies no
  // texels.
  std::vector<gpu::TraceView> batch;
  std::vector<ShadowLayer> batchLayers;
  for (std::size_t i : changed) {
    batch.push_back(views[i].trace);
    batchLayers.push_back(std::move(layers_[i]));
  }
  try {
    tracer_.traceShadow(batch, batchLayers);
  } catch (...) {
    // Some layers were moved out: none is known to hold any more.
    layers_.clear();
    tracedViews_.clear();
    throw;
  }
  for (std::size_t k = 0; k < changed.size(); ++k) layers_[changed[k]] = std::move(batchLayers[k]);
  for (std::size_t i = 0; i < views.size(); ++i) tracedViews_[i] = views[i].trace;
  tracedVersion_ = tracer_.sceneVersion();
  return int(changed.size());
}

RenderedFrame FrameRenderer::render(const Scene& scene, const RenderOptions& options) {
  const SceneDesc& desc = scene.desc();
  checkRenderOptions(options);
  if (!desc.camera) throwBadInput(desc.file.string() + ": camera: a scene needs a camera to be rendered");
  const CameraFrame camera = cameraFrame(*desc.camera, options.width, options.height);
  const bool raytraced = options.shadows == ShadowSource::Raytraced;

  RenderedFrame frame;
  frame.width = camera.width;
  frame.height = camera.height;
  for (const LightDesc& l : desc.lights) frame.lightNames.push_back(l.name);

  // Shadow layers: ray-traced shadows need none (the layer debug view still does).
  auto t0 = Clock::now();
  const bool needMaps = !raytraced || options.debug == DebugView::Layer;
  frame.views = needMaps ? buildLightViews(desc, scene.worldBounds(), &camera) : std::vector<LightView>{};
  if (options.debug == DebugView::Layer && (options.debugLayer < 0 || std::size_t(options.debugLayer) >= frame.views.size()))
    throwBadInput("--debug layer=" + std::to_string(options.debugLayer) + ": the scene has " +
                  std::to_string(frame.views.size()) + " shadow layers (0.." +
                  std::to_string(int(frame.views.size()) - 1) + ")");
  // A frame without maps leaves the layers as they are, for the next frame that has them.
  if (needMaps) frame.layersTraced = traceChangedLayers(frame.views);
  frame.timings.shadowMs = msSince(t0);

  t0 = Clock::now();
  frame.gbuffer = traceGBuffer(scene, camera, tracer_);
  frame.timings.gbufferMs = msSince(t0);

  const ShadeInputs inputs =
      makeShadeInputs(desc, frame.views, needMaps ? std::span<const ShadowLayer>(layers_) : std::span<const ShadowLayer>(),
                      raytraced);
  t0 = Clock::now();
  std::vector<std::uint32_t> visible;
  if (std::any_of(inputs.rayLength.begin(), inputs.rayLength.end(), [](float l) { return l != 0.0f; })) {
    std::vector<gpu::TraceRay> rays = visibilityRays(frame.gbuffer, inputs.lights, inputs.rayLength, scene.worldBounds());
    visible.resize(rays.size());
    tracer_.traceAny(rays, visible);
    for (std::uint32_t& v : visible) v = v == 0u ? 1u : 0u;
  }
  frame.timings.visibilityMs = msSince(t0);

  t0 = Clock::now();
  const gpu::ShadePush push = makeShadePush(desc, camera.width, camera.height, shadeMode(options.debug), raytraced);
  ShadeOutput shaded;
  if (VulkanTracer* vulkan = tracer_.vulkan()) {
    if (!vulkan_) vulkan_ = std::make_unique<VulkanPass>(vulkan->context());
    shaded = vulkan_->lighting.shade(inputs, push, frame.gbuffer, visible);
  } else {
    shaded = shadeOnCpu(inputs, push, frame.gbuffer, visible);
  }
  frame.color = std::move(shaded.color);
  frame.shadowTerms = std::move(shaded.shadowTerms);
  frame.timings.lightingMs = msSince(t0);

  if (options.debug == DebugView::Layer) {
    // The layer itself, scaled to the frame: depth as grey (near dark), misses white.
    const LightView& v = frame.views[std::size_t(options.debugLayer)];
    const ShadowLayer& layer = layers_[std::size_t(options.debugLayer)];
    for (int y = 0; y < frame.height; ++y)
      for (int x = 0; x < frame.width; ++x) {
        const int lx = std::min(layer.width - 1, x * layer.width / frame.width);
        const int ly = std::min(layer.height - 1, y * layer.height / frame.height);
        const float d = layer.texels[std::size_t(ly) * std::size_t(layer.width) + std::size_t(lx)] / v.range;
        frame.color[std::size_t(y) * std::size_t(frame.width) + std::size_t(x)] = glm::vec4(glm::vec3(d), 1.0f);
      }
  }
  return frame;
}

}  // namespace vs
