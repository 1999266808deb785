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
  // The portable per-ray traversal, exactly what the shader runs: the walk over the scene's box table
  // (compute/box_table.h) where the scene has one, else the brickmap hierarchy.
  Reference,
  // The fast path (compute/cpu/lane_tracer.h): the box-table walk of the widest SIMD lanes this processor
  // runs (AVX-512, AVX2, else one scalar lane), equal to Reference ray for ray; the portable tiles where the
  // scene has no box table.
  Interleaved,
  // Round-robin tiles over the brickmap hierarchy walk (compute/cpu/tile_tracer.h), whatever the processor:
  // the walk that does not read the box table, kept as a check on it.
  PortableTiles,
  // The fast path with the lanes named (vs::Error(BadInput) where the processor or the scene cannot run it).
  LanesScalar,
  LanesAvx2,
  LanesAvx512,
};

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

  // Seconds the last table build took (0 before the first trace).
  double tableBuildSeconds() const { return tableSeconds_; }
  // Whether the scene has a box table (built on the first trace); without one every path walks the hierarchy.
  bool hasBoxTable();

 private:
  void ensureTables();

  const SceneData* scene_;
  std::vector<std::int32_t> boxTable_;
  bool tablesBuilt_ = false;
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
