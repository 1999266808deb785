// tracer.h: the one interface of both trace backends (the CPU tracer and the Vulkan shader), for every ray kind:
// shadow texels of light views, closest-hit rays and any-hit rays (compute/shared/trace_rays.h). The bake, the
// benchmark and the tests drive a backend through it alike; both give the same results bit for bit.
#ifndef VOXSHADOW_TRACER_H
#define VOXSHADOW_TRACER_H

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "compute/scene_data.h"
#include "compute/shared/trace_rays.h"
#include "compute/trace_types.h"

namespace vs {

class CpuTracer;
class VulkanTracer;
struct VulkanOptions;

class Tracer {
 public:
  virtual ~Tracer() = default;

  // "cpu" or "vulkan".
  virtual std::string backend() const = 0;
  // What runs the rays: the Vulkan device's name, or "CPU, N threads".
  virtual std::string deviceName() const = 0;
  // The host threads that the work around the rays may use (FrameRenderer's G-buffer resolve, CPU shading and
  // EVSM filter): the CPU backend's CpuTracerOptions::threads, the Vulkan backend's VulkanOptions::hostThreads.
  // 0 or less: the arena the caller runs in (its own tbb::task_arena, else every hardware thread).
  virtual int hostThreads() const = 0;

  // Holds the tracer for one thread across several calls. Every call below holds it for its own length, so a
  // tracer may be called from several threads at once: the calls run one after another. A caller whose calls
  // belong together (bind a scene, then trace it; FrameRenderer holds it for a whole frame) holds an
  // Exclusive, so that no other thread's call comes between them. Calls from the holding thread go through
  // (the lock is recursive). The backend objects of cpu() and vulkan() are not guarded by themselves: use
  // them only while holding an Exclusive.
  class Exclusive {
   public:
    explicit Exclusive(const Tracer& tracer) : lock_(tracer.mutex_) {}

   private:
    std::unique_lock<std::recursive_mutex> lock_;
  };

  // Binds the scene, after it was built or any voxel changed (edits, objects added). The shared form keeps
  // the arrays alive while they are bound, so they can never be traced after they were freed (what
  // FrameRenderer uses). The reference form does not: the CPU backend reads `scene` in place, so it must
  // outlive the tracer or the next setScene. The Vulkan backend copies it to the device. Throws
  // vs::Error(Runtime) when it does not fit the device.
  void setScene(std::shared_ptr<const SceneData> scene) {
    if (!scene) throwNullScene();
    Exclusive hold(*this);
    bindScene(*scene);
    owned_ = std::move(scene);
    ++sceneVersion_;
  }
  void setScene(const SceneData& scene) {
    Exclusive hold(*this);
    bindScene(scene);
    owned_.reset();
    ++sceneVersion_;
  }
  // The per-frame update after changes the scene reported (SceneDelta from SceneData's changes): only the
  // byte ranges, box-table entries, instances and BVH the delta names are copied again. Precondition: `scene`
  // is the bound one, changed only as the deltas since the last bind or update say.
  void sceneChanged(const SceneData& scene, const SceneDelta& delta) {
    Exclusive hold(*this);
    bindDelta(scene, delta);
    ++sceneVersion_;
  }
  // The per-frame update when only instances moved (SceneData::moveInstance): no voxel data is copied again.
  // Precondition: setScene was called with this scene and no voxel changed since.
  void instancesMoved(const SceneData& scene) {
    Exclusive hold(*this);
    bindMovedInstances(scene);
    ++sceneVersion_;
  }
  // Counts the scene updates bound so far (setScene, sceneChanged and instancesMoved calls). A caller that
  // keeps results across frames (FrameRenderer) compares it with the count after its own last update: any
  // other update means it no longer knows what the tracer holds.
  std::uint64_t sceneVersion() const {
    Exclusive hold(*this);
    return sceneVersion_;
  }
  // The arrays bound through the shared form of setScene (null after the reference form). Updates by anyone
  // (sceneChanged, instancesMoved, setScene of the same arrays) bring the tracer's copy to the arrays' current
  // state, so every holder of the same arrays may keep using it.
  std::shared_ptr<const SceneData> boundScene() const {
    Exclusive hold(*this);
    return owned_;
  }
  // Bytes copied to the device so far by scene binds and updates (0 on the CPU backend).
  std::uint64_t bytesUploaded() const {
    Exclusive hold(*this);
    return uploadedBytes();
  }

  // Expires when the tracer is destroyed: a FrameRenderer made on it says so instead of using a dead tracer.
  std::weak_ptr<const int> liveness() const { return alive_; }

  // The three ray kinds. Preconditions: setScene was called; views as in CpuTracer::trace; the outputs are as
  // long as `rays` (else vs::Error(BadInput)).
  TraceStats traceShadow(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers) {
    Exclusive hold(*this);
    return runShadow(views, layers);
  }
  TraceStats traceClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits) {
    Exclusive hold(*this);
    return runClosest(rays, hits);
  }
  TraceStats traceAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded) {
    Exclusive hold(*this);
    return runAny(rays, occluded);
  }
  // The closest hits of a camera's primary rays (compute/shared/camera_rays.h), hits[k] that of pixels[k]
  // (row-major pixel indices; an empty list: every pixel of camera.size, row by row). The Vulkan backend
  // makes the rays on the device, so only the record and the list go up; the CPU backend makes the same rays
  // (cameraRays) and traces them as traceClosest does: the same hits bit for bit. camera.size.z is ignored.
  // Preconditions: setScene was called; hits has one record per traced pixel, every listed pixel lies in the
  // frame, the record's sizes are 1.. and its numbers finite (else vs::Error(BadInput), nothing traced).
  TraceStats traceCamera(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                         std::span<gpu::RayHit> hits) {
    Exclusive hold(*this);
    return runCamera(camera, pixels, hits);
  }
  // The any-hit answers of visibility rays (compute/shared/visibility_rays.h): occluded[k * lights.size() + l]
  // is 1 where receiver k's ray toward light l holds a solid voxel, 0 where it is clear or empty. The Vulkan
  // backend makes the rays on the device, so only the record, the lights and the receivers go up (32 bytes a
  // receiver instead of 48 a ray); the CPU backend makes the same rays (visibilityRays) and traces them as
  // traceAny does: the same answers bit for bit. frame.counts is ignored.
  // Preconditions: setScene was called; at least one light; occluded as long as receivers * lights; every
  // number of the record, lights and receivers finite except a light's `target.w` (any length < 0 means
  // unbounded), a light kind one of VS_VISIBILITY_TOWARD_* and its range `kind.y` >= 0 (else
  // vs::Error(BadInput), nothing traced).
  TraceStats traceVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                             std::span<const gpu::VisibilityReceiver> receivers, std::span<std::uint32_t> occluded) {
    Exclusive hold(*this);
    return runVisibility(frame, lights, receivers, occluded);
  }

  // The backend's own tracer, for its statistics (the CPU fast path's table build, the Vulkan pipeline cache
  // and box table), or null for the other backend. Not guarded: use it while holding an Exclusive.
  virtual CpuTracer* cpu() { return nullptr; }
  virtual VulkanTracer* vulkan() { return nullptr; }

 protected:
  // The backend's work, called with the tracer held.
  virtual void bindScene(const SceneData& scene) = 0;
  virtual void bindMovedInstances(const SceneData& scene) = 0;
  virtual void bindDelta(const SceneData& scene, const SceneDelta& delta) = 0;
  virtual std::uint64_t uploadedBytes() const { return 0; }
  virtual TraceStats runShadow(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers) = 0;
  virtual TraceStats runClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits) = 0;
  virtual TraceStats runAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded) = 0;
  virtual TraceStats runCamera(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                               std::span<gpu::RayHit> hits) = 0;
  virtual TraceStats runVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                                   std::span<const gpu::VisibilityReceiver> receivers,
                                   std::span<std::uint32_t> occluded) = 0;

 private:
  [[noreturn]] static void throwNullScene();
  mutable std::recursive_mutex mutex_;
  std::uint64_t sceneVersion_ = 0;
  std::shared_ptr<const SceneData> owned_;
  std::shared_ptr<const int> alive_ = std::make_shared<const int>(0);
};

struct CpuTracerOptions {
  CpuTracePath path = CpuTracePath::Interleaved;
  int threads = 0;  // <= 0: the arena the caller runs in (its own tbb::task_arena, else every hardware thread)
};

// Checks a camera trace's arguments as Tracer::traceCamera states them (vs::Error(BadInput) naming what is
// wrong) and returns the number of rays it traces.
std::uint64_t checkCameraTrace(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                               std::size_t hitCount);
// The rays traceCamera traces, made on the host (the same bits the device makes). Preconditions: as
// checkCameraTrace accepts.
std::vector<gpu::TraceRay> cameraRays(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels = {});

// Checks a visibility trace's arguments as Tracer::traceVisibility states them (vs::Error(BadInput) naming the
// field) and returns the number of rays it traces.
std::uint64_t checkVisibilityTrace(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                                   std::span<const gpu::VisibilityReceiver> receivers, std::size_t answerCount);
// The rays traceVisibility traces, made on the host (the same bits the device makes) into `rays` (resized, its
// storage reused): ray k * lights.size() + l is receivers[k]'s toward light l. Preconditions: as
// checkVisibilityTrace accepts.
void visibilityRays(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                    std::span<const gpu::VisibilityReceiver> receivers, std::vector<gpu::TraceRay>& rays);

std::unique_ptr<Tracer> makeCpuTracer(const CpuTracerOptions& options = {});
// Runs `run` in the process's kept TBB arena of `threads` threads (made on first use, shared by every caller
// asking for that count, as the CPU tracer's own are), or directly in the caller's arena when threads <= 0.
void inHostArena(int threads, const std::function<void()>& run);
// Throws vs::Error(Runtime) when no usable Vulkan device exists (VulkanTracer; its options in
// compute/vulkan/vulkan_tracer.h).
std::unique_ptr<Tracer> makeVulkanTracer();
std::unique_ptr<Tracer> makeVulkanTracer(const VulkanOptions& options);

}  // namespace vs

#endif
