// Uses the installed library as an application would: writes the demo world, loads its scene, traces a band
// of rows across the middle of every shadow view on the CPU reference path and with the Vulkan compute shader
// (the SPIR-V embedded in libvoxshadow_compute.a), and expects hits, misses and the same texels bit for bit.
// Usage: consumer WORK_DIR
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/scene.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer WORK_DIR\n");
    return 2;
  }
  try {
    const std::filesystem::path dir = argv[1];
    std::vector<std::string> files = vs::writeDemoWorld(dir / "demo");
    vs::Scene scene = vs::Scene::load(files.back());
    std::vector<vs::LightView> lightViews = scene.lightViews();
    std::vector<vs::gpu::TraceView> views;
    for (const vs::LightView& v : lightViews) {
      vs::gpu::TraceView view = v.trace;
      const int height = view.rect.w - view.rect.y, band = std::min(height, 32);
      view.rect.y += (height - band) / 2;
      view.rect.w = view.rect.y + band;
      views.push_back(view);
    }
    if (views.empty()) {
      std::fprintf(stderr, "consumer: the demo scene has no shadow views\n");
      return 1;
    }

    std::vector<vs::ShadowLayer> cpu;
    vs::traceCpu(scene.data(), views, cpu, vs::CpuTracePath::Reference, 0);
    // Every texel of view i's rectangle, as an index into its layer.
    auto forEachTexel = [&](std::size_t i, auto&& f) {
      const vs::gpu::TraceView& v = views[i];
      for (int y = v.rect.y; y < v.rect.w; ++y)
        for (int x = v.rect.x; x < v.rect.z; ++x) f(std::size_t(y) * std::size_t(v.info.x) + std::size_t(x));
    };
    std::size_t texels = 0, hits = 0;
    for (std::size_t i = 0; i < cpu.size(); ++i)
      forEachTexel(i, [&](std::size_t k) {
        ++texels;
        if (cpu[i].texels[k] < lightViews[i].range) ++hits;
      });
    std::printf("consumer: %zu views, %zu texels, %zu hits on the CPU\n", views.size(), texels, hits);
    if (hits == 0 || hits == texels) {
      std::fprintf(stderr, "consumer: expected both hits and misses\n");
      return 1;
    }

    vs::VulkanOptions options;
    options.cacheDir = dir / "pipeline-cache";
    vs::VulkanTracer tracer(options);
    tracer.upload(scene.data());
    std::vector<vs::ShadowLayer> gpu;
    tracer.trace(views, gpu);
    std::size_t different = 0;
    for (std::size_t i = 0; i < cpu.size(); ++i) {
      if (gpu.size() != cpu.size() || gpu[i].texels.size() != cpu[i].texels.size()) {
        std::fprintf(stderr, "consumer: the Vulkan layers differ in size from the CPU layers\n");
        return 1;
      }
      forEachTexel(i, [&](std::size_t k) {
        if (std::memcmp(&cpu[i].texels[k], &gpu[i].texels[k], sizeof(float)) != 0) ++different;
      });
    }
    std::printf("consumer: %zu of them differ between the CPU and Vulkan\n", different);
    return different == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
}
