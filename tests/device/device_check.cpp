// device_check: the shader against the CPU fast path on city512 (DESIGN.md §10), texel by texel, and their
// speeds, in a program that needs nothing but the Vulkan loader, TBB and the C++ runtime. It is how the Vulkan
// path is checked on a GPU machine that has no Debian packages (BENCHMARKS.md, "On a real GPU"): the program
// and its few libraries are all that must travel there. ctest runs it small on lavapipe.
//
// Usage: device_check [RESOLUTION [REPS [THREADS]]]   (defaults 1024, 5, 2)
// Prints the device, then per view the texels, hits, texels not bit-identical and the median Mrays/s of each
// side; exits 1 when any texel differs or no texel hits, 2 on bad arguments.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "compute/cpu/cpu_tracer.h"
#include "compute/scene_data.h"
#include "compute/shared/trace_view.h"
#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "voxel/city512.h"

namespace {

struct NamedView {
  const char* name;
  vs::gpu::TraceView view;
};

// An orthographic view along `direction` over the whole city, and a spot light's perspective view from above
// one corner: the two kinds of texel ray (parallel, one origin).
std::vector<NamedView> cityViews(int res) {
  const glm::vec3 center(256.0f);
  const float radius = 256.0f * 1.7321f + 1.0f;
  const glm::vec3 d = glm::normalize(glm::vec3(-0.4f, -1.0f, -0.3f));
  const glm::mat4 sunView = glm::lookAtRH(center - d * radius * 2.0f, center, glm::vec3(0, 1, 0));
  const glm::mat4 sunProj = glm::orthoRH_ZO(-radius, radius, -radius, radius, radius * 0.5f, radius * 3.5f);
  const glm::vec3 lamp(40.0f, 300.0f, 40.0f);
  const float range = 900.0f;
  const glm::mat4 spotView = glm::lookAtRH(lamp, center, glm::vec3(0, 1, 0));
  const glm::mat4 spotProj = glm::perspectiveRH_ZO(glm::radians(70.0f), 1.0f, range * 1e-3f, range);
  return {
      {"sun", vs::gpu::makeTraceView(glm::dmat4(sunProj * sunView), res, res, vs::gpu::VS_ENCODING_NDC_DEPTH,
                                     vs::gpu::VS_DEPTH_POINT_ENTRY)},
      {"spot", vs::gpu::makeTraceView(glm::dmat4(spotProj * spotView), res, res, vs::gpu::VS_ENCODING_LINEAR_DISTANCE,
                                      vs::gpu::VS_DEPTH_POINT_ENTRY, glm::vec4(lamp, range))},
  };
}

template <class Run>
double medianMs(int reps, Run&& run) {
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) ms.push_back(run());
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

double wallMs(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

int parse(const char* text, int lo, int hi, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < lo || v > hi) {
    std::fprintf(stderr, "device_check: %s must be a whole number from %d to %d (got '%s')\n", what, lo, hi, text);
    std::exit(2);
  }
  return int(v);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 4) {
    std::fprintf(stderr, "usage: device_check [RESOLUTION [REPS [THREADS]]]\n");
    return 2;
  }
  const int res = argc > 1 ? parse(argv[1], 16, 8192, "RESOLUTION") : 1024;
  const int reps = argc > 2 ? parse(argv[2], 1, 100, "REPS") : 5;
  const int threads = argc > 3 ? parse(argv[3], 1, 1024, "THREADS") : 2;
  try {
    const vs::Brickmap city = vs::Brickmap::build(vs::city512Voxels());
    const vs::Brickmap* objects[] = {&city};
    const vs::SceneInstance instances[] = {{0u, glm::dmat4(1.0)}};
    auto scene = std::make_shared<const vs::SceneData>(vs::SceneData::build(objects, instances));
    std::unique_ptr<vs::Tracer> gpu = vs::makeVulkanTracer();
    std::unique_ptr<vs::Tracer> cpu = vs::makeCpuTracer({vs::CpuTracePath::Interleaved, threads});
    gpu->setScene(scene);
    cpu->setScene(scene);
    std::printf("device: %s; cpu: %s; city512 %dx%d, median of %d\n", gpu->deviceName().c_str(),
                cpu->deviceName().c_str(), res, res, reps);
    bool ok = true;
    for (const NamedView& nv : cityViews(res)) {
      std::vector<vs::ShadowLayer> gpuLayers, cpuLayers;
      const vs::gpu::TraceView views[] = {nv.view};
      gpu->traceShadow(views, gpuLayers);  // warm-up: pipeline and buffers
      const double gpuMs = medianMs(reps, [&] {
        const vs::TraceStats s = gpu->traceShadow(views, gpuLayers);
        return s.gpuMs >= 0.0 ? s.gpuMs : s.wallMs;
      });
      cpu->traceShadow(views, cpuLayers);
      const double cpuMs = medianMs(reps, [&] {
        const auto t0 = std::chrono::steady_clock::now();
        cpu->traceShadow(views, cpuLayers);
        return wallMs(t0);
      });
      const std::vector<float>& g = gpuLayers.at(0).texels;
      const std::vector<float>& c = cpuLayers.at(0).texels;
      const float miss = nv.view.info.z == vs::gpu::VS_ENCODING_NDC_DEPTH ? 1.0f : nv.view.eyeHigh.w;
      // Texels that differ: whether one side hit and the other missed, and by how many float steps and world
      // units the depths of two hits differ.
      std::size_t differ = 0, hits = 0, hitMiss = 0, withinFourSteps = 0;
      double maxDelta = 0.0;
      std::int64_t maxSteps = 0;
      for (std::size_t i = 0; i < c.size(); ++i) {
        if (c[i] != miss) ++hits;
        if (std::memcmp(&g[i], &c[i], sizeof(float)) == 0) continue;
        ++differ;
        if ((g[i] == miss) != (c[i] == miss)) {
          ++hitMiss;
          continue;
        }
        std::int32_t gi = 0, ci = 0;
        std::memcpy(&gi, &g[i], sizeof gi);
        std::memcpy(&ci, &c[i], sizeof ci);
        const std::int64_t steps = std::llabs(std::int64_t(gi) - std::int64_t(ci));
        maxSteps = std::max(maxSteps, steps);
        if (steps <= 4) ++withinFourSteps;
        maxDelta = std::max(maxDelta, std::abs(double(g[i]) - double(c[i])));
      }
      if (differ)
        std::printf("%s: of %zu differing texels, %zu hit on one side only, %zu within 4 float steps; largest "
                    "difference %lld steps, %.3g in the texel's unit\n",
                    nv.name, differ, hitMiss, withinFourSteps, static_cast<long long>(maxSteps), maxDelta);
      const double texels = double(c.size());
      std::printf("%s: %zu texels, %zu hits, %zu not bit-identical; gpu %.2f ms (%.1f Mrays/s), cpu %.2f ms "
                  "(%.1f Mrays/s), gpu/cpu %.2fx\n",
                  nv.name, c.size(), hits, differ, gpuMs, texels / gpuMs * 1e-3, cpuMs, texels / cpuMs * 1e-3,
                  cpuMs / gpuMs);
      ok = ok && differ == 0 && hits > 0 && g.size() == c.size();
    }
    if (const vs::VulkanTracer* v = gpu->vulkan(); v && !v->validationMessages().empty()) {
      std::printf("validation: %zu messages, first: %s\n", v->validationMessages().size(),
                  v->validationMessages().front().c_str());
      ok = false;
    }
    std::printf("%s\n", ok ? "device_check: every texel bit-identical" : "device_check: FAILED");
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "device_check: %s\n", e.what());
    return 1;
  }
}
