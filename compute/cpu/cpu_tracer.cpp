#include "compute/cpu/cpu_tracer.h"

#include <algorithm>
#include <chrono>
#include <string>

#include <tbb/blocked_range2d.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "compute/cpu/lane_tracer.h"
#include "compute/cpu/scene_arrays.h"
#include "compute/cpu/tile_tracer.h"
#include "voxel/error.h"

namespace vs {
namespace {

// Work is split into tiles of this many texels (one interleaved batch, kMaxTileRays): big enough to
// amortise scheduling, small enough that threads stay balanced on views whose hits cluster in one corner.
constexpr int kTileWidth = 16;
constexpr int kTileHeight = 4;
static_assert(kTileWidth * kTileHeight <= kMaxTileRays, "a tile is one interleaved batch");

void checkView(const gpu::TraceView& view, std::size_t index) {
  const glm::ivec4& r = view.rect;
  if (view.info.x <= 0 || view.info.y <= 0 || r.x < 0 || r.y < 0 || r.z > view.info.x || r.w > view.info.y ||
      r.x > r.z || r.y > r.w) {
    throwBadInput("trace view " + std::to_string(index) + ": rectangle outside the view");
  }
}

}  // namespace

CpuTracer::CpuTracer(const SceneData& scene) : scene_(&scene), tables_(std::make_unique<LaneTables>()) {}

CpuTracer::~CpuTracer() = default;

void CpuTracer::voxelsChanged() { tablesBuilt_ = false; }

void traceCpu(const SceneData& scene, std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers,
              CpuTracePath path, int threads) {
  CpuTracer(scene).trace(views, layers, path, threads);
}

void CpuTracer::trace(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers, CpuTracePath path,
                      int threads) {
  const SceneData& scene = *scene_;
  layers.resize(views.size());
  std::vector<TexelTile> jobs;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const gpu::TraceView& view = views[i];
    checkView(view, i);
    ShadowLayer& layer = layers[i];
    if (layer.width != view.info.x || layer.height != view.info.y) {
      layer.width = view.info.x;
      layer.height = view.info.y;
      layer.texels.assign(std::size_t(layer.width) * layer.height, 0.0f);
    }
    for (int y = view.rect.y; y < view.rect.w; y += kTileHeight)
      for (int x = view.rect.x; x < view.rect.z; x += kTileWidth)
        jobs.push_back({int(i), x, y, std::min(x + kTileWidth, view.rect.z), std::min(y + kTileHeight, view.rect.w)});
  }

  gpu::SceneArrays arrays(scene);
  const LaneTables& laneTables = *tables_;
  auto run = [&] {
    // Built here, inside the caller's thread count, on the first fast-path trace after a voxel change.
    if (path == CpuTracePath::Interleaved && !tablesBuilt_) {
      auto start = std::chrono::steady_clock::now();
      lanes_ = laneTracerSupported(scene) && buildLaneTables(scene, *tables_);
      tablesBuilt_ = true;
      tableSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    const bool lanes = path == CpuTracePath::Interleaved && lanes_;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, jobs.size()), [&](const tbb::blocked_range<std::size_t>& r) {
      if (lanes) {
        // One stream over the whole range, so that lanes freed by short rays pick up the next tile's texels.
        traceTilesLanes(arrays, laneTables, views, std::span<const TexelTile>(jobs).subspan(r.begin(), r.size()), layers);
        return;
      }
      for (std::size_t j = r.begin(); j != r.end(); ++j) {
        const TexelTile& job = jobs[j];
        const gpu::TraceView& view = views[job.view];
        ShadowLayer& layer = layers[job.view];
        if (path == CpuTracePath::Interleaved) {
          traceTileInterleaved(arrays, view, job.x0, job.y0, job.x1, job.y1, layer.texels.data(), layer.width);
          continue;
        }
        for (int y = job.y0; y < job.y1; ++y)
          for (int x = job.x0; x < job.x1; ++x)
            layer.texels[std::size_t(y) * layer.width + x] = arrays.vsShadowTexel(view, glm::ivec2(x, y));
      }
    });
  };
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(run);
  } else {
    run();
  }
}

bool traceRayCpu(const SceneData& scene, glm::vec3 origin, glm::vec3 direction, float tMin, float tMax, float& tHit,
                 std::uint32_t& instance, glm::ivec3& voxel) {
  gpu::SceneArrays arrays(scene);
  return arrays.vsRayIsFinite(arrays.vsWorldRay(origin, direction, tMin, tMax)) &&
         arrays.vsTraceClosest(arrays.vsWorldRay(origin, direction, tMin, tMax), tHit, instance, voxel);
}

float shadowTexelCpu(const SceneData& scene, const gpu::TraceView& view, glm::ivec2 texel) {
  gpu::SceneArrays arrays(scene);
  return arrays.vsShadowTexel(view, texel);
}

}  // namespace vs
