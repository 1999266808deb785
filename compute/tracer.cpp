#include "compute/tracer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include <tbb/parallel_for.h>

#include "compute/cpu/cpu_tracer.h"
#include "compute/shared/camera_rays.h"
#include "compute/shared/visibility_rays.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "voxel/error.h"

namespace vs {
namespace {

class CpuBackend final : public Tracer {
 public:
  explicit CpuBackend(const CpuTracerOptions& options) : options_(options) {}

  std::string backend() const override { return "cpu"; }
  std::string deviceName() const override {
    int threads = options_.threads > 0 ? options_.threads : int(std::thread::hardware_concurrency());
    return "CPU, " + std::to_string(threads) + (threads == 1 ? " thread" : " threads");
  }
  int hostThreads() const override { return options_.threads; }
  void bindScene(const SceneData& scene) override {
    // The tables derived from the voxels are rebuilt on the next trace.
    tracer_ = std::make_unique<CpuTracer>(scene);
  }
  void bindMovedInstances(const SceneData& scene) override {
    // The fast path's tables depend on the voxels only: moved instances keep them.
    if (!tracer_) throwRuntime("Tracer::instancesMoved called before setScene()");
    (void)scene;
  }
  void bindDelta(const SceneData& scene, const SceneDelta& delta) override {
    if (!tracer_) throwRuntime("Tracer::sceneChanged called before setScene()");
    (void)scene;
    tracer_->sceneChanged(delta);
  }
  TraceStats runShadow(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers) override {
    return timed(raysOf(views), [&] { bound().trace(views, layers, options_.path, options_.threads); });
  }
  TraceStats runClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits) override {
    return timed(rays.size(), [&] { bound().traceClosest(rays, hits, options_.path, options_.threads); });
  }
  TraceStats runAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded) override {
    return timed(rays.size(), [&] { bound().traceAny(rays, occluded, options_.path, options_.threads); });
  }
  TraceStats runCamera(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                       std::span<gpu::RayHit> hits) override {
    const std::uint64_t count = checkCameraTrace(camera, pixels, hits.size());
    CpuTracer& tracer = bound();
    // In slices through one kept buffer per calling thread: a whole frame's rays in fresh pages cost more to
    // fault in than to make, and a slice of this many rays still spreads over every thread. (Named through a
    // reference: the workers that fill it must write the caller's buffer, not their own.)
    constexpr std::size_t kSlice = std::size_t(1) << 16;
    thread_local std::vector<gpu::TraceRay> callerSlice;
    std::vector<gpu::TraceRay>& slice = callerSlice;
    return timed(count, [&] {
      for (std::size_t first = 0; first < count; first += kSlice) {
        const std::size_t n = std::min<std::size_t>(kSlice, count - first);
        slice.resize(n);
        tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
          slice[k] = gpu::vsCameraRay(camera, pixels.empty() ? std::uint32_t(first + k) : pixels[first + k]);
        });
        tracer.traceClosest(slice, hits.subspan(first, n), options_.path, options_.threads);
      }
    });
  }
  TraceStats runVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                           std::span<const gpu::VisibilityReceiver> receivers,
                           std::span<std::uint32_t> occluded) override {
    const std::uint64_t count = checkVisibilityTrace(frame, lights, receivers, occluded.size());
    CpuTracer& tracer = bound();
    // In slices, as traceCamera: whole receivers of about 65,536 rays each.
    const std::size_t perSlice = std::max<std::size_t>(1, (std::size_t(1) << 16) / lights.size());
    thread_local std::vector<gpu::TraceRay> callerSlice;
    std::vector<gpu::TraceRay>& slice = callerSlice;
    return timed(count, [&] {
      for (std::size_t first = 0; first < receivers.size(); first += perSlice) {
        const std::size_t n = std::min(perSlice, receivers.size() - first);
        visibilityRays(frame, lights, receivers.subspan(first, n), slice);
        tracer.traceAny(slice, occluded.subspan(first * lights.size(), slice.size()), options_.path,
                        options_.threads);
      }
    });
  }
  CpuTracer* cpu() override { return tracer_.get(); }

 private:
  CpuTracer& bound() {
    if (!tracer_) throwRuntime("Tracer: rays traced before setScene()");
    return *tracer_;
  }
  static std::uint64_t raysOf(std::span<const gpu::TraceView> views) {
    std::uint64_t n = 0;
    for (const gpu::TraceView& v : views)
      n += std::uint64_t(std::max(0, v.rect.z - v.rect.x)) * std::uint64_t(std::max(0, v.rect.w - v.rect.y));
    return n;
  }
  template <class Run>
  static TraceStats timed(std::uint64_t rays, Run&& run) {
    auto t0 = std::chrono::steady_clock::now();
    run();
    TraceStats stats;
    stats.rays = rays;
    stats.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (stats.wallMs > 0.0) stats.mraysPerSecond = double(rays) / (stats.wallMs * 1e3);
    return stats;
  }

  CpuTracerOptions options_;
  std::unique_ptr<CpuTracer> tracer_;
};

class VulkanBackend final : public Tracer {
 public:
  explicit VulkanBackend(const VulkanOptions& options) : tracer_(options), hostThreads_(options.hostThreads) {}

  std::string backend() const override { return "vulkan"; }
  std::string deviceName() const override { return tracer_.device().name; }
  int hostThreads() const override { return hostThreads_; }
  void bindScene(const SceneData& scene) override { tracer_.upload(scene); }
  void bindMovedInstances(const SceneData& scene) override { tracer_.uploadInstances(scene); }
  void bindDelta(const SceneData& scene, const SceneDelta& delta) override { tracer_.update(scene, delta); }
  std::uint64_t uploadedBytes() const override { return tracer_.bytesUploaded(); }
  TraceStats runShadow(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers) override {
    return tracer_.trace(views, layers);
  }
  TraceStats runClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits) override {
    return tracer_.traceClosest(rays, hits);
  }
  TraceStats runAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded) override {
    return tracer_.traceAny(rays, occluded);
  }
  TraceStats runCamera(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                       std::span<gpu::RayHit> hits) override {
    return tracer_.traceCamera(camera, pixels, hits);
  }
  TraceStats runVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                           std::span<const gpu::VisibilityReceiver> receivers,
                           std::span<std::uint32_t> occluded) override {
    return tracer_.traceVisibility(frame, lights, receivers, occluded);
  }
  VulkanTracer* vulkan() override { return &tracer_; }

 private:
  VulkanTracer tracer_;
  int hostThreads_;
};

}  // namespace

std::unique_ptr<Tracer> makeCpuTracer(const CpuTracerOptions& options) { return std::make_unique<CpuBackend>(options); }

std::uint64_t checkCameraTrace(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                               std::size_t hitCount) {
  const std::uint64_t width = camera.size.x, height = camera.size.y;
  if (width == 0 || height == 0)
    throwBadInput("traceCamera: CameraRays.size: a " + std::to_string(width) + " x " + std::to_string(height) +
                  " frame has no pixel");
  const std::uint64_t frame = width * height;
  if (frame > std::numeric_limits<std::uint32_t>::max())
    throwBadInput("traceCamera: CameraRays.size: " + std::to_string(width) + " x " + std::to_string(height) +
                  " pixels do not fit 32-bit pixel indices");
  const glm::vec4 members[5] = {camera.originHigh, camera.originLow, camera.forward, camera.right, camera.up};
  const char* names[5] = {"originHigh", "originLow", "forward", "right", "up"};
  for (int m = 0; m < 5; ++m)
    for (int c = 0; c < 4; ++c)
      if (!std::isfinite(members[m][c]))
        throwBadInput(std::string("traceCamera: CameraRays.") + names[m] + ": not a finite number");
  const std::uint64_t count = pixels.empty() ? frame : pixels.size();
  if (hitCount != count)
    throwBadInput("traceCamera: " + std::to_string(hitCount) + " hit records for " + std::to_string(count) + " pixels");
  for (std::size_t k = 0; k < pixels.size(); ++k)
    if (pixels[k] >= frame)
      throwBadInput("traceCamera: pixels[" + std::to_string(k) + "] = " + std::to_string(pixels[k]) +
                    " lies outside the " + std::to_string(width) + " x " + std::to_string(height) + " frame");
  return count;
}

std::vector<gpu::TraceRay> cameraRays(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels) {
  const std::size_t count = pixels.empty() ? std::size_t(camera.size.x) * std::size_t(camera.size.y) : pixels.size();
  std::vector<gpu::TraceRay> rays(count);
  tbb::parallel_for(std::size_t(0), count, [&](std::size_t k) {
    rays[k] = gpu::vsCameraRay(camera, pixels.empty() ? std::uint32_t(k) : pixels[k]);
  });
  return rays;
}

std::uint64_t checkVisibilityTrace(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                                   std::span<const gpu::VisibilityReceiver> receivers, std::size_t answerCount) {
  if (lights.empty()) throwBadInput("traceVisibility: lights: none (a visibility ray goes toward a light)");
  const std::uint64_t count = std::uint64_t(receivers.size()) * lights.size();
  if (count > std::numeric_limits<std::uint32_t>::max() || lights.size() > std::numeric_limits<std::uint32_t>::max())
    throwBadInput("traceVisibility: " + std::to_string(receivers.size()) + " receivers x " +
                  std::to_string(lights.size()) + " lights: more than 2^32 rays in one call");
  if (answerCount != count)
    throwBadInput("traceVisibility: " + std::to_string(answerCount) + " answers for " + std::to_string(count) +
                  " rays (receivers x lights)");
  auto finite = [](const glm::vec4& v, int components) {
    for (int c = 0; c < components; ++c)
      if (!std::isfinite(v[c])) return false;
    return true;
  };
  if (!finite(frame.boundsMin, 4) || !finite(frame.boundsMax, 4))
    throwBadInput("traceVisibility: VisibilityRays.bounds: not a finite number");
  for (std::size_t l = 0; l < lights.size(); ++l) {
    const std::string name = "traceVisibility: lights[" + std::to_string(l) + "]";
    if (!finite(lights[l].target, 3) || std::isnan(lights[l].target.w))
      throwBadInput(name + ".target: not a finite number");
    if (lights[l].kind.x != gpu::VS_VISIBILITY_TOWARD_POINT && lights[l].kind.x != gpu::VS_VISIBILITY_TOWARD_DIRECTION)
      throwBadInput(name + ".kind: " + std::to_string(lights[l].kind.x) +
                    " is neither VS_VISIBILITY_TOWARD_POINT nor VS_VISIBILITY_TOWARD_DIRECTION");
    if (!(lights[l].kind.y >= 0.0f && std::isfinite(lights[l].kind.y)))
      throwBadInput(name + ".kind.y (the light's range): " + std::to_string(lights[l].kind.y) +
                    " is not a finite number >= 0");
  }
  for (std::size_t k = 0; k < receivers.size(); ++k)
    if (!finite(receivers[k].position, 4) || !finite(receivers[k].normal, 4))
      throwBadInput("traceVisibility: receivers[" + std::to_string(k) + "]: not a finite number");
  return count;
}

void visibilityRays(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                    std::span<const gpu::VisibilityReceiver> receivers, std::vector<gpu::TraceRay>& rays) {
  const std::size_t lightCount = lights.size();
  rays.resize(receivers.size() * lightCount);
  tbb::parallel_for(std::size_t(0), receivers.size(), [&](std::size_t k) {
    for (std::size_t l = 0; l < lightCount; ++l)
      rays[k * lightCount + l] = gpu::vsVisibilityRay(frame, lights[l], receivers[k]);
  });
}

void Tracer::throwNullScene() { throwBadInput("Tracer::setScene: no scene (a null pointer)"); }

std::unique_ptr<Tracer> makeVulkanTracer() { return makeVulkanTracer(VulkanOptions{}); }

std::unique_ptr<Tracer> makeVulkanTracer(const VulkanOptions& options) {
  return std::make_unique<VulkanBackend>(options);
}

}  // namespace vs
