// renderer.h: one lit frame of a scene (DESIGN.md §7): shadow layers, G-buffer, visibility rays and the
// deferred lighting pass, on either backend. A FrameRenderer lives across frames: it keeps the layers and
// buffers of the last frame, and traces a layer again only when its view or the bound scene changed.
#ifndef VOXSHADOW_RENDERER_H
#define VOXSHADOW_RENDERER_H

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "compute/tracer.h"
#include "lighting/deferred.h"
#include "lighting/gbuffer.h"
#include "lighting/scene.h"

namespace vs {

enum class ShadowSource { Maps, Raytraced };
enum class DebugView { None, Cascades, Shadow, Normals, Layer };

struct RenderOptions {
  int width = 0, height = 0;  // 0: the scene camera's; else 1..limits::kMaxImageSide
  ShadowSource shadows = ShadowSource::Maps;
  DebugView debug = DebugView::None;
  int debugLayer = 0;  // DebugView::Layer: which shadow layer (light view order)
};

// Refuses (vs::Error(BadInput), "RenderOptions.<field>: <problem>") what render() cannot draw: a width or
// height below 0 or above limits::kMaxImageSide, a ShadowSource or DebugView that names no enumerator (a cast
// from an unchecked integer), and, for DebugView::Layer, a negative debugLayer. render() calls it first.
void checkRenderOptions(const RenderOptions& options);

struct RenderTimings {
  double shadowMs = 0.0;      // shadow layers
  double gbufferMs = 0.0;     // primary rays and their resolution
  double visibilityMs = 0.0;  // ray-traced or contact shadow rays
  double lightingMs = 0.0;    // the deferred pass
};

struct RenderedFrame {
  int width = 0, height = 0;
  std::vector<glm::vec4> color;    // linear HDR, row 0 at the top
  GBuffer gbuffer;
  std::vector<float> shadowTerms;  // per pixel and light
  std::vector<std::string> lightNames;
  std::vector<LightView> views;    // the frame's shadow views (none with ray-traced shadows)
  // How many of `views` were traced for this frame; the others kept the last frame's layer, whose view and
  // scene were the same (a static scene under a still or sub-texel-moving camera traces none).
  int layersTraced = 0;
  RenderTimings timings;
};

class FrameRenderer {
 public:
  // `tracer` traces every ray kind; on the Vulkan backend the lighting pass also runs on its device.
  // Preconditions: tracer outlives the renderer.
  explicit FrameRenderer(Tracer& tracer);
  ~FrameRenderer();

  // Renders the scene from its camera. Preconditions: the scene has a camera (else vs::Error(BadInput));
  // tracer.setScene(scene.data()) was called after its last voxel change and tracer.instancesMoved after
  // instances moved (the tracer's sceneVersion() tells this renderer which layers still hold); options.debugLayer
  // names an existing layer for DebugView::Layer (else vs::Error(BadInput)).
  RenderedFrame render(const Scene& scene, const RenderOptions& options);

  // The shadow layers of the last frame that had shadow maps (light view order), reused by the next one.
  const std::vector<ShadowLayer>& layers() const { return layers_; }
  // Makes the next frame trace every layer (a benchmark timing the trace, or a caller that changed what the
  // tracer reads without telling it).
  void invalidateLayers() { tracedViews_.clear(); }

 private:
  Tracer& tracer_;
  std::vector<ShadowLayer> layers_;
  // Traces the layers whose view or scene changed since they were traced; returns how many.
  int traceChangedLayers(const std::vector<LightView>& views);

  // What layers_[i] was traced from, and the tracer's scene version then.
  std::vector<gpu::TraceView> tracedViews_;
  std::uint64_t tracedVersion_ = 0;
  struct VulkanPass;
  std::unique_ptr<VulkanPass> vulkan_;
};

}  // namespace vs

#endif
