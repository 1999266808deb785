// vulkan_tracer.cpp: scene upload (split across bindings), the trace dispatch, timestamps and readback.
#include "compute/vulkan/vulkan_tracer.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstring>
#include <functional>
#include <limits>
#include <map>
#include <utility>

#include "compute/box_table.h"
#include "compute/tracer.h"
#include "compute/vulkan/pipeline_cache.h"
#include "shadow_trace.spv.h"
#include "compute/shared/trace_interface.h"
#include "voxel/error.h"
#include "voxel/one_call.h"

namespace vs {
namespace {

constexpr std::uint32_t kSplitBindings = gpu::VS_SPLIT_ARRAY_COUNT;  // bindings 0..5
static_assert(gpu::VS_BINDING_REGION_TABLE == 0u && gpu::VS_BINDING_PAYLOAD == kSplitBindings - 1u,
              "split array i is bound at binding i");
constexpr std::uint32_t kObjectsBinding = gpu::VS_BINDING_OBJECTS, kInstancesBinding = gpu::VS_BINDING_INSTANCES;
constexpr std::uint32_t kNodesBinding = gpu::VS_BINDING_NODES, kIndicesBinding = gpu::VS_BINDING_INSTANCE_INDICES;
constexpr std::uint32_t kViewsBinding = gpu::VS_BINDING_VIEW, kImageBinding = gpu::VS_BINDING_SHADOW_IMAGE;
constexpr std::uint32_t kBoxCodesBinding = gpu::VS_BINDING_BOX_TABLE, kEscapesBinding = gpu::VS_BINDING_NODE_ESCAPES;
constexpr const char* kSplitNames[kSplitArrayCount] = {"regionTable", "regions", "sectors", "bricks", "occupancy",
                                                       "payload"};
// The ray buffers, the camera's and the visibility rays', bound as single storage buffers.
constexpr std::uint32_t kRayBindings[6] = {gpu::VS_BINDING_RAYS,   gpu::VS_BINDING_HITS,       gpu::VS_BINDING_OCCLUDED,
                                           gpu::VS_BINDING_CAMERA, gpu::VS_BINDING_VISIBILITY, gpu::VS_BINDING_RECEIVERS};
bool isRayBinding(std::uint32_t b) {
  return std::find(std::begin(kRayBindings), std::end(kRayBindings), b) != std::end(kRayBindings);
}

using gpu::TracePush;
using gpu::TracePipelineOptions;

// The shift fields of the push block, in split-array order.
std::uint32_t* pushShifts(TracePush& push) { return &push.regionTableShift; }
static_assert(offsetof(TracePush, payloadShift) - offsetof(TracePush, regionTableShift) ==
                  (kSplitArrayCount - 1) * sizeof(std::uint32_t),
              "the shifts are consecutive, in split-array order");

// The per-ray records, bound as texel buffers (see shadow_trace.comp): name, texel format, texels per element.
struct RecordArray {
  const char* name;
  VkFormat format;
  std::uint32_t texelsPerElement;
};
constexpr int kRecordArrayCount = 5;
constexpr RecordArray kRecordArrays[kRecordArrayCount] = {
    {"objects", VK_FORMAT_R32G32B32A32_UINT, gpu::VS_OBJECT_TEXELS},
    {"instances", VK_FORMAT_R32G32B32A32_UINT, gpu::VS_INSTANCE_TEXELS},
    {"nodes", VK_FORMAT_R32G32B32A32_UINT, gpu::VS_NODE_TEXELS},
    {"instanceIndices", VK_FORMAT_R32_UINT, 1},
    {"nodeEscapes", VK_FORMAT_R32_UINT, 1},
};
// Their bindings, in kRecordArrays order.
constexpr std::uint32_t kRecordBindings[kRecordArrayCount] = {kObjectsBinding, kInstancesBinding, kNodesBinding,
                                                              kIndicesBinding, kEscapesBinding};

std::string mib(std::uint64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f MiB", double(bytes) / (1024.0 * 1024.0));
  return buf;
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// One array's host data.
struct HostArray {
  const void* data;
  std::uint64_t elements;
  std::uint64_t size;  // bytes per element
};

// The record arrays of kRecordArrays, in order. Throws vs::Error(BadInput) when the BVH's node escapes do not
// match its nodes.
std::array<HostArray, kRecordArrayCount> recordArrays(const SceneArrays& s) {
  if (s.nodeEscapes.size() != s.nodes.size())
    throwBadInput("scene arrays: " + std::to_string(s.nodeEscapes.size()) + " node escapes for " +
                  std::to_string(s.nodes.size()) + " BVH nodes (one per node expected)");
  return {{
      {s.objects.data(), s.objects.size(), sizeof(gpu::ObjectRecord)},
      {s.instances.data(), s.instances.size(), sizeof(gpu::InstanceRecord)},
      {s.nodes.data(), s.nodes.size(), sizeof(gpu::BvhNode)},
      {s.instanceIndices.data(), s.instanceIndices.size(), sizeof(std::uint32_t)},
      {s.nodeEscapes.data(), s.nodeEscapes.size(), sizeof(std::uint32_t)},
  }};
}

// One array's device copy: its buffers and how indices map onto them.
struct DeviceArray {
  std::vector<vk::Buffer> buffers;
  std::uint64_t elements = 0;
  std::uint64_t capacity = 0;  // elements the buffers hold (more than `elements` after a growth's headroom)
  std::uint32_t shift = 0;
  std::uint64_t generation = 0;  // advanced whenever the buffers are made anew: views of the old ones are stale
};

// A copy of host bytes into a device buffer, one region of update()'s staging copy.
struct UploadRegion {
  VkBuffer dst;
  VkDeviceSize offset;
  const std::uint8_t* src;
  VkDeviceSize size;
};

// Bytes of one staging buffer of update(): larger copies go in several submissions.
constexpr VkDeviceSize kUpdateStagingBytes = VkDeviceSize(64) << 20;

// Each call holds the tracer (voxel/one_call.h): its buffers, staging memory and command pool serve one call
// at a time. vs::Tracer (makeVulkanTracer) runs its calls one after another; this catches direct use of one
// VulkanTracer from two threads at once.
class CallInProgress : public OneCallAtATime {
 public:
  CallInProgress(std::atomic<bool>& busy, const char* call)
      : OneCallAtATime(busy, "VulkanTracer", call, "tracer",
                       "a VulkanTracer serves one call at a time (share it through vs::Tracer, whose calls run one "
                       "after another)") {}
};

}  // namespace

struct VulkanTracer::Impl {
  std::atomic<bool> busy{false};  // CallInProgress
  VulkanOptions options;
  // Shared with what records on this device beside the tracer (the lighting pass), so that the device lives
  // until the last of them is gone, whichever goes first.
  std::shared_ptr<VulkanContext> contextOwner;
  VulkanContext& context;
  std::unique_ptr<DiskPipelineCache> cache;
  vk::ComputePipeline pipeline;   // its layouts; the pipelines themselves are `variants`
  vk::UniqueShaderModule module;
  // One pipeline per value of the shader's specialization constants (arrays over several bindings or not,
  // walk with or without the box table, depth at the entry point or the voxel centre), created on first need
  // by variant().
  std::map<TracePipelineOptions, vk::UniquePipeline> variants;
  vk::UniqueDescriptorPool descriptorPool;
  VkDescriptorSet descriptorSet = VK_NULL_HANDLE;
  vk::UniqueQueryPool queryPool;
  std::uint32_t queryCapacity = 0;
  PipelineStats pipelineStats;

  std::array<DeviceArray, kSplitArrayCount> split;
  std::array<DeviceArray, kRecordArrayCount> whole;  // kRecordArrays
  std::array<vk::UniqueBufferView, kRecordArrayCount> wholeViews;
  DeviceArray boxCodes;              // the box table; empty when the walk reads the hierarchy
  vk::UniqueBufferView boxCodesView;
  bool boxTableUploaded = false;
  vk::Buffer placeholder;  // bound where an array is empty or unused, through a view of the format needed
  vk::UniqueBufferView placeholderSint, placeholderUint, placeholderUint4;
  VkDeviceSize viewStride = 0;  // bytes between views in viewBuffer: the dynamic-offset alignment
  std::uint32_t nodeCount = 0;
  bool uploaded = false;

  // The box table as last uploaded from a SceneData (update() changes it around edits); empty otherwise.
  std::vector<std::int32_t> hostTable;
  bool tableFromScene = false;
  vk::Buffer updateStaging;
  std::uint64_t uploadedBytes = 0;
  int growths = 0;

  vk::Buffer viewBuffer;
  vk::Buffer readback;
  vk::Image image;
  // Closest- and any-hit dispatches: the rays in, the results out (host-visible, grown as needed); camera
  // dispatches: the camera record and the listed pixels in; visibility dispatches: the record, lights and
  // receivers in.
  vk::Buffer rayBuffer, hitBuffer, occludedBuffer, cameraBuffer, visibilityBuffer;
  std::uint64_t cameraTraceRays = 0;  // the rays of the camera trace whose results hitBuffer holds (lastCameraTrace)
  std::uint64_t cameraTracePixels = 0;
  bool cameraTraceListed = false;
  gpu::CameraRays cameraTraceRecord{};
  VisibilityTraceBuffers visibilityTrace;  // the last trace from DeviceReceivers (lastVisibilityTrace)
  VkBuffer deviceReceivers = VK_NULL_HANDLE;  // bound at VS_BINDING_RECEIVERS for the call under way (else the placeholder)

  explicit Impl(const VulkanOptions& o)
      : options(o),
        contextOwner(o.context ? o.context
                               : std::make_shared<VulkanContext>(
                                     VulkanContextOptions{o.deviceIndex, o.deviceName, o.validation})),
        context(*contextOwner) {
    const VulkanDeviceInfo& info = context.info();
    std::uint32_t needed = gpu::VS_STORAGE_BUFFER_COUNT;
    if (info.maxPerStageStorageBuffers < needed)
      throwRuntime("Vulkan device " + info.name + " allows " + std::to_string(info.maxPerStageStorageBuffers) +
                   " storage buffers per shader stage (maxPerStageDescriptorStorageBuffers); the trace shader needs " +
                   std::to_string(needed));
    createPipeline();
    placeholder = context.createDeviceBuffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                                     VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
                                                     VK_BUFFER_USAGE_TRANSFER_DST_BIT);
    placeholderSint = context.createTexelView(placeholder, VK_FORMAT_R32_SINT);
    placeholderUint = context.createTexelView(placeholder, VK_FORMAT_R32_UINT);
    placeholderUint4 = context.createTexelView(placeholder, VK_FORMAT_R32G32B32A32_UINT);
    const VkDeviceSize align = info.minUniformBufferOffsetAlignment;
    viewStride = (sizeof(gpu::TraceView) + align - 1) / align * align;
    ensureQueries(2);
  }

  // One timestamp before the first dispatch and one after each: grows the pool to `count` queries.
  void ensureQueries(std::uint32_t count) {
    if (context.info().timestampValidBits == 0 || (queryPool && queryCapacity >= count)) return;
    auto qi = vk::make<VkQueryPoolCreateInfo>(VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO);
    qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qi.queryCount = std::max(count, 2 * queryCapacity);
    VkQueryPool q = VK_NULL_HANDLE;
    vk::check(context.functions().vkCreateQueryPool(context.device(), &qi, context.functions().allocator, &q), "vkCreateQueryPool");
    queryPool = vk::UniqueQueryPool(context.functions(), context.device(), q);
    queryCapacity = qi.queryCount;
  }

  void createPipeline() {
    VkDevice dev = context.device();
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (std::uint32_t b = 0; b < gpu::VS_BINDING_COUNT; ++b) {
      VkDescriptorSetLayoutBinding lb{};
      lb.binding = b;
      lb.descriptorType = b < kSplitBindings || isRayBinding(b) ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER
                          : b == kImageBinding ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                          : b == kViewsBinding ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER_DYNAMIC
                                               : VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
      lb.descriptorCount = b < kSplitBindings ? kMaxBuffersPerArray : 1;
      lb.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
      bindings.push_back(lb);
    }
    auto dl = vk::make<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
    dl.bindingCount = static_cast<std::uint32_t>(bindings.size());
    dl.pBindings = bindings.data();
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    vk::check(context.functions().vkCreateDescriptorSetLayout(dev, &dl, context.functions().allocator, &setLayout), "vkCreateDescriptorSetLayout");
    pipeline.setLayout = vk::UniqueDescriptorSetLayout(context.functions(), dev, setLayout);

    pipeline.layout = context.createPipelineLayout(setLayout, sizeof(TracePush));

    std::filesystem::path dir = options.cacheDir.empty() ? defaultPipelineCacheDir() : options.cacheDir;
    cache = std::make_unique<DiskPipelineCache>(context, dir);
    module = context.createShaderModule(shadow_trace, sizeof(shadow_trace));
    auto t0 = std::chrono::steady_clock::now();
    variant(TracePipelineOptions{.boxTable = options.boxTable});  // the usual one: creation is timed and cached here
    pipelineStats.createMs = msSince(t0);
    pipelineStats.warmCache = cache->warm();
    pipelineStats.cacheEmpty = cache->empty();
    pipelineStats.cacheFile = cache->file();
    pipelineStats.cacheSaved = cache->lastError().empty();
    pipelineStats.cacheError = cache->lastError();

    std::array<VkDescriptorPoolSize, 4> sizes{{
        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, gpu::VS_STORAGE_BUFFER_COUNT},
        {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1},
        {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kRecordArrayCount + 1},
        {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER_DYNAMIC, 1},
    }};
    auto dp = vk::make<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
    dp.maxSets = 1;
    dp.poolSizeCount = static_cast<std::uint32_t>(sizes.size());
    dp.pPoolSizes = sizes.data();
    VkDescriptorPool pool = VK_NULL_HANDLE;
    vk::check(context.functions().vkCreateDescriptorPool(dev, &dp, context.functions().allocator, &pool), "vkCreateDescriptorPool");
    descriptorPool = vk::UniqueDescriptorPool(context.functions(), dev, pool);
    auto ai = vk::make<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
    ai.descriptorPool = pool;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &setLayout;
    vk::check(context.functions().vkAllocateDescriptorSets(dev, &ai, &descriptorSet), "vkAllocateDescriptorSets");
  }

  // The trace pipeline of one variant; created (and the disk cache saved) on first need.
  VkPipeline variant(const TracePipelineOptions& options) {
    vk::UniquePipeline& p = variants[options];
    if (!p) {
      p = makePipeline(options);
      cache->save();
    }
    return p.get();
  }

  vk::UniquePipeline makePipeline(const TracePipelineOptions& options) {
    // Four 32-bit words: three VkBool32 and the ray kind's int.
    std::uint32_t values[4] = {options.splitBindings ? VK_TRUE : VK_FALSE, options.boxTable ? VK_TRUE : VK_FALSE,
                               options.depthAtCenter ? VK_TRUE : VK_FALSE, std::uint32_t(options.rayKind)};
    VkSpecializationMapEntry entries[4] = {{gpu::VS_SPEC_SPLIT_BINDINGS, 0, sizeof(VkBool32)},
                                           {gpu::VS_SPEC_BOX_TABLE, 4, sizeof(VkBool32)},
                                           {gpu::VS_SPEC_DEPTH_AT_CENTER, 8, sizeof(VkBool32)},
                                           {gpu::VS_SPEC_RAY_KIND, 12, sizeof(std::int32_t)}};
    VkSpecializationInfo spec{4, entries, sizeof values, values};
    return context.createComputePipeline(module.get(), pipeline.layout.get(), &spec, cache->get());
  }

  // Whether any split array spans more than one binding after upload().
  bool splitBindings() const {
    for (const DeviceArray& a : split)
      if (a.buffers.size() > 1) return true;
    return false;
  }

  std::uint64_t bindingLimit() const {
    std::uint64_t limit = context.info().maxStorageBufferRange;
    if (options.maxBindingBytes > 0) limit = std::min(limit, options.maxBindingBytes);
    return limit;
  }

  // Uploads one array, reusing its buffers when the element count (and so the split) is unchanged.
  void uploadArray(DeviceArray& dst, const void* data, std::uint64_t elements, std::uint64_t elementSize,
                   std::uint64_t elementsPerBuffer, std::uint32_t shift,
                   VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT) {
    usage |= VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    bool reuse = dst.elements == elements && dst.capacity == elements && dst.shift == shift && !dst.buffers.empty();
    if (!reuse) allocateArray(dst, elements, elements, elementSize, elementsPerBuffer, shift, usage);
    const auto* bytes = static_cast<const std::uint8_t*>(data);
    for (std::size_t b = 0; b < dst.buffers.size(); ++b) {
      context.upload(dst.buffers[b], 0, bytes + b * elementsPerBuffer * elementSize, dst.buffers[b].size);
      uploadedBytes += dst.buffers[b].size;
    }
  }

  // Gives an array new buffers holding `capacity` elements (of which `elements` are in use), split every
  // elementsPerBuffer elements; no data is copied.
  void allocateArray(DeviceArray& dst, std::uint64_t elements, std::uint64_t capacity, std::uint64_t elementSize,
                     std::uint64_t elementsPerBuffer, std::uint32_t shift, VkBufferUsageFlags usage) {
    usage |= VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    dst.buffers.clear();
    for (std::uint64_t first = 0; first < capacity; first += elementsPerBuffer) {
      std::uint64_t n = std::min(elementsPerBuffer, capacity - first);
      dst.buffers.push_back(context.createDeviceBuffer(n * elementSize, usage));
    }
    dst.elements = elements;
    dst.capacity = capacity;
    dst.shift = shift;
    ++dst.generation;
  }

  // The most texels one texel-buffer binding may hold: the device limit, or the test override in bytes.
  std::uint64_t texelLimit() const {
    std::uint64_t limit = context.info().maxTexelBufferElements;
    if (options.maxBindingBytes > 0) limit = std::min(limit, options.maxBindingBytes / sizeof(std::int32_t));
    return limit;
  }

  // The box table's bound: the one of every backend (kMaxBoxTableElements), or less where the device's
  // texel-buffer limit (or the test override) is lower.
  std::uint64_t tableLimit() const { return std::min(kMaxBoxTableElements, texelLimit()); }

  void upload(const SceneData& scene) {
    std::vector<std::int32_t> table;
    if (options.boxTable) table = buildBoxTable(scene, tableLimit());
    upload(SceneArrays::from(scene), table);
    hostTable = std::move(table);
    tableFromScene = options.boxTable;
  }

  void uploadArrays(const SceneArrays& s) {
    upload(s);
    hostTable.clear();
    tableFromScene = false;
  }

  static std::array<HostArray, kSplitArrayCount> splitArrays(const SceneArrays& s) {
    return {{
        {s.regionTable.data(), s.regionTable.size(), sizeof(std::uint32_t)},
        {s.regions.data(), s.regions.size(), sizeof(gpu::Region)},
        {s.sectors.data(), s.sectors.size(), sizeof(gpu::Sector)},
        {s.bricks.data(), s.bricks.size(), sizeof(gpu::Brick)},
        {s.occupancy.data(), s.occupancy.size(), sizeof(std::uint32_t)},
        {s.payload.data(), s.payload.size(), sizeof(std::uint32_t)},
    }};
  }

  // How split array a is cut into buffers under the binding limit: elements per buffer and its log2. Throws
  // vs::Error(Runtime) naming the limit when the array needs more than kMaxBuffersPerArray of them.
  std::uint64_t splitPlan(int a, const HostArray& src, std::uint32_t& shift) const {
    const std::uint64_t limit = bindingLimit();
    const std::uint64_t bytes = src.elements * src.size;
    // A power-of-two element count per buffer lets the shader split an index with a shift and a mask.
    std::uint64_t fit = std::min<std::uint64_t>(limit / src.size, std::uint64_t(1) << 31);
    if (fit == 0) throwRuntime("binding limit of " + std::to_string(limit) + " bytes is below one element");
    const std::uint64_t perBuffer = std::bit_floor(fit);
    shift = static_cast<std::uint32_t>(std::countr_zero(perBuffer));
    std::uint64_t buffers = (src.elements + perBuffer - 1) / perBuffer;
    if (buffers > kMaxBuffersPerArray)
      throwRuntime("scene array '" + std::string(kSplitNames[a]) + "' needs " + mib(bytes) + ", more than " +
                   std::to_string(kMaxBuffersPerArray) + " buffers of the device's storage-buffer limit (" +
                   mib(limit) + ", maxStorageBufferRange) on " + context.info().name);
    return perBuffer;
  }

  void upload(const SceneArrays& s, std::span<const std::int32_t> table = {}) {
    const VulkanDeviceInfo& info = context.info();
    const std::array<HostArray, kSplitArrayCount> splitSrc = splitArrays(s);
    const std::array<HostArray, kRecordArrayCount> wholeSrc = recordArrays(s);

    // Refuse what cannot fit before allocating anything.
    std::uint64_t total = 0;
    std::array<std::uint64_t, kSplitArrayCount> perBuffer{};
    std::array<std::uint32_t, kSplitArrayCount> shifts{};
    for (int a = 0; a < kSplitArrayCount; ++a) {
      total += splitSrc[a].elements * splitSrc[a].size;
      perBuffer[a] = splitPlan(a, splitSrc[a], shifts[a]);
    }
    for (int a = 0; a < kRecordArrayCount; ++a) {
      total += wholeSrc[a].elements * wholeSrc[a].size;
      checkRecordArray(a, wholeSrc[a].elements);
    }
    total += std::uint64_t(table.size()) * sizeof(std::int32_t);
    if (info.deviceLocalBytes > 0 && total > info.deviceLocalBytes)
      throwRuntime("scene needs " + mib(total) + " of device memory, more than the device-local heap (" +
                   mib(info.deviceLocalBytes) + ") of " + info.name);

    for (int a = 0; a < kSplitArrayCount; ++a)
      uploadArray(split[a], splitSrc[a].data, splitSrc[a].elements, splitSrc[a].size, perBuffer[a], shifts[a]);
    for (int a = 0; a < kRecordArrayCount; ++a) uploadRecordArray(a, wholeSrc[a]);
    if (table.empty()) {
      boxCodesView.reset();
      boxCodes = DeviceArray{};
    } else {
      const std::uint64_t generation = boxCodes.generation;
      uploadArray(boxCodes, table.data(), table.size(), sizeof(std::int32_t), table.size(), 0,
                  VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT);
      if (generation != boxCodes.generation || !boxCodesView)
        boxCodesView = context.createTexelView(boxCodes.buffers[0], VK_FORMAT_R32_SINT);
    }
    boxTableUploaded = !table.empty();
    nodeCount = static_cast<std::uint32_t>(s.nodes.size());
    uploaded = true;
    updateFailed = false;
  }

  // Record arrays are bound whole as texel buffers: only the device's texel limit applies, not the splitting
  // threshold.
  void checkRecordArray(int a, std::uint64_t elements) const {
    const VulkanDeviceInfo& info = context.info();
    std::uint64_t texels = elements * kRecordArrays[a].texelsPerElement;
    if (texels > info.maxTexelBufferElements)
      throwRuntime("scene array '" + std::string(kRecordArrays[a].name) + "' needs " + std::to_string(texels) +
                   " texels, more than the device's texel-buffer limit (" +
                   std::to_string(info.maxTexelBufferElements) + ", maxTexelBufferElements) on " + info.name);
  }

  void uploadRecordArray(int a, const HostArray& src) {
    const std::uint64_t generation = whole[a].generation;
    uploadArray(whole[a], src.data, src.elements, src.size, std::max<std::uint64_t>(src.elements, 1), 0,
                VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT);
    if (whole[a].buffers.empty())
      wholeViews[a].reset();
    else if (generation != whole[a].generation || !wholeViews[a])
      wholeViews[a] = context.createTexelView(whole[a].buffers[0], kRecordArrays[a].format);
  }

  // The instances and the BVH only (record arrays 1..4), keeping the voxel arrays and the box table.
  void uploadInstances(const SceneData& scene) {
    requireUploaded("VulkanTracer::uploadInstances called");
    const SceneArrays s = SceneArrays::from(scene);
    const std::uint64_t voxelArrays[kSplitArrayCount] = {s.regionTable.size(), s.regions.size(), s.sectors.size(),
                                                         s.bricks.size(), s.occupancy.size(), s.payload.size()};
    bool same = whole[0].elements == s.objects.size();
    for (int a = 0; a < kSplitArrayCount; ++a) same = same && split[a].elements == voxelArrays[a];
    if (!same)
      throwBadInput("VulkanTracer::uploadInstances: the scene's objects or voxel arrays differ in size from the "
                    "last upload(); call upload() after voxel edits");
    const std::array<HostArray, kRecordArrayCount> records = recordArrays(s);
    for (int a = 1; a < kRecordArrayCount; ++a) checkRecordArray(a, records[a].elements);
    for (int a = 1; a < kRecordArrayCount; ++a) uploadRecordArray(a, records[a]);
    nodeCount = static_cast<std::uint32_t>(s.nodes.size());
  }

  // What update() copies into one array: the byte ranges `ranges` of `src` (clipped to its size), or all of
  // it when `whole`; cut at the buffer boundaries of a split array.
  static void regionsOf(const DeviceArray& dst, const HostArray& src, bool whole,
                        std::span<const std::pair<std::uint64_t, std::uint64_t>> ranges,
                        std::vector<UploadRegion>& out) {
    const std::uint64_t bytes = src.elements * src.size;
    if (bytes == 0 || dst.buffers.empty()) return;
    const std::uint64_t chunk = dst.buffers.size() > 1 ? (std::uint64_t(1) << dst.shift) * src.size : ~std::uint64_t(0);
    auto add = [&](std::uint64_t first, std::uint64_t end) {
      end = std::min(end, bytes);
      while (first < end) {
        const std::uint64_t c = dst.buffers.size() > 1 ? first / chunk : 0;
        const std::uint64_t chunkEnd = dst.buffers.size() > 1 ? (c + 1) * chunk : end;
        const std::uint64_t n = std::min(end, chunkEnd) - first;
        out.push_back({dst.buffers[std::size_t(c)].get(), first - c * (dst.buffers.size() > 1 ? chunk : 0),
                       static_cast<const std::uint8_t*>(src.data) + first, n});
        first += n;
      }
    };
    if (whole) {
      add(0, bytes);
      return;
    }
    for (const auto& [offset, size] : ranges) add(offset, offset + size);
  }

  // Copies every region through one staging buffer: one submission with a copy region per range (more only
  // when they exceed kUpdateStagingBytes).
  void uploadRegions(const std::vector<UploadRegion>& regions) {
    VkDeviceSize total = 0;
    for (const UploadRegion& r : regions) total += r.size;
    if (total == 0) return;
    const VkDeviceSize stagingBytes = std::min(total, kUpdateStagingBytes);
    if (!updateStaging.buffer || updateStaging.size < stagingBytes)
      updateStaging = context.createHostBuffer(stagingBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
    auto* staging = static_cast<std::uint8_t*>(updateStaging.mapped);
    std::size_t next = 0;
    VkDeviceSize done = 0;  // of regions[next]
    while (next < regions.size()) {
      VkDeviceSize used = 0;
      std::vector<std::pair<VkBuffer, VkBufferCopy>> copies;
      while (next < regions.size() && used < updateStaging.size) {
        const UploadRegion& r = regions[next];
        const VkDeviceSize n = std::min(r.size - done, updateStaging.size - used);
        if (n > 0) {
          std::memcpy(staging + used, r.src + done, n);
          copies.push_back({r.dst, VkBufferCopy{used, r.offset + done, n}});
        }
        used += n;
        done += n;
        if (done == r.size) {
          ++next;
          done = 0;
        }
      }
      std::stable_sort(copies.begin(), copies.end(),
                       [](const auto& a, const auto& b) { return std::less<VkBuffer>{}(a.first, b.first); });
      context.submitAndWait([&](VkCommandBuffer cmd) {
        std::vector<VkBufferCopy> group;
        for (std::size_t i = 0; i < copies.size();) {
          group.clear();
          std::size_t j = i;
          for (; j < copies.size() && copies[j].first == copies[i].first; ++j) group.push_back(copies[j].second);
          context.functions().vkCmdCopyBuffer(cmd, updateStaging.get(), copies[i].first, static_cast<std::uint32_t>(group.size()),
                          group.data());
          i = j;
        }
      });
      uploadedBytes += used;
    }
  }

  // Whether the device holds a whole scene; else vs::Error(Runtime) naming `what` and why not.
  bool updateFailed = false;  // an update() failed part-way since the last upload()
  void requireUploaded(const char* what) const {
    if (uploaded) return;
    throwRuntime(std::string(what) + (updateFailed ? " after an update that failed part-way left the device's "
                                                     "scene incomplete; call upload() again"
                                                   : " before upload()"));
  }

  void update(const SceneData& scene, const SceneDelta& delta) {
    requireUploaded("VulkanTracer::update called");
    const VulkanDeviceInfo& info = context.info();
    const SceneArrays s = SceneArrays::from(scene);
    const std::array<HostArray, kSplitArrayCount> splitSrc = splitArrays(s);
    const std::array<HostArray, kRecordArrayCount> wholeSrc = recordArrays(s);
    // Half as much again, within what one array may hold.
    auto headroom = [](std::uint64_t needed, std::uint64_t most) {
      return std::max(needed, std::min(most, needed + needed / 2));
    };

    // Every refusal before any change: the binding and texel limits, then device memory with the new capacities.
    std::array<std::uint64_t, kSplitArrayCount> perBuffer{}, splitCapacity{};
    std::array<std::uint32_t, kSplitArrayCount> shifts{};
    std::array<bool, kSplitArrayCount> splitGrows{};
    std::uint64_t total = 0;
    for (int a = 0; a < kSplitArrayCount; ++a) {
      perBuffer[a] = splitPlan(a, splitSrc[a], shifts[a]);
      const std::uint64_t n = splitSrc[a].elements;
      const DeviceArray& d = split[a];
      splitGrows[a] = n > 0 && (d.buffers.empty() || n > d.capacity || d.shift != shifts[a]);
      splitCapacity[a] = splitGrows[a] ? headroom(n, perBuffer[a] * kMaxBuffersPerArray) : d.capacity;
      total += splitCapacity[a] * splitSrc[a].size;
    }
    std::array<std::uint64_t, kRecordArrayCount> recordCapacity{};
    std::array<bool, kRecordArrayCount> recordGrows{};
    for (int a = 0; a < kRecordArrayCount; ++a) {
      checkRecordArray(a, wholeSrc[a].elements);
      const std::uint64_t n = wholeSrc[a].elements;
      recordGrows[a] = n > 0 && (whole[a].buffers.empty() || n > whole[a].capacity);
      recordCapacity[a] = recordGrows[a] ? headroom(n, info.maxTexelBufferElements / kRecordArrays[a].texelsPerElement)
                                         : whole[a].capacity;
      total += recordCapacity[a] * wholeSrc[a].size;
    }
    // The table this scene gets (updateBoxTable gives what buildBoxTable would): its size is known beforehand.
    const bool withTable = options.boxTable && tableFromScene;
    std::uint64_t tableElements = 0;
    if (withTable) {
      tableElements = scene.objects.size() + scene.occupancy.size();
      for (const gpu::ObjectRecord& o : scene.objects)
        tableElements +=
            std::uint64_t(o.regionDims.x) * std::uint64_t(o.regionDims.y) * std::uint64_t(o.regionDims.z) * 4096u;
      if (tableElements > std::min<std::uint64_t>(tableLimit(), std::numeric_limits<std::int32_t>::max()))
        tableElements = 0;
    }
    const bool tableGrows = tableElements > 0 && (boxCodes.buffers.empty() || tableElements > boxCodes.capacity);
    const std::uint64_t tableCapacity = tableGrows ? headroom(tableElements, tableLimit()) : boxCodes.capacity;
    total += tableCapacity * sizeof(std::int32_t);
    if (info.deviceLocalBytes > 0 && total > info.deviceLocalBytes)
      throwRuntime("scene needs " + mib(total) + " of device memory, more than the device-local heap (" +
                   mib(info.deviceLocalBytes) + ") of " + info.name);

    // The delta's ranges per array; the BVH's are over its three arrays in a row (SceneArray::Bvh).
    using Ranges = std::vector<std::pair<std::uint64_t, std::uint64_t>>;
    std::array<Ranges, kSplitArrayCount> splitRanges;
    std::array<Ranges, kRecordArrayCount> recordRanges;
    bool instanceRanges = false, bvhRanges = false;
    const std::uint64_t bvhStarts[4] = {
        0, bytesOfArray(wholeSrc[2]), bytesOfArray(wholeSrc[2]) + bytesOfArray(wholeSrc[3]),
        bytesOfArray(wholeSrc[2]) + bytesOfArray(wholeSrc[3]) + bytesOfArray(wholeSrc[4])};
    for (const SceneDirtyRange& r : delta.ranges) {
      const int a = int(r.array);
      if (a < kSplitArrayCount) {
        splitRanges[a].push_back({r.byteOffset, r.byteSize});
      } else if (r.array == SceneArray::Objects) {
        recordRanges[0].push_back({r.byteOffset, r.byteSize});
      } else if (r.array == SceneArray::Instances) {
        recordRanges[1].push_back({r.byteOffset, r.byteSize});
        instanceRanges = true;
      } else if (r.array == SceneArray::Bvh) {
        bvhRanges = true;
        for (int k = 0; k < 3; ++k) {
          const std::uint64_t lo = std::max<std::uint64_t>(r.byteOffset, bvhStarts[k]);
          const std::uint64_t hi = std::min<std::uint64_t>(r.byteOffset + r.byteSize, bvhStarts[k + 1]);
          if (lo < hi) recordRanges[2 + k].push_back({lo - bvhStarts[k], hi - lo});
        }
      }
    }

    // From here the device's arrays and the host's copy of the box table change: a failure part-way (a device
    // error, memory) leaves them out of step, so the tracer then asks for a whole upload() before any trace
    // rather than tracing a half-updated scene (the table's updates name only the codes that changed, which a
    // later update would not send again).
    struct Unwound {
      Impl& impl;
      bool done = false;
      ~Unwound() {
        if (done) return;
        impl.uploaded = false;
        impl.updateFailed = true;
        impl.hostTable.clear();
      }
    } unwound{*this};
    std::vector<UploadRegion> regions;
    for (int a = 0; a < kSplitArrayCount; ++a) {
      DeviceArray& d = split[a];
      if (splitGrows[a]) {
        if (!d.buffers.empty()) ++growths;
        allocateArray(d, splitSrc[a].elements, splitCapacity[a], splitSrc[a].size, perBuffer[a], shifts[a],
                      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
      }
      d.elements = splitSrc[a].elements;
      regionsOf(d, splitSrc[a], splitGrows[a] || delta.voxelLayout, splitRanges[a], regions);
    }
    for (int a = 0; a < kRecordArrayCount; ++a) {
      DeviceArray& d = whole[a];
      if (recordGrows[a]) {
        if (!d.buffers.empty()) ++growths;
        allocateArray(d, wholeSrc[a].elements, recordCapacity[a], wholeSrc[a].size, recordCapacity[a], 0,
                      VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT);
        wholeViews[a] = context.createTexelView(d.buffers[0], kRecordArrays[a].format);
      }
      d.elements = wholeSrc[a].elements;
      // Instances and the BVH go whole when the delta says they changed without saying where.
      const bool all = recordGrows[a] || (a == 0 && delta.voxelLayout) ||
                       (a == 1 && delta.instances && !instanceRanges) || (a >= 2 && delta.instances && !bvhRanges);
      regionsOf(d, wholeSrc[a], all, recordRanges[a], regions);
    }
    if (withTable) {
      const BoxTableUpdate changed = updateBoxTable(hostTable, scene, delta, tableLimit());
      if (hostTable.empty()) {
        boxCodesView.reset();
        boxCodes = DeviceArray{};
      } else {
        if (tableGrows || boxCodes.capacity < hostTable.size()) {
          if (!boxCodes.buffers.empty()) ++growths;
          allocateArray(boxCodes, hostTable.size(), std::max<std::uint64_t>(tableCapacity, hostTable.size()),
                        sizeof(std::int32_t), std::max<std::uint64_t>(tableCapacity, hostTable.size()), 0,
                        VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT);
          boxCodesView = context.createTexelView(boxCodes.buffers[0], VK_FORMAT_R32_SINT);
        }
        const bool all = tableGrows || changed.rebuilt;
        boxCodes.elements = hostTable.size();
        Ranges tableRanges;
        for (const auto& [first, count] : changed.rewritten)
          tableRanges.push_back({first * sizeof(std::int32_t), count * sizeof(std::int32_t)});
        regionsOf(boxCodes, HostArray{hostTable.data(), hostTable.size(), sizeof(std::int32_t)}, all, tableRanges,
                  regions);
      }
      boxTableUploaded = !hostTable.empty();
    }
    uploadRegions(regions);
    nodeCount = static_cast<std::uint32_t>(s.nodes.size());
    unwound.done = true;
  }

  static std::uint64_t bytesOfArray(const HostArray& a) { return a.elements * a.size; }

  void writeDescriptors() {
    std::vector<VkDescriptorBufferInfo> infos;
    infos.reserve(gpu::VS_STORAGE_BUFFER_COUNT + 1);  // pointers into it are kept: no reallocation
    std::vector<VkWriteDescriptorSet> writes;
    auto bufferInfo = [&](const vk::Buffer* b) {
      const vk::Buffer& use = b ? *b : placeholder;
      infos.push_back({use.get(), 0, VK_WHOLE_SIZE});
      return &infos.back();
    };
    for (std::uint32_t a = 0; a < kSplitBindings; ++a) {
      VkDescriptorBufferInfo* first = nullptr;
      for (int c = 0; c < kMaxBuffersPerArray; ++c) {
        const auto& bufs = split[a].buffers;
        VkDescriptorBufferInfo* p = bufferInfo(c < int(bufs.size()) ? &bufs[c] : nullptr);
        if (c == 0) first = p;
      }
      auto w = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
      w.dstSet = descriptorSet;
      w.dstBinding = a;
      w.descriptorCount = kMaxBuffersPerArray;
      w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w.pBufferInfo = first;
      writes.push_back(w);
    }
    infos.push_back({viewBuffer.get(), 0, sizeof(gpu::TraceView)});
    auto vw = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
    vw.dstSet = descriptorSet;
    vw.dstBinding = kViewsBinding;
    vw.descriptorCount = 1;
    vw.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER_DYNAMIC;
    vw.pBufferInfo = &infos.back();
    writes.push_back(vw);
    auto orPlaceholder = [](const vk::UniqueBufferView& view, const vk::UniqueBufferView& placeholderView) {
      return view ? view.get() : placeholderView.get();
    };
    std::array<VkBufferView, kRecordArrayCount + 1> texelViews{};
    std::array<std::uint32_t, kRecordArrayCount + 1> texelBindings{};
    for (int a = 0; a < kRecordArrayCount; ++a) {
      bool uint4 = kRecordArrays[a].format == VK_FORMAT_R32G32B32A32_UINT;
      texelViews[a] = orPlaceholder(wholeViews[a], uint4 ? placeholderUint4 : placeholderUint);
      texelBindings[a] = kRecordBindings[a];
    }
    texelViews[kRecordArrayCount] = orPlaceholder(boxCodesView, placeholderSint);
    texelBindings[kRecordArrayCount] = kBoxCodesBinding;
    for (std::size_t t = 0; t < texelViews.size(); ++t) {
      auto w = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
      w.dstSet = descriptorSet;
      w.dstBinding = texelBindings[t];
      w.descriptorCount = 1;
      w.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
      w.pTexelBufferView = &texelViews[t];
      writes.push_back(w);
    }
    const vk::Buffer* rayBuffers[5] = {&rayBuffer, &hitBuffer, &occludedBuffer, &cameraBuffer, &visibilityBuffer};
    for (int r = 0; r < 6; ++r) {
      VkDescriptorBufferInfo* info = nullptr;
      if (r == 5) {
        // The device's receivers of this call, or the placeholder.
        infos.push_back({deviceReceivers ? deviceReceivers : placeholder.get(), 0, VK_WHOLE_SIZE});
        info = &infos.back();
      } else {
        info = bufferInfo(rayBuffers[r]->buffer ? rayBuffers[r] : nullptr);
      }
      auto rw = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
      rw.dstSet = descriptorSet;
      rw.dstBinding = kRayBindings[r];
      rw.descriptorCount = 1;
      rw.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      rw.pBufferInfo = info;
      writes.push_back(rw);
    }
    VkDescriptorImageInfo imageInfo{VK_NULL_HANDLE, image.view.get(), VK_IMAGE_LAYOUT_GENERAL};
    auto w = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
    w.dstSet = descriptorSet;
    w.dstBinding = kImageBinding;
    w.descriptorCount = 1;
    w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
    w.pImageInfo = &imageInfo;
    writes.push_back(w);
    context.functions().vkUpdateDescriptorSets(context.device(), static_cast<std::uint32_t>(writes.size()), writes.data(), 0, nullptr);
  }

  // Traces the views' rectangles into `layers` (read back) or, given `target`, copies them on the device into
  // target->buffer at target->places (nothing read back; `layers` untouched).
  TraceStats trace(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers,
                   const DeviceTexelTarget* target = nullptr) {
    auto t0 = std::chrono::steady_clock::now();
    requireUploaded("VulkanTracer::trace called");
    TraceStats stats;
    if (target) {
      if (target->buffer == VK_NULL_HANDLE) throwBadInput("VulkanTracer::traceInto: no target buffer");
      if (target->places.size() != views.size())
        throwBadInput("VulkanTracer::traceInto: " + std::to_string(target->places.size()) + " places for " +
                      std::to_string(views.size()) + " views");
    } else {
      layers.resize(views.size());
    }
    std::uint32_t maxW = 1, maxH = 1, dispatchW = 0, dispatchH = 0;
    std::uint64_t readbackTexels = 0;
    for (std::size_t i = 0; i < views.size(); ++i) {
      const gpu::TraceView& v = views[i];
      int w = v.info.x, h = v.info.y;
      if (w <= 0 || h <= 0)
        throwBadInput("trace view " + std::to_string(i) + ": size " + std::to_string(w) + "x" + std::to_string(h) +
                      " must be positive");
      const glm::ivec4& r = v.rect;
      if (r.x < 0 || r.y < 0 || r.x > r.z || r.y > r.w || r.z > w || r.w > h)
        throwBadInput("trace view " + std::to_string(i) + ": rect (" + std::to_string(r.x) + ", " +
                      std::to_string(r.y) + ", " + std::to_string(r.z) + ", " + std::to_string(r.w) +
                      ") must lie inside the " + std::to_string(w) + "x" + std::to_string(h) + " view");
      if (target) {
        // Every texel of the rectangle lands inside the buffer.
        const DeviceTexelPlace& place = target->places[i];
        if (r.z > r.x && r.w > r.y) {
          const std::int64_t first = place.origin + std::int64_t(r.y) * place.rowLength + r.x;
          const std::int64_t last = place.origin + std::int64_t(r.w - 1) * place.rowLength + (r.z - 1);
          if (place.rowLength < std::uint32_t(r.z - r.x) || first < 0 ||
              std::uint64_t(last) >= target->bufferTexels)
            throwBadInput("VulkanTracer::traceInto: view " + std::to_string(i) + "'s rectangle lands outside the " +
                          std::to_string(target->bufferTexels) + "-texel target");
        }
      } else if (layers[i].width != w || layers[i].height != h) {
        layers[i].width = w;
        layers[i].height = h;
        layers[i].texels.assign(std::size_t(w) * std::size_t(h), 0.0f);
      }
      maxW = std::max<std::uint32_t>(maxW, w);
      maxH = std::max<std::uint32_t>(maxH, h);
      dispatchW = std::max<std::uint32_t>(dispatchW, r.z - r.x);
      dispatchH = std::max<std::uint32_t>(dispatchH, r.w - r.y);
      readbackTexels += std::uint64_t(r.z - r.x) * std::uint64_t(r.w - r.y);
    }
    stats.rays = readbackTexels;
    if (readbackTexels == 0) {
      stats.wallMs = msSince(t0);
      return stats;
    }
    const VulkanDeviceInfo& info = context.info();
    std::uint32_t groupsX = (dispatchW + gpu::VS_TRACE_GROUP_WIDTH - 1) / gpu::VS_TRACE_GROUP_WIDTH;
    std::uint32_t groupsY = (dispatchH + gpu::VS_TRACE_GROUP_HEIGHT - 1) / gpu::VS_TRACE_GROUP_HEIGHT;
    auto layerCount = static_cast<std::uint32_t>(views.size());
    if (groupsX > info.maxWorkGroupCount[0] || groupsY > info.maxWorkGroupCount[1])
      throwRuntime("trace of " + std::to_string(dispatchW) + "x" + std::to_string(dispatchH) +
                   " texels exceeds maxComputeWorkGroupCount on " + info.name);

    // The image grows to hold later batches, so a partial trace of a smaller batch reuses it; but never to the
    // union of a wide batch and a deep one (2048 layers of 16^2, then one of 16384^2, would ask for 2 TiB):
    // past twice what this batch needs it is made to measure, the old one released first.
    auto bytesOf = [](std::uint64_t w, std::uint64_t h, std::uint64_t l) { return w * h * l * sizeof(float); };
    const std::uint64_t needBytes = bytesOf(maxW, maxH, layerCount);
    if (!image.image || image.extent.width < maxW || image.extent.height < maxH || image.layers < layerCount ||
        bytesOf(image.extent.width, image.extent.height, image.layers) > 2 * needBytes) {
      std::uint32_t w = std::max(maxW, image.extent.width), h = std::max(maxH, image.extent.height);
      std::uint32_t l = std::max(layerCount, image.layers);
      if (!image.image || bytesOf(w, h, l) > 2 * needBytes) w = maxW, h = maxH, l = layerCount;
      image = vk::Image{};
      image = context.createStorageImage(w, h, l);
    }
    VkDeviceSize viewBytes = views.size() * viewStride;
    if (!viewBuffer.buffer || viewBuffer.size < viewBytes)
      viewBuffer = context.createHostBuffer(viewBytes, VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
    for (std::size_t i = 0; i < views.size(); ++i)
      std::memcpy(static_cast<std::uint8_t*>(viewBuffer.mapped) + i * viewStride, &views[i], sizeof(gpu::TraceView));
    VkDeviceSize readbackBytes = readbackTexels * sizeof(float);
    if (!target && (!readback.buffer || readback.size < readbackBytes || readback.size > 2 * readbackBytes)) {
      readback = vk::Buffer{};
      readback = context.createHostBuffer(readbackBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
    }
    writeDescriptors();

    std::vector<VkBufferImageCopy> copies;
    VkDeviceSize offset = 0;
    for (std::uint32_t i = 0; i < layerCount; ++i) {
      const glm::ivec4& r = views[i].rect;
      if (r.z == r.x || r.w == r.y) continue;
      VkBufferImageCopy c{};
      c.bufferOffset = offset;
      if (target) {
        const DeviceTexelPlace& place = target->places[i];
        c.bufferOffset = VkDeviceSize(place.origin + std::int64_t(r.y) * place.rowLength + r.x) * sizeof(float);
        c.bufferRowLength = place.rowLength;
      }
      c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, i, 1};
      c.imageOffset = {r.x, r.y, 0};
      c.imageExtent = {std::uint32_t(r.z - r.x), std::uint32_t(r.w - r.y), 1};
      copies.push_back(c);
      offset += VkDeviceSize(r.z - r.x) * VkDeviceSize(r.w - r.y) * sizeof(float);
    }

    ensureQueries(layerCount + 1);
    const bool useSplit = splitBindings();
    // Each view's pipeline: the depth point is a specialization constant, so the other one's code is not run.
    std::vector<VkPipeline> viewPipelines(layerCount);
    for (std::uint32_t i = 0; i < layerCount; ++i)
      viewPipelines[i] = variant(TracePipelineOptions{.splitBindings = useSplit,
                                                      .boxTable = boxTableUploaded,
                                                      .depthAtCenter = views[i].info.w == gpu::VS_DEPTH_POINT_VOXEL_CENTER});
    TracePush push = scenePush();

    context.submitAndWait([&](VkCommandBuffer cmd) {
      barrierBeforeDispatch(cmd);
      const std::uint32_t queries = layerCount + 1;
      if (queryPool) {
        context.functions().vkCmdResetQueryPool(cmd, queryPool.get(), 0, queries);
        context.functions().vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queryPool.get(), 0);
      }
      VkPipeline bound = VK_NULL_HANDLE;
      // One dispatch per layer, sized to its own rectangle: no workgroups wasted on a batch's largest view,
      // and a timestamp after each gives per-view GPU times (exact where dispatches run one after another,
      // as on lavapipe; on other devices neighbouring dispatches may overlap a little).
      for (std::uint32_t i = 0; i < layerCount; ++i) {
        const glm::ivec4& r = views[i].rect;
        std::uint32_t gx = (std::uint32_t(r.z - r.x) + gpu::VS_TRACE_GROUP_WIDTH - 1) / gpu::VS_TRACE_GROUP_WIDTH;
        std::uint32_t gy = (std::uint32_t(r.w - r.y) + gpu::VS_TRACE_GROUP_HEIGHT - 1) / gpu::VS_TRACE_GROUP_HEIGHT;
        if (gx > 0 && gy > 0) {
          if (viewPipelines[i] != bound) {
            bound = viewPipelines[i];
            context.functions().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, bound);
          }
          auto viewOffset = static_cast<std::uint32_t>(i * viewStride);
          context.functions().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout.get(), 0, 1, &descriptorSet,
                                  1, &viewOffset);
          push.layer = i;
          context.functions().vkCmdPushConstants(cmd, pipeline.layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, &push);
          context.functions().vkCmdDispatch(cmd, gx, gy, 1);
          ++stats.dispatches;
        }
        if (queryPool) context.functions().vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queryPool.get(), i + 1);
      }

      auto toCopy = vk::make<VkImageMemoryBarrier>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER);
      toCopy.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      toCopy.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
      toCopy.oldLayout = VK_IMAGE_LAYOUT_GENERAL;
      toCopy.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
      toCopy.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
      toCopy.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
      toCopy.image = image.get();
      toCopy.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, image.layers};
      context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr,
                           0, nullptr, 1, &toCopy);
      context.functions().vkCmdCopyImageToBuffer(cmd, image.get(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                             target ? target->buffer : readback.get(), static_cast<std::uint32_t>(copies.size()),
                             copies.data());
      // Back to GENERAL for the next dispatch; the layout change keeps the texels.
      VkImageMemoryBarrier toShader = toCopy;
      toShader.srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
      toShader.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      toShader.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
      toShader.newLayout = VK_IMAGE_LAYOUT_GENERAL;
      // The copied texels, for the host and for later shaders (a target is read by the lighting pass).
      auto toHost = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
      toHost.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT | VK_ACCESS_SHADER_READ_BIT;
      context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                           0, 1, &toHost, 0, nullptr, 1, &toShader);
    });

    const auto* texels = static_cast<const float*>(target ? nullptr : readback.mapped);
    for (std::uint32_t i = 0; i < layerCount && !target; ++i) {
      const glm::ivec4& r = views[i].rect;
      int w = r.z - r.x;
      ShadowLayer& layer = layers[i];
      for (int y = r.y; y < r.w; ++y) {
        std::memcpy(&layer.texels[std::size_t(y) * layer.width + r.x], texels, std::size_t(w) * sizeof(float));
        texels += w;
      }
    }

    if (queryPool) {
      stats.viewGpuMs = timestampMs(layerCount);
      stats.gpuMs = 0.0;
      for (double ms : stats.viewGpuMs) stats.gpuMs += ms;
    }
    stats.wallMs = msSince(t0);
    double ms = stats.gpuMs > 0.0 ? stats.gpuMs : stats.wallMs;
    if (ms > 0.0) stats.mraysPerSecond = double(stats.rays) / (ms * 1e3);
    return stats;
  }

  // Earlier uploads, host writes (views, rays) and the previous readback all precede a dispatch.
  void barrierBeforeDispatch(VkCommandBuffer cmd) const {
    auto before = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
    before.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT;
    before.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &before, 0, nullptr, 0, nullptr);
  }

  // The push block's scene fields: the node count and each split array's chunk shift.
  TracePush scenePush() const {
    TracePush push{};
    push.nodeCount = nodeCount;
    for (int a = 0; a < kSplitArrayCount; ++a) pushShifts(push)[a] = split[a].shift;
    return push;
  }

  // Closest- or any-hit rays: the rays go up through a host-visible buffer, each workgroup takes
  // VS_RAYS_PER_GROUP of them, and the results come back the same way; `out` receives rays.size() results of
  // `resultBytes` each.
  // Camera rays (kind Camera, `rays` empty): the camera record and its listed pixels go up instead, and the
  // shader makes each ray (compute/shared/camera_rays.h); `rayCount` results come back.
  // Visibility rays (kind Visibility, `rays` empty): writeSource fills sourceBytes of the visibility buffer
  // (the record, its lights and receivers, as the shader reads them), and the shader makes each ray
  // (compute/shared/visibility_rays.h).
  TraceStats traceRays(gpu::RayKind kind, std::span<const gpu::TraceRay> rays, void* out, std::size_t resultBytes,
                       const gpu::CameraRays* camera = nullptr, std::span<const std::uint32_t> pixels = {},
                       std::uint64_t rayCount = 0, std::size_t sourceBytes = 0,
                       const std::function<void(std::byte*)>& writeSource = {}) {
    auto t0 = std::chrono::steady_clock::now();
    requireUploaded("VulkanTracer: rays traced");
    if (kind != gpu::RayKind::Camera && kind != gpu::RayKind::Visibility) rayCount = rays.size();
    TraceStats stats;
    stats.rays = rayCount;
    if (rayCount == 0) {
      stats.wallMs = msSince(t0);
      return stats;
    }
    if (rayCount > std::uint64_t(std::numeric_limits<std::uint32_t>::max()))
      throwBadInput("trace of " + std::to_string(rayCount) + " rays: more than 2^32 in one call");
    const VulkanDeviceInfo& info = context.info();
    const VkDeviceSize outBytes = rayCount * resultBytes;
    auto ensure = [&](vk::Buffer& b, VkDeviceSize bytes) {
      if (!b.buffer || b.size < bytes || b.size > 4 * bytes) {
        b = vk::Buffer{};
        b = context.createHostBuffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
      }
    };
    if (kind == gpu::RayKind::Camera) {
      // The listed pixels; the record goes to the view's uniform binding below.
      ensure(cameraBuffer, std::max<VkDeviceSize>(pixels.size_bytes(), 4));
      if (!pixels.empty()) std::memcpy(cameraBuffer.mapped, pixels.data(), pixels.size_bytes());
    } else if (kind == gpu::RayKind::Visibility) {
      ensure(visibilityBuffer, sourceBytes);
      writeSource(static_cast<std::byte*>(visibilityBuffer.mapped));
    } else {
      const VkDeviceSize rayBytes = rays.size() * sizeof(gpu::TraceRay);
      ensure(rayBuffer, rayBytes);
      std::memcpy(rayBuffer.mapped, rays.data(), rayBytes);
    }
    vk::Buffer& results =
        kind == gpu::RayKind::Any || kind == gpu::RayKind::Visibility ? occludedBuffer : hitBuffer;
    ensure(results, outBytes);
    // The shadow image and the view are bound whatever the kind: a placeholder where no trace made them yet.
    if (!image.image) image = context.createStorageImage(1, 1, 1);
    if (!viewBuffer.buffer) {
      viewBuffer = context.createHostBuffer(viewStride, VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
      std::memset(viewBuffer.mapped, 0, viewStride);
    }
    // A camera dispatch reads its record through the view's uniform binding (the shader's CameraViewBlock): from
    // a storage buffer, llvmpipe loaded it lane by lane for every ray. Layer traces write their own views.
    if (kind == gpu::RayKind::Camera) std::memcpy(viewBuffer.mapped, camera, sizeof(gpu::CameraRays));
    writeDescriptors();

    const std::uint64_t groups = (rayCount + gpu::VS_RAYS_PER_GROUP - 1) / gpu::VS_RAYS_PER_GROUP;
    const std::uint64_t groupsPerDispatch = info.maxWorkGroupCount[0];
    VkPipeline pipe = variant(TracePipelineOptions{.splitBindings = splitBindings(),
                                                   .boxTable = boxTableUploaded,
                                                   .depthAtCenter = false,
                                                   .rayKind = kind});
    TracePush push = scenePush();
    push.rayCount = static_cast<std::uint32_t>(rayCount);
    ensureQueries(2);
    context.submitAndWait([&](VkCommandBuffer cmd) {
      barrierBeforeDispatch(cmd);
      if (queryPool) {
        context.functions().vkCmdResetQueryPool(cmd, queryPool.get(), 0, 2);
        context.functions().vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queryPool.get(), 0);
      }
      context.functions().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipe);
      std::uint32_t viewOffset = 0;
      context.functions().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout.get(), 0, 1, &descriptorSet, 1,
                              &viewOffset);
      for (std::uint64_t first = 0; first < groups; first += groupsPerDispatch) {
        std::uint64_t n = std::min(groupsPerDispatch, groups - first);
        push.rayOffset = static_cast<std::uint32_t>(first * gpu::VS_RAYS_PER_GROUP);
        context.functions().vkCmdPushConstants(cmd, pipeline.layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, &push);
        context.functions().vkCmdDispatch(cmd, static_cast<std::uint32_t>(n), 1, 1);
        ++stats.dispatches;
      }
      if (queryPool) context.functions().vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queryPool.get(), 1);
      // The results to the host, and to a later pass on this device that reads them in place (lastCameraTrace).
      auto toHost = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
      toHost.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT | VK_ACCESS_SHADER_READ_BIT;
      context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                                               VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                                               &toHost, 0, nullptr, 0, nullptr);
    });
    if (out) std::memcpy(out, results.mapped, outBytes);  // null: the results stay on the device
    if (queryPool) stats.gpuMs = timestampMs(1)[0];
    stats.wallMs = msSince(t0);
    double ms = stats.gpuMs > 0.0 ? stats.gpuMs : stats.wallMs;
    if (ms > 0.0) stats.mraysPerSecond = double(stats.rays) / (ms * 1e3);
    return stats;
  }

  // Milliseconds between timestamp 0 and each of the next `count` (vkGetQueryPoolResults, waiting).
  std::vector<double> timestampMs(std::uint32_t count) {
    const VulkanDeviceInfo& info = context.info();
    std::vector<std::uint64_t> ts(count + 1, 0);
    vk::check(context.functions().vkGetQueryPoolResults(context.device(), queryPool.get(), 0, count + 1, ts.size() * sizeof(std::uint64_t),
                                    ts.data(), sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
              "vkGetQueryPoolResults");
    std::uint64_t mask =
        info.timestampValidBits >= 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << info.timestampValidBits) - 1;
    std::vector<double> ms(count);
    for (std::uint32_t i = 0; i < count; ++i)
      ms[i] = double(((ts[i + 1] & mask) - (ts[i] & mask)) & mask) * double(info.timestampPeriodNs) * 1e-6;
    return ms;
  }
};

VulkanTracer::VulkanTracer(const VulkanOptions& options) : impl_(std::make_unique<Impl>(options)) {}
VulkanTracer::~VulkanTracer() = default;
void VulkanTracer::upload(const SceneData& scene) {
  CallInProgress call(impl_->busy, "upload");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  impl_->upload(scene);
}
bool VulkanTracer::boxTableInUse() const { return impl_->boxTableUploaded; }
void VulkanTracer::upload(const SceneArrays& scene) {
  CallInProgress call(impl_->busy, "upload");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  impl_->uploadArrays(scene);
}
void VulkanTracer::update(const SceneData& scene, const SceneDelta& delta) {
  CallInProgress call(impl_->busy, "update");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  impl_->update(scene, delta);
}
std::uint64_t VulkanTracer::bytesUploaded() const { return impl_->uploadedBytes; }
int VulkanTracer::bufferGrowths() const { return impl_->growths; }
void VulkanTracer::uploadInstances(const SceneData& scene) {
  CallInProgress call(impl_->busy, "uploadInstances");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  impl_->uploadInstances(scene);
}
TraceStats VulkanTracer::trace(std::span<const gpu::TraceView> views, std::vector<ShadowLayer>& layers) {
  CallInProgress call(impl_->busy, "trace");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  return impl_->trace(views, layers);
}
TraceStats VulkanTracer::traceInto(std::span<const gpu::TraceView> views, const DeviceTexelTarget& target) {
  CallInProgress call(impl_->busy, "traceInto");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  std::vector<ShadowLayer> none;
  return impl_->trace(views, none, &target);
}
TraceStats VulkanTracer::traceClosest(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits) {
  CallInProgress call(impl_->busy, "traceClosest");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  if (hits.size() != rays.size())
    throwBadInput("traceClosest: " + std::to_string(hits.size()) + " hit records for " + std::to_string(rays.size()) +
                  " rays");
  return impl_->traceRays(gpu::RayKind::Closest, rays, hits.data(), sizeof(gpu::RayHit));
}
TraceStats VulkanTracer::traceAny(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded) {
  CallInProgress call(impl_->busy, "traceAny");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  if (occluded.size() != rays.size())
    throwBadInput("traceAny: " + std::to_string(occluded.size()) + " results for " + std::to_string(rays.size()) +
                  " rays");
  return impl_->traceRays(gpu::RayKind::Any, rays, occluded.data(), sizeof(std::uint32_t));
}
TraceStats VulkanTracer::traceCamera(const gpu::CameraRays& camera, std::span<const std::uint32_t> pixels,
                                     std::span<gpu::RayHit> hits) {
  CallInProgress call(impl_->busy, "traceCamera");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  const std::uint64_t count = checkCameraTrace(camera, pixels, hits.size());
  gpu::CameraRays record = camera;
  record.size.z = static_cast<std::uint32_t>(pixels.size());
  const TraceStats stats =
      impl_->traceRays(gpu::RayKind::Camera, {}, hits.data(), sizeof(gpu::RayHit), &record, pixels, count);
  impl_->cameraTraceRays = count;
  impl_->cameraTracePixels = std::uint64_t(camera.size.x) * std::uint64_t(camera.size.y);
  impl_->cameraTraceListed = !pixels.empty();
  impl_->cameraTraceRecord = record;
  return stats;
}
TraceStats VulkanTracer::traceCameraOnDevice(const gpu::CameraRays& camera) {
  CallInProgress call(impl_->busy, "traceCameraOnDevice");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  const std::uint64_t count = std::uint64_t(camera.size.x) * std::uint64_t(camera.size.y);
  checkCameraTrace(camera, {}, count);
  gpu::CameraRays record = camera;
  record.size.z = 0;
  const TraceStats stats = impl_->traceRays(gpu::RayKind::Camera, {}, nullptr, sizeof(gpu::RayHit), &record, {}, count);
  impl_->cameraTraceRays = count;
  impl_->cameraTracePixels = count;
  impl_->cameraTraceListed = false;
  impl_->cameraTraceRecord = record;
  return stats;
}

TraceStats VulkanTracer::traceVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                                         const DeviceReceivers& receivers, std::span<std::uint32_t> occluded) {
  CallInProgress call(impl_->busy, "traceVisibility");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  checkVisibilityTrace(frame, lights, {}, 0);  // the record and the lights
  if (receivers.buffer == VK_NULL_HANDLE) throwBadInput("traceVisibility: DeviceReceivers.buffer: none");
  const std::uint64_t taken = receivers.pixels.empty() ? receivers.pixelCount : receivers.pixels.size();
  const std::uint64_t count = taken * lights.size();
  if (receivers.pixelCount > std::numeric_limits<std::uint32_t>::max())
    throwBadInput("traceVisibility: DeviceReceivers.pixelCount: " + std::to_string(receivers.pixelCount) +
                  ", more than 2^32 pixels");
  if (count > std::numeric_limits<std::uint32_t>::max())
    throwBadInput("traceVisibility: " + std::to_string(taken) + " receivers x " + std::to_string(lights.size()) +
                  " lights: more than 2^32 rays in one call");
  if (occluded.size() != count)
    throwBadInput("traceVisibility: " + std::to_string(occluded.size()) + " answers for " + std::to_string(count) +
                  " rays (receivers x lights)");
  for (std::size_t k = 0; k < receivers.pixels.size(); ++k)
    if (receivers.pixels[k] >= receivers.pixelCount)
      throwBadInput("traceVisibility: DeviceReceivers.pixels[" + std::to_string(k) + "] = " +
                    std::to_string(receivers.pixels[k]) + " is not below pixelCount " +
                    std::to_string(receivers.pixelCount));
  gpu::VisibilityRays record = frame;
  record.counts = glm::uvec4(std::uint32_t(lights.size()), std::uint32_t(taken), 1u, receivers.pixels.empty() ? 0u : 1u);
  // The record, the lights and the listed pixels, in the order the shader reads them.
  auto write = [&](std::byte* to) {
    std::memcpy(to, &record, sizeof record);
    std::memcpy(to + sizeof record, lights.data(), lights.size_bytes());
    if (!receivers.pixels.empty())
      std::memcpy(to + sizeof record + lights.size_bytes(), receivers.pixels.data(), receivers.pixels.size_bytes());
  };
  impl_->deviceReceivers = receivers.buffer;
  struct Unbind {
    VkBuffer& b;
    ~Unbind() { b = VK_NULL_HANDLE; }
  } unbind{impl_->deviceReceivers};
  const TraceStats stats =
      impl_->traceRays(gpu::RayKind::Visibility, {}, occluded.data(), sizeof(std::uint32_t), nullptr, {}, count,
                       sizeof record + lights.size_bytes() + receivers.pixels.size_bytes(), write);
  if (count > 0)
    impl_->visibilityTrace = {impl_->occludedBuffer.get(), impl_->visibilityBuffer.get(), taken,
                              receivers.pixelCount, std::uint32_t(lights.size()), !receivers.pixels.empty()};
  return stats;
}
VisibilityTraceBuffers VulkanTracer::lastVisibilityTrace() const { return impl_->visibilityTrace; }
CameraTraceBuffers VulkanTracer::lastCameraTrace() const {
  if (impl_->cameraTraceRays == 0) return {};
  return {impl_->hitBuffer.get(), impl_->cameraBuffer.get(), impl_->cameraTraceRays, impl_->cameraTracePixels,
          impl_->cameraTraceListed, impl_->cameraTraceRecord};
}
TraceStats VulkanTracer::traceVisibility(const gpu::VisibilityRays& frame, std::span<const gpu::VisibilityLight> lights,
                                         std::span<const gpu::VisibilityReceiver> receivers,
                                         std::span<std::uint32_t> occluded) {
  CallInProgress call(impl_->busy, "traceVisibility");
  impl_->cameraTraceRays = 0;
  impl_->visibilityTrace = {};
  const std::uint64_t count = checkVisibilityTrace(frame, lights, receivers, occluded.size());
  gpu::VisibilityRays record = frame;
  record.counts = glm::uvec4(std::uint32_t(lights.size()), std::uint32_t(receivers.size()), 0u, 0u);
  // The record, the lights and the receivers, in the order the shader reads them.
  auto write = [&](std::byte* to) {
    std::memcpy(to, &record, sizeof record);
    std::memcpy(to + sizeof record, lights.data(), lights.size_bytes());
    std::memcpy(to + sizeof record + lights.size_bytes(), receivers.data(), receivers.size_bytes());
  };
  return impl_->traceRays(gpu::RayKind::Visibility, {}, occluded.data(), sizeof(std::uint32_t), nullptr, {}, count,
                          sizeof record + lights.size_bytes() + receivers.size_bytes(), write);
}
const VulkanDeviceInfo& VulkanTracer::device() const { return impl_->context.info(); }
const PipelineStats& VulkanTracer::pipelineStats() const { return impl_->pipelineStats; }
int VulkanTracer::bufferCount(SplitArray array) const {
  return std::max<int>(1, static_cast<int>(impl_->split[static_cast<int>(array)].buffers.size()));
}
std::vector<std::string> VulkanTracer::validationMessages() const { return impl_->context.validationMessages(); }
VulkanContext& VulkanTracer::context() { return impl_->context; }
std::shared_ptr<VulkanContext> VulkanTracer::sharedContext() { return impl_->contextOwner; }

}  // namespace vs
