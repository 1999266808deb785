// cpu_tracer.h: the CPU trace backend: the portable traversal run over SceneData with TBB.
#ifndef VOXSHADOW_CPU_TRACER_H
#define VOXSHADOW_CPU_TRACER_H

#include <memory>
#include <span>
#include <vector>

#include "compute/scene_data.h"

namespace vs {

// One shadow layer: width x height R32F texels, row 0 first.
struct ShadowLayer {
  int width = 0;
  int height = 0;
  std::vector<float> texels;
};

enum class CpuTracePath {
  Reference,    // the portable per-ray traversal, exactly what the shader runs
  // Batches of rays walked in lockstep, equal to Reference ray for ray: eight rays per AVX2 step
  // (compute/cpu/lane_tracer.h) where the processor has AVX2, else round-robin (compute/cpu/tile_tracer.h).
  Interleaved,
  // The round-robin tiles whatever the processor: what Interleaved runs where AVX2 is missing.
  PortableTiles,
};

struct LaneTables;

// The CPU backend bound to one scene: shadow texels, closest-hit and any-hit rays. The fast path's lookup tables (dense per-object codes of every sector
// and brick, and the empty boxes around empty bricks; compute/cpu/lane_tracer.h) are derived from the voxel
// arrays once and kept between traces, so a frame in which no voxel changed rebuilds nothing; moving
// instances changes no table.
class CpuTracer {
 public:
  // Precondition: `scene` outlives the tracer.
  explicit CpuTracer(const SceneData& scene);
  ~CpuTracer();
  CpuTracer(const CpuTracer&) = delete;
  CpuTracer& operator=(const CpuTracer&) = delete;

  // Must be called after the scene's voxel arrays changed (edits, compaction, objects added); the tables are
  // rebuilt on the next trace.
  void voxelsChanged();

  // Traces every view's texel rectangle into layers[i] (resized to the view's size when it differs; texels
  // outside the rectangle keep their values). Preconditions: views[i].info.xy > 0, rect inside the view (else
  // vs::Error(BadInput)). threads <= 0 uses every hardware thread.
  void trace(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers,
             CpuTracePath path = CpuTracePath::Interleaved, int threads = 0);

  // Closest-hit records of rays[i] into hits[i] (same length, else vs::Error(BadInput)): instance, object
  // voxel, entry face, t and palette index (compute/shared/trace_rays.h).
  void traceClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits,
                    CpuTracePath path = CpuTracePath::Interleaved, int threads = 0);
  // Any-hit answers: occluded[i] = 1 where rays[i]'s segment [tMin, tMax] holds a solid voxel, else 0.
  void traceAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded,
                CpuTracePath path = CpuTracePath::Interleaved, int threads = 0);

  // Seconds the last table build took (0 before the first fast-path trace).
  double tableBuildSeconds() const { return tableSeconds_; }

 private:
  void ensureTables();

  const SceneData* scene_;
  std::unique_ptr<LaneTables> tables_;
  bool tablesBuilt_ = false;
  bool lanes_ = false;
  double tableSeconds_ = 0.0;
};

// One trace with a CpuTracer made for the call (the tables are built each time).
void traceCpu(const SceneData& scene, std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers,
              CpuTracePath path = CpuTracePath::Interleaved, int threads = 0);

// Traces a single ray through the scene with the reference traversal (for tests and tools).
bool traceRayCpu(const SceneData& scene, glm::vec3 origin, glm::vec3 direction, float tMin, float tMax,
                 float& tHit, std::uint32_t& instance, glm::ivec3& voxel);

// The texel value of one view texel with the reference traversal.
float shadowTexelCpu(const SceneData& scene, const gpu::TraceView& view, glm::ivec2 texel);

}  // namespace vs

#endif
