// voxshadow render: scene -> shadow layers + G-buffer -> deferred lighting -> PNG (sRGB) or EXR (linear HDR
// with the G-buffer and shadow terms).
#include <algorithm>
#include <chrono>
#include <cstdio>

#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "lighting/camera.h"
#include "lighting/light_views.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "tools/atomic_file.h"
#include "tools/commands.h"
#include "tools/file_kind.h"
#include "tools/progress.h"
#include "tools/render_output.h"
#include "tools/resources.h"
#include "voxel/error.h"
#include "voxel/valid_range.h"

namespace vs::cli {

namespace {

// "cascades", "shadow", "normals", "layer=N" or "moments=N".
void parseDebug(const std::string& text, RenderOptions& options) {
  if (text.empty() || text == "none") return;
  if (text == "cascades") options.debug = DebugView::Cascades;
  else if (text == "shadow") options.debug = DebugView::Shadow;
  else if (text == "normals") options.debug = DebugView::Normals;
  else if (text.rfind("layer=", 0) == 0) {
    const std::string n = text.substr(6);
    if (n.empty() || n.size() > 6 || n.find_first_not_of("0123456789") != std::string::npos)
      throwBadInput("--debug " + text + ": layer=N takes a layer index (0, 1, ...)");
    options.debug = DebugView::Layer;
    options.debugLayer = std::stoi(n);
  } else if (text.rfind("moments=", 0) == 0) {
    const std::string n = text.substr(8);
    if (n.empty() || n.size() > 6 || n.find_first_not_of("0123456789") != std::string::npos)
      throwBadInput("--debug " + text + ": moments=N takes a layer index (0, 1, ...)");
    options.debug = DebugView::Moments;
    options.debugLayer = std::stoi(n);
  } else {
    throwBadInput("--debug " + text + ": expected cascades, shadow, normals, layer=N or moments=N");
  }
}

// The sizes a frame's buffers are made from.
struct FrameSizes {
  int width = 0, height = 0;
  std::uint64_t pixels = 0, lights = 0;
  std::uint64_t layerBytes = 0;            // every shadow layer the frame traces
  std::uint64_t momentBytes = 0;           // EVSM: the moment store and the moment pass's scratch (16 B each)
  std::uint64_t maxW = 0, maxH = 0, views = 0;
  std::uint64_t rays = 0;                  // visibility rays: one per pixel and light that needs them
};

FrameSizes frameSizes(const Scene& scene, const RenderOptions& render) {
  const SceneDesc& desc = scene.desc();
  const CameraFrame camera = cameraFrame(*desc.camera, render.width, render.height);
  FrameSizes f;
  f.width = camera.width;
  f.height = camera.height;
  f.pixels = std::uint64_t(camera.width) * std::uint64_t(camera.height);
  f.lights = desc.lights.size();
  const bool raytraced = render.shadows == ShadowSource::Raytraced;
  if (!raytraced || render.debug == DebugView::Layer || render.debug == DebugView::Moments)
    for (const LightView& v : buildLightViews(desc, scene.worldBounds(), &camera)) {
      f.layerBytes += std::uint64_t(v.trace.info.x) * std::uint64_t(v.trace.info.y) * sizeof(float);
      const LightDesc& l = desc.lights[std::size_t(v.lightIndex)];
      if (!raytraced && l.shadow && l.shadow->filter == ShadowFilter::Evsm)
        f.momentBytes += std::uint64_t(v.trace.info.x) * std::uint64_t(v.trace.info.y) * 32;
      f.maxW = std::max<std::uint64_t>(f.maxW, std::uint64_t(v.trace.info.x));
      f.maxH = std::max<std::uint64_t>(f.maxH, std::uint64_t(v.trace.info.y));
      ++f.views;
    }
  // At most: a receiver beyond a light's range gets no ray, but the buffers are sized for every pixel.
  const std::uint64_t rayLights = std::uint64_t(std::count_if(desc.lights.begin(), desc.lights.end(), [&](const LightDesc& l) {
    return l.enabled && l.shadow && (raytraced || l.shadow->contactShadow != 0.0f);
  }));
  f.rays = f.pixels * rayLights;
  return f;
}

// What a render holds in host memory at its peak, from what FrameRenderer allocates in each stage: the shadow
// layers, and the copy of their texels the lighting inputs keep; the G-buffer trace (primary rays 48 B, hits
// 32 B and G-buffer texels 64 B a pixel); the visibility rays (a 32-byte receiver a pixel, a 4-byte answer a
// ray toward each light that has rays, kept, and their spread per pixel and light, 4 B each: the rays
// themselves are made where they are traced, in slices on the CPU); the lit image
// (16 B a pixel) and shadow terms (4 B a pixel and light); the file's pixels; and on Vulkan the host-visible
// buffers the tracer and the lighting pass keep until the end (on a CPU device such as lavapipe, whose device
// memory is host memory, the shadow image, the device's visibility receivers and the driver's own working
// memory too).
std::uint64_t renderBytesNeeded(const FrameSizes& f, bool exr, const VulkanDeviceInfo* device) {
  const std::uint64_t layers = f.layerBytes, pixels = f.pixels;
  const std::uint64_t perLight = pixels * f.lights * sizeof(float);
  const std::uint64_t gbuffer = pixels * 64;
  const std::uint64_t file = exr ? pixels * (15 + f.lights) * sizeof(float) : pixels * 3;
  const std::uint64_t receivers = f.rays > 0 ? pixels * 32 : 0;
  // The answers (kept across frames) and their spread per pixel and light.
  const std::uint64_t answers = f.rays > 0 ? f.rays * 4 + perLight : 0;
  // The Vulkan buffers, as each stage adds them.
  std::uint64_t vTrace = 0, vPrimary = 0, vVisibility = 0, vShade = 0;
  if (device) {
    const bool cpuDevice = device->type == VulkanDeviceType::Cpu;
    vTrace = layers + (cpuDevice ? f.maxW * f.maxH * f.views * sizeof(float) + kCpuVulkanDeviceWorkingBytes : 0);
    // The camera trace's buffers, then the lighting pass's G-buffer and the receivers the device resolve writes
    // beside it (device-local: host memory only on a CPU device).
    vPrimary = pixels * (48 + 32) + gbuffer + (cpuDevice ? pixels * 32 : 0);
    // The visibility trace's record, lights and listed pixels (at most one a pixel), and its answers.
    vVisibility = pixels * 4 + f.rays * 4;
    vShade = layers + 2 * perLight + pixels * 16;
  }
  const std::uint64_t stages[] = {
      layers + vTrace,
      layers + pixels * (48 + 32 + 64) + vTrace + vPrimary,
      2 * layers + gbuffer + receivers + answers + vTrace + vPrimary + vVisibility,
      2 * layers + f.momentBytes + gbuffer + answers + 2 * perLight + pixels * 16 + vTrace + vPrimary + vVisibility +
          vShade,
      layers + f.momentBytes + gbuffer + answers + pixels * 16 + perLight + file + vTrace + vPrimary + vVisibility +
          vShade,
  };
  return *std::max_element(std::begin(stages), std::end(stages));
}

void checkRenderMemory(const Scene& scene, const RenderOptions& render, const RenderCommandOptions& options,
                       const VulkanDeviceInfo* device) {
  const FrameSizes f = frameSizes(scene, render);
  const std::string frame = scene.desc().file.string() + ": a " + std::to_string(f.width) + "x" +
                            std::to_string(f.height) + " frame";
  if (device) {
    // The lighting pass binds each of these as one storage buffer.
    const std::uint64_t largest =
        std::max({f.pixels * 64, f.layerBytes, f.pixels * f.lights * sizeof(float), f.pixels * 16});
    if (largest > device->maxStorageBufferRange)
      throwBadInput(frame + " needs a " + formatBytes(largest) + " lighting buffer, more than maxStorageBufferRange (" +
                    formatBytes(device->maxStorageBufferRange) + ") of " + device->name +
                    "; render a smaller image (--width, --height) or use --backend cpu");
  }
  checkMemoryNeed(renderBytesNeeded(f, hasExtension(options.output, ".exr"), device),
                  memoryBudget(options.memoryBudget, tracingCommandThreads(options.threads)),
                  frame + " (G-buffer, lit image, shadow layers and visibility rays) needs",
                  "render a smaller image (--width, --height) or lower the lights' shadow.resolution");
}

}  // namespace

void runRender(const RenderCommandOptions& options) {
  if (!hasExtension(options.output, ".png") && !hasExtension(options.output, ".exr")) throwBadInput(options.output.string() + ": the output must be a .png or .exr file");
  if (options.backend != "cpu" && options.backend != "vulkan")
    throwBadInput("unknown backend '" + options.backend + "' (cpu or vulkan)");
  if (options.shadows != "maps" && options.shadows != "raytraced")
    throwBadInput("--shadows " + options.shadows + ": expected maps or raytraced");
  if (!options.device.empty() && options.backend != "vulkan")
    throwBadInput("--device chooses a Vulkan device; it needs --backend vulkan");
  if (options.threads < 0 || options.threads > kMaxThreads)
    throwBadInput("--threads: must be between 0 and " + std::to_string(kMaxThreads) + ", not " + std::to_string(options.threads));
  for (int side : {options.width, options.height})
    if (side < 0 || side > limits::kMaxImageSide)
      throwBadInput("--width/--height: must be between 1 and " + std::to_string(limits::kMaxImageSide) + ", not " +
                    std::to_string(side));
  RenderOptions render;
  render.width = options.width;
  render.height = options.height;
  render.shadows = options.shadows == "raytraced" ? ShadowSource::Raytraced : ShadowSource::Maps;
  parseDebug(options.debug, render);

  checkInputBytes(options.scene, InputKind::Scene);
  SceneDesc desc = parseSceneFile(options.scene);
  checkSceneAssetBytes(desc);
  if (!desc.camera) throwBadInput(options.scene.string() + ": camera: missing; `render` draws the scene from its camera");
  const std::vector<std::filesystem::path> outputs = {options.output};
  checkCommandOutputs(desc, outputs);

  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  Scene scene = Scene::load(std::move(desc));
  // Before any trace, and before the Vulkan driver maps its own share of the address space.
  checkRenderMemory(scene, render, options, nullptr);
  std::unique_ptr<Tracer> tracer;
  if (options.backend == "cpu") {
    tracer = makeCpuTracer({CpuTracePath::Interleaved, options.threads});
  } else {
    tracer = openVulkanBackend(options.device, options.threads);
    checkRenderMemory(scene, render, options, &tracer->vulkan()->device());
  }
  Progress progress("rendering (" + tracer->deviceName() + ")");
  progress.update(0, 3);
  tracer->setScene(scene.data());
  progress.update(1, 3);
  FrameRenderer renderer(*tracer);
  RenderedFrame frame = renderer.render(scene, render);
  progress.update(2, 3);
  writeAtomically(outputs, [&](std::size_t, const std::filesystem::path& tmp) {
    writeRenderedFrame(options.output, tmp, frame);
  });
  progress.update(3, 3);
  progress.finish();
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf("rendered %dx%d (%s shadows) into %s\n", frame.width, frame.height, options.shadows.c_str(),
              options.output.c_str());
  if (options.stats) {
    const RenderTimings& t = frame.timings;
    std::printf("stats: backend %s (%s), %zu shadow layers\n", options.backend.c_str(), tracer->deviceName().c_str(),
                frame.views.size());
    std::printf("  shadow trace %.1f ms, G-buffer %.1f ms, visibility rays %.1f ms, lighting %.1f ms; total %.3f s\n",
                t.shadowMs, t.gbufferMs, t.visibilityMs, t.lightingMs, seconds);
  }
}

void registerRender(CLI::App& app) {
  auto options = std::make_shared<RenderCommandOptions>();
  CLI::App* sub = app.add_subcommand("render", "Render a scene's lit image from its camera (PNG or EXR)");
  sub->add_option("SCENE", options->scene, "Scene file (JSON, version 1) with a camera")->required();
  sub->add_option("-o,--output", options->output, "Output .png (tonemapped sRGB) or .exr (linear HDR + G-buffer)")
      ->required();
  sub->add_option("--backend", options->backend, "Trace backend")
      ->check(CLI::IsMember({"cpu", "vulkan"}))
      ->capture_default_str();
  sub->add_option("--shadows", options->shadows, "Shadow maps, or one exact visibility ray per pixel and light that reaches it")
      ->check(CLI::IsMember({"maps", "raytraced"}))
      ->capture_default_str();
  sub->add_option("--debug", options->debug, "Debug view: cascades, shadow, normals, layer=N (a shadow layer's depths) or moments=N (its EVSM moments)");
  sub->add_option("--width", options->width, "Image width (default: the camera's)");
  sub->add_option("--height", options->height, "Image height (default: the camera's)");
  addThreadsOption(sub, options->threads, "CPU threads: the CPU backend's tracing and either backend's host work (0: all)", 0);
  sub->add_option("--device", options->device, "Vulkan device: an index or part of a name (default: best)");
  sub->add_option_function<std::string>(
         "--memory-budget",
         [options](const std::string& text) { options->memoryBudget = parseByteSize(text, "--memory-budget"); },
         "Most host memory the render may plan to use, e.g. 8G, 512M (default: the memory available now)")
      ->type_name("SIZE");
  sub->add_flag("--stats", options->stats, "Print the time of each stage");
  sub->callback([options] { runRender(*options); });
}

}  // namespace vs::cli
