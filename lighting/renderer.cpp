// renderer.cpp: the frame loop (DESIGN.md §11): learn what changed, trace the layer texels and pixels it
// touches, shade the pixels whose inputs changed.
#include "lighting/renderer.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/evsm.h"
#include "lighting/host_gbuffer.h"
#include "lighting/vulkan_lighting.h"
#include "voxel/error.h"
#include "voxel/one_call.h"
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

bool sameCamera(const CameraFrame& a, const CameraFrame& b) {
  return a.position == b.position && a.forward == b.forward && a.right == b.right && a.up == b.up &&
         a.tanHalfFovY == b.tanHalfFovY && a.aspect == b.aspect && a.nearPlane == b.nearPlane &&
         a.farPlane == b.farPlane && a.width == b.width && a.height == b.height;
}

// The debug views that draw a shadow layer (or its moments) on the host instead of the lit image.
bool drawsALayer(const RenderOptions& o) { return o.debug == DebugView::Layer || o.debug == DebugView::Moments; }

bool sameOptions(const RenderOptions& a, const RenderOptions& b) {
  // Of the host's G-buffer only whether there is one (a kept frame's pointer may dangle, and is not read): a
  // frame with one redoes every pixel anyway.
  return a.width == b.width && a.height == b.height && a.shadows == b.shadows && a.debug == b.debug &&
         a.debugLayer == b.debugLayer && (a.hostGBuffer != nullptr) == (b.hostGBuffer != nullptr);
}

TexelRect intersect(const TexelRect& a, const TexelRect& b) {
  return {std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
}

// The part of `w` that `old` does not cover, as disjoint rectangles: the strips a scrolled window exposes.
std::vector<TexelRect> exposedStrips(const TexelRect& old, const TexelRect& w) {
  const TexelRect kept = intersect(old, w);
  if (kept.empty()) return {w};
  std::vector<TexelRect> out;
  // Columns outside the kept span, full height; then rows outside it, within the kept columns.
  if (w.x0 < kept.x0) out.push_back({w.x0, w.y0, kept.x0, w.y1});
  if (kept.x1 < w.x1) out.push_back({kept.x1, w.y0, w.x1, w.y1});
  if (w.y0 < kept.y0) out.push_back({kept.x0, w.y0, kept.x1, kept.y0});
  if (kept.y1 < w.y1) out.push_back({kept.x0, kept.y1, kept.x1, w.y1});
  return out;
}

// Merges overlapping rectangles into their bounding rectangle until none overlap; more than kMaxRects
// left become one. A texel traced twice would be harmless, but counted twice.
constexpr std::size_t kMaxRects = 16;
void mergeRects(std::vector<TexelRect>& rects) {
  rects.erase(std::remove_if(rects.begin(), rects.end(), [](const TexelRect& r) { return r.empty(); }), rects.end());
  bool merged = true;
  while (merged) {
    merged = false;
    for (std::size_t i = 0; i < rects.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < rects.size() && !merged; ++j)
        if (!intersect(rects[i], rects[j]).empty()) {
          rects[i] = {std::min(rects[i].x0, rects[j].x0), std::min(rects[i].y0, rects[j].y0),
                      std::max(rects[i].x1, rects[j].x1), std::max(rects[i].y1, rects[j].y1)};
          rects.erase(rects.begin() + std::ptrdiff_t(j));
          merged = true;
        }
  }
  if (rects.size() > kMaxRects) {
    TexelRect all = rects.front();
    for (const TexelRect& r : rects)
      all = {std::min(all.x0, r.x0), std::min(all.y0, r.y0), std::max(all.x1, r.x1), std::max(all.y1, r.y1)};
    rects = {all};
  }
}

// Where a world point lands in a view's texel coordinates (global texels for a ring view), in double; false
// behind a perspective view's eye.
bool texelOf(const LightView& v, const glm::dvec3& p, glm::dvec2& texel) {
  if (isRingView(v)) {
    const glm::dvec3 l = v.gridBasis * p;
    texel = glm::dvec2(l.x / v.texelWorld, -l.y / v.texelWorld);
    return true;
  }
  const glm::dvec4 clip = v.eyeToClip * glm::dvec4(p - v.eye, 1.0);
  if (!(clip.w > 0.0)) return false;
  texel = (glm::dvec2(clip) / clip.w * 0.5 + 0.5) * double(v.resolution);
  return true;
}

// The texels of view v whose rays may pass through world box `box`: the box's corners projected (convex, so
// their hull holds the box's footprint), rounded outward by a texel; the whole window where the box reaches
// behind a perspective view's eye.
TexelRect footprint(const LightView& v, const Aabb& box, double margin) {
  glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  auto corner = [&](int c) {
    return glm::dvec3((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y, (c & 4) ? box.max.z : box.min.z);
  };
  if (isRingView(v)) {
    for (int c = 0; c < 8; ++c) {
      glm::dvec2 t;
      texelOf(v, corner(c), t);
      lo = glm::min(lo, t);
      hi = glm::max(hi, t);
    }
  } else {
    // A perspective view sees only the part of the box in front of its eye: the box clipped at a plane just
    // in front of it (its corners there, and where its edges cross the plane), projected.
    glm::dvec4 clip[8];
    double reach = 0.0;
    for (int c = 0; c < 8; ++c) {
      clip[c] = v.eyeToClip * glm::dvec4(corner(c) - v.eye, 1.0);
      reach = std::max(reach, std::abs(clip[c].w));
    }
    const double front = 1e-9 * std::max(reach, 1e-30);
    std::vector<glm::dvec4> points;
    for (int c = 0; c < 8; ++c)
      if (clip[c].w > front) points.push_back(clip[c]);
    if (points.empty()) return {};
    for (int a = 0; a < 8; ++a)
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int b = a | bit;
        if (b == a || ((clip[a].w > front) == (clip[b].w > front))) continue;
        const double s = (front - clip[a].w) / (clip[b].w - clip[a].w);
        points.push_back(clip[a] + (clip[b] - clip[a]) * s);
      }
    for (const glm::dvec4& p : points) {
      const glm::dvec2 t = (glm::dvec2(p) / std::max(p.w, front) * 0.5 + 0.5) * double(v.resolution);
      lo = glm::min(lo, t);
      hi = glm::max(hi, t);
    }
  }
  const double limit = 4.0e18;  // far beyond any window: clamps a corner projected near the eye's plane
  lo = glm::clamp(glm::floor(lo) - margin, -limit, limit);
  hi = glm::clamp(glm::floor(hi) + 1.0 + margin, -limit, limit);
  return intersect({std::int64_t(lo.x), std::int64_t(lo.y), std::int64_t(hi.x), std::int64_t(hi.y)}, windowRect(v));
}

// The pixels whose primary rays may pass through world box `box`, rounded outward by a pixel; the whole image
// where the box reaches to or behind the camera's near plane.
void markBoxPixels(const CameraFrame& camera, const Aabb& box, std::vector<std::uint8_t>& marks) {
  glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  bool whole = false;
  for (int c = 0; c < 8 && !whole; ++c) {
    const glm::dvec3 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y, (c & 4) ? box.max.z : box.min.z);
    const glm::dvec3 d = p - camera.position;
    const double z = glm::dot(d, camera.forward);
    if (!(z > 0.5 * camera.nearPlane)) {
      whole = true;
      break;
    }
    const double sx = glm::dot(d, camera.right) / z / (camera.tanHalfFovY * camera.aspect);
    const double sy = glm::dot(d, camera.up) / z / camera.tanHalfFovY;
    const glm::dvec2 px((sx + 1.0) * 0.5 * camera.width - 0.5, (1.0 - sy) * 0.5 * camera.height - 0.5);
    lo = glm::min(lo, px);
    hi = glm::max(hi, px);
  }
  int x0 = 0, y0 = 0, x1 = camera.width, y1 = camera.height;
  if (!whole) {
    x0 = int(std::clamp(std::floor(lo.x) - 1.0, 0.0, double(camera.width)));
    y0 = int(std::clamp(std::floor(lo.y) - 1.0, 0.0, double(camera.height)));
    x1 = int(std::clamp(std::ceil(hi.x) + 2.0, 0.0, double(camera.width)));
    y1 = int(std::clamp(std::ceil(hi.y) + 2.0, 0.0, double(camera.height)));
  }
  for (int y = y0; y < y1; ++y)
    std::fill(marks.begin() + std::ptrdiff_t(y) * camera.width + x0, marks.begin() + std::ptrdiff_t(y) * camera.width + x1,
              std::uint8_t(1));
}

std::vector<std::uint32_t> markedPixels(const std::vector<std::uint8_t>& marks) {
  std::vector<std::uint32_t> out;
  for (std::size_t i = 0; i < marks.size(); ++i)
    if (marks[i]) out.push_back(std::uint32_t(i));
  return out;
}

// How far (texels) from where a receiver projects its shadow lookups read: the filter's reach, the normal
// bias (which moves the receiver along its normal by that many texels) and a texel for rounding.
double lookupReach(const LightDesc& light) {
  if (!light.shadow) return 0.0;
  double reach = 1.0;
  switch (light.shadow->filter) {
    case ShadowFilter::Hard: reach = 0.5; break;
    case ShadowFilter::Pcf3: reach = 1.5; break;
    case ShadowFilter::Pcf5: reach = 2.5; break;
    case ShadowFilter::Poisson16: reach = double(gpu::VS_POISSON_RADIUS) + 0.5; break;
    case ShadowFilter::Pcss: reach = double(gpu::VS_PCSS_MAX_RADIUS) + 0.5; break;
    // The bilinear fetch; the blur's spread is in the moment rectangles the marks start from.
    case ShadowFilter::Evsm: reach = 1.0; break;
  }
  // The depth and slope biases move the receiver along the light, which is along a texel's own ray: they
  // change no view's lateral position.
  return reach + std::abs(double(light.shadow->normalBias)) + 2.0;
}

// The bands `r` texels wide inside window w's left and right edges (columns) and top and bottom edges (rows),
// disjoint so that mergeRects keeps them apart (overlapping at the corners it would join them into the window).
void appendEdgeBands(const TexelRect& w, std::int64_t r, bool columns, bool rows, std::vector<TexelRect>& out) {
  if (rows) {
    out.push_back({w.x0, w.y0, w.x1, std::min(w.y0 + r, w.y1)});
    out.push_back({w.x0, std::max(w.y1 - r, w.y0), w.x1, w.y1});
  }
  if (columns) {
    const std::int64_t y0 = rows ? std::min(w.y0 + r, w.y1) : w.y0, y1 = rows ? std::max(w.y1 - r, y0) : w.y1;
    out.push_back({w.x0, y0, std::min(w.x0 + r, w.x1), y1});
    out.push_back({std::max(w.x1 - r, w.x0), y0, w.x1, y1});
  }
}

// A view's identity across frames: its light (by id, which survives other lights' removal) and its name.
struct ViewKey {
  std::uint64_t light = 0;
  std::string name;
  bool operator==(const ViewKey&) const = default;
};

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
    case DebugView::Layer:
    case DebugView::Moments: break;
    default:
      throwBadInput("RenderOptions.debug: " + std::to_string(int(options.debug)) +
                    " is no DebugView (None, Cascades, Shadow, Normals, Layer or Moments)");
  }
  if (drawsALayer(options) && options.debugLayer < 0)
    throwBadInput("RenderOptions.debugLayer: must be 0 or more, not " + std::to_string(options.debugLayer));
}

void traceLayers(Tracer& tracer, std::span<const LightView> views, std::vector<ShadowLayer>& layers) {
  layers.resize(views.size());
  std::vector<gpu::TraceView> batch;
  std::vector<std::pair<std::size_t, glm::ivec2>> targets;
  for (std::size_t i = 0; i < views.size(); ++i) {
    layers[i].width = layers[i].height = views[i].resolution;
    layers[i].texels.assign(std::size_t(views[i].resolution) * std::size_t(views[i].resolution), 0.0f);
    for (const LayerTrace& t : layerTraces(views[i], windowRect(views[i]))) {
      batch.push_back(t.view);
      targets.push_back({i, t.storeOrigin});
    }
  }
  std::vector<ShadowLayer> pieces;
  tracer.traceShadow(batch, pieces);
  for (std::size_t k = 0; k < batch.size(); ++k) {
    const glm::ivec4 r = batch[k].rect;
    ShadowLayer& layer = layers[targets[k].first];
    for (int y = r.y; y < r.w; ++y)
      std::memcpy(&layer.texels[std::size_t(targets[k].second.y + y) * std::size_t(layer.width) +
                                std::size_t(targets[k].second.x + r.x)],
                  &pieces[k].texels[std::size_t(y) * std::size_t(pieces[k].width) + std::size_t(r.x)],
                  std::size_t(r.z - r.x) * sizeof(float));
  }
}

struct FrameRenderer::State {
  // The binding: which scene's arrays the tracer holds, and the revision the kept frame shows.
  std::shared_ptr<const SceneData> data;
  std::uint64_t sceneId = 0, revision = 0;
  bool valid = false;  // a complete frame is kept

  CameraFrame camera;
  RenderOptions options;
  // The host's working copy of the kept G-buffer (Vulkan): the marking of a frame's changed pixels reads it.
  // It is stale after a frame that left its G-buffer on the device alone (RenderOptions::readGBuffer false);
  // the first frame that marks pixels from it reads the device's back first. While the caller asks for no
  // G-buffer, the copy waits here instead of in RenderedFrame::gbuffer.
  bool gbufferOnHost = true;
  std::vector<gpu::GBufferTexel> keptTexels;
  // The layer store: the views of the last frame with shadow maps, each layer's first texel, every texel
  // (cascades in ring order). A frame without maps leaves it for the next one that has them.
  std::vector<ViewKey> keys;
  std::vector<LightView> storeViews;
  std::vector<int> storeOffsets;
  std::vector<float> storeTexels;
  // EVSM: each stored view's first moment texel (-1: none) and, on the CPU, the moment store (on Vulkan the
  // lighting pass keeps it on the device).
  std::vector<int> momentOffsets;
  std::vector<glm::vec4> storeMoments;
  std::size_t momentTexels = 0;
  std::vector<std::uint64_t> lightIds; // per light of the kept frame
  std::vector<float> rayLength;        // per light of the kept frame
  std::vector<std::uint32_t> visible;  // per pixel and light: 1 clear (empty: no light needs rays)
  RenderedFrame frame;
  std::vector<ShadowLayer> scratch;    // trace pieces, reused
  std::vector<gpu::RayHit> hits;       // primary hits, reused
  std::vector<gpu::VisibilityReceiver> receivers;  // of the visibility rays, reused
  std::vector<std::uint32_t> answers;               // their answers (receiver by light with rays), reused
  gpu::ShadePush push{};
  Aabb bounds;  // the world's bounds at the kept frame

  std::shared_ptr<VulkanContext> context;  // keeps the device of the lighting pass alive
  std::unique_ptr<VulkanLighting> lighting;
  // The Vulkan pass's buffers hold the kept frame's lighting inputs, except the store's texel ranges in
  // `pendingTexels` (traced by frames that shaded no pixel); false when they may hold anything else.
  bool lightingHeld = false;
  std::vector<std::pair<std::size_t, std::size_t>> pendingTexels;
  // The Vulkan pass's store holds the layers and storeTexels may be stale (traced on the device in place).
  bool storeOnDevice = false;
};

FrameRenderer::FrameRenderer(Tracer& tracer)
    : tracer_(tracer), tracerAlive_(tracer.liveness()), state_(std::make_unique<State>()) {}

FrameRenderer::~FrameRenderer() = default;

class FrameRenderer::InUse : public OneCallAtATime {
 public:
  InUse(const FrameRenderer& renderer, const char* call)
      : OneCallAtATime(renderer.busy_, "FrameRenderer", call, "renderer",
                       "a renderer serves one call at a time (make one renderer per thread, or wait for the other "
                       "call)") {}
};

void FrameRenderer::invalidateLayers() {
  InUse use(*this, "invalidateLayers");
  forceFull_ = true;
}

void FrameRenderer::setFootprintMargin(double texels) {
  InUse use(*this, "setFootprintMargin");
  footprintMargin_ = texels;
}

std::vector<ShadowLayer> FrameRenderer::layers() const {
  InUse use(*this, "layers");
  if (tracerAlive_.expired())
    throwRuntime("FrameRenderer::layers: the renderer's tracer was destroyed");
  Tracer::Exclusive hold(tracer_);
  std::vector<ShadowLayer> out;
  const State& s = *state_;
  // Layers kept on the device are read back now, since the caller asks for them.
  std::vector<float> deviceTexels;
  if (s.storeOnDevice) {
    deviceTexels.resize(s.storeTexels.size());
    s.lighting->readStore(deviceTexels);
  }
  const std::vector<float>& store = s.storeOnDevice ? deviceTexels : s.storeTexels;
  for (std::size_t i = 0; i < s.storeViews.size(); ++i) {
    const int n = s.storeViews[i].resolution;
    ShadowLayer layer;
    layer.width = layer.height = n;
    const auto first = store.begin() + s.storeOffsets[i];
    layer.texels.assign(first, first + std::ptrdiff_t(n) * n);
    out.push_back(std::move(layer));
  }
  return out;
}

std::vector<std::vector<glm::vec4>> FrameRenderer::moments() const {
  InUse use(*this, "moments");
  if (tracerAlive_.expired())
    throwRuntime("FrameRenderer::moments: the renderer's tracer was destroyed");
  Tracer::Exclusive hold(tracer_);
  const State& s = *state_;
  std::vector<glm::vec4> device;
  if (s.lighting && tracer_.vulkan() && s.momentTexels > 0) {
    device.resize(s.momentTexels);
    s.lighting->readMoments(device);
  }
  const std::vector<glm::vec4>& store = device.empty() ? s.storeMoments : device;
  std::vector<std::vector<glm::vec4>> out(s.storeViews.size());
  for (std::size_t i = 0; i < s.storeViews.size() && i < s.momentOffsets.size(); ++i) {
    if (s.momentOffsets[i] < 0) continue;
    const std::size_t n = std::size_t(s.storeViews[i].resolution) * std::size_t(s.storeViews[i].resolution);
    if (std::size_t(s.momentOffsets[i]) + n > store.size()) throwRuntime("FrameRenderer::moments: no moments are kept");
    out[i].assign(store.begin() + s.momentOffsets[i], store.begin() + s.momentOffsets[i] + std::ptrdiff_t(n));
  }
  return out;
}

VulkanShadows FrameRenderer::vulkanShadows() const {
  InUse use(*this, "vulkanShadows");
  if (tracerAlive_.expired())
    throwRuntime("FrameRenderer::vulkanShadows: the renderer's tracer was destroyed");
  if (!tracer_.vulkan())
    throwBadInput("FrameRenderer::vulkanShadows: the renderer's tracer is not a Vulkan tracer (a CPU tracer's "
                  "layers are on the host: layers())");
  Tracer::Exclusive hold(tracer_);
  State& s = *state_;
  const bool layerView = drawsALayer(s.options);
  if (!s.valid || !s.lighting || s.options.shadows != ShadowSource::Maps || layerView)
    throwRuntime("FrameRenderer::vulkanShadows: the last frame left no shadow maps on the device (render a "
                 "frame with shadow maps first; ray-traced shadows and the layer and moment views have none)");
  // Texels traced by frames that shaded no pixel wait on the host (pendingTexels), or, past a sixteenth of the
  // store, the pass holds none of the frame: written now.
  if (!s.lightingHeld) {
    if (s.storeOnDevice || !s.lighting->holdsStore(s.storeTexels.size()))
      throwRuntime("FrameRenderer::vulkanShadows: the device holds no whole frame (render a frame first)");
    const std::pair<std::size_t, std::size_t> whole{0, s.storeTexels.size()};
    s.lighting->writeStore(s.storeTexels, std::span(&whole, 1));
    s.lightingHeld = true;
  } else if (!s.pendingTexels.empty()) {
    s.lighting->writeStore(s.storeTexels, s.pendingTexels);
  }
  s.pendingTexels.clear();
  return s.lighting->shadows(s.frame.width, s.frame.height);
}

GBuffer FrameRenderer::deviceGBuffer() const {
  InUse use(*this, "deviceGBuffer");
  if (tracerAlive_.expired())
    throwRuntime("FrameRenderer::deviceGBuffer: the renderer's tracer was destroyed");
  if (!tracer_.vulkan())
    throwBadInput("FrameRenderer::deviceGBuffer: the renderer's tracer is not a Vulkan tracer (the CPU backend's "
                  "G-buffer is RenderedFrame::gbuffer)");
  Tracer::Exclusive hold(tracer_);
  const State& s = *state_;
  if (!s.valid || !s.lighting)
    throwRuntime("FrameRenderer::deviceGBuffer: no completed frame's lighting pass holds a G-buffer");
  GBuffer out;
  out.width = s.frame.width;
  out.height = s.frame.height;
  out.texels.resize(std::size_t(out.width) * std::size_t(out.height));
  s.lighting->readGBuffer(out);
  return out;
}

const RenderedFrame& FrameRenderer::render(const Scene& scene, const RenderOptions& options) {
  InUse use(*this, "render");
  if (tracerAlive_.expired())
    throwRuntime("FrameRenderer::render: the renderer's tracer was destroyed; make the renderer on a live tracer");
  checkRenderOptions(options);
  Scene::Reading reading(scene, "FrameRenderer::render");
  // Another renderer's frame on this tracer (another thread) runs before or after this one, never between its
  // scene binding and its traces.
  Tracer::Exclusive hold(tracer_);
  const RenderedFrame* frame = nullptr;
  inHostArena(tracer_.hostThreads(), [&] { frame = &renderFrame(scene, options); });
  return *frame;
}

const RenderedFrame& FrameRenderer::renderFrame(const Scene& scene, const RenderOptions& options) {
  const SceneDesc& desc = scene.desc();
  if (!desc.camera) throwBadInput(desc.file.string() + ": camera: a scene needs a camera to be rendered");
  const CameraFrame camera = cameraFrame(*desc.camera, options.width, options.height);
  const bool raytraced = options.shadows == ShadowSource::Raytraced;
  const bool layerView = drawsALayer(options);
  const bool needMaps = !raytraced || layerView;
  State& s = *state_;
  VulkanTracer* vulkan = tracer_.vulkan();
  // The host's G-buffer is checked before anything changes.
  if (options.hostGBuffer) {
    if (!vulkan)
      throwBadInput("RenderOptions.hostGBuffer: a host engine's G-buffer needs the Vulkan backend (its images are on "
                    "its device); this renderer's tracer is a CPU tracer");
    checkHostGBuffer(*vulkan->sharedContext(), *options.hostGBuffer, camera.width, camera.height);
  }

  // The views first: a bad debug layer is refused before anything changes.
  std::vector<LightView> views = needMaps ? buildLightViews(desc, scene.worldBounds(), &camera) : std::vector<LightView>{};
  const std::string debugName = options.debug == DebugView::Moments ? "moments" : "layer";
  if (layerView && std::size_t(options.debugLayer) >= views.size())
    throwBadInput("--debug " + debugName + "=" + std::to_string(options.debugLayer) + ": the scene has " +
                  std::to_string(views.size()) + " shadow layers (0.." + std::to_string(int(views.size()) - 1) + ")");
  if (options.debug == DebugView::Moments) {
    const LightDesc& l = desc.lights[std::size_t(views[std::size_t(options.debugLayer)].lightIndex)];
    if (!l.shadow || l.shadow->filter != ShadowFilter::Evsm || raytraced)
      throwBadInput("--debug moments=" + std::to_string(options.debugLayer) + ": layer " +
                    views[std::size_t(options.debugLayer)].name + " has no EVSM moments (its light's filter is " +
                    (l.shadow ? shadowFilterName(l.shadow->filter) : "none") +
                    (raytraced ? ", and ray-traced shadows use no maps)" : "; set \"filter\": \"evsm\")"));
  }

  // 1. What changed in the scene since the kept frame, and the tracer's copy brought up to date.
  auto t0 = Clock::now();
  FrameStats stats;
  stats.hostThreads = tbb::this_task_arena::max_concurrency();
  std::vector<const SceneChange*> changes;
  const std::uint64_t uploadedBefore = tracer_.bytesUploaded();
  bool full = forceFull_ || !s.valid || s.sceneId != scene.id() || s.data != scene.sharedData() ||
              tracer_.boundScene() != scene.sharedData() || !scene.changesSince(s.revision, changes);
  std::vector<Aabb> boxes;
  std::vector<std::uint64_t> changedLights;
  bool shadingChanged = false;
  // Invalid until this frame completes: an exception below leaves nothing half-kept, and the next frame
  // redoes everything.
  s.valid = false;
  const bool lightingHeld = s.lightingHeld;
  s.lightingHeld = false;
  if (full) {
    s.data = scene.sharedData();
    tracer_.setScene(s.data);
  } else if (!changes.empty()) {
    SceneDelta delta;
    for (const SceneChange* c : changes) {
      boxes.insert(boxes.end(), c->boxes.begin(), c->boxes.end());
      changedLights.insert(changedLights.end(), c->lights.begin(), c->lights.end());
      shadingChanged = shadingChanged || c->shading;
      delta.merge(c->arrays);
    }
    if (!delta.ranges.empty() || !delta.editedBricks.empty() || delta.voxelLayout || delta.instances)
      tracer_.sceneChanged(scene.data(), delta);
  }
  s.sceneId = scene.id();
  s.revision = scene.revision();
  stats.full = full;
  stats.dirtyBoxes = boxes.size();
  RenderTimings timings;
  timings.sceneMs = msSince(t0);

  // 2. Shadow layers: per view, what must be traced.
  t0 = Clock::now();
  std::vector<ViewKey> keys;
  for (const LightView& v : views) keys.push_back({scene.lightId(std::size_t(v.lightIndex)), v.name});
  std::vector<std::uint64_t> lightIds;
  for (std::size_t l = 0; l < desc.lights.size(); ++l) lightIds.push_back(scene.lightId(l));
  // Where each view's layer was kept (-1: new).
  std::vector<int> kept(views.size(), -1);
  // A frame without maps cannot keep the store up to date: a change then leaves nothing of it to keep.
  if (!needMaps && (full || !boxes.empty() || !changedLights.empty())) s.keys.clear();
  if (!full)
    for (std::size_t i = 0; i < views.size(); ++i)
      for (std::size_t k = 0; k < s.keys.size(); ++k)
        if (s.keys[k] == keys[i]) kept[i] = int(k);
  // The records and the texel store of this frame's views; kept layers are copied over when the layout moved.
  ShadeInputs inputs = makeShadeRecords(desc, views, raytraced);
  const std::size_t storeTexels = shadeStoreTexels(views);
  bool sameLayout = !full && keys == s.keys && storeTexels == s.storeTexels.size();
  if (sameLayout)
    for (std::size_t i = 0; i < views.size(); ++i)
      sameLayout = sameLayout && inputs.views[i].info.x == s.storeOffsets[std::size_t(kept[i])];
  // On Vulkan the layers stay on the device while the store keeps its layout: texels are traced into the
  // lighting pass's store in place, and the host's copy is left stale until someone needs it (a layout move,
  // a layer debug view, layers()), which reads it back then.
  const bool deviceStore = vulkan && sameLayout && s.lighting && lightingHeld && s.pendingTexels.empty() &&
                           !layerView && s.lighting->holdsStore(storeTexels);
  if (s.storeOnDevice && !deviceStore) {
    // A frame without maps keeps the store for the next one that has them (unless a change cleared it).
    const bool storeKept = needMaps ? std::any_of(kept.begin(), kept.end(), [](int k) { return k >= 0; })
                                    : !s.keys.empty();
    if (!storeKept) {
      // Nothing of the store is kept: no need to read it.
    } else if (s.lighting && s.lighting->holdsStore(s.storeTexels.size())) {
      LightingTraffic traffic;
      s.lighting->readStore(s.storeTexels, &traffic);
      stats.bytesReadBack += traffic.readBack;
    } else {
      // The device's store is gone with a failed pass: every layer is traced again.
      std::fill(kept.begin(), kept.end(), -1);
      sameLayout = false;
      s.keys.clear();
    }
    s.storeOnDevice = false;
  }
  if (sameLayout) {
    inputs.shadowTexels.swap(s.storeTexels);
  } else {
    inputs.shadowTexels.resize(storeTexels);
    for (std::size_t i = 0; i < views.size(); ++i)
      if (kept[i] >= 0 && views[i].resolution == s.storeViews[std::size_t(kept[i])].resolution) {
        const std::size_t n = std::size_t(views[i].resolution) * std::size_t(views[i].resolution);
        std::copy_n(s.storeTexels.begin() + s.storeOffsets[std::size_t(kept[i])], n,
                    inputs.shadowTexels.begin() + inputs.views[i].info.x);
      } else {
        kept[i] = -1;
      }
  }
  std::vector<std::vector<TexelRect>> rects(views.size());
  stats.layers.resize(views.size());
  bool anyWhole = false;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const LightView& v = views[i];
    LayerTraceStats& ls = stats.layers[i];
    ls.view = v.name;
    stats.layerTexels += std::uint64_t(v.resolution) * std::uint64_t(v.resolution);
    bool whole = kept[i] < 0;
    if (!whole) {
      const LightView& old = s.storeViews[std::size_t(kept[i])];
      if (std::find(changedLights.begin(), changedLights.end(), keys[i].light) != changedLights.end()) whole = true;
      else if (isRingView(v)) whole = !sameGrid(v, old);
      else whole = std::memcmp(&v.trace, &old.trace, sizeof(gpu::TraceView)) != 0;
      if (!whole && isRingView(v)) rects[i] = exposedStrips(windowRect(old), windowRect(v));
    }
    if (whole) {
      rects[i] = {windowRect(v)};
      anyWhole = true;
    } else {
      for (const Aabb& b : boxes) rects[i].push_back(footprint(v, b, footprintMargin_));
      mergeRects(rects[i]);
    }
    ls.whole = whole;
  }
  // One batch for every piece; each piece lands in its layer's store at its place.
  std::vector<gpu::TraceView> batch;
  std::vector<std::pair<std::size_t, glm::ivec2>> targets;
  for (std::size_t i = 0; i < views.size(); ++i) {
    for (const TexelRect& r : rects[i]) {
      for (const LayerTrace& t : layerTraces(views[i], r)) {
        batch.push_back(t.view);
        targets.push_back({i, t.storeOrigin});
        const std::uint64_t n = std::uint64_t(t.view.rect.z - t.view.rect.x) * std::uint64_t(t.view.rect.w - t.view.rect.y);
        stats.layers[i].texels += n;
      }
      ++stats.layers[i].rectangles;
    }
  }
  // The store's rows this frame writes, for a lighting pass that keeps the store in place.
  std::vector<std::pair<std::size_t, std::size_t>> tracedTexels;
  if (!batch.empty() && deviceStore) {
    std::vector<DeviceTexelPlace> places(batch.size());
    for (std::size_t k = 0; k < batch.size(); ++k) {
      const int n = views[targets[k].first].resolution;
      places[k].origin = std::int64_t(inputs.views[targets[k].first].info.x) +
                         std::int64_t(targets[k].second.y) * n + targets[k].second.x;
      places[k].rowLength = std::uint32_t(n);
    }
    const TraceStats ts =
        vulkan->traceInto(batch, {s.lighting->storeTarget(storeTexels), storeTexels, places});
    stats.dispatches += ts.dispatches;
    stats.bytesUploaded += batch.size() * sizeof(gpu::TraceView);
    s.storeOnDevice = true;
  } else if (!batch.empty()) {
    const TraceStats ts = tracer_.traceShadow(batch, s.scratch);
    stats.dispatches += vulkan ? ts.dispatches : 1;
    for (std::size_t k = 0; k < batch.size(); ++k) {
      const glm::ivec4 r = batch[k].rect;
      const int n = views[targets[k].first].resolution;
      const std::size_t layerStart = std::size_t(inputs.views[targets[k].first].info.x);
      float* layer = inputs.shadowTexels.data() + layerStart;
      const ShadowLayer& piece = s.scratch[k];
      for (int y = r.y; y < r.w; ++y) {
        const std::size_t at =
            std::size_t(targets[k].second.y + y) * std::size_t(n) + std::size_t(targets[k].second.x + r.x);
        std::memcpy(layer + at, &piece.texels[std::size_t(y) * std::size_t(piece.width) + std::size_t(r.x)],
                    std::size_t(r.z - r.x) * sizeof(float));
        if (vulkan) tracedTexels.push_back({layerStart + at, std::size_t(r.z - r.x)});
      }
    }
    if (vulkan) {
      stats.bytesUploaded += batch.size() * sizeof(gpu::TraceView);
    }
  }
  for (const LayerTraceStats& ls : stats.layers) {
    stats.texelsTraced += ls.texels;
    if (ls.texels > 0) ++stats.layersTraced;
  }
  // EVSM: the moments that this frame's texels change (each traced rectangle grown by the blur radius, and a
  // scrolled ring's r texels inside each edge that moved, where the blur's clamp to the window moved), or every
  // EVSM layer's when the moment store does not carry over.
  std::vector<int> momentOffsets;
  for (const gpu::ShadeView& sv : inputs.views) momentOffsets.push_back(sv.trace.w);
  const bool momentsKept = sameLayout && momentOffsets == s.momentOffsets;
  std::vector<MomentRect> momentRects;
  // Per view, the window texels whose moments change, in the layer's texel coordinates (for the shading marks).
  std::vector<std::vector<TexelRect>> momentTouched(views.size());
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (!hasMoments(inputs, i)) continue;
    const LightView& v = views[i];
    const TexelRect w = windowRect(v);
    const std::int64_t r = std::int64_t(inputs.lights[std::size_t(v.lightIndex)].evsm.w);
    std::vector<TexelRect> changed;
    if (!momentsKept || stats.layers[i].whole) {
      changed = {w};
    } else {
      for (const TexelRect& t : rects[i]) changed.push_back(intersect({t.x0 - r, t.y0 - r, t.x1 + r, t.y1 + r}, w));
      if (kept[i] >= 0 && isRingView(v) && r > 0) {
        const TexelRect old = windowRect(s.storeViews[std::size_t(kept[i])]);
        appendEdgeBands(w, r, old.x0 != w.x0, old.y0 != w.y0, changed);
      }
      // A cube face's blur reads its neighbours' texels within r of its edges: texels traced that near an
      // edge of another face of the light change this face's moments along its edges (all four: the
      // bands are r texels wide, cheaper than finding which edge meets which).
      if (r > 0 && inputs.lights[std::size_t(v.lightIndex)].info.x == gpu::VS_LIGHT_POINT) {
        bool neighbourEdge = false;
        for (std::size_t j = 0; j < views.size() && !neighbourEdge; ++j) {
          if (j == i || views[j].lightIndex != v.lightIndex) continue;
          const TexelRect wj = windowRect(views[j]);
          for (const TexelRect& t : rects[j])
            if (!t.empty() && (t.x0 < wj.x0 + r || t.y0 < wj.y0 + r || t.x1 > wj.x1 - r || t.y1 > wj.y1 - r))
              neighbourEdge = true;
        }
        if (neighbourEdge) appendEdgeBands(w, r, true, true, changed);
      }
      mergeRects(changed);
    }
    for (const TexelRect& t : changed)
      momentRects.push_back({int(i), int(t.x0 - w.x0), int(t.y0 - w.y0), int(t.x1 - w.x0), int(t.y1 - w.y0)});
    momentTouched[i] = std::move(changed);
  }
  const MomentWork momentJobs = momentWork(views, inputs, momentRects);
  auto wholeMoments = [&]() { return momentWork(views, inputs, wholeMomentRects(inputs)); };
  if (!vulkan) {
    if (momentsKept) inputs.moments.swap(s.storeMoments);
    computeMomentsOnCpu(inputs, momentJobs, inputs.moments);
    stats.momentTexels = momentJobs.vertical;
    if (!momentJobs.empty()) stats.dispatches += 1;
  }
  if (vulkan && !deviceStore) stats.bytesReadBack += stats.texelsTraced * sizeof(float);
  timings.shadowMs = msSince(t0);

  // The Vulkan lighting pass, made on the tracer's device with the first frame that needs it.
  auto lightingPass = [&]() -> VulkanLighting& {
    if (!s.lighting) {
      s.context = vulkan->sharedContext();
      s.lighting = std::make_unique<VulkanLighting>(s.context);
    }
    return *s.lighting;
  };

  // 3. The G-buffer: every pixel when the camera or the frame changed, else the pixels whose primary rays
  // may pass through a changed box.
  t0 = Clock::now();
  RenderedFrame& frame = s.frame;
  const std::size_t pixelCount = std::size_t(camera.width) * std::size_t(camera.height);
  // Rays that reach past the scene are cut where it ends (vsSceneEndT), and the cut sets the pads their walks
  // are re-based with: when the world's bounds move, every primary ray's hit may change in its last bits.
  const Aabb& bounds = scene.worldBounds();
  const bool boundsMoved = bounds.min != s.bounds.min || bounds.max != s.bounds.max;
  const bool allPixels = full || boundsMoved || !sameCamera(camera, s.camera) || !sameOptions(options, s.options) ||
                         options.hostGBuffer;
  std::vector<std::uint8_t> marks(pixelCount, allPixels ? 1 : 0);
  // The rays are made where they are traced (on the device on Vulkan: only the camera record and the pixel
  // list go up); the resolve makes the same rays again on the host.
  const gpu::CameraRays cameraRecord = cameraRaysOf(camera);
  std::vector<std::uint32_t> primaryPixels;
  // Per-frame arrays keep their storage across frames: fresh pages of a whole frame's rays and hits cost more
  // to fault in than to fill.
  std::vector<gpu::RayHit>& hits = s.hits;
  if (frame.gbuffer.texels.empty()) frame.gbuffer.texels.swap(s.keptTexels);
  if (!vulkan) s.gbufferOnHost = true;
  // The host's copy sized for this frame (the lighting pass's checks read its size), its texels not yet
  // read: stale until hostGBuffer() reads them.
  auto leaveGBufferOnDevice = [&] {
    frame.gbuffer.width = camera.width;
    frame.gbuffer.height = camera.height;
    frame.gbuffer.texels.resize(pixelCount);
    s.gbufferOnHost = false;
  };
  // The host's copy brought up to date from the device's before host code reads it (a frame after one that
  // kept its G-buffer on the device alone); the pass holds it whole (no frame of another size came between,
  // which would have redone every pixel).
  auto hostGBuffer = [&] {
    if (s.gbufferOnHost) return;
    leaveGBufferOnDevice();
    LightingTraffic traffic;
    lightingPass().readGBuffer(frame.gbuffer, &traffic);
    stats.bytesReadBack += traffic.readBack;
    s.gbufferOnHost = true;
  };
  // A whole G-buffer made on the device stays there unless the caller asks for it: no hit is read back.
  const bool gbufferOnDeviceOnly = vulkan && !options.readGBuffer;
  bool hitsReadBack = false;
  // What the resolve reads besides the hits, made once for the host's resolve and the device's.
  GBufferTables tables;
  if (!options.hostGBuffer && (allPixels || !boxes.empty())) tables = gbufferTables(scene);
  if (options.hostGBuffer) {
    // The host's surfaces instead of primary rays: imported on the device beside its receivers, and read back
    // for the caller and the host's own uses of the frame's G-buffer.
    LightingTraffic traffic;
    lightingPass().importGBuffer(*options.hostGBuffer, camera.width, camera.height, &traffic);
    leaveGBufferOnDevice();
    if (!gbufferOnDeviceOnly) hostGBuffer();
    stats.bytesUploaded += traffic.uploaded;
    stats.bytesReadBack += traffic.readBack;
    stats.dispatches += traffic.dispatches;
  } else if (allPixels && gbufferOnDeviceOnly) {
    const TraceStats ts = vulkan->traceCameraOnDevice(cameraRecord);
    stats.dispatches += std::max(ts.dispatches, 1);
    leaveGBufferOnDevice();
    stats.primaryRays = pixelCount;
  } else if (allPixels) {
    hits.resize(pixelCount);
    const TraceStats ts = tracer_.traceCamera(cameraRecord, {}, hits);
    stats.dispatches += vulkan ? std::max(ts.dispatches, 1) : 1;
    resolveGBuffer(tables, camera, hits, frame.gbuffer);
    s.gbufferOnHost = true;
    hitsReadBack = true;
    stats.primaryRays = pixelCount;
  } else if (!boxes.empty()) {
    for (const Aabb& b : boxes) markBoxPixels(camera, b, marks);
    primaryPixels = markedPixels(marks);
    if (!primaryPixels.empty()) {
      hostGBuffer();  // the listed texels go into a whole copy
      hitsReadBack = true;
      hits.resize(primaryPixels.size());
      const TraceStats ts = tracer_.traceCamera(cameraRecord, primaryPixels, hits);
      stats.dispatches += vulkan ? std::max(ts.dispatches, 1) : 1;
      resolveGBufferPixels(tables, camera, hits, primaryPixels, frame.gbuffer);
      stats.primaryRays = primaryPixels.size();
    }
  }
  if (vulkan && stats.primaryRays > 0 && !options.hostGBuffer) {
    stats.bytesUploaded += sizeof(gpu::CameraRays) + primaryPixels.size() * sizeof(std::uint32_t);
    if (hitsReadBack) stats.bytesReadBack += stats.primaryRays * sizeof(gpu::RayHit);
    // The same hits resolved on the device into the lighting pass's G-buffer, which then reads it in place: the
    // host's copy above serves the marking below and the caller.
    LightingTraffic traffic;
    lightingPass().resolveGBuffer(vulkan->lastCameraTrace(), tables, frame.gbuffer, &traffic);
    stats.bytesUploaded += traffic.uploaded;
    stats.dispatches += traffic.dispatches;
  }
  timings.gbufferMs = msSince(t0);

  // 4. Visibility rays: every pixel's when the lights' rays or the G-buffer changed whole, else the marked
  // pixels' and those whose rays meet a changed box.
  t0 = Clock::now();
  const std::size_t lightCount = desc.lights.size();
  // The lights that have rays (a ray length other than 0): the others' answers are clear without a ray (in the
  // demo two lights of three, whose empty rays took a third of the stage).
  std::vector<std::size_t> rayLights;
  for (std::size_t l = 0; l < lightCount; ++l)
    if (inputs.rayLength[l] != 0.0f) rayLights.push_back(l);
  const bool needRays = !rayLights.empty();
  const bool raysChanged = lightIds != s.lightIds || inputs.rayLength != s.rayLength || !changedLights.empty() ||
                           s.visible.size() != pixelCount * lightCount;
  std::vector<std::uint32_t> visible;
  std::size_t receiversTraced = 0;
  std::uint64_t receiverBytes = 0;  // receivers or their pixel list, uploaded (Vulkan)
  if (needRays) {
    // The rays are made where they are traced, from one receiver per pixel (Tracer::traceVisibility), toward
    // the lights that have rays.
    std::vector<gpu::ShadeLight> tracedLights;
    std::vector<float> tracedLengths;
    for (std::size_t l : rayLights) {
      tracedLights.push_back(inputs.lights[l]);
      tracedLengths.push_back(inputs.rayLength[l]);
    }
    const VisibilitySetup setup = visibilitySetup(tracedLights, tracedLengths, scene.worldBounds());
    std::vector<gpu::VisibilityReceiver>& receivers = s.receivers;
    std::vector<std::uint32_t>& answers = s.answers;
    // Traces the rays of the given pixels' receivers (every pixel's when empty) toward the lights that have
    // rays, and spreads receiver k's answers (ray k * traced + j toward light rayLights[j], nonzero where
    // occluded) into `visible` at its pixel: 1 where clear, and 1 for every light without a ray. On Vulkan the
    // receivers are those the G-buffer resolve left on the device beside the G-buffer, where it holds them
    // whole: only the pixel list goes up.
    auto traceAndSpread = [&](std::span<const std::uint32_t> pixels) {
      const std::size_t taken = pixels.empty() ? pixelCount : pixels.size();
      const std::size_t traced = rayLights.size();
      answers.resize(taken * traced);
      DeviceReceivers onDevice = vulkan ? lightingPass().receivers(pixelCount) : DeviceReceivers{};
      TraceStats ts;
      if (onDevice.buffer) {
        onDevice.pixels = pixels;
        ts = vulkan->traceVisibility(setup.frame, setup.lights, onDevice, answers);
        receiverBytes += pixels.size_bytes();
      } else {
        hostGBuffer();
        visibilityReceivers(frame.gbuffer, pixels, receivers);
        ts = tracer_.traceVisibility(setup.frame, setup.lights, receivers, answers);
        receiverBytes += receivers.size() * sizeof(gpu::VisibilityReceiver);
      }
      stats.dispatches += vulkan ? std::max(ts.dispatches, 1) : 1;
      tbb::parallel_for(std::size_t(0), taken, [&](std::size_t k) {
        std::uint32_t* row = visible.data() + std::size_t(pixels.empty() ? k : pixels[k]) * lightCount;
        std::fill(row, row + lightCount, 1u);
        for (std::size_t j = 0; j < traced; ++j) row[rayLights[j]] = answers[k * traced + j] == 0u ? 1u : 0u;
      });
      stats.visibilityRays = answers.size();
      receiversTraced = taken;
      if (vulkan) {
        // The same spread on the device, from the answers the trace left there, into the lighting pass's
        // answers, which it then reads in place.
        std::vector<int> slots(lightCount, -1);
        for (std::size_t j = 0; j < traced; ++j) slots[rayLights[j]] = int(j);
        LightingTraffic traffic;
        lightingPass().spreadVisibility(onDevice.buffer ? vulkan->lastVisibilityTrace() : VisibilityTraceBuffers{},
                                        slots, pixelCount, visible, &traffic);
        stats.bytesUploaded += traffic.uploaded;
        stats.dispatches += traffic.dispatches;
      }
    };
    if (allPixels || raysChanged) {
      visible.swap(s.visible);
      visible.resize(pixelCount * lightCount);
      traceAndSpread({});
      std::fill(marks.begin(), marks.end(), std::uint8_t(1));
    } else {
      visible.swap(s.visible);
      if (!boxes.empty()) hostGBuffer();
      markVisibilityRaysMeeting(frame.gbuffer, inputs.lights, inputs.rayLength, scene.worldBounds(), boxes, marks);
      const std::vector<std::uint32_t> pixels = markedPixels(marks);
      if (!pixels.empty()) traceAndSpread(pixels);
    }
  }
  if (vulkan && receiversTraced > 0) {
    stats.bytesUploaded += sizeof(gpu::VisibilityRays) + rayLights.size() * sizeof(gpu::VisibilityLight) + receiverBytes;
    stats.bytesReadBack += stats.visibilityRays * sizeof(std::uint32_t);
  }
  timings.visibilityMs = msSince(t0);

  // 5. Lighting: every pixel when any input changed whole, else the marked ones and those whose shadow
  // lookups read a traced texel.
  t0 = Clock::now();
  const gpu::ShadePush push = makeShadePush(desc, camera.width, camera.height, shadeMode(options.debug), raytraced);
  // On Vulkan the pass's buffers hold the kept image whether or not the host has a copy (the pass itself shades
  // whole when they hold none of this frame's size).
  const bool shadeAll = allPixels || anyWhole || shadingChanged || lightIds != s.lightIds ||
                        (!vulkan && frame.color.size() != pixelCount) || std::memcmp(&push, &s.push, sizeof push) != 0;
  // What a Vulkan frame copies back (RenderOptions): the layer and moment views draw the colour on the host.
  const bool readColor = options.readColor || layerView;
  const bool readTerms = options.readShadowTerms;
  // Whether the host's copies hold the kept image whole (a Vulkan frame that did not read one back left it
  // empty; one of another size is redone whole).
  const bool colorHeld = frame.color.size() == pixelCount;
  const bool termsHeld = frame.shadowTerms.size() == pixelCount * lightCount;
  bool shadedWhole = false;  // the pass shaded and read back whole (shade())
  // The pixels whose G-buffer texel or visibility answers this frame changed (marked so far), before those
  // marked only because a shadow lookup reads a traced texel: the Vulkan pass writes only their inputs.
  std::vector<std::uint32_t> inputPixels;
  if (vulkan && !shadeAll) inputPixels = markedPixels(marks);
  if (!shadeAll && stats.texelsTraced > 0 && !raytraced) {
    // Per light, the views it traced in and the traced rectangles grown by its lookups' reach.
    for (std::size_t l = 0; l < lightCount; ++l) {
      std::vector<std::pair<std::size_t, TexelRect>> touched;
      const double reach = lookupReach(desc.lights[l]);
      for (std::size_t i = 0; i < views.size(); ++i) {
        if (std::size_t(views[i].lightIndex) != l) continue;
        // An EVSM layer's lookups read moments, which change where momentTouched says (the blur included).
        for (const TexelRect& r : hasMoments(inputs, i) ? momentTouched[i] : rects[i]) {
          const std::int64_t m = std::int64_t(std::ceil(reach));
          touched.push_back({i, {r.x0 - m, r.y0 - m, r.x1 + m, r.y1 + m}});
        }
      }
      if (touched.empty()) continue;
      hostGBuffer();
      tbb::parallel_for(std::size_t(0), pixelCount, [&](std::size_t px) {
        const gpu::GBufferTexel& g = frame.gbuffer.texels[px];
        if (marks[px] || g.info.w == 0u) return;
        const glm::dvec3 p(glm::vec3(g.position));
        for (const auto& [i, r] : touched) {
          glm::dvec2 t;
          if (!texelOf(views[i], p, t)) continue;
          // Lookups outside the window read its edge (vsStoredDepth clamps).
          const TexelRect w = windowRect(views[i]);
          t = glm::clamp(t, glm::dvec2(double(w.x0), double(w.y0)), glm::dvec2(double(w.x1) - 0.5, double(w.y1) - 0.5));
          if (t.x >= double(r.x0) && t.x < double(r.x1) && t.y >= double(r.y0) && t.y < double(r.y1)) {
            marks[px] = 1;
            return;
          }
        }
      });
    }
  }
  ShadeOutput shaded;
  shaded.color.swap(frame.color);
  shaded.shadowTerms.swap(frame.shadowTerms);
  std::vector<std::uint32_t> pixels;
  if (!shadeAll) pixels = markedPixels(marks);
  if (vulkan) {
    if (shadeAll || !pixels.empty() || !momentJobs.empty()) {
      lightingPass();
      LightingTraffic traffic;
      // The pass keeps its inputs in place: while the layer store keeps its layout, a frame writes only the
      // texels traced since the pass last ran (this frame's rows and those of frames that shaded nothing), and
      // its marked pixels' inputs, or every pixel's when everything is shaded again (a moved camera, a changed
      // light); it reads back those pixels.
      if (!lightingHeld || !sameLayout) {
        const MomentWork whole = inputs.momentTexels > 0 ? wholeMoments() : MomentWork{};
        shaded = s.lighting->shade(inputs, push, frame.gbuffer, visible, &traffic, &whole, readColor, readTerms, true,
                                   needRays);
        shadedWhole = true;
      } else {
        s.pendingTexels.insert(s.pendingTexels.end(), tracedTexels.begin(), tracedTexels.end());
        ShadeChanges changes;
        changes.texelRanges = s.pendingTexels;
        changes.pixels = pixels;
        changes.inputPixels = inputPixels;
        changes.allPixels = shadeAll;
        changes.storeInPlace = deviceStore;
        changes.gbufferOnDevice = true;
        changes.visibilityOnDevice = needRays;
        changes.moments = &momentJobs;
        changes.wholeMoments = wholeMoments;
        // Changed pixels are copied into a host copy that holds the rest; without one, read whole below.
        changes.readColor = readColor && colorHeld;
        changes.readTerms = readTerms && termsHeld;
        s.lighting->shadeChanged(inputs, push, frame.gbuffer, visible, changes, shaded, &traffic);
      }
      s.pendingTexels.clear();
      s.lightingHeld = true;
      stats.pixelsShaded = traffic.pixelsShaded;
      // The pass's own count: where it held no moments of this frame's size it computed the whole store.
      stats.momentTexels = traffic.momentTexels;
      stats.dispatches += traffic.dispatches;
      stats.bytesUploaded += traffic.uploaded;
      stats.bytesReadBack += traffic.readBack;
    } else if (lightingHeld && sameLayout) {
      // Nothing to shade: the pass's buffers still hold this frame's inputs but for the rows traced now.
      s.pendingTexels.insert(s.pendingTexels.end(), tracedTexels.begin(), tracedTexels.end());
      std::size_t pending = 0;
      for (const auto& range : s.pendingTexels) pending += range.second;
      s.lightingHeld = pending < inputs.shadowTexels.size() / 16;
      if (!s.lightingHeld) s.pendingTexels.clear();
    }
  } else if (shadeAll) {
    shadeOnCpu(inputs, push, frame.gbuffer, visible, shaded);
    stats.pixelsShaded = pixelCount;
    stats.dispatches += 1;
  } else if (!pixels.empty()) {
    shadeOnCpu(inputs, push, frame.gbuffer, visible, pixels, shaded);
    stats.pixelsShaded = pixels.size();
    stats.dispatches += 1;
  }
  if (vulkan) {
    // Copied back only where asked; asked after frames that were not, whole (the pass's buffers hold it).
    const bool colorCurrent = shadedWhole || colorHeld;
    const bool termsCurrent = shadedWhole || termsHeld;
    if ((readColor && !colorCurrent) || (readTerms && !termsCurrent)) {
      if (!s.lighting) throwRuntime("FrameRenderer::render: no lighting pass holds the frame's image to read back");
      LightingTraffic whole;
      s.lighting->readResults(readColor && !colorCurrent ? &shaded.color : nullptr,
                              readTerms && !termsCurrent ? &shaded.shadowTerms : nullptr, &whole);
      stats.bytesReadBack += whole.readBack;
    }
    if (!readColor) shaded.color.clear();
    if (!readTerms) shaded.shadowTerms.clear();
    if (shaded.color.size() != (readColor ? pixelCount : 0) ||
        shaded.shadowTerms.size() != (readTerms ? pixelCount * lightCount : 0))
      throwRuntime("FrameRenderer::render: the lighting pass's results are not of this frame's size");
  }
  frame.color.swap(shaded.color);
  frame.shadowTerms.swap(shaded.shadowTerms);
  timings.lightingMs = msSince(t0);

  if (options.debug == DebugView::Layer) {
    // The layer itself, in window order, scaled to the frame: depth as grey (near dark), misses white.
    const std::size_t li = std::size_t(options.debugLayer);
    const LightView& v = views[li];
    const std::vector<float> texels = windowTexels(
        v, std::span<const float>(inputs.shadowTexels).subspan(std::size_t(inputs.views[li].info.x),
                                                                std::size_t(v.resolution) * std::size_t(v.resolution)));
    for (int y = 0; y < camera.height; ++y)
      for (int x = 0; x < camera.width; ++x) {
        const int lx = std::min(v.resolution - 1, x * v.resolution / camera.width);
        const int ly = std::min(v.resolution - 1, y * v.resolution / camera.height);
        const float d = texels[std::size_t(ly) * std::size_t(v.resolution) + std::size_t(lx)] / v.range;
        frame.color[std::size_t(y) * std::size_t(camera.width) + std::size_t(x)] = glm::vec4(glm::vec3(d), 1.0f);
      }
  }

  if (options.debug == DebugView::Moments) {
    // The first moment of each texel, in window order, as the warped depth it is the mean of, from near
    // (dark) to far (white).
    const std::size_t li = std::size_t(options.debugLayer);
    const LightView& v = views[li];
    const std::size_t n = std::size_t(v.resolution) * std::size_t(v.resolution);
    std::vector<glm::vec4> stored(n);
    if (vulkan) {
      std::vector<glm::vec4> all(inputs.momentTexels);
      LightingTraffic traffic;
      s.lighting->readMoments(all, &traffic);
      stats.bytesReadBack += traffic.readBack;
      std::copy_n(all.begin() + inputs.views[li].trace.w, n, stored.begin());
    } else {
      std::copy_n(inputs.moments.begin() + inputs.views[li].trace.w, n, stored.begin());
    }
    const std::vector<glm::vec4> m = windowMoments(v, stored);
    const float c = inputs.lights[std::size_t(v.lightIndex)].evsm.x;
    for (int y = 0; y < camera.height; ++y)
      for (int x = 0; x < camera.width; ++x) {
        const int lx = std::min(v.resolution - 1, x * v.resolution / camera.width);
        const int ly = std::min(v.resolution - 1, y * v.resolution / camera.height);
        const float first = m[std::size_t(ly) * std::size_t(v.resolution) + std::size_t(lx)].x;
        const float grey = std::clamp((std::log(std::max(first, 1e-30f)) / c + 1.0f) * 0.5f, 0.0f, 1.0f);
        frame.color[std::size_t(y) * std::size_t(camera.width) + std::size_t(x)] = glm::vec4(glm::vec3(grey), 1.0f);
      }
  }

  // The G-buffer the caller asked for is this frame's (its read counted with the G-buffer stage).
  if (vulkan && options.readGBuffer && !s.gbufferOnHost) {
    const auto tr = Clock::now();
    hostGBuffer();
    timings.gbufferMs += msSince(tr);
  }
  stats.bytesUploaded += tracer_.bytesUploaded() - uploadedBefore;
  frame.width = camera.width;
  frame.height = camera.height;
  frame.lightNames.clear();
  for (const LightDesc& l : desc.lights) frame.lightNames.push_back(l.name);
  frame.views = std::move(views);
  frame.layersTraced = stats.layersTraced;
  frame.timings = timings;
  frame.stats = std::move(stats);
  // One not asked for waits as the working copy.
  if (vulkan && !options.readGBuffer) s.keptTexels.swap(frame.gbuffer.texels);
  s.camera = camera;
  s.options = options;
  if (needMaps) {
    s.keys = std::move(keys);
    s.storeViews = frame.views;
    s.storeOffsets.clear();
    for (const gpu::ShadeView& v : inputs.views) s.storeOffsets.push_back(v.info.x);
    s.storeTexels.swap(inputs.shadowTexels);
    s.momentOffsets = std::move(momentOffsets);
    s.momentTexels = inputs.momentTexels;
    s.storeMoments.swap(inputs.moments);
  }
  s.lightIds = std::move(lightIds);
  s.rayLength = inputs.rayLength;
  s.visible = std::move(visible);
  s.push = push;
  s.bounds = bounds;
  s.valid = true;
  forceFull_ = false;
  return frame;
}

}  // namespace vs
