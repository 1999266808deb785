// tracer.h: the one interface of both trace backends (the CPU tracer and the Vulkan shader), for every ray kind:
// shadow texels of light views, closest-hit rays and any-hit rays (compute/shared/trace_rays.h). The bake, the
// benchmark and the tests drive a backend through it alike; both give the same results bit for bit.
#ifndef VOXSHADOW_TRACER_H
#define VOXSHADOW_TRACER_H

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "compute/scene_data.h"
#include "compute/vulkan/vulkan_tracer.h"

namespace vs {

class Tracer {
 public:
  virtual ~Tracer() = default;

  // "cpu" or "vulkan".
  virtual std::string backend() const = 0;
  // What runs the rays: the Vulkan device's name, or "CPU, N threads".
  virtual std::string deviceName() const = 0;

  // Binds the scene, after it was built or any voxel changed (edits, objects added). The CPU backend reads
  // `scene` in place and keeps a pointer to it: it must outlive the tracer or the next setScene. The Vulkan
  // backend copies it to the device. Throws vs::Error(Runtime) when it does not fit the device.
  void setScene(const SceneData& scene) {
    ++sceneVersion_;
    bindScene(scene);
  }
  // The per-frame update when only instances moved (SceneData::moveInstance): no voxel data is copied again.
  // Precondition: setScene was called with this scene and no voxel changed since.
  void instancesMoved(const SceneData& scene) {
    ++sceneVersion_;
    bindMovedInstances(scene);
  }
  // Counts the scene updates bound so far (setScene and instancesMoved calls). Whatever was traced at one
  // version stays exact while the version holds, so a frame loop keeps the shadow layers whose view did not
  // change (FrameRenderer) instead of tracing them again.
  std::uint64_t sceneVersion() const { return sceneVersion_; }

  // The three ray kinds. Preconditions: setScene was called; views as in CpuTracer::trace; the outputs are as
  // long as `rays` (else vs::Error(BadInput)).
  virtual TraceStats traceShadow(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers) = 0;
  virtual TraceStats traceClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits) = 0;
  virtual TraceStats traceAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded) = 0;

  // The backend's own tracer, for its statistics (the CPU fast path's table build, the Vulkan pipeline cache
  // and box table), or null for the other backend.
  virtual CpuTracer* cpu() { return nullptr; }
  virtual VulkanTracer* vulkan() { return nullptr; }

 protected:
  virtual void bindScene(const SceneData& scene) = 0;
  virtual void bindMovedInstances(const SceneData& scene) = 0;

 private:
  std::uint64_t sceneVersion_ = 0;
};

struct CpuTracerOptions {
  CpuTracePath path = CpuTracePath::Interleaved;
  int threads = 0;  // <= 0: every hardware thread
};

// Precondition for both: the scene passed to setScene outlives its use (see Tracer::setScene).
std::unique_ptr<Tracer> makeCpuTracer(const CpuTracerOptions& options = {});
// Throws vs::Error(Runtime) when no usable Vulkan device exists (VulkanTracer).
std::unique_ptr<Tracer> makeVulkanTracer(const VulkanOptions& options = {});

}  // namespace vs

#endif
