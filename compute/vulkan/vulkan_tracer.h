// vulkan_tracer.h: the Vulkan shadow-trace backend: the portable traversal (compute/shared/traverse.h) run as
// a compute shader over the scene arrays, one invocation per texel, into an R32F 2D-array image.
#ifndef VOXSHADOW_VULKAN_TRACER_H
#define VOXSHADOW_VULKAN_TRACER_H

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "compute/scene_data.h"
#include "compute/trace_types.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_interface.h"
#include "compute/vulkan/vulkan_context.h"

namespace vs {

struct VulkanOptions {
  // The device to work on: a context already made (standalone, or on a host engine's device through
  // VulkanHostDevice); null: the tracer makes its own from deviceIndex, deviceName and validation.
  std::shared_ptr<VulkanContext> context;
  int deviceIndex = -1;       // >= 0: that device (listVulkanDevices order)
  std::string deviceName;     // else: first device whose name contains this (case-insensitive)
  std::optional<bool> validation;  // unset: VOXSHADOW_VALIDATION=1 in the environment turns it on
  std::filesystem::path cacheDir;  // empty: defaultPipelineCacheDir()
  // Largest storage-buffer binding to use, in bytes; 0 uses the device's maxStorageBufferRange. Smaller
  // values split the scene arrays into more buffers (the path large scenes take), e.g. to test it.
  std::uint64_t maxBindingBytes = 0;
  // Walk objects through a box table built on upload(const SceneData&) (one read per step, large empty boxes;
  // the same texels) instead of the brickmap hierarchy. Off, or where the table cannot be built, the shader
  // walks the hierarchy exactly as the CPU reference does. The table is bounded by kMaxBoxTableElements
  // (compute/box_table.h), as the CPU tracer's is, so both walk a scene the same way (a device texel limit or
  // maxBindingBytes below it lowers it here).
  bool boxTable = true;
  // Host threads for the work around the rays (Tracer::hostThreads: FrameRenderer's G-buffer resolve and
  // EVSM filter when they run on the host); 0 or less: the arena the caller runs in.
  int hostThreads = 0;
};

// Views into the arrays the shader reads, named as its buffers. Lets callers trace arrays they assembled
// themselves; SceneData gives them through from().
struct SceneArrays {
  std::span<const std::uint32_t> regionTable;
  std::span<const gpu::Region> regions;
  std::span<const gpu::Sector> sectors;
  std::span<const gpu::Brick> bricks;
  std::span<const std::uint32_t> occupancy;
  std::span<const std::uint32_t> payload;
  std::span<const gpu::ObjectRecord> objects;
  std::span<const gpu::InstanceRecord> instances;
  std::span<const gpu::BvhNode> nodes;
  std::span<const std::uint32_t> instanceIndices;
  std::span<const std::uint32_t> nodeEscapes;  // one per node (Bvh::nodeEscapes)

  static SceneArrays from(const SceneData& scene) {
    return {scene.regionTable, scene.regions,   scene.sectors,           scene.bricks,
            scene.occupancy,   scene.payload,   scene.objects,           scene.instances,
            scene.bvh.nodes(), scene.bvh.instanceIndices(), scene.bvh.nodeEscapes()};
  }
};

// The arrays the shader may split over several bindings, in binding order.
enum class SplitArray { RegionTable = 0, Regions, Sectors, Bricks, Occupancy, Payload };
inline constexpr int kSplitArrayCount = int(gpu::VS_SPLIT_ARRAY_COUNT);
// Bindings per split array in the shader (compute/shared/trace_interface.h).
inline constexpr int kMaxBuffersPerArray = gpu::VS_MAX_CHUNKS;

struct PipelineStats {
  double createMs = 0.0;   // vkCreateComputePipelines of the trace pipeline
  bool warmCache = false;  // a pipeline-cache file for this device and driver, with pipelines in it, was loaded
  bool cacheEmpty = false; // the loaded file held a header only: the driver caches nothing
  std::filesystem::path cacheFile;
  bool cacheSaved = false;
  std::string cacheError;  // why the cache could not be saved, when it could not
};

// Where traceInto puts a view's rectangle: texel (x, y) of the view at element origin + y * rowLength + x of
// the target buffer (floats).
struct DeviceTexelPlace {
  std::int64_t origin = 0;
  std::uint32_t rowLength = 0;
};
// A buffer of floats on the tracer's device (usage TRANSFER_DST), bufferTexels long, and a place per view.
struct DeviceTexelTarget {
  VkBuffer buffer = VK_NULL_HANDLE;
  std::uint64_t bufferTexels = 0;
  std::span<const DeviceTexelPlace> places;
};

// The device buffers a camera trace left its results in (VulkanTracer::lastCameraTrace): the hit records, one
// per ray in call order, and the camera buffer (its listed pixels), as compute/shaders/shadow_trace.comp binds
// them (storage buffers), with the record the rays were made from.
struct CameraTraceBuffers {
  VkBuffer hits = VK_NULL_HANDLE;
  VkBuffer camera = VK_NULL_HANDLE;
  std::uint64_t rays = 0;  // 0: no camera trace's results are held
  std::uint64_t pixels = 0;  // the camera's pixels (width x height)
  bool listed = false;       // the rays are the listed pixels' (else every pixel's, in order)
  gpu::CameraRays record{};  // as traced; size.z: the listed pixels in `camera` (0: every pixel)
};

// Visibility receivers that a pass on the tracer's device made, one VisibilityReceiver per pixel in a storage
// buffer (lighting/shaders/gbuffer_resolve.comp), and the pixels whose receivers a trace takes (row-major, each
// below pixelCount; empty: every pixel, in order).
struct DeviceReceivers {
  VkBuffer buffer = VK_NULL_HANDLE;
  std::uint64_t pixelCount = 0;
  std::span<const std::uint32_t> pixels;
};

// The device buffers a visibility trace from DeviceReceivers left its results in (VulkanTracer::
// lastVisibilityTrace): the answers (uint per ray, receiver by light) and the trace's source buffer (the
// VisibilityRays record, its lights, then its listed pixels), as compute/shaders/shadow_trace.comp binds them.
struct VisibilityTraceBuffers {
  VkBuffer answers = VK_NULL_HANDLE;
  VkBuffer source = VK_NULL_HANDLE;
  std::uint64_t receivers = 0;  // 0: no such trace's results are held
  std::uint64_t pixels = 0;     // DeviceReceivers::pixelCount
  std::uint32_t lights = 0;
  bool listed = false;  // the receivers are the listed pixels' (else pixel k's)
};

class VulkanTracer {
 public:
  // Creates the context (device choice, validation) and the trace pipeline through the disk cache.
  // Throws vs::Error(Runtime) when no usable Vulkan device exists (see VulkanContext).
  explicit VulkanTracer(const VulkanOptions& options = {});
  ~VulkanTracer();
  VulkanTracer(const VulkanTracer&) = delete;
  VulkanTracer& operator=(const VulkanTracer&) = delete;

  // Copies the scene to the device through a staging buffer. Arrays whose size is unchanged reuse their
  // buffers. Throws vs::Error(Runtime) naming the limit when a voxel array needs more than
  // kMaxBuffersPerArray bindings of the binding limit, a record array (objects, instances, BVH) exceeds
  // maxTexelBufferElements, or the whole scene exceeds the device-local heap; vs::Error(BadInput) when the
  // node escapes do not match the nodes. Preconditions: the arrays are consistent (as SceneData::build makes
  // them). upload(const SceneData&) also builds and uploads the box table (VulkanOptions::boxTable; about
  // 0.15 s for a 512^3 scene); arrays given as SceneArrays are walked through the hierarchy.
  void upload(const SceneData& scene);
  void upload(const SceneArrays& scene);
  // The per-frame upload when only instances moved (SceneData::moveInstance, instances added or removed):
  // copies the instances and the BVH, keeps the voxel arrays and the box table on the device. Precondition:
  // no voxel changed since the last upload() or update() (after edits, call update()); throws
  // vs::Error(BadInput) when the objects or voxel arrays differ in size from it, vs::Error(Runtime) before any
  // upload().
  void uploadInstances(const SceneData& scene);
  // The per-frame upload after changes to the scene last uploaded with upload(const SceneData&) or update()
  // (SceneData::updateObject, addObject, addInstance, removeInstance, setInstanceObject, moveInstance), with
  // what they reported (several merged with SceneDelta::merge). Copies only the delta's byte ranges, in one
  // staging copy with a region per range (whole arrays where delta.voxelLayout); updates the box table
  // around the delta's edited bricks only (updateBoxTable) and copies the elements it rewrote; copies the
  // instances and the BVH by their ranges when delta.instances. An array that outgrew its buffers gets new
  // ones with headroom (half as much again, within the binding limits), copied whole, and counted
  // (bufferGrowths). Throws vs::Error(Runtime) before any upload() and, as upload() does, when the scene no
  // longer fits the device (nothing is copied then). Precondition: the delta covers every change since the
  // last upload() or update().
  void update(const SceneData& scene, const SceneDelta& delta);
  // Whether the last upload() or update() gave the shader a box table.
  bool boxTableInUse() const;
  // Bytes of scene data (voxel arrays, records, BVH, box table) copied to the device since the tracer was
  // made, by upload(), uploadInstances() and update().
  std::uint64_t bytesUploaded() const;
  // How many times update() gave an array new, larger buffers.
  int bufferGrowths() const;

  // Traces views[i]'s texel rectangle into layers[i] (layers resized to views.size(); a layer whose size
  // differs from its view is resized and zero-filled; texels outside the rectangle keep their values).
  // One submission and one readback for the whole batch, one dispatch per view (timed per view when the
  // queue has timestamps); the pipeline that reads split bindings is used only when upload() split an array.
  // Preconditions: upload() was called; views[i].info.xy > 0; 0 <= rect.x0 <= rect.x1 <= width, same for y.
  // Throws vs::Error(BadInput) when a view breaks them.
  TraceStats trace(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers);
  // The same trace, with the texels copied on the device into target.buffer (a layer store that a pass on this
  // device reads in place) instead of read back: nothing crosses to the host. The copies are made visible to
  // later transfers, shaders and host reads. Throws vs::Error(BadInput) as trace() does, and when a rectangle
  // would land outside the buffer or a place's rowLength is narrower than its rectangle.
  TraceStats traceInto(std::span<const gpu::TraceView> views, const DeviceTexelTarget& target);
  // Closest-hit records of rays[i] into hits[i], and any-hit answers into occluded[i] (1 where the segment
  // holds a solid voxel), as the CPU backend gives them bit for bit. One submission and one readback per call.
  // Preconditions: upload() was called; the output is as long as `rays` (else vs::Error(BadInput)).
  TraceStats traceClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits);
  TraceStats traceAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded);
  // Tracer::traceCamera: the rays made on the device from the record; only it and the pixel list go up.
  TraceStats traceCamera(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                         std::span<gpu::RayHit> hits);
  // Every pixel's camera ray, its hit left on the device for a pass that reads it in place (lastCameraTrace):
  // nothing is read back. Throws as traceCamera does.
  TraceStats traceCameraOnDevice(const gpu::CameraRays& camera);
  // The same rays from receivers already on the device: only the record, the lights and the pixel list go up.
  // occluded[k * lights + l] answers the k-th receiver taken (pixels[k], or pixel k) toward light l. Throws
  // vs::Error(BadInput) as traceVisibility does, and when the buffer is missing or a pixel is not below
  // pixelCount. Precondition: the buffer holds pixelCount receivers, their writes visible to shaders.
  TraceStats traceVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                             const DeviceReceivers& receivers, std::span<std::uint32_t> occluded);
  // Where the last traceVisibility with DeviceReceivers left its answers and pixel list on the device, for a pass
  // that reads them in place (the lighting pass's spread of the answers); valid as lastCameraTrace is.
  VisibilityTraceBuffers lastVisibilityTrace() const;
  // Where the last traceCamera's hits and camera record are on the device, for a pass on this device that reads
  // them in place (the G-buffer resolve); valid until the tracer's next call that traces or uploads (rays 0
  // then, and when the last trace was not a camera trace). The shader's writes are visible to later shaders.
  CameraTraceBuffers lastCameraTrace() const;
  // Tracer::traceVisibility: the rays made on the device; only the record, the lights and the receivers go up.
  TraceStats traceVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                             std::span<const gpu::VisibilityReceiver> receivers, std::span<std::uint32_t> occluded);

  const VulkanDeviceInfo& device() const;
  const PipelineStats& pipelineStats() const;
  // Buffers holding one split array after upload() (at least 1: an empty array binds a placeholder).
  int bufferCount(SplitArray array) const;
  // Validation warnings and errors so far (empty when validation is off or nothing was reported).
  std::vector<std::string> validationMessages() const;
  VulkanContext& context();
  // The same context, shared: whoever holds it keeps the device alive after the tracer is gone.
  std::shared_ptr<VulkanContext> sharedContext();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vs

#endif
