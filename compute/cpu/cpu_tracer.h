// cpu_tracer.h: the CPU trace backend: the portable traversal run over SceneData with TBB.
#ifndef VOXSHADOW_CPU_TRACER_H
#define VOXSHADOW_CPU_TRACER_H

#include <memory>
#include <span>
#include <vector>

#include "compute/scene_data.h"
#include "compute/trace_types.h"

namespace vs {

class CpuTracer {
 public:
  // Precondition: `scene` outlives the tracer.
  explicit CpuTracer(const SceneData& scene);
  ~CpuTracer();
  CpuTracer(const CpuTracer&) = delete;
  CpuTracer& operator=(const CpuTracer&) = delete;

  // Everything changed (the scene was replaced or rebuilt in place): the tables are rebuilt whole on the next
  // trace.
  void voxelsChanged();
  // Must be called after each change to the scene (SceneData::updateObject, addObject, instance changes) with
  // what it reported; several deltas may be given one after the other, or merged. The box table is updated on
  // the next trace, around the delta's edited bricks only (updateBoxTable), or built anew where the delta
  // laid the voxel arrays out again. Instance changes need nothing: the tracer reads the scene in place.
  void sceneChanged(const SceneDelta& delta);

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

  // Seconds the last table build or update took (0 before the first trace).
  double tableBuildSeconds() const { return tableSeconds_; }
  // Whether the last table change was a local update (false: a whole build, or none yet).
  bool tableUpdatedLocally() const { return tableLocal_; }
  // Whether the scene has a box table (built on the first trace); without one every path walks the hierarchy.
  bool hasBoxTable();

 private:
  void ensureTables();

  const SceneData* scene_;
  std::vector<std::int32_t> boxTable_;
  bool tablesBuilt_ = false;
  SceneDelta pending_;  // changes since the table was last brought up to date
  bool tableLocal_ = false;
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
