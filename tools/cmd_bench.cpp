// voxshadow bench: the CPU backend (and the Vulkan backend when asked) against the OpenVDB peer on city512,
// same rays, same thread count, in one run (DESIGN.md §10): shadow texels, primary rays from a perspective
// camera (closest hits) and visibility rays from every primary hit toward the sun (any hits).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <glm/glm.hpp>

#include "compute/cpu/lane_tracer.h"
#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "lighting/vulkan_lighting.h"
#include "tools/bench_embree.h"
#include "tools/bench_loop.h"
#include "tools/commands.h"
#include "tools/resources.h"
#include "tools/peer/openvdb_peer.h"
#include "voxel/city512.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace vs::cli {

// The calibration window of DESIGN.md §10: an orthographic view along d over the projection of [0,512]^3.
gpu::TraceView city512CalibrationView(int res) {
  glm::vec3 d = glm::normalize(glm::vec3(-0.4f, -1.0f, -0.3f));
  glm::vec3 u = glm::normalize(glm::cross(glm::vec3(0, 0, 1), d));
  glm::vec3 v = glm::cross(d, u);
  // (u, -v, -d) is a right-handed camera frame looking along d; rows are flipped relative to v only.
  glm::vec3 y = -v;
  float uMin = 1e30f, uMax = -1e30f, yMin = 1e30f, yMax = -1e30f, dMin = 1e30f, dMax = -1e30f;
  for (int c = 0; c < 8; ++c) {
    glm::vec3 p((c & 1) ? 512.0f : 0.0f, (c & 2) ? 512.0f : 0.0f, (c & 4) ? 512.0f : 0.0f);
    uMin = std::min(uMin, glm::dot(p, u)), uMax = std::max(uMax, glm::dot(p, u));
    yMin = std::min(yMin, glm::dot(p, y)), yMax = std::max(yMax, glm::dot(p, y));
    dMin = std::min(dMin, glm::dot(p, d)), dMax = std::max(dMax, glm::dot(p, d));
  }
  // World -> view: x = u.p, y = y.p, z = -(d.p); view -> clip: orthographic, depth 0 at d.p = dMin.
  glm::mat4 view(1.0f);
  for (int i = 0; i < 3; ++i) {
    view[i][0] = u[i];
    view[i][1] = y[i];
    view[i][2] = -d[i];
  }
  glm::mat4 proj(1.0f);
  proj[0][0] = 2.0f / (uMax - uMin);
  proj[3][0] = -(uMax + uMin) / (uMax - uMin);
  proj[1][1] = 2.0f / (yMax - yMin);
  proj[3][1] = -(yMax + yMin) / (yMax - yMin);
  // z_view = -(d.p); depth = (d.p - dMin) / (dMax - dMin) = (-z_view - dMin) / (dMax - dMin).
  proj[2][2] = -1.0f / (dMax - dMin);
  proj[3][2] = -dMin / (dMax - dMin);
  return gpu::makeTraceView(glm::dmat4(proj * view), res, res, gpu::VS_ENCODING_NDC_DEPTH, gpu::VS_DEPTH_POINT_ENTRY);
}

namespace {

struct BenchOptions {
  int threads = 2;
  int resolution = 1024;
  int reps = 5;
  bool skipPeer = false;
  bool vulkan = false;
  bool frame = false;
  bool embree = false;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Seconds of one call of fn.
double timeOnce(const std::function<void()>& fn) {
  auto start = std::chrono::steady_clock::now();
  fn();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Runs fn once to warm up, then `reps` times; returns the median seconds.
double timeMedian(int reps, const std::function<void()>& fn) {
  fn();
  std::vector<double> seconds;
  for (int i = 0; i < reps; ++i) seconds.push_back(timeOnce(fn));
  return median(seconds);
}

// The machine's speed drifts over seconds (shared cores, clock changes), which medians taken one after the
// other do not cancel. Pairs of back-to-back runs see the same conditions: the median of their ratios
// (theirs / ours seconds) is the steadier figure. Prints it with its range.
void printPairedRatio(const char* label, int reps, const std::function<double()>& ours,
                      const std::function<double()>& theirs) {
  std::vector<double> ratios;
  for (int i = 0; i < reps; ++i) {
    double a = ours();
    ratios.push_back(theirs() / a);
  }
  std::sort(ratios.begin(), ratios.end());
  std::printf("ratio %s / peer, median of %d back-to-back pairs: %.2fx (range %.2f-%.2fx)\n", label, reps,
              median(ratios), ratios.front(), ratios.back());
}

// The Vulkan backend on the same rays: pipeline creation (the shader JIT on lavapipe) and the first trace
// are reported apart from the steady state, the median over `reps` traces after one more warm-up trace.
struct VulkanBench {
  std::unique_ptr<Tracer> tracer;  // kept for the paired runs
  std::vector<ShadowLayer> layers;
  std::string device;
  double pipelineMs = 0.0;
  bool warmCache = false;
  double uploadMs = 0.0;           // upload(): the voxel arrays, the records and the box table (built here)
  double instanceUploadMs = 0.0;   // uploadInstances(): a frame where only instances moved
  double firstWallMs = 0.0;
  double medianGpuMs = -1.0;   // from timestamps; < 0 when the device has none
  double medianWallMs = 0.0;   // host time of a whole trace call: submission, dispatch, readback
  std::size_t differing = 0;   // texels differing from the CPU reference
};

VulkanBench benchVulkan(const SceneData& scene, const std::vector<gpu::TraceView>& views, int reps,
                        const std::vector<ShadowLayer>& reference) {
  VulkanBench b;
  b.tracer = makeVulkanTracer();
  Tracer& tracer = *b.tracer;
  b.device = tracer.deviceName();
  b.pipelineMs = tracer.vulkan()->pipelineStats().createMs;
  b.warmCache = tracer.vulkan()->pipelineStats().warmCache;
  b.uploadMs = timeOnce([&] { tracer.setScene(scene); }) * 1e3;
  b.instanceUploadMs = timeOnce([&] { tracer.instancesMoved(scene); }) * 1e3;
  std::vector<ShadowLayer>& layers = b.layers;
  b.firstWallMs = tracer.traceShadow(views, layers).wallMs;
  tracer.traceShadow(views, layers);
  std::vector<double> gpu, wall;
  for (int i = 0; i < reps; ++i) {
    TraceStats t = tracer.traceShadow(views, layers);
    gpu.push_back(t.gpuMs);
    wall.push_back(t.wallMs);
  }
  b.medianGpuMs = median(gpu);
  b.medianWallMs = median(wall);
  for (std::size_t i = 0; i < layers.size() && i < reference.size(); ++i)
    for (std::size_t k = 0; k < layers[i].texels.size(); ++k)
      if (std::memcmp(&layers[i].texels[k], &reference[i].texels[k], sizeof(float)) != 0) ++b.differing;
  return b;
}

// The camera of the primary rays: 1280x720, 60 degrees vertical field of view, over the city from a corner.
constexpr int kCameraWidth = 1280, kCameraHeight = 720;

struct RayBench {
  std::vector<gpu::TraceRay> rays;        // primary rays
  std::vector<gpu::RayHit> hits;
  gpu::CameraRays camera{};               // the same camera, for rays made where they are traced
  std::vector<gpu::TraceRay> visibility;  // one per primary hit, toward the sun
  std::vector<std::uint32_t> occluded;
};

// Seconds of a ray trace: GPU timestamps where the device has them, else the call's host time.
double raySeconds(const TraceStats& t) { return (t.gpuMs > 0.0 ? t.gpuMs : t.wallMs) * 1e-3; }

RayBench primaryRays(int) {
  RayBench b;
  const glm::dvec3 eye(700.0, 300.0, 760.0), target(256.0, 30.0, 256.0);
  const glm::dvec3 forward = glm::normalize(target - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, glm::dvec3(0.0, 1.0, 0.0)));
  const glm::dvec3 up = glm::cross(right, forward);
  const double tanHalf = std::tan(glm::radians(30.0)), aspect = double(kCameraWidth) / kCameraHeight;
  b.rays.reserve(std::size_t(kCameraWidth) * kCameraHeight);
  for (int y = 0; y < kCameraHeight; ++y)
    for (int x = 0; x < kCameraWidth; ++x) {
      double u = ((x + 0.5) / kCameraWidth * 2.0 - 1.0) * tanHalf * aspect;
      double v = (1.0 - (y + 0.5) / kCameraHeight * 2.0) * tanHalf;
      b.rays.push_back(gpu::makeTraceRay(eye, glm::normalize(forward + right * u + up * v), 0.0f, 4000.0f));
    }
  b.hits.resize(b.rays.size());
  glm::vec3 high, low;
  gpu::splitToFloats(eye, high, low);
  b.camera.originHigh = glm::vec4(high, float(tanHalf * aspect));
  b.camera.originLow = glm::vec4(low, float(tanHalf));
  b.camera.forward = glm::vec4(glm::vec3(forward), 1e-3f);
  b.camera.right = glm::vec4(glm::vec3(right), 4000.0f);
  b.camera.up = glm::vec4(glm::vec3(up), 0.0f);
  b.camera.size = glm::uvec4(kCameraWidth, kCameraHeight, 0u, 0u);
  return b;
}

// Primary rays on `tracer`, then visibility rays from their hits (built once, from the first tracer's hits:
// every backend gives the same), and the median seconds of each kind.
void benchRayKinds(RayBench& b, Tracer& tracer, int reps, const char* label) {
  std::vector<double> primary, visibility, visibilityClosest;
  tracer.traceClosest(b.rays, b.hits);
  if (b.visibility.empty()) {
    // Toward the sun of the shadow view, from just before each hit's entry point (on the camera's side, so the
    // ray does not start inside the voxel it hit).
    const glm::dvec3 sun = glm::normalize(glm::dvec3(0.4, 1.0, 0.3));
    for (std::size_t i = 0; i < b.rays.size(); ++i) {
      if (!b.hits[i].hit) continue;
      const gpu::TraceRay& r = b.rays[i];
      glm::dvec3 o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
      glm::dvec3 d(glm::vec3(r.direction));
      b.visibility.push_back(gpu::makeTraceRay(o + d * (double(b.hits[i].t) - 1e-3), sun, 0.0f, 4000.0f));
    }
    b.occluded.resize(b.visibility.size());
  }
  tracer.traceAny(b.visibility, b.occluded);
  for (int i = 0; i < reps; ++i) {
    primary.push_back(raySeconds(tracer.traceClosest(b.rays, b.hits)));
    visibility.push_back(raySeconds(tracer.traceAny(b.visibility, b.occluded)));
    // The same rays as closest-hit rays: what the any-hit kind saves.
    std::vector<gpu::RayHit> visibilityHits(b.visibility.size());
    visibilityClosest.push_back(raySeconds(tracer.traceClosest(b.visibility, visibilityHits)));
  }
  std::size_t hits = std::count_if(b.hits.begin(), b.hits.end(), [](const gpu::RayHit& h) { return h.hit != 0u; });
  std::size_t shadowed = std::count(b.occluded.begin(), b.occluded.end(), 1u);
  double p = median(primary), v = median(visibility);
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (%zu hits)\n", (std::string(label) + " primary").c_str(), p,
              double(b.rays.size()) / p / 1e6, hits);
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (%zu occluded)\n", (std::string(label) + " visibility").c_str(), v,
              double(b.visibility.size()) / v / 1e6, shadowed);
  double c = median(visibilityClosest);
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (the visibility rays as closest-hit rays)\n",
              (std::string(label) + " visibility closest").c_str(), c, double(b.visibility.size()) / c / 1e6);
  // The camera's rays made where they are traced (Tracer::traceCamera; on Vulkan only the record goes up)
  // against the host-made rays of the same camera, whole calls (making, moving and tracing), back to back.
  std::vector<gpu::RayHit> cameraHits(b.rays.size());
  std::vector<double> cameraSeconds, ratios;
  for (int i = 0; i < reps; ++i) {
    const double host = timeOnce([&] { tracer.traceClosest(b.rays, b.hits); });
    cameraSeconds.push_back(timeOnce([&] { tracer.traceCamera(b.camera, {}, cameraHits); }));
    ratios.push_back(host / cameraSeconds.back());
  }
  std::sort(ratios.begin(), ratios.end());
  const double m = median(cameraSeconds);
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (whole call; host-made rays' call / this, median of %d pairs: "
              "%.2fx, range %.2f-%.2fx)\n",
              (std::string(label) + " camera rays").c_str(), m, double(b.rays.size()) / m / 1e6, reps,
              median(ratios), ratios.front(), ratios.back());
}

// Every lane width of the CPU fast path that this processor runs, on each ray kind, against the one the
// dispatcher picks for `picked` (the widest), pairs run back to back: the figures behind the dispatcher's
// rule, which a processor of another vendor may not back. Preconditions: benchRayKinds filled b.
void benchLaneWidths(const SceneData& scene, std::span<const gpu::TraceView> views, double texels, RayBench& b,
                     Tracer& picked, const BenchOptions& opt) {
  if (!picked.cpu() || !picked.cpu()->hasBoxTable()) {
    std::printf("lane widths: not compared (no box table: the portable tiles run)\n");
    return;
  }
  struct Path {
    CpuTracePath path;
    LaneWidth width;
    const char* name;
  };
  const Path paths[] = {{CpuTracePath::LanesAvx512, LaneWidth::Avx512, "avx512"},
                        {CpuTracePath::LanesAvx2, LaneWidth::Avx2, "avx2"},
                        {CpuTracePath::LanesScalar, LaneWidth::Scalar, "scalar"}};
  std::vector<ShadowLayer> layers;
  std::vector<gpu::RayHit> hits(b.rays.size());
  std::vector<std::uint32_t> occluded(b.visibility.size());
  struct Kind {
    const char* name;
    double rays;
    std::function<double(Tracer&)> run;  // seconds of one call
  };
  const Kind kinds[] = {
      {"shadow", texels, [&](Tracer& t) { return raySeconds(t.traceShadow(views, layers)); }},
      {"primary", double(b.rays.size()), [&](Tracer& t) { return raySeconds(t.traceClosest(b.rays, hits)); }},
      {"visibility", double(b.visibility.size()),
       [&](Tracer& t) { return raySeconds(t.traceAny(b.visibility, occluded)); }},
  };
  std::printf("lane widths of the cpu fast path (the dispatcher picks %s):\n", laneWidthName(widestLaneWidth()));
  for (const Path& p : paths) {
    if (!laneWidthSupported(p.width)) {
      std::printf("lanes %s: not run, this processor lacks it\n", p.name);
      continue;
    }
    std::unique_ptr<Tracer> tracer = makeCpuTracer({p.path, opt.threads});
    tracer->setScene(scene);
    for (const Kind& k : kinds) {
      k.run(*tracer);  // warm-up
      std::vector<double> seconds, ratios;
      for (int r = 0; r < opt.reps; ++r) {
        seconds.push_back(k.run(*tracer));
        ratios.push_back(k.run(picked) / seconds.back());
      }
      std::sort(ratios.begin(), ratios.end());
      std::printf("lanes %s %s: %.2f Mrays/s, %.2fx the picked width's speed (median of %d pairs, range %.2f-%.2fx)\n",
                  p.name, k.name, k.rays / median(seconds) / 1e6, median(ratios), opt.reps, ratios.front(),
                  ratios.back());
    }
  }
}

// Each option out of its range is refused by name, before any work.
void checkBenchRange(const char* option, int value, int lo, int hi) {
  if (value < lo || value > hi)
    throwBadInput(std::string("bench: ") + option + ": must be between " + std::to_string(lo) + " and " +
                  std::to_string(hi) + ", not " + std::to_string(value));
}

void runBench(const BenchOptions& opt) {
  checkBenchRange("--threads", opt.threads, 1, kMaxThreads);
  checkBenchRange("--resolution", opt.resolution, 16, 16384);
  checkBenchRange("--reps", opt.reps, 1, 1000);
  std::printf("city512: generating voxels...\n");
  auto voxels = city512Voxels();
  auto start = std::chrono::steady_clock::now();
  Brickmap brickmap = Brickmap::build(voxels);
  double buildSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const Brickmap* objects[] = {&brickmap};
  SceneInstance instance{0u, glm::dmat4(1.0)};
  SceneData scene = SceneData::build(objects, std::span<const SceneInstance>(&instance, 1));
  std::printf("city512: %llu solid voxels, brickmap built in %.2f s, occupancy %.2f MiB\n",
              static_cast<unsigned long long>(brickmap.solidCount()), buildSeconds,
              brickmap.memory().occupancyStructureBytes() / 1048576.0);

  gpu::TraceView view = city512CalibrationView(opt.resolution);
  std::vector<gpu::TraceView> views = {view};
  const double rays = double(opt.resolution) * opt.resolution;

  std::vector<ShadowLayer> layers;
  std::unique_ptr<Tracer> reference = makeCpuTracer({CpuTracePath::Reference, opt.threads});
  reference->setScene(scene);
  double referenceSeconds = timeMedian(opt.reps, [&] { reference->traceShadow(views, layers); });
  std::size_t hits = std::count_if(layers[0].texels.begin(), layers[0].texels.end(), [](float t) { return t < 1.0f; });
  std::printf("rays: %dx%d orthographic along (-0.4,-1,-0.3), %zu texels hit, %d threads, median of %d\n",
              opt.resolution, opt.resolution, hits, opt.threads, opt.reps);
  // The box table is built once per scene, like the peer's grid and intersector: outside the timed traces,
  // and reported apart.
  std::unique_ptr<Tracer> fast = makeCpuTracer({CpuTracePath::Interleaved, opt.threads});
  fast->setScene(scene);
  double cpuSeconds = timeMedian(opt.reps, [&] { fast->traceShadow(views, layers); });
  std::printf("%-28s %9.3f s  %8.2f Mrays/s\n", "cpu reference (per ray)", referenceSeconds,
              rays / referenceSeconds / 1e6);
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (%s; box table built once in %.1f ms)\n", "cpu interleaved tiles",
              cpuSeconds, rays / cpuSeconds / 1e6,
              fast->cpu()->hasBoxTable() ? laneWidthName(widestLaneWidth()) : "no box table: portable tiles",
              fast->cpu()->tableBuildSeconds() * 1e3);
  double vulkanSeconds = 0.0;
  VulkanBench vb;
  if (opt.vulkan) {
    std::vector<ShadowLayer> referenceLayers;
    reference->traceShadow(views, referenceLayers);
    vb = benchVulkan(scene, views, opt.reps, referenceLayers);
    // Steady state from GPU timestamps where the device has them (the dispatch alone), else host time.
    vulkanSeconds = (vb.medianGpuMs > 0.0 ? vb.medianGpuMs : vb.medianWallMs) * 1e-3;
    std::printf("vulkan device: %s; pipeline creation %.1f ms (%s cache), first trace %.1f ms (wall)\n",
                vb.device.c_str(), vb.pipelineMs, vb.warmCache ? "warm" : "cold", vb.firstWallMs);
    std::printf("vulkan upload %.1f ms (box table built in it), instances-only upload %.2f ms\n", vb.uploadMs,
                vb.instanceUploadMs);
    std::printf("%-28s %9.3f s  %8.2f Mrays/s  (GPU timestamps; whole call %.3f s, %.2f Mrays/s)\n",
                "vulkan steady state", vulkanSeconds, rays / vulkanSeconds / 1e6, vb.medianWallMs * 1e-3,
                rays / (vb.medianWallMs * 1e-3) / 1e6);
    std::printf("vulkan texels differing from the cpu reference: %zu\n", vb.differing);
  }
  RayBench primary = primaryRays(opt.resolution);
  std::printf("primary rays: %zu from a %dx%d perspective camera; visibility rays from each primary hit toward the "
              "sun\n", primary.rays.size(), kCameraWidth, kCameraHeight);
  benchRayKinds(primary, *fast, opt.reps, "cpu interleaved");
  if (opt.vulkan) benchRayKinds(primary, *vb.tracer, opt.reps, "vulkan");
  benchLaneWidths(scene, views, rays, primary, *fast, opt);
  if (opt.skipPeer) return;

  OpenVdbPeer peer(objects, scene);
  std::vector<std::vector<float>> peerOut;
  double peerSeconds = timeMedian(opt.reps, [&] { peerOut = peer.traceViews(scene, views, opt.threads); });
  std::size_t peerHits = std::count_if(peerOut[0].begin(), peerOut[0].end(), [](float t) { return t < 1.0f; });
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (%zu texels hit)\n", "openvdb peer (VRI + DDA)", peerSeconds,
              rays / peerSeconds / 1e6, peerHits);
  std::printf("ratio cpu reference / peer:   %.2fx\n", peerSeconds / referenceSeconds);
  std::printf("ratio cpu interleaved / peer: %.2fx\n", peerSeconds / cpuSeconds);
  if (opt.vulkan) std::printf("ratio vulkan / peer:          %.2fx\n", peerSeconds / vulkanSeconds);
  auto peerRun = [&] { return timeOnce([&] { peerOut = peer.traceViews(scene, views, opt.threads); }); };
  printPairedRatio("cpu interleaved", opt.reps, [&] { return timeOnce([&] { fast->traceShadow(views, layers); }); },
                   peerRun);
  if (opt.vulkan) {
    // The steady state as above: the dispatch from GPU timestamps where the device has them.
    printPairedRatio("vulkan", opt.reps, [&] {
      TraceStats t = vb.tracer->traceShadow(views, vb.layers);
      return (t.gpuMs > 0.0 ? t.gpuMs : t.wallMs) * 1e-3;
    }, peerRun);
  }
  // The ray kinds against the peer on the same rays (its visibility search stops at the first hit).
  std::vector<std::uint8_t> peerRayHits;
  auto peerClosest = [&] { return timeOnce([&] { peerRayHits = peer.traceRays(primary.rays, false, opt.threads); }); };
  auto peerVisibility = [&] { return timeOnce([&] { peerRayHits = peer.traceRays(primary.visibility, true, opt.threads); }); };
  peerClosest();
  std::printf("openvdb peer: %zu primary hits", std::size_t(std::count(peerRayHits.begin(), peerRayHits.end(), 1)));
  peerVisibility();
  std::printf(", %zu visibility rays occluded\n", std::size_t(std::count(peerRayHits.begin(), peerRayHits.end(), 1)));
  std::vector<Tracer*> rayTracers = {fast.get()};
  if (opt.vulkan) rayTracers.push_back(vb.tracer.get());
  for (Tracer* t : rayTracers) {
    std::string label = t == fast.get() ? "cpu interleaved" : "vulkan";
    printPairedRatio((label + " primary").c_str(), opt.reps,
                     [&] { return raySeconds(t->traceClosest(primary.rays, primary.hits)); }, peerClosest);
    printPairedRatio((label + " visibility").c_str(), opt.reps,
                     [&] { return raySeconds(t->traceAny(primary.visibility, primary.occluded)); }, peerVisibility);
  }
}

// The lit frame of the demo scene (1280 x 720; a sun in 3 cascades of 2048^2, a spot lamp at 1024^2, a point
// torch at 6 x 512^2) with shadow maps and with ray-traced shadows, on the CPU backend and on Vulkan: the
// median time of each stage over `reps` frames after a warm-up frame, all in this one run.
void runFrameBench(const BenchOptions& opt) {
  checkBenchRange("--threads", opt.threads, 1, kMaxThreads);
  checkBenchRange("--reps", opt.reps, 1, 1000);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("voxshadow-bench-" + std::to_string(::getpid()));
  const std::vector<std::string> written = writeDemoWorld(dir);
  const Scene scene = Scene::load(std::filesystem::path(written.back()));
  std::filesystem::remove_all(dir);
  std::vector<std::pair<std::string, std::unique_ptr<Tracer>>> backends;
  backends.emplace_back("cpu", makeCpuTracer({CpuTracePath::Interleaved, opt.threads}));
  VulkanOptions vulkanOptions;
  vulkanOptions.hostThreads = opt.threads;
  if (opt.vulkan) backends.emplace_back("vulkan", makeVulkanTracer(vulkanOptions));
  std::printf("demo frame 1280x720: sun 3 x 2048^2 cascades, lamp 1024^2, torch 6 x 512^2; %d reps after a warm-up\n",
              opt.reps);
  for (auto& [name, tracer] : backends) {
    tracer->setScene(scene.data());
    FrameRenderer renderer(*tracer);
    for (ShadowSource source : {ShadowSource::Maps, ShadowSource::Raytraced}) {
      RenderOptions options;
      options.shadows = source;
      // Warm-up: pipelines, box table, buffers, and on Vulkan the lighting shader specialised for the frame's
      // lights (VulkanLighting::kCallsBeforeSpecializing shading calls of one shape), which a frame loop runs.
      const int warmUps = name == "vulkan" ? VulkanLighting::kCallsBeforeSpecializing : 1;
      for (int w = 0; w < warmUps; ++w) {
        renderer.invalidateLayers();
        renderer.render(scene, options);
      }
      std::vector<double> shadow, gbuffer, visibility, lighting, total;
      for (int r = 0; r < opt.reps; ++r) {
        renderer.invalidateLayers();  // every frame traces its layers, as when the scene changes each frame
        const RenderTimings t = renderer.render(scene, options).timings;
        shadow.push_back(t.shadowMs);
        gbuffer.push_back(t.gbufferMs);
        visibility.push_back(t.visibilityMs);
        lighting.push_back(t.lightingMs);
        total.push_back(t.shadowMs + t.gbufferMs + t.visibilityMs + t.lightingMs);
      }
      std::printf("%-7s %-9s shadow trace %8.1f ms  G-buffer %7.1f ms  visibility rays %7.1f ms  lighting %7.1f ms  "
                  "frame %8.1f ms  (%s)\n",
                  name.c_str(), source == ShadowSource::Maps ? "maps" : "raytraced", median(shadow), median(gbuffer),
                  median(visibility), median(lighting), median(total), tracer->deviceName().c_str());
    }
    // A frame loop over a static scene and camera: the renderer keeps every layer of the last frame.
    RenderOptions options;
    renderer.render(scene, options);
    std::vector<double> shadow, total;
    int traced = 0;
    for (int r = 0; r < opt.reps; ++r) {
      const RenderedFrame frame = renderer.render(scene, options);
      const RenderTimings& t = frame.timings;
      traced += frame.layersTraced;
      shadow.push_back(t.shadowMs);
      total.push_back(t.shadowMs + t.gbufferMs + t.visibilityMs + t.lightingMs);
    }
    std::printf("%-7s %-9s shadow trace %8.1f ms  (%d layers traced in %d frames; nothing changed)  frame %8.1f ms\n",
                name.c_str(), "maps", median(shadow), traced, opt.reps, median(total));
  }
}

}  // namespace

void registerBench(CLI::App& app) {
  auto options = std::make_shared<BenchOptions>();
  CLI::App* cmd = app.add_subcommand("bench", "Trace city512 with each backend and the OpenVDB peer; print Mrays/s");
  addThreadsOption(cmd, options->threads, "CPU threads for every CPU tracer (default 2)", 1);
  cmd->add_option("--resolution", options->resolution, "view resolution in texels per side (default 1024)");
  cmd->add_option("--reps", options->reps, "timed repetitions after a warm-up; the median is reported (default 5)");
  cmd->add_flag("--no-peer", options->skipPeer, "skip the OpenVDB peer");
  cmd->add_flag("--vulkan", options->vulkan,
                "also trace on the Vulkan backend (default device): steady-state median after warm-up, pipeline "
                "creation and first trace reported apart");
  CLI::Option* frame = cmd->add_flag("--frame", options->frame,
                "instead, time the lit 1280x720 demo frame per stage (shadow maps traced every frame, ray-traced "
                "shadows, and a still frame that keeps its layers; CPU, and Vulkan with --vulkan)");
  // --loop: a scripted game loop (tools/bench_loop.h); --threads and --vulkan are shared with the other benches.
  auto loop = std::make_shared<LoopBenchOptions>();
  auto loopOn = std::make_shared<bool>(false);
  auto size = std::make_shared<std::string>();
  CLI::Option* loopFlag = cmd->add_flag("--loop", *loopOn,
                "instead, run a scripted game loop over the 1280x720 demo (phases still, pan, actor, dig, sun) and "
                "print each phase's frame times beside forced full frames; CPU, and Vulkan with --vulkan");
  loopFlag->excludes(frame);
  CLI::Option* embreeFlag = cmd->add_flag("--embree", options->embree,
                "instead, each backend against the Embree peer (a watertight triangle mesh of the voxels) on the same "
                "shadow texels, primary and visibility rays of city512 and of the demo scene, paired run by run; "
                "prints `vs-embree SCENE KIND BACKEND / QUERY: RATIOx` lines");
  embreeFlag->excludes(frame)->excludes(loopFlag);
  for (const char* other : {"--resolution", "--reps", "--no-peer"}) loopFlag->excludes(cmd->get_option(other));
  cmd->add_option("--frames", loop->frames, "--loop: frames per phase, 1..100000 (default 100)")->needs(loopFlag);
  cmd->add_option("--full-every", loop->fullEvery,
                  "--loop: a forced full frame of the same state after every K-th frame (default 1)")->needs(loopFlag);
  cmd->add_option("--csv", loop->csv, "--loop: write one row per frame to this CSV file")->needs(loopFlag);
  cmd->add_option("--plot", loop->plot,
                  "--loop: draw the frame times into this .png (tools/plot_loop.py; needs python3-matplotlib)")
      ->needs(loopFlag);
  // Smaller frames and shadow layers, for tests.
  cmd->add_option("--size", *size, "--loop: frame size WxH (default 1280x720)")->needs(loopFlag)->group("");
  cmd->add_option("--shadow-divisor", loop->shadowDivisor, "--loop: shadow resolutions divided by this power of two")
      ->needs(loopFlag)->group("");
  cmd->callback([options, loop, loopOn, size] {
    if (*loopOn) {
      LoopBenchOptions o = *loop;
      o.threads = options->threads;
      o.vulkan = options->vulkan;
      if (!size->empty()) {
        int w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(size->c_str(), "%dx%d%c", &w, &h, &tail) != 2)
          throwBadInput("bench --loop: --size " + *size + ": must be WxH, e.g. 320x180");
        o.width = w;
        o.height = h;
      }
      runLoopBench(o);
    } else if (options->frame) {
      runFrameBench(*options);
    } else if (options->embree) {
      checkBenchRange("--threads", options->threads, 1, kMaxThreads);
      checkBenchRange("--resolution", options->resolution, 16, 16384);
      checkBenchRange("--reps", options->reps, 1, 1000);
      runEmbreeBench({options->threads, options->resolution, options->reps, options->vulkan});
    } else {
      runBench(*options);
    }
  });
}

}  // namespace vs::cli
