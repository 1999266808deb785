// voxshadow bench: the CPU backend (and the Vulkan backend when asked) against the OpenVDB peer on city512,
// same rays, same thread count, in one run (DESIGN.md §10).
#include <algorithm>
#include <chrono>
#include <cstring>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "compute/cpu/cpu_tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "tools/commands.h"
#include "tools/resources.h"
#include "tools/peer/openvdb_peer.h"
#include "voxel/city512.h"
#include "voxel/error.h"

namespace vs::cli {
namespace {

struct BenchOptions {
  int threads = 2;
  int resolution = 1024;
  int reps = 5;
  bool skipPeer = false;
  bool vulkan = false;
};

// The calibration window of DESIGN.md §10: an orthographic view along d over the projection of [0,512]^3.
gpu::TraceView calibrationView(int res) {
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
  std::unique_ptr<VulkanTracer> tracer;  // kept for the paired runs
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
  b.tracer = std::make_unique<VulkanTracer>();
  VulkanTracer& tracer = *b.tracer;
  b.device = tracer.device().name;
  b.pipelineMs = tracer.pipelineStats().createMs;
  b.warmCache = tracer.pipelineStats().warmCache;
  b.uploadMs = timeOnce([&] { tracer.upload(scene); }) * 1e3;
  b.instanceUploadMs = timeOnce([&] { tracer.uploadInstances(scene); }) * 1e3;
  std::vector<ShadowLayer>& layers = b.layers;
  b.firstWallMs = tracer.trace(views, layers).wallMs;
  tracer.trace(views, layers);
  std::vector<double> gpu, wall;
  for (int i = 0; i < reps; ++i) {
    TraceStats t = tracer.trace(views, layers);
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

void runBench(const BenchOptions& opt) {
  if (opt.threads < 1 || opt.resolution < 16 || opt.resolution > 16384 || opt.reps < 1) {
    throwBadInput("bench: --threads >= 1, --resolution in 16..16384 and --reps >= 1 required");
  }
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

  gpu::TraceView view = calibrationView(opt.resolution);
  std::vector<gpu::TraceView> views = {view};
  const double rays = double(opt.resolution) * opt.resolution;

  std::vector<ShadowLayer> layers;
  double referenceSeconds =
      timeMedian(opt.reps, [&] { traceCpu(scene, views, layers, CpuTracePath::Reference, opt.threads); });
  std::size_t hits = std::count_if(layers[0].texels.begin(), layers[0].texels.end(), [](float t) { return t < 1.0f; });
  std::printf("rays: %dx%d orthographic along (-0.4,-1,-0.3), %zu texels hit, %d threads, median of %d\n",
              opt.resolution, opt.resolution, hits, opt.threads, opt.reps);
  // The fast path's lookup tables are built once per scene, like the peer's grid and intersector: outside
  // the timed traces, and reported apart.
  CpuTracer tracer(scene);
  double cpuSeconds =
      timeMedian(opt.reps, [&] { tracer.trace(views, layers, CpuTracePath::Interleaved, opt.threads); });
  std::printf("%-28s %9.3f s  %8.2f Mrays/s\n", "cpu reference (per ray)", referenceSeconds,
              rays / referenceSeconds / 1e6);
  std::printf("%-28s %9.3f s  %8.2f Mrays/s  (lookup tables built once in %.1f ms)\n", "cpu interleaved tiles",
              cpuSeconds, rays / cpuSeconds / 1e6, tracer.tableBuildSeconds() * 1e3);
  double vulkanSeconds = 0.0;
  VulkanBench vb;
  if (opt.vulkan) {
    std::vector<ShadowLayer> reference;
    traceCpu(scene, views, reference, CpuTracePath::Reference, opt.threads);
    vb = benchVulkan(scene, views, opt.reps, reference);
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
  printPairedRatio("cpu interleaved", opt.reps,
                   [&] { return timeOnce([&] { tracer.trace(views, layers, CpuTracePath::Interleaved, opt.threads); }); },
                   peerRun);
  if (opt.vulkan) {
    // The steady state as above: the dispatch from GPU timestamps where the device has them.
    printPairedRatio("vulkan", opt.reps, [&] {
      TraceStats t = vb.tracer->trace(views, vb.layers);
      return (t.gpuMs > 0.0 ? t.gpuMs : t.wallMs) * 1e-3;
    }, peerRun);
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
  cmd->callback([options] { runBench(*options); });
}

}  // namespace vs::cli
