// voxshadow bench --loop: the demo scene driven as a game drives it, one small change a frame, so that each
// frame's cost can be set against what changed in it and against a forced full frame of the same state
// (DESIGN.md §11: "bench reports a forced full re-trace beside every incremental figure").
#include "tools/bench_loop.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/camera.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "tools/atomic_file.h"
#include "tools/resources.h"
#include "voxel/brickmap.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

extern char** environ;

namespace vs::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kPhaseNames[] = {"still", "pan", "actor", "dig", "sun"};
constexpr int kPhaseCount = 5;
constexpr const char* kPlotScript = "plot_loop.py";
constexpr const char* kPlotPackage = "python3-matplotlib";

struct FrameRecord {
  std::string backend;
  int phase = 0;
  int frame = 0;
  bool full = false;
  double ms = 0.0;
  RenderTimings timings;
  std::uint64_t texels = 0, layerTexels = 0, primary = 0, visibility = 0, pixels = 0;
  std::uint64_t uploaded = 0, readback = 0;
  int dispatches = 0;
  int panEighths = 0;  // pan: the camera's step this frame in eighths of a cascade-0 texel
  std::vector<std::pair<std::string, std::uint64_t>> layers;  // texels traced per layer
};

void checkRange(const char* option, long long value, long long lo, long long hi) {
  if (value < lo || value > hi)
    throwBadInput(std::string("bench --loop: ") + option + ": must be between " + std::to_string(lo) + " and " +
                  std::to_string(hi) + ", not " + std::to_string(value));
}

bool endsWithPng(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".png";
}

// ---- Statistics of a set of frames.

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Nearest rank: the smallest value that at least 99% of the frames do not exceed.
double p99(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t rank = std::size_t(std::ceil(0.99 * double(v.size())));
  return v[std::max<std::size_t>(rank, 1) - 1];
}

struct Summary {
  int frames = 0;
  double medianMs = 0.0, p99Ms = 0.0;
  double sceneMs = 0.0, shadowMs = 0.0, gbufferMs = 0.0, visibilityMs = 0.0, lightingMs = 0.0;
  double texels = 0.0, share = 0.0, rays = 0.0, uploaded = 0.0, readback = 0.0, dispatches = 0.0;
};

Summary summarize(const std::vector<const FrameRecord*>& frames) {
  Summary s;
  s.frames = int(frames.size());
  if (frames.empty()) {
    s.medianMs = s.p99Ms = std::nan("");
    return s;
  }
  std::vector<double> ms, scene, shadow, gbuffer, visibility, lighting;
  double texels = 0.0, layerTexels = 0.0, rays = 0.0, up = 0.0, down = 0.0, dispatches = 0.0;
  for (const FrameRecord* f : frames) {
    ms.push_back(f->ms);
    scene.push_back(f->timings.sceneMs);
    shadow.push_back(f->timings.shadowMs);
    gbuffer.push_back(f->timings.gbufferMs);
    visibility.push_back(f->timings.visibilityMs);
    lighting.push_back(f->timings.lightingMs);
    texels += double(f->texels);
    layerTexels += double(f->layerTexels);
    rays += double(f->texels + f->primary + f->visibility);
    up += double(f->uploaded);
    down += double(f->readback);
    dispatches += f->dispatches;
  }
  const double n = double(frames.size());
  s.medianMs = median(ms);
  s.p99Ms = p99(ms);
  s.sceneMs = median(scene);
  s.shadowMs = median(shadow);
  s.gbufferMs = median(gbuffer);
  s.visibilityMs = median(visibility);
  s.lightingMs = median(lighting);
  s.texels = texels / n;
  s.share = layerTexels > 0.0 ? 100.0 * texels / layerTexels : 0.0;
  s.rays = rays / n;
  s.uploaded = up / n;
  s.readback = down / n;
  s.dispatches = dispatches / n;
  return s;
}

void printTableHeader() {
  std::printf("  %-16s %6s %10s %10s %10s | %8s %8s %8s %8s %8s | %11s %7s %11s %10s %10s %6s\n", "phase", "frames",
              "median ms", "p99 ms", "full ms", "scene", "shadow", "G-buffer", "visib.", "lighting", "texels",
              "share%", "rays", "up KiB", "down KiB", "disp.");
}

void printTableRow(const std::string& label, const Summary& s, double fullMs) {
  std::printf("  %-16s %6d %10.2f %10.2f %10.1f | %8.2f %8.2f %8.2f %8.2f %8.2f | %11.0f %7.3f %11.0f %10.1f %10.1f %6.1f\n",
              label.c_str(), s.frames, s.medianMs, s.p99Ms, fullMs, s.sceneMs, s.shadowMs, s.gbufferMs,
              s.visibilityMs, s.lightingMs, s.texels, s.share, s.rays, s.uploaded / 1024.0, s.readback / 1024.0,
              s.dispatches);
}

// Which layers the texels of a phase went to: the mean a frame of each layer that had any.
void printLayerMeans(const std::vector<const FrameRecord*>& frames) {
  if (frames.empty()) return;
  std::vector<std::pair<std::string, double>> sums;
  for (const FrameRecord* f : frames)
    for (const auto& layer : f->layers) {
      const std::string& view = layer.first;
      auto it = std::find_if(sums.begin(), sums.end(), [&](const auto& s) { return s.first == view; });
      if (it == sums.end()) it = sums.insert(sums.end(), {view, 0.0});
      it->second += double(layer.second);
    }
  std::string line;
  for (const auto& [view, sum] : sums)
    if (sum > 0.0) line += "  " + view + " " + std::to_string(std::llround(sum / double(frames.size())));
  if (!line.empty()) std::printf("    texels by layer:%s\n", line.c_str());
}

std::string panLabel(int eighths) {
  if (eighths % 8 == 0) return "  pan " + std::to_string(eighths / 8) + " texel" + (eighths == 8 ? "" : "s");
  return "  pan " + std::to_string(eighths) + "/8 texel";
}

// ---- The plotting tool.

// The plotting script: beside the executable (the build tree puts it there), else where `cmake --install`
// puts it (<prefix>/share/voxshadow beside <prefix>/bin).
std::vector<fs::path> plotScriptCandidates() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const fs::path dir = exe.parent_path();
  return {dir / kPlotScript, dir.parent_path() / "share" / "voxshadow" / kPlotScript};
}

// Debian's matplotlib is installed for Debian's interpreter, which a python3 earlier on PATH (a pyenv or
// virtual environment) may not see.
std::string pythonInterpreter() { return ::access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : "python3"; }

// Runs argv[0] (searched on PATH) with argv; returns its exit status, 127 when it cannot start, 128 + signal
// when a signal ended it. `quiet` sends its output to /dev/null.
int runProgram(const std::vector<std::string>& argv, bool quiet) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (quiet) {
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  }
  std::fflush(nullptr);
  pid_t pid = 0;
  const int err = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (err != 0) return 127;
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return 127;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 127;
}

struct PlotTool {
  std::string python;
  fs::path script;
};

// Found before any work, so that a long run does not end without its plot.
PlotTool findPlotTool() {
  PlotTool tool;
  const std::vector<fs::path> candidates = plotScriptCandidates();
  for (const fs::path& c : candidates) {
    std::error_code ec;
    if (fs::is_regular_file(c, ec)) {
      tool.script = c;
      break;
    }
  }
  if (tool.script.empty()) {
    std::string where;
    for (const fs::path& c : candidates) where += (where.empty() ? "" : " or ") + c.string();
    throwRuntime(std::string("bench --loop --plot: ") + kPlotScript + " not found (looked for " +
                 (where.empty() ? std::string("it beside the executable") : where) +
                 "; it is tools/plot_loop.py of the source tree)");
  }
  tool.python = pythonInterpreter();
  if (runProgram({tool.python, "-c", "import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot"}, true) != 0)
    throwRuntime("bench --loop --plot: " + tool.python + " cannot import matplotlib: install the Debian package " +
                 kPlotPackage + " (apt-get install " + kPlotPackage + ", or tools/install-deps.sh)");
  return tool;
}

// ---- Outputs.

void writeCsv(const fs::path& out, const std::vector<FrameRecord>& records) {
  std::ofstream f(out, std::ios::binary | std::ios::trunc);
  if (!f) throwRuntime(out.string() + ": cannot open for writing");
  f << "backend,phase,frame,kind,ms,scene_ms,shadow_ms,gbuffer_ms,visibility_ms,lighting_ms,texels,primary,"
       "visibility,pixels_shaded,uploaded,readback,dispatches\n";
  char line[512];
  for (const FrameRecord& r : records) {
    std::snprintf(line, sizeof line, "%s,%s,%d,%s,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%llu,%llu,%llu,%llu,%llu,%llu,%d\n",
                  r.backend.c_str(), kPhaseNames[r.phase], r.frame, r.full ? "full" : "incremental", r.ms,
                  r.timings.sceneMs, r.timings.shadowMs, r.timings.gbufferMs, r.timings.visibilityMs,
                  r.timings.lightingMs, (unsigned long long)r.texels, (unsigned long long)r.primary,
                  (unsigned long long)r.visibility, (unsigned long long)r.pixels, (unsigned long long)r.uploaded,
                  (unsigned long long)r.readback, r.dispatches);
    f << line;
  }
  f.flush();
  if (!f) throwRuntime(out.string() + ": write failed");
}

// ---- The scene's parts the phases change.

struct Ground {
  const Scene* scene = nullptr;
  std::size_t object = 0;
  glm::dmat4 brickToWorld{1.0};
  glm::dmat4 worldToBrick{1.0};
  // Looked up at each use: the scene's objects move when an object is added.
  const Brickmap& brickmap() const { return scene->objects()[object].brickmap; }
};

Ground findGround(const Scene& scene) {
  const auto& assets = scene.desc().assets;
  for (std::size_t a = 0; a < assets.size(); ++a) {
    if (assets[a].name != "ground" || scene.assetObjects()[a].count == 0) continue;
    Ground g;
    g.scene = &scene;
    g.object = scene.assetObjects()[a].first;
    for (std::size_t i = 0; i < scene.instances().size(); ++i)
      if (scene.instanceActive(i) && scene.instances()[i].object == g.object) {
        g.brickToWorld = scene.instances()[i].brickToWorld;
        g.worldToBrick = glm::inverse(g.brickToWorld);
        return g;
      }
  }
  throwRuntime("bench --loop: the demo scene has no placed asset 'ground'");
}

glm::ivec3 toBrick(const Ground& g, const glm::dvec3& world) {
  const glm::dvec4 b = g.worldToBrick * glm::dvec4(world, 1.0);
  return glm::ivec3(glm::floor(glm::dvec3(b)));
}

// The highest solid voxel of the ground's column (x, z), or nothing.
std::optional<int> groundTop(const Ground& g, int x, int z) {
  const Brickmap& brickmap = g.brickmap();
  const VoxelBox bounds = brickmap.bounds();
  if (bounds.empty()) return std::nullopt;
  for (int y = bounds.max.y - 1; y >= bounds.min.y; --y)
    if (brickmap.isSolid({x, y, z})) return y;
  return std::nullopt;
}

// Where a camera ray first meets the ground (in the ground's brick space), marching in small steps: the
// phases only need a place on the ground that the camera sees.
std::optional<glm::ivec3> groundHit(const Ground& g, const glm::dvec3& origin, const glm::dvec3& direction, double far) {
  const Brickmap& brickmap = g.brickmap();
  for (double t = 0.0; t < far; t += 0.1) {
    const glm::ivec3 v = toBrick(g, origin + direction * t);
    if (brickmap.isSolid(v)) return v;
  }
  return std::nullopt;
}

// The actor: a 16^3 block, hollow, its shell in a two-colour checker.
Brickmap actorBrickmap() {
  std::vector<SolidVoxel> voxels;
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        const bool inside = x >= 2 && x < 14 && y >= 2 && y < 14 && z >= 2 && z < 14;
        if (inside) continue;
        voxels.push_back({{x, y, z}, std::uint8_t(((x / 4 + y / 4 + z / 4) & 1) ? 1 : 2)});
      }
  return Brickmap::build(voxels);
}

// ---- One backend's run.

struct LoopRun {
  const LoopBenchOptions& opt;
  std::string backend;
  Scene& scene;
  FrameRenderer& renderer;
  RenderOptions renderOptions;
  std::vector<FrameRecord>& records;

  FrameRecord render(int phase, int frame, bool full) {
    if (full) renderer.invalidateLayers();
    const auto t0 = Clock::now();
    const RenderedFrame& f = renderer.render(scene, renderOptions);
    FrameRecord r;
    r.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    r.backend = backend;
    r.phase = phase;
    r.frame = frame;
    r.full = full;
    r.timings = f.timings;
    r.texels = f.stats.texelsTraced;
    r.layerTexels = f.stats.layerTexels;
    r.primary = f.stats.primaryRays;
    r.visibility = f.stats.visibilityRays;
    r.pixels = f.stats.pixelsShaded;
    r.uploaded = f.stats.bytesUploaded;
    r.readback = f.stats.bytesReadBack;
    r.dispatches = f.stats.dispatches;
    for (const LayerTraceStats& l : f.stats.layers) r.layers.push_back({l.view, l.texels});
    return r;
  }

  // N frames of `phase`, change(f) before each; a forced full frame of the same state after every
  // fullEvery-th. change returns the pan step of the frame (eighths of a texel; 0 elsewhere).
  void phase(int phase, const std::function<int(int)>& change) {
    std::fprintf(stderr, "bench --loop: %s %s, %d frames\n", backend.c_str(), kPhaseNames[phase], opt.frames);
    for (int f = 0; f < opt.frames; ++f) {
      const int eighths = change(f);
      FrameRecord r = render(phase, f, false);
      r.panEighths = eighths;
      records.push_back(r);
      if ((f + 1) % opt.fullEvery == 0) records.push_back(render(phase, f, true));
    }
  }
};

void runBackend(const LoopBenchOptions& opt, const std::string& name, Tracer& tracer, const Scene& loaded,
                std::vector<FrameRecord>& records) {
  Scene scene = loaded;  // each backend starts from the demo as it was loaded
  FrameRenderer renderer(tracer);
  // A game's frame: it shows the lit colour (and reads the shadow terms, as the figures before did), and has no
  // use for the G-buffer, which a Vulkan frame then keeps on the device.
  RenderOptions gameOptions;
  gameOptions.readGBuffer = false;
  LoopRun run{opt, name, scene, renderer, gameOptions, records};
  run.renderOptions.width = opt.width;
  run.renderOptions.height = opt.height;
  const std::size_t first = records.size();

  std::printf("%s: %s; demo scene at %dx%d, %d frames a phase, a forced full frame every %d frame%s\n", name.c_str(),
              tracer.deviceName().c_str(), opt.width, opt.height, opt.frames, opt.fullEvery,
              opt.fullEvery == 1 ? "" : "s");
  // The first frame builds everything (the box table, pipelines, buffers): reported apart, not in a phase.
  const FrameRecord warm = run.render(0, -1, false);
  std::printf("%s: first frame %.1f ms (scene %.1f, shadow %.1f, G-buffer %.1f, visibility %.1f, lighting %.1f); "
              "%llu layer texels\n",
              name.c_str(), warm.ms, warm.timings.sceneMs, warm.timings.shadowMs, warm.timings.gbufferMs,
              warm.timings.visibilityMs, warm.timings.lightingMs, (unsigned long long)warm.layerTexels);
  double texel = 0.0;
  for (const LightView& v : renderer.render(scene, run.renderOptions).views)
    if (v.lightIndex == 0 && v.cascade == 0) texel = v.texelWorld;
  if (!(texel > 0.0)) throwRuntime("bench --loop: the demo's sun has no cascade 0");

  // 1. still: nothing changes.
  run.phase(0, [](int) { return 0; });

  // 2. pan: sideways, the first half in eighths of a texel, the second 1, 2, 3, 4 texels a frame in turn.
  const CameraDesc camera0 = *scene.desc().camera;
  const CameraFrame frame0 = cameraFrame(camera0, opt.width, opt.height);
  const glm::dvec3 position0(camera0.position), target0(camera0.target);
  double offset = 0.0;
  const int subTexelFrames = (opt.frames + 1) / 2;
  run.phase(1, [&](int f) {
    const int eighths = f < subTexelFrames ? 1 : 8 * (1 + (f - subTexelFrames) % 4);
    offset += texel * eighths / 8.0;
    CameraDesc c = camera0;
    c.position = glm::vec3(position0 + frame0.right * offset);
    c.target = glm::vec3(target0 + frame0.right * offset);
    scene.setCamera(c);
    return eighths;
  });

  // 3. actor: walks along the camera's right across the ground below the image centre, 0.25 a frame, its
  // feet on the ground's top.
  const Ground ground = findGround(scene);
  const CameraFrame frame1 = cameraFrame(*scene.desc().camera, opt.width, opt.height);
  const glm::dvec3 lowerMiddle = pixelDirection(frame1, opt.width / 2, opt.height * 3 / 4);
  const std::optional<glm::ivec3> walkHit = groundHit(ground, frame1.position, lowerMiddle, frame1.farPlane);
  const glm::dvec3 walkCentre =
      walkHit ? glm::dvec3(ground.brickToWorld * glm::dvec4(glm::dvec3(*walkHit) + 0.5, 1.0)) : glm::dvec3(0.0);
  const glm::dvec3 walkDir = glm::normalize(glm::dvec3(frame1.right.x, 0.0, frame1.right.z));
  constexpr double kStep = 0.25;
  const glm::dmat4 actorBrickToObject = scene.objects()[ground.object].brickToObject;  // the ground's voxel size
  const glm::dvec3 actorCentre(actorBrickToObject * glm::dvec4(8.0, 0.0, 8.0, 1.0));  // the bottom's centre
  auto actorTransform = [&](int f) {
    glm::dvec3 p = walkCentre + walkDir * (kStep * (double(f) - 0.5 * double(opt.frames)));
    const glm::ivec3 column = toBrick(ground, p);
    double y = walkCentre.y;
    if (std::optional<int> top = groundTop(ground, column.x, column.z))
      y = (ground.brickToWorld * glm::dvec4(double(column.x) + 0.5, double(*top + 1), double(column.z) + 0.5, 1.0)).y;
    return glm::translate(glm::dmat4(1.0), glm::dvec3(p.x, y, p.z) - actorCentre);
  };
  const std::size_t actorObject =
      scene.addObject(actorBrickmap(), {glm::vec3(0.0f), glm::vec3(0.85f, 0.2f, 0.15f), glm::vec3(0.95f, 0.85f, 0.2f)},
                      actorBrickToObject);
  const std::size_t actor = scene.addInstance(actorObject, actorTransform(0));
  run.phase(2, [&](int f) {
    if (f > 0) scene.moveInstance(actor, actorTransform(f));
    return 0;
  });

  // 4. dig: 4^3 holes from the top of the ground on a grid around the image centre's ground point, every 10th
  // frame a 16^3 block on the ground instead.
  const CameraFrame frame2 = cameraFrame(*scene.desc().camera, opt.width, opt.height);
  const std::optional<glm::ivec3> centreHit =
      groundHit(ground, frame2.position, frame2.forward, frame2.farPlane);
  const glm::ivec3 digCentre = centreHit ? *centreHit : toBrick(ground, glm::dvec3(0.0));
  run.phase(3, [&](int f) {
    const int col = f % 10, row = (f / 10) % 10;
    const int x = digCentre.x + (col - 5) * 6, z = digCentre.z + (row - 5) * 6;
    const int top = groundTop(ground, x, z).value_or(digCentre.y);
    if ((f + 1) % 10 == 0)
      scene.fillVoxels(ground.object, VoxelBox{{x, top + 1, z}, {x + 16, top + 17, z + 16}}, 3);
    else
      scene.fillVoxels(ground.object, VoxelBox{{x, top - 3, z}, {x + 4, top + 1, z + 4}}, 0);
    return 0;
  });

  // 5. sun: from 50 degrees above the horizon down to 5, its azimuth kept.
  const glm::vec3 sun0 = scene.desc().lights.at(0).direction;
  if (scene.desc().lights.at(0).type != LightType::Directional)
    throwRuntime("bench --loop: the demo's light 0 is not a directional sun");
  const glm::dvec2 azimuth = glm::normalize(glm::dvec2(sun0.x, sun0.z));
  run.phase(4, [&](int f) {
    const double t = opt.frames > 1 ? double(f) / double(opt.frames - 1) : 0.0;
    const double elevation = glm::radians(50.0 - 45.0 * t);
    const glm::dvec3 d(std::cos(elevation) * azimuth.x, -std::sin(elevation), std::cos(elevation) * azimuth.y);
    scene.moveLight(0, glm::vec3(0.0f), glm::vec3(d));
    return 0;
  });

  // The table, then the lines scripts read.
  std::printf("%s: medians of the incremental frames (ms per stage); \"full\" rows: the forced full frames; "
              "texels, rays, KiB and dispatches are means a frame, share%% of all layer texels\n", name.c_str());
  printTableHeader();
  std::vector<Summary> incremental(kPhaseCount), full(kPhaseCount);
  for (int p = 0; p < kPhaseCount; ++p) {
    std::vector<const FrameRecord*> inc, fulls;
    std::map<int, std::vector<const FrameRecord*>> byStep;
    for (std::size_t i = first; i < records.size(); ++i) {
      const FrameRecord& r = records[i];
      if (r.phase != p) continue;
      (r.full ? fulls : inc).push_back(&r);
      if (!r.full && p == 1) byStep[r.panEighths].push_back(&r);
    }
    incremental[p] = summarize(inc);
    full[p] = summarize(fulls);
    printTableRow(kPhaseNames[p], incremental[p], full[p].medianMs);
    for (const auto& [eighths, frames] : byStep) printTableRow(panLabel(eighths), summarize(frames), full[p].medianMs);
    if (!fulls.empty()) printTableRow("  full", full[p], full[p].medianMs);
    printLayerMeans(inc);
  }
  for (int p = 0; p < kPhaseCount; ++p) {
    const Summary& s = incremental[p];
    std::printf("loop %s %s frames=%d median_ms=%.3f p99_ms=%.3f full_median_ms=%.3f texels=%.0f texel_share=%.4f "
                "rays=%.0f uploaded=%.0f readback=%.0f\n",
                name.c_str(), kPhaseNames[p], s.frames, s.medianMs, s.p99Ms, full[p].medianMs, s.texels, s.share,
                s.rays, s.uploaded, s.readback);
  }
  if (VulkanTracer* vulkan = tracer.vulkan())
    if (vulkan->context().validationEnabled()) {
      const std::vector<std::string> messages = vulkan->validationMessages();
      std::printf("%s: validation messages: %zu\n", name.c_str(), messages.size());
      for (std::size_t i = 0; i < messages.size() && i < 10; ++i) std::fprintf(stderr, "validation: %s\n", messages[i].c_str());
    }
  std::fflush(stdout);
}

}  // namespace

void runLoopBench(const LoopBenchOptions& opt) {
  checkRange("--frames", opt.frames, 1, 100000);
  checkRange("--full-every", opt.fullEvery, 1, 100000);
  checkRange("--threads", opt.threads, 1, kMaxThreads);
  checkRange("--size width", opt.width, 1, 16384);
  checkRange("--size height", opt.height, 1, 16384);
  if (opt.shadowDivisor < 1 || opt.shadowDivisor > 1024 || (opt.shadowDivisor & (opt.shadowDivisor - 1)) != 0)
    throwBadInput("bench --loop: --shadow-divisor: must be a power of two from 1 to 1024, not " +
                  std::to_string(opt.shadowDivisor));
  if (opt.plot && !endsWithPng(*opt.plot))
    throwBadInput("bench --loop: --plot " + opt.plot->string() + ": must end in .png");
  std::vector<fs::path> outputs;
  if (opt.csv) outputs.push_back(*opt.csv);
  if (opt.plot) outputs.push_back(*opt.plot);
  std::optional<PlotTool> plotTool;
  if (opt.plot) plotTool = findPlotTool();
  {
    std::vector<fs::path> inputs;
    std::vector<std::string> what;
    if (plotTool) {
      inputs.push_back(plotTool->script);
      what.push_back("plotting script");
    }
    refuseOutputsOverInputs(outputs, inputs, what);
    for (const fs::path& out : outputs) checkOutputDirectory(out);
  }

  const fs::path dir = fs::temp_directory_path() / ("voxshadow-loop-" + std::to_string(::getpid()));
  std::optional<Scene> loaded;
  try {
    SceneDesc desc = parseSceneFile(fs::path(writeDemoWorld(dir).back()));
    for (LightDesc& light : desc.lights)
      if (light.shadow) light.shadow->resolution = std::max(16, light.shadow->resolution / opt.shadowDivisor);
    loaded = Scene::load(std::move(desc));
  } catch (...) {
    std::error_code ec;
    fs::remove_all(dir, ec);
    throw;
  }
  {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }

  std::vector<FrameRecord> records;
  {
    std::unique_ptr<Tracer> cpu = makeCpuTracer({CpuTracePath::Interleaved, opt.threads});
    runBackend(opt, "cpu", *cpu, *loaded, records);
  }
  if (opt.vulkan) {
    VulkanOptions vulkanOptions;
    vulkanOptions.hostThreads = opt.threads;
    std::unique_ptr<Tracer> vulkan = makeVulkanTracer(vulkanOptions);
    runBackend(opt, "vulkan", *vulkan, *loaded, records);
  }

  if (opt.csv) {
    writeAtomically(std::span<const fs::path>(&*opt.csv, 1),
                    [&](std::size_t, const fs::path& tmp) { writeCsv(tmp, records); });
    std::printf("wrote %s (%zu frames)\n", opt.csv->string().c_str(), records.size());
  }
  if (opt.plot) {
    // Without --csv the plot reads a CSV of its own, written beside it and removed afterwards.
    const fs::path csv = opt.csv ? *opt.csv : temporarySibling(*opt.plot, ".csv");
    if (!opt.csv) writeCsv(csv, records);
    try {
      writeAtomically(std::span<const fs::path>(&*opt.plot, 1), [&](std::size_t, const fs::path& tmp) {
        const int rc = runProgram({plotTool->python, plotTool->script.string(), csv.string(), tmp.string()}, false);
        if (rc != 0)
          throwRuntime("bench --loop --plot: " + plotTool->script.string() + " failed (exit status " +
                       std::to_string(rc) + ")");
      });
    } catch (...) {
      std::error_code ec;
      if (!opt.csv) fs::remove(csv, ec);
      throw;
    }
    std::error_code ec;
    if (!opt.csv) fs::remove(csv, ec);
    std::printf("wrote %s\n", opt.plot->string().c_str());
  }
}

}  // namespace vs::cli
