// voxshadow render: scene -> shadow layers + G-buffer -> deferred lighting -> PNG (sRGB) or EXR (linear HDR
// with the G-buffer and shadow terms).
#include <chrono>
#include <cstdio>

#include "compute/tracer.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "tools/atomic_file.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "tools/render_output.h"
#include "tools/resources.h"
#include "voxel/error.h"
#include "voxel/valid_range.h"

namespace vs::cli {

namespace {

// "cascades", "shadow", "normals" or "layer=N".
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
  } else {
    throwBadInput("--debug " + text + ": expected cascades, shadow, normals or layer=N");
  }
}

}  // namespace

void runRender(const RenderCommandOptions& options) {
  const std::string ext = options.output.extension().string();
  if (ext != ".png" && ext != ".exr") throwBadInput(options.output.string() + ": the output must be a .png or .exr file");
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

  SceneDesc desc = parseSceneFile(options.scene);
  if (!desc.camera) throwBadInput(options.scene.string() + ": camera: missing; `render` draws the scene from its camera");
  const std::vector<std::filesystem::path> outputs = {options.output};
  checkCommandOutputs(desc, outputs);

  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  Scene scene = Scene::load(std::move(desc));
  std::unique_ptr<Tracer> tracer;
  if (options.backend == "cpu") {
    tracer = makeCpuTracer({CpuTracePath::Interleaved, options.threads});
  } else {
    tracer = openVulkanBackend(options.device);
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
  sub->add_option("--shadows", options->shadows, "Shadow maps, or one exact visibility ray per pixel and light")
      ->check(CLI::IsMember({"maps", "raytraced"}))
      ->capture_default_str();
  sub->add_option("--debug", options->debug, "Debug view: cascades, shadow, normals or layer=N");
  sub->add_option("--width", options->width, "Image width (default: the camera's)");
  sub->add_option("--height", options->height, "Image height (default: the camera's)");
  addThreadsOption(sub, options->threads, "CPU threads (0: all)", 0);
  sub->add_option("--device", options->device, "Vulkan device: an index or part of a name (default: best)");
  sub->add_flag("--stats", options->stats, "Print the time of each stage");
  sub->callback([options] { runRender(*options); });
}

}  // namespace vs::cli
