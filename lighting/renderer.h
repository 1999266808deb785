// renderer.h: one lit frame of a scene (DESIGN.md §7, §11): shadow layers, G-buffer, visibility rays and the
// deferred lighting pass, on either backend. A FrameRenderer lives across frames: it keeps the layers, the
// G-buffer, the visibility answers and the lit image of the last frame, and redoes only what the scene's
// changes and the camera touched.
#ifndef VOXSHADOW_RENDERER_H
#define VOXSHADOW_RENDERER_H

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <optional>
#include <string>
#include <vector>

#include "compute/tracer.h"
#include "lighting/deferred.h"
#include "lighting/gbuffer.h"
#include "lighting/scene.h"

namespace vs {

enum class ShadowSource { Maps, Raytraced };
enum class DebugView { None, Cascades, Shadow, Normals, Layer, Moments };

struct HostGBuffer;  // lighting/host_gbuffer.h

struct RenderOptions {
  int width = 0, height = 0;  // 0: the scene camera's; else 1..limits::kMaxImageSide
  ShadowSource shadows = ShadowSource::Maps;
  DebugView debug = DebugView::None;
  int debugLayer = 0;  // DebugView::Layer, Moments: which shadow layer (light view order)
  // What a frame on the Vulkan backend copies to the host: RenderedFrame::color and ::shadowTerms. A host that
  // shades with the device's shadows (FrameRenderer::vulkanShadows) asks for neither, and its frames read no
  // pixel of them back (they are left empty); a later frame that asks gets them whole. The CPU backend makes
  // them on the host and always fills them. The layer and moment debug views draw the colour on the host and
  // read it back whatever readColor says. Neither changes what is traced or shaded.
  bool readColor = true;
  bool readShadowTerms = true;
  // Whether a frame on the Vulkan backend copies its G-buffer to the host (RenderedFrame::gbuffer). Without it
  // RenderedFrame::gbuffer is empty (FrameRenderer::deviceGBuffer() reads it on demand), and a frame that redoes
  // every pixel (a moved camera) leaves the primary hits and the G-buffer on the device; the first later frame
  // that needs the host's copy (to find the pixels its changes touch, or asked for it) reads it back once. The
  // CPU backend always fills it.
  bool readGBuffer = true;
  // A host engine's own G-buffer on the tracer's device (lighting/host_gbuffer.h; README "Embedding in an
  // engine"): the frame is lit, and its contact rays traced, from the host's surfaces instead of the library's
  // primary rays (none is traced). Every pixel is imported, traced toward the lights with rays and shaded again
  // each such frame (the host's G-buffer may differ anywhere); the layers are kept and traced as in any frame.
  // RenderedFrame::gbuffer holds the imported texels (vsImportTexel), read back unless readGBuffer is false.
  // Null: the library's own G-buffer.
  // Vulkan only; the images must stay valid, in their stated layouts, until render() returns.
  const HostGBuffer* hostGBuffer = nullptr;
};

// Refuses (vs::Error(BadInput), "RenderOptions.<field>: <problem>") what render() cannot draw: a width or
// height below 0 or above limits::kMaxImageSide, a ShadowSource or DebugView that names no enumerator (a cast
// from an unchecked integer), and, for DebugView::Layer and Moments, a negative debugLayer. render() calls it
// first.
void checkRenderOptions(const RenderOptions& options);

struct RenderTimings {
  double sceneMs = 0.0;       // learning the scene's changes and updating the tracer's copy
  double shadowMs = 0.0;      // shadow layers
  double gbufferMs = 0.0;     // primary rays and their resolution
  double visibilityMs = 0.0;  // ray-traced or contact shadow rays
  double lightingMs = 0.0;    // the deferred pass
};

// What one layer's trace did in a frame.
struct LayerTraceStats {
  std::string view;            // the layer's name
  std::uint64_t texels = 0;    // texels traced
  bool whole = false;          // traced whole: new, its grid or view changed, its light changed
  int rectangles = 0;          // texel rectangles traced (exposed strips, dirty boxes' footprints)
};

// What a frame did (DESIGN.md §11): it follows what changed, not the size of the world.
struct FrameStats {
  bool full = false;              // everything redone: the first frame, another scene or tracer binding, forced
  std::vector<LayerTraceStats> layers;  // per view of the frame, in view order
  int layersTraced = 0;           // layers with any texel traced
  std::uint64_t texelsTraced = 0; // shadow rays: the sum over layers
  std::uint64_t layerTexels = 0;  // every texel of the frame's layers
  std::uint64_t momentTexels = 0; // EVSM moments computed again (each traced rectangle grown by the blur)
  std::uint64_t primaryRays = 0;  // G-buffer rays
  std::uint64_t visibilityRays = 0;  // ray-traced and contact shadow rays
  std::uint64_t pixelsShaded = 0; // pixels the lighting pass computed
  std::uint64_t dirtyBoxes = 0;   // world boxes the scene's changes reported
  // Bytes the frame moved between host and device (0 on the CPU backend): scene updates, trace records,
  // rays, layers and G-buffer to the lighting pass, and results read back.
  std::uint64_t bytesUploaded = 0;
  std::uint64_t bytesReadBack = 0;
  int dispatches = 0;             // compute dispatches recorded (Vulkan), trace batches and passes run (CPU)
  // The host threads the frame's own work could use (the arena it ran in: Tracer::hostThreads, else the
  // caller's).
  int hostThreads = 0;
};

struct RenderedFrame {
  int width = 0, height = 0;
  std::vector<glm::vec4> color;    // linear HDR, row 0 at the top (empty: not read back, RenderOptions)
  GBuffer gbuffer;                 // empty texels: not read back (RenderOptions::readGBuffer)
  std::vector<float> shadowTerms;  // per pixel and light (empty: not read back, RenderOptions)
  std::vector<std::string> lightNames;
  std::vector<LightView> views;    // the frame's shadow views (none with ray-traced shadows)
  // How many of `views` had texels traced for this frame (stats.layers says how many texels).
  int layersTraced = 0;
  RenderTimings timings;
  FrameStats stats;
};

struct VulkanShadows;  // lighting/vulkan_shadows.h

class FrameRenderer {
 public:
  // `tracer` traces every ray kind; on the Vulkan backend the lighting pass also runs on its device. The
  // renderer binds the scenes it renders to the tracer itself. A tracer destroyed before the renderer makes
  // render() throw vs::Error(Runtime); the renderer's own device resources keep the device alive until it goes.
  // Threads: a renderer serves one call at a time (render, layers, moments, invalidateLayers,
  // setFootprintMargin), from any thread; a call made while another runs on the same renderer throws
  // vs::Error(Runtime) and changes nothing. Renderers on several threads may share one tracer: each holds it for
  // its frame (Tracer::Exclusive), so frames run one after another on it. The host work of a frame (G-buffer
  // resolve, CPU shading, EVSM filter) runs on Tracer::hostThreads threads.
  explicit FrameRenderer(Tracer& tracer);
  ~FrameRenderer();
  FrameRenderer(const FrameRenderer&) = delete;
  FrameRenderer& operator=(const FrameRenderer&) = delete;

  // Renders the scene from its camera, redoing only what changed since the last frame (DESIGN.md §11): it
  // reads the scene's change journal (Scene::changesSince) and updates the tracer's copy with the deltas
  // (Tracer::sceneChanged), traces the layer texels that the changes' boxes, the exposed strips of scrolled
  // cascades and changed lights need, and traces, resolves and shades again only the pixels those touch. The
  // result equals, bit for bit, what a new renderer gives for the same scene, camera and options. Another
  // scene (Scene::id), a journal that no longer reaches back, or a tracer bound to other arrays since (another
  // scene, or the reference form of Tracer::setScene) makes the frame redo everything; renderers of one scene
  // may share a tracer. The frame stays owned by the renderer, valid until the next render() call.
  // Preconditions: the scene has a camera (else vs::Error(BadInput)); options pass checkRenderOptions;
  // options.debugLayer names an existing layer for DebugView::Layer, and one of an EVSM light for
  // DebugView::Moments (else vs::Error(BadInput)). While it runs it reads the scene (Scene::Reading): a change to
  // the scene from another thread meanwhile is refused with vs::Error(Runtime), as a render of a scene that
  // another thread is changing is.
  const RenderedFrame& render(const Scene& scene, const RenderOptions& options);

  // The shadow layers of the last frame that had shadow maps (its views' order), as stored: a cascade's
  // layer is a ring over its grid (windowTexels in lighting/light_views.h gives window order).
  std::vector<ShadowLayer> layers() const;
  // The EVSM moment layers of that frame (lighting/shared/evsm.h), one per view in the same order and storage
  // order, each (p, p^2, n, n^2) per texel; empty for views whose light does not use EVSM. On Vulkan they are
  // read back from the device now; there, after a frame without shadow maps (ray-traced shadows), the device
  // no longer holds them and this throws vs::Error until the next frame with maps.
  std::vector<std::vector<glm::vec4>> moments() const;
  // The last frame's shadows on the Vulkan device, for a host engine's shader that includes
  // lighting/shared/shadows.glsl (lighting/vulkan_shadows.h: the buffers, their lifetime and state). Nothing is
  // read back. Preconditions: a Vulkan tracer (else vs::Error(BadInput)); a last frame with shadow maps
  // (not RenderOptions::shadows Raytraced, nor a layer or moment debug view) that completed (else
  // vs::Error(Runtime)).
  VulkanShadows vulkanShadows() const;
  // The G-buffer the Vulkan lighting pass reads, read back from the device now: the frame's primary hits
  // resolved there (vsResolveHit), which RenderedFrame::gbuffer, resolved from the same hits on the host, equals
  // bit for bit. Preconditions: a Vulkan tracer (else vs::Error(BadInput)); a last frame that completed and whose
  // lighting pass holds its G-buffer whole (else vs::Error).
  GBuffer deviceGBuffer() const;
  // Makes the next frame redo everything (a benchmark's forced full frame).
  void invalidateLayers();

  // Texels added on every side of a changed box's footprint in each layer (DESIGN.md §11: one). Exists so
  // that the frame-loop tests can show they notice an invalidation one texel too small (-1); a renderer with
  // anything below 1 no longer equals a new one.
  void setFootprintMargin(double texels);

 private:
  struct State;
  // Held by each call for its length; a second call meanwhile is refused (vs::Error(Runtime)).
  class InUse;
  const RenderedFrame& renderFrame(const Scene& scene, const RenderOptions& options);
  mutable std::atomic<bool> busy_{false};
  Tracer& tracer_;
  std::weak_ptr<const int> tracerAlive_;
  bool forceFull_ = false;
  double footprintMargin_ = 1.0;
  std::unique_ptr<State> state_;
};

// Traces every texel of each view into layers[i], stored as FrameRenderer stores it (cascades through their
// pages, in ring order): what makeShadeInputs reads. Preconditions: views from buildLightViews.
void traceLayers(Tracer& tracer, std::span<const LightView> views, std::vector<ShadowLayer>& layers);

}  // namespace vs

#endif
