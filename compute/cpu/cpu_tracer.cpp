#include "compute/cpu/cpu_tracer.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include <tbb/blocked_range2d.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "compute/box_table.h"
#include "compute/cpu/lane_tracer.h"
#include "compute/cpu/scene_arrays.h"
#include "compute/cpu/ray_sources.h"
#include "compute/cpu/tile_tracer.h"
#include "compute/tracer.h"
#include "voxel/error.h"

namespace vs {
namespace {

// Work is split into tiles of this many texels: big enough to
// amortise scheduling, small enough that threads stay balanced on views whose hits cluster in one corner.
constexpr int kTileWidth = 16;
constexpr int kTileHeight = 4;


void checkView(const gpu::TraceView& view, std::size_t index) {
  const glm::ivec4& r = view.rect;
  if (view.info.x <= 0 || view.info.y <= 0 || r.x < 0 || r.y < 0 || r.z > view.info.x || r.w > view.info.y ||
      r.x > r.z || r.y > r.w) {
    throwBadInput("trace view " + std::to_string(index) + ": rectangle outside the view");
  }
}

}  // namespace

CpuTracer::CpuTracer(const SceneData& scene) : scene_(&scene) {}

CpuTracer::~CpuTracer() = default;

void CpuTracer::voxelsChanged() {
  tablesBuilt_ = false;
  pending_ = SceneDelta{};
}

void CpuTracer::sceneChanged(const SceneDelta& delta) {
  if (tablesBuilt_ && (!delta.editedBricks.empty() || delta.voxelLayout || !delta.ranges.empty()))
    pending_.merge(delta);
}

void traceCpu(const SceneData& scene, std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers,
              CpuTracePath path, int threads) {
  CpuTracer(scene).trace(views, layers, path, threads);
}

void CpuTracer::ensureTables() {
  // Built (or updated) on the first trace after a voxel change, inside the caller's thread count.
  if (tablesBuilt_ && pending_.empty()) return;
  auto start = std::chrono::steady_clock::now();
  if (tablesBuilt_) {
    tableLocal_ = !updateBoxTable(boxTable_, *scene_, pending_).rebuilt;
  } else {
    boxTable_ = buildBoxTable(*scene_);
    tableLocal_ = false;
  }
  pending_ = SceneDelta{};
  tablesBuilt_ = true;
  tableSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

bool CpuTracer::hasBoxTable() {
  ensureTables();
  return !boxTable_.empty();
}

namespace {

// How a path walks: the lanes it runs (none: no lanes), and whether its walks read the box table.
struct PathPlan {
  bool lanes = false;
  LaneWidth width = LaneWidth::Scalar;
  bool boxTable = false;
};

PathPlan planFor(CpuTracePath path, bool hasBoxTable) {
  PathPlan plan;
  auto lanesOf = [&](LaneWidth width) {
    if (!hasBoxTable) throwBadInput("the lane tracer needs a box table, and this scene has none (too large)");
    if (!laneWidthSupported(width))
      throwBadInput(std::string("this processor does not run the ") + laneWidthName(width) + " lane tracer");
    plan.lanes = true;
    plan.width = width;
    plan.boxTable = true;
  };
  switch (path) {
    case CpuTracePath::Reference:
      plan.boxTable = hasBoxTable;
      break;
    case CpuTracePath::Interleaved:
      if (hasBoxTable) lanesOf(widestLaneWidth());
      break;
    case CpuTracePath::PortableTiles:
      break;
    case CpuTracePath::LanesScalar:
      lanesOf(LaneWidth::Scalar);
      break;
    case CpuTracePath::LanesAvx2:
      lanesOf(LaneWidth::Avx2);
      break;
    case CpuTracePath::LanesAvx512:
      lanesOf(LaneWidth::Avx512);
      break;
  }
  return plan;
}

// One arena per thread count for the whole process, made on first use and kept: an arena made and destroyed
// per call (every trace of a frame loop) left oneTBB's bookkeeping behind when the machine was loaded, about
// 4 KiB a frame of resident memory outside the heap (FrameLoop.SoakKeepsMemoryFlat under ctest -j2). Several
// threads may execute in one arena at once; its concurrency stays `threads`. The map is never destroyed, so a
// trace running while the process exits (a static destructor, a thread not joined) never meets a dead arena.
tbb::task_arena& arenaFor(int threads) {
  static std::mutex lock;
  static auto* arenas = new std::map<int, std::unique_ptr<tbb::task_arena>>;
  std::lock_guard<std::mutex> guard(lock);
  std::unique_ptr<tbb::task_arena>& arena = (*arenas)[threads];
  if (!arena) arena = std::make_unique<tbb::task_arena>(threads);
  return *arena;
}

template <class Run>
void inArena(int threads, Run&& run) {
  if (threads > 0) {
    arenaFor(threads).execute(run);
  } else {
    run();
  }
}

}  // namespace

void inHostArena(int threads, const std::function<void()>& run) { inArena(threads, run); }

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
  inArena(threads, [&] {
    ensureTables();
    const PathPlan plan = planFor(path, !boxTable_.empty());
    if (plan.boxTable) arrays.boxTable = boxTable_.data();
    const bool lanes = plan.lanes;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, jobs.size()), [&](const tbb::blocked_range<std::size_t>& r) {
      // One stream over the whole range, so that lanes freed by short rays pick up the next tile's texels.
      std::span<const TexelTile> range = std::span<const TexelTile>(jobs).subspan(r.begin(), r.size());
      if (lanes) {
        traceTilesLanes(plan.width, arrays, views, range, layers);
        return;
      }
      if (path != CpuTracePath::Reference) {
        rays::TexelSource source(views, range, layers);
        traceInterleaved(arrays, source);
        return;
      }
      for (const TexelTile& job : range) {
        const gpu::TraceView& view = views[job.view];
        ShadowLayer& layer = layers[job.view];
        for (int y = job.y0; y < job.y1; ++y)
          for (int x = job.x0; x < job.x1; ++x)
            layer.texels[std::size_t(y) * layer.width + x] = arrays.vsShadowTexel(view, glm::ivec2(x, y));
      }
    });
  });
}

// Rays are handed out in chunks of this many: a chunk is one lane stream, long enough that lanes stay full.
constexpr std::size_t kRayChunk = 1024;

// Every ray of one kind on the chosen path, in chunks over the threads: lanes (`laneTrace(first, count)`),
// portable tiles (`source`), or one at a time through the reference (`reference(i)`).
template <class Source, class Lanes, class Reference>
void traceRayKind(gpu::SceneArrays& arrays, std::size_t count, CpuTracePath path, const PathPlan& plan,
                  Source source, Lanes&& laneTrace, Reference&& reference) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, kRayChunk), [&](const auto& r) {
    if (plan.lanes) {
      laneTrace(r.begin(), r.size());
    } else if (path != CpuTracePath::Reference) {
      Source chunk = source;
      chunk.cursor = r.begin();
      chunk.end = r.end();
      traceInterleaved(arrays, chunk);
    } else {
      for (std::size_t i = r.begin(); i != r.end(); ++i) reference(i);
    }
  });
}

void checkOutputLength(const char* call, std::size_t outputs, std::size_t rays) {
  if (outputs != rays)
    throwBadInput(std::string(call) + ": " + std::to_string(outputs) + " results for " + std::to_string(rays) + " rays");
}

void CpuTracer::traceClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits, CpuTracePath path,
                             int threads) {
  checkOutputLength("traceClosest", hits.size(), rays.size());
  gpu::SceneArrays arrays(*scene_);
  rays::ClosestSource source;
  source.rays = rays;
  source.hits = hits.data();
  inArena(threads, [&] {
    ensureTables();
    const PathPlan plan = planFor(path, !boxTable_.empty());
    if (plan.boxTable) arrays.boxTable = boxTable_.data();
    traceRayKind(
        arrays, rays.size(), path, plan, source,
        [&](std::size_t first, std::size_t n) {
          traceClosestLanes(plan.width, arrays, rays.subspan(first, n), hits.subspan(first, n));
        },
        [&](std::size_t i) { hits[i] = arrays.vsClosestHit(arrays.vsTraceRayToWorld(rays[i])); });
  });
}

void CpuTracer::traceAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded, CpuTracePath path,
                         int threads) {
  checkOutputLength("traceAny", occluded.size(), rays.size());
  gpu::SceneArrays arrays(*scene_);
  rays::AnySource source;
  source.rays = rays;
  source.occluded = occluded.data();
  inArena(threads, [&] {
    ensureTables();
    const PathPlan plan = planFor(path, !boxTable_.empty());
    if (plan.boxTable) arrays.boxTable = boxTable_.data();
    traceRayKind(
        arrays, rays.size(), path, plan, source,
        [&](std::size_t first, std::size_t n) {
          traceAnyLanes(plan.width, arrays, rays.subspan(first, n), occluded.subspan(first, n));
        },
        [&](std::size_t i) { occluded[i] = arrays.vsAnyHit(arrays.vsTraceRayToWorld(rays[i])) ? 1u : 0u; });
  });
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
