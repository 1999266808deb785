// cpu_tracer.h: the CPU trace backend: the portable traversal run over SceneData with TBB.
#ifndef VOXSHADOW_CPU_TRACER_H
#define VOXSHADOW_CPU_TRACER_H

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
  // Tiles of rays walked in lockstep, equal to Reference texel for texel: eight rays per AVX2 step
  // (compute/cpu/lane_tracer.h) where the processor has AVX2, else round-robin (compute/cpu/tile_tracer.h).
  Interleaved,
};

// Traces every view's texel rectangle into layers[i] (resized to the view's size when it differs; texels
// outside the rectangle keep their values). Preconditions: views[i].info.xy > 0, rect inside the view.
// threads <= 0 uses every hardware thread.
void traceCpu(const SceneData& scene, std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers,
              CpuTracePath path = CpuTracePath::Interleaved, int threads = 0);

// Traces a single ray through the scene with the reference traversal (for tests and tools).
bool traceRayCpu(const SceneData& scene, glm::vec3 origin, glm::vec3 direction, float tMin, float tMax,
                 float& tHit, std::uint32_t& instance, glm::ivec3& voxel);

// The texel value of one view texel with the reference traversal.
float shadowTexelCpu(const SceneData& scene, const gpu::TraceView& view, glm::ivec2 texel);

}  // namespace vs

#endif
