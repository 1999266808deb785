// Embedding in an engine (README "Embedding in an engine"): a host that made its own Vulkan instance and device
// (validation layer and its own messenger on) hands them to a VulkanContext. Frames traced and lit on the
// host's device equal those of the library's own device bit for bit, every call goes through the host's
// vkGetInstanceProcAddr, a device lacking what the library needs is refused with one message naming each
// missing thing, and destroying the library's objects and then the host's leaves nothing for the layer's
// object tracker to report.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <vulkan/vulkan.h>

#include "compute/vulkan/vulkan_context.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/camera.h"
#include "lighting/host_gbuffer.h"
#include "lighting/renderer.h"
#include "lighting/shared/gbuffer_import.h"
#include "lighting/vulkan_shadows.h"
#include "lighting/scene_file.h"
#include "support/demo_frames.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"
#include "host_shadows.spv.h"  // tests/shaders/host_shadows.comp

// LeakSanitizer's switches, present only in sanitized builds (weak: null otherwise).
extern "C" void __lsan_disable() __attribute__((weak));
extern "C" void __lsan_enable() __attribute__((weak));

namespace vs {
namespace {

// What the host's getInstanceProcAddr wrapper does: it records every name the library asks for, counts queue
// submissions, and can make the device look as if it lacked things.
struct HostDispatch {
  std::mutex mutex;
  std::set<std::string> requested;
  std::atomic<int> submits{0};
  std::atomic<int> buffersCreated{0}, buffersDestroyed{0}, dispatches{0};
  std::atomic<int> pipelinesCreated{0}, pipelinesThroughHostCache{0};
  VkPipelineCache hostCache = VK_NULL_HANDLE;
  bool reportVulkan10 = false;
  bool hideR32fStorage = false;
  bool reportFourStorageBuffers = false;
  bool hideCmdDispatch = false;
  std::atomic<bool> failBufferCreation{false};  // vkCreateBuffer answers VK_ERROR_OUT_OF_DEVICE_MEMORY
  PFN_vkGetDeviceProcAddr getDeviceProcAddr = nullptr;
  PFN_vkQueueSubmit queueSubmit = nullptr;
  PFN_vkCreateBuffer createBuffer = nullptr;
  PFN_vkDestroyBuffer destroyBuffer = nullptr;
  PFN_vkCmdDispatch cmdDispatch = nullptr;
  PFN_vkCreateComputePipelines createComputePipelines = nullptr;
  PFN_vkGetPhysicalDeviceProperties getProperties = nullptr;
  PFN_vkGetPhysicalDeviceFormatProperties getFormatProperties = nullptr;

  void reset() {
    std::lock_guard lock(mutex);
    requested.clear();
    submits = buffersCreated = buffersDestroyed = dispatches = pipelinesCreated = pipelinesThroughHostCache = 0;
    hostCache = VK_NULL_HANDLE;
    reportVulkan10 = hideR32fStorage = reportFourStorageBuffers = hideCmdDispatch = false;
    failBufferCreation = false;
  }
  bool wasRequested(const std::string& name) {
    std::lock_guard lock(mutex);
    return requested.count(name) != 0;
  }
};

HostDispatch dispatch;

VKAPI_ATTR VkResult VKAPI_CALL countedQueueSubmit(VkQueue queue, std::uint32_t count, const VkSubmitInfo* submits,
                                                  VkFence fence) {
  ++dispatch.submits;
  return dispatch.queueSubmit(queue, count, submits, fence);
}

VKAPI_ATTR VkResult VKAPI_CALL countedCreateBuffer(VkDevice device, const VkBufferCreateInfo* info,
                                                   const VkAllocationCallbacks* allocator, VkBuffer* buffer) {
  if (dispatch.failBufferCreation) return VK_ERROR_OUT_OF_DEVICE_MEMORY;
  ++dispatch.buffersCreated;
  return dispatch.createBuffer(device, info, allocator, buffer);
}

VKAPI_ATTR void VKAPI_CALL countedDestroyBuffer(VkDevice device, VkBuffer buffer, const VkAllocationCallbacks* allocator) {
  if (buffer != VK_NULL_HANDLE) ++dispatch.buffersDestroyed;
  dispatch.destroyBuffer(device, buffer, allocator);
}

VKAPI_ATTR void VKAPI_CALL countedCmdDispatch(VkCommandBuffer cmd, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  ++dispatch.dispatches;
  dispatch.cmdDispatch(cmd, x, y, z);
}

VKAPI_ATTR VkResult VKAPI_CALL countedCreateComputePipelines(VkDevice device, VkPipelineCache cache, std::uint32_t count,
                                                             const VkComputePipelineCreateInfo* infos,
                                                             const VkAllocationCallbacks* allocator,
                                                             VkPipeline* pipelines) {
  dispatch.pipelinesCreated += int(count);
  if (cache != VK_NULL_HANDLE && cache == dispatch.hostCache) dispatch.pipelinesThroughHostCache += int(count);
  return dispatch.createComputePipelines(device, cache, count, infos, allocator, pipelines);
}

// The host's allocation callbacks: every allocation the driver makes for the library's objects, counted.
struct CountingAllocator {
  std::mutex mutex;
  std::map<void*, std::size_t> live;
  std::size_t total = 0;
};
CountingAllocator allocations;

VKAPI_ATTR void* VKAPI_CALL countedAlloc(void*, std::size_t size, std::size_t alignment, VkSystemAllocationScope) {
  void* p = std::aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
  if (!p) return nullptr;
  std::lock_guard lock(allocations.mutex);
  allocations.live[p] = size;
  ++allocations.total;
  return p;
}

VKAPI_ATTR void VKAPI_CALL countedFree(void*, void* p) {
  if (!p) return;
  {
    std::lock_guard lock(allocations.mutex);
    allocations.live.erase(p);
  }
  std::free(p);
}

VKAPI_ATTR void* VKAPI_CALL countedRealloc(void* user, void* old, std::size_t size, std::size_t alignment,
                                           VkSystemAllocationScope scope) {
  if (!old) return countedAlloc(user, size, alignment, scope);
  if (size == 0) {
    countedFree(user, old);
    return nullptr;
  }
  std::size_t oldSize = 0;
  {
    std::lock_guard lock(allocations.mutex);
    oldSize = allocations.live.at(old);
  }
  void* p = countedAlloc(user, size, alignment, scope);
  if (!p) return nullptr;
  std::memcpy(p, old, std::min(oldSize, size));
  countedFree(user, old);
  return p;
}

VkAllocationCallbacks hostAllocator() {
  VkAllocationCallbacks a{};
  a.pfnAllocation = &countedAlloc;
  a.pfnReallocation = &countedRealloc;
  a.pfnFree = &countedFree;
  return a;
}

VKAPI_ATTR void VKAPI_CALL maskedProperties(VkPhysicalDevice device, VkPhysicalDeviceProperties* properties) {
  dispatch.getProperties(device, properties);
  if (dispatch.reportVulkan10) properties->apiVersion = VK_API_VERSION_1_0;
  if (dispatch.reportFourStorageBuffers) properties->limits.maxPerStageDescriptorStorageBuffers = 4;
}

VKAPI_ATTR void VKAPI_CALL maskedFormatProperties(VkPhysicalDevice device, VkFormat format,
                                                  VkFormatProperties* properties) {
  dispatch.getFormatProperties(device, format, properties);
  if (dispatch.hideR32fStorage && format == VK_FORMAT_R32_SFLOAT)
    properties->optimalTilingFeatures &= ~VkFormatFeatureFlags(VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT);
}

VKAPI_ATTR PFN_vkVoidFunction VKAPI_CALL hostGetDeviceProcAddr(VkDevice device, const char* name) {
  {
    std::lock_guard lock(dispatch.mutex);
    dispatch.requested.insert(name);
  }
  const std::string n = name;
  if (n == "vkCmdDispatch" && dispatch.hideCmdDispatch) return nullptr;
  PFN_vkVoidFunction real = dispatch.getDeviceProcAddr(device, name);
  if (!real) return real;
  if (n == "vkQueueSubmit") {
    dispatch.queueSubmit = reinterpret_cast<PFN_vkQueueSubmit>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&countedQueueSubmit);
  }
  if (n == "vkCreateBuffer") {
    dispatch.createBuffer = reinterpret_cast<PFN_vkCreateBuffer>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&countedCreateBuffer);
  }
  if (n == "vkDestroyBuffer") {
    dispatch.destroyBuffer = reinterpret_cast<PFN_vkDestroyBuffer>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&countedDestroyBuffer);
  }
  if (n == "vkCmdDispatch") {
    dispatch.cmdDispatch = reinterpret_cast<PFN_vkCmdDispatch>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&countedCmdDispatch);
  }
  if (n == "vkCreateComputePipelines") {
    dispatch.createComputePipelines = reinterpret_cast<PFN_vkCreateComputePipelines>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&countedCreateComputePipelines);
  }
  return real;
}

VKAPI_ATTR PFN_vkVoidFunction VKAPI_CALL hostGetInstanceProcAddr(VkInstance instance, const char* name) {
  {
    std::lock_guard lock(dispatch.mutex);
    dispatch.requested.insert(name);
  }
  const std::string n = name;
  PFN_vkVoidFunction real = vkGetInstanceProcAddr(instance, name);
  if (n == "vkGetDeviceProcAddr") {
    dispatch.getDeviceProcAddr = reinterpret_cast<PFN_vkGetDeviceProcAddr>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&hostGetDeviceProcAddr);
  }
  if (n == "vkGetPhysicalDeviceProperties") {
    dispatch.getProperties = reinterpret_cast<PFN_vkGetPhysicalDeviceProperties>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&maskedProperties);
  }
  if (n == "vkGetPhysicalDeviceFormatProperties") {
    dispatch.getFormatProperties = reinterpret_cast<PFN_vkGetPhysicalDeviceFormatProperties>(real);
    return reinterpret_cast<PFN_vkVoidFunction>(&maskedFormatProperties);
  }
  return real;
}

// A host engine's Vulkan set-up, as an engine would write it: its own instance (validation layer and a
// messenger of its own), the first device with a compute queue and shaderFloat64, its own device and queue.
class HostEngine {
 public:
  explicit HostEngine(bool enableFloat64 = true) {
    auto messenger = messengerInfo();
    VkApplicationInfo app{};
    app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
    app.pApplicationName = "host engine";
    app.pEngineName = "host";
    app.apiVersion = VK_API_VERSION_1_1;
    const char* layer = "VK_LAYER_KHRONOS_validation";
    const char* extension = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
    VkInstanceCreateInfo ici{};
    ici.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    ici.pNext = &messenger;
    ici.pApplicationInfo = &app;
    ici.enabledLayerCount = 1;
    ici.ppEnabledLayerNames = &layer;
    ici.enabledExtensionCount = 1;
    ici.ppEnabledExtensionNames = &extension;
    if (vkCreateInstance(&ici, nullptr, &instance_) != VK_SUCCESS)
      throw std::runtime_error("the host engine cannot create an instance with the validation layer");
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    create(instance_, &messenger, nullptr, &messenger_);
    std::uint32_t count = 0;
    vkEnumeratePhysicalDevices(instance_, &count, nullptr);
    std::vector<VkPhysicalDevice> devices(count);
    vkEnumeratePhysicalDevices(instance_, &count, devices.data());
    for (VkPhysicalDevice d : devices) {
      VkPhysicalDeviceFeatures features{};
      vkGetPhysicalDeviceFeatures(d, &features);
      std::uint32_t families = 0;
      vkGetPhysicalDeviceQueueFamilyProperties(d, &families, nullptr);
      std::vector<VkQueueFamilyProperties> props(families);
      vkGetPhysicalDeviceQueueFamilyProperties(d, &families, props.data());
      for (std::uint32_t f = 0; f < families && physical_ == VK_NULL_HANDLE; ++f)
        if ((props[f].queueFlags & VK_QUEUE_COMPUTE_BIT) && features.shaderFloat64) {
          physical_ = d;
          family_ = f;
        }
    }
    if (physical_ == VK_NULL_HANDLE) throw std::runtime_error("the host engine found no device (lavapipe?)");
    float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{};
    qci.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
    qci.queueFamilyIndex = family_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    enabled_.shaderFloat64 = enableFloat64 ? VK_TRUE : VK_FALSE;
    VkDeviceCreateInfo dci{};
    dci.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    dci.pEnabledFeatures = &enabled_;
    if (vkCreateDevice(physical_, &dci, nullptr, &device_) != VK_SUCCESS)
      throw std::runtime_error("the host engine cannot create its device");
    vkGetDeviceQueue(device_, family_, 0, &queue_);
  }
  ~HostEngine() { destroy(); }
  HostEngine(const HostEngine&) = delete;
  HostEngine& operator=(const HostEngine&) = delete;

  // The documented order's last steps: the host's device, then its instance (after every voxshadow object).
  void destroy() {
    if (device_ != VK_NULL_HANDLE) vkDestroyDevice(device_, nullptr);
    device_ = VK_NULL_HANDLE;
    if (messenger_ != VK_NULL_HANDLE) {
      auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
      destroy(instance_, messenger_, nullptr);
    }
    messenger_ = VK_NULL_HANDLE;
    if (instance_ != VK_NULL_HANDLE) vkDestroyInstance(instance_, nullptr);
    instance_ = VK_NULL_HANDLE;
  }

  VulkanHostDevice handles(PFN_vkGetInstanceProcAddr getInstanceProcAddr = &hostGetInstanceProcAddr) const {
    VulkanHostDevice h;
    h.getInstanceProcAddr = getInstanceProcAddr;
    h.instance = instance_;
    h.instanceApiVersion = VK_API_VERSION_1_1;
    h.physicalDevice = physical_;
    h.device = device_;
    h.enabledFeatures = enabled_;
    h.queueFamily = family_;
    h.queue = queue_;
    return h;
  }
  VkDevice device() const { return device_; }
  VkPhysicalDevice physicalDevice() const { return physical_; }
  std::uint32_t queueFamily() const { return family_; }
  VkQueue queue() const { return queue_; }

  std::vector<std::string> messages() {
    std::lock_guard lock(mutex_);
    return messages_;
  }

 private:
  VkDebugUtilsMessengerCreateInfoEXT messengerInfo() {
    VkDebugUtilsMessengerCreateInfoEXT m{};
    m.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
    m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    m.pfnUserCallback = &HostEngine::onMessage;
    m.pUserData = this;
    return m;
  }
  static VKAPI_ATTR VkBool32 VKAPI_CALL onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT,
                                                  VkDebugUtilsMessageTypeFlagsEXT,
                                                  const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    auto* self = static_cast<HostEngine*>(user);
    std::lock_guard lock(self->mutex_);
    self->messages_.push_back(data && data->pMessage ? data->pMessage : "(no text)");
    return VK_FALSE;
  }

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  std::uint32_t family_ = 0;
  VkPhysicalDeviceFeatures enabled_{};
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::mutex mutex_;
  std::vector<std::string> messages_;
};

RenderOptions smallFrame() {
  RenderOptions o;
  o.width = 120;
  o.height = 68;
  return o;
}

struct FrameCopy {
  RenderedFrame frame;
  std::vector<ShadowLayer> layers;
};

FrameCopy renderOn(const std::shared_ptr<VulkanContext>& context, const Scene& scene) {
  VulkanOptions o;
  o.context = context;
  o.validation = true;
  std::unique_ptr<Tracer> tracer = makeVulkanTracer(o);
  FrameRenderer renderer(*tracer);
  FrameCopy out{renderer.render(scene, smallFrame()), renderer.layers()};
  if (!context) test::expectNoValidationMessages(*tracer);
  return out;
}

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Embedding, FramesOnTheHostsDeviceEqualTheLibrarysOwn) {
  dispatch.reset();
  const Scene scene = test::demoScene("embedding_frames", 64, 0.0f);
  const FrameCopy own = renderOn(nullptr, scene);
  HostEngine host;
  VkPipelineCacheCreateInfo pci{};
  pci.sType = VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO;
  ASSERT_EQ(vkCreatePipelineCache(host.device(), &pci, nullptr, &dispatch.hostCache), VK_SUCCESS);
  const VkAllocationCallbacks allocator = hostAllocator();
  const std::size_t allocationsBefore = allocations.total;
  {
    VulkanHostDevice handles = host.handles();
    handles.allocator = &allocator;
    handles.pipelineCache = dispatch.hostCache;
    const FrameCopy hosted = renderOn(std::make_shared<VulkanContext>(handles), scene);
    EXPECT_TRUE(test::sameBytes(hosted.frame.color, own.frame.color)) << "colour";
    EXPECT_TRUE(test::sameBytes(hosted.frame.gbuffer.texels, own.frame.gbuffer.texels)) << "G-buffer";
    EXPECT_TRUE(test::sameBytes(hosted.frame.shadowTerms, own.frame.shadowTerms)) << "shadow terms";
    ASSERT_EQ(hosted.layers.size(), own.layers.size());
    ASSERT_FALSE(own.layers.empty());
    for (std::size_t i = 0; i < own.layers.size(); ++i)
      EXPECT_TRUE(test::sameBytes(hosted.layers[i].texels, own.layers[i].texels)) << "layer " << i;
  }
  // Its calls went through the host's table: device functions from the host's vkGetDeviceProcAddr (the
  // submissions counted by the host's wrapper), instance functions from its vkGetInstanceProcAddr.
  // Calls a global prototype would make are not counted, so a create or destroy made beside the table shows as
  // an imbalance.
  EXPECT_TRUE(dispatch.wasRequested("vkGetPhysicalDeviceMemoryProperties"));
  EXPECT_GT(dispatch.submits.load(), 0);
  EXPECT_GT(dispatch.dispatches.load(), 0);
  EXPECT_GT(dispatch.buffersCreated.load(), 0);
  EXPECT_EQ(dispatch.buffersCreated.load(), dispatch.buffersDestroyed.load());
  // Every pipeline, the lighting pass's included, compiled through the host's cache.
  EXPECT_GT(dispatch.pipelinesCreated.load(), 0);
  EXPECT_EQ(dispatch.pipelinesThroughHostCache.load(), dispatch.pipelinesCreated.load());
  // The driver allocated through the host's callbacks, and freed all of it with the library's objects.
  EXPECT_GT(allocations.total, allocationsBefore);
  {
    std::lock_guard lock(allocations.mutex);
    EXPECT_TRUE(allocations.live.empty()) << allocations.live.size() << " allocations still live";
  }
  vkDestroyPipelineCache(host.device(), dispatch.hostCache, nullptr);
  host.destroy();
  const std::vector<std::string> messages = host.messages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages, the first: " << messages.front();
}

TEST(Embedding, ADeviceLackingWhatTheLibraryNeedsIsRefusedNamingEachThing) {
  dispatch.reset();
  {
    HostEngine host(/*enableFloat64=*/false);
    const std::string refusal = errorOf([&] { VulkanContext context(host.handles()); });
    EXPECT_NE(refusal.find("cannot run voxshadow"), std::string::npos) << refusal;
    EXPECT_NE(refusal.find("the feature shaderFloat64 (supported, but not enabled when the VkDevice was created)"),
              std::string::npos)
        << refusal;
    host.destroy();
    EXPECT_TRUE(host.messages().empty()) << "a refusal creates nothing: " << host.messages().front();
  }
  HostEngine host;
  dispatch.reportVulkan10 = true;
  dispatch.hideR32fStorage = true;
  dispatch.reportFourStorageBuffers = true;
  dispatch.hideCmdDispatch = true;
  VulkanHostDevice handles = host.handles();
  handles.instanceApiVersion = VK_API_VERSION_1_0;
  const std::string refusal = errorOf([&] { VulkanContext context(handles); });
  for (const char* missing :
       {"Vulkan 1.1 on the instance (VulkanHostDevice::instanceApiVersion is 1.0)",
        "Vulkan 1.1 on the device (it reports 1.0)", "VK_FORMAT_R32_SFLOAT as an optimal-tiling storage image",
        "maxPerStageDescriptorStorageBuffers >= 30 (the device has 4)", "the entry point vkCmdDispatch"})
    EXPECT_NE(refusal.find(missing), std::string::npos) << missing << "\n" << refusal;
  EXPECT_EQ(refusal.find("shaderFloat64"), std::string::npos) << refusal;
  dispatch.reset();

  const std::string nulls = errorOf([] { VulkanContext context(VulkanHostDevice{}); });
  EXPECT_NE(nulls.find("VulkanHostDevice: null getInstanceProcAddr, instance, physicalDevice, device, queue"),
            std::string::npos)
      << nulls;
  host.destroy();
  EXPECT_TRUE(host.messages().empty()) << host.messages().front();
}

// The host engine's own Vulkan calls: a failure is the test's, not the library's.
void checkHostCall(VkResult r, const char* call) {
  if (r != VK_SUCCESS) throw std::runtime_error(std::string("the host engine's ") + call + " failed");
}

// Memory of the first type that `req` allows with every flag of `want`, on the host engine's device.
VkDeviceMemory allocateHostMemory(const HostEngine& host, VkDevice device, const VkMemoryRequirements& req,
                                  VkMemoryPropertyFlags want, const char* what) {
  VkPhysicalDeviceMemoryProperties props{};
  vkGetPhysicalDeviceMemoryProperties(host.physicalDevice(), &props);
  std::uint32_t type = props.memoryTypeCount;
  for (std::uint32_t t = 0; t < props.memoryTypeCount && type == props.memoryTypeCount; ++t)
    if ((req.memoryTypeBits & (1u << t)) && (props.memoryTypes[t].propertyFlags & want) == want) type = t;
  if (type == props.memoryTypeCount) throw std::runtime_error(std::string("the host engine found no memory for ") + what);
  VkMemoryAllocateInfo mai{};
  mai.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = type;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  checkHostCall(vkAllocateMemory(device, &mai, nullptr, &memory), "vkAllocateMemory");
  return memory;
}

// A host engine's own compute pass (tests/shaders/host_shadows.comp) on its own device: its G-buffer in a buffer
// of its own, voxshadow's shadow buffers bound after its own bindings, one shadow term per pixel and light.
class HostShadowPass {
 public:
  explicit HostShadowPass(const HostEngine& host) : host_(host), device_(host.device()) {
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (std::uint32_t b = 0; b < 8; ++b) {
      VkDescriptorSetLayoutBinding binding{};
      binding.binding = b;
      // shadows.glsl's +1 (binding 4 here): the view records as a uniform texel buffer.
      binding.descriptorType = b == 4 ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      binding.descriptorCount = 1;
      binding.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
      bindings.push_back(binding);
    }
    VkDescriptorSetLayoutCreateInfo dli{};
    dli.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    dli.bindingCount = std::uint32_t(bindings.size());
    dli.pBindings = bindings.data();
    check(vkCreateDescriptorSetLayout(device_, &dli, nullptr, &setLayout_), "vkCreateDescriptorSetLayout");
    const VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, 2 * sizeof(std::uint32_t)};
    VkPipelineLayoutCreateInfo pli{};
    pli.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &setLayout_;
    pli.pushConstantRangeCount = 1;
    pli.pPushConstantRanges = &range;
    check(vkCreatePipelineLayout(device_, &pli, nullptr, &layout_), "vkCreatePipelineLayout");
    VkShaderModuleCreateInfo smi{};
    smi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    smi.codeSize = sizeof host_shadows;
    smi.pCode = host_shadows;
    check(vkCreateShaderModule(device_, &smi, nullptr, &module_), "vkCreateShaderModule");
    VkComputePipelineCreateInfo cpi{};
    cpi.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    cpi.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cpi.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cpi.stage.module = module_;
    cpi.stage.pName = "main";
    cpi.layout = layout_;
    check(vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &cpi, nullptr, &pipeline_), "vkCreateComputePipelines");
    const std::array<VkDescriptorPoolSize, 2> sizes{{{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 7},
                                                     {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 1}}};
    VkDescriptorPoolCreateInfo dpi{};
    dpi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    dpi.maxSets = 1;
    dpi.poolSizeCount = std::uint32_t(sizes.size());
    dpi.pPoolSizes = sizes.data();
    check(vkCreateDescriptorPool(device_, &dpi, nullptr, &pool_), "vkCreateDescriptorPool");
    VkDescriptorSetAllocateInfo dai{};
    dai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    dai.descriptorPool = pool_;
    dai.descriptorSetCount = 1;
    dai.pSetLayouts = &setLayout_;
    check(vkAllocateDescriptorSets(device_, &dai, &set_), "vkAllocateDescriptorSets");
    VkCommandPoolCreateInfo cpci{};
    cpci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    cpci.queueFamilyIndex = host.queueFamily();
    check(vkCreateCommandPool(device_, &cpci, nullptr, &commandPool_), "vkCreateCommandPool");
  }
  ~HostShadowPass() {
    for (auto& [buffer, memory] : buffers_) {
      vkDestroyBuffer(device_, buffer, nullptr);
      vkFreeMemory(device_, memory, nullptr);
    }
    vkDestroyCommandPool(device_, commandPool_, nullptr);
    vkDestroyDescriptorPool(device_, pool_, nullptr);
    vkDestroyPipeline(device_, pipeline_, nullptr);
    vkDestroyShaderModule(device_, module_, nullptr);
    vkDestroyPipelineLayout(device_, layout_, nullptr);
    vkDestroyDescriptorSetLayout(device_, setLayout_, nullptr);
  }
  HostShadowPass(const HostShadowPass&) = delete;
  HostShadowPass& operator=(const HostShadowPass&) = delete;

  // Each pixel's shadow term per light, from the host's copy of the frame's G-buffer and voxshadow's buffers.
  std::vector<float> run(const VulkanShadows& shadows, const std::vector<gpu::GBufferTexel>& gbuffer) {
    const std::size_t pixels = gbuffer.size();
    const std::size_t terms = pixels * shadows.lightCount;
    auto [gbufferBuffer, gbufferMemory] = hostBuffer(pixels * sizeof(gpu::GBufferTexel));
    auto [termBuffer, termMemory] = hostBuffer(terms * sizeof(float));
    void* mapped = nullptr;
    check(vkMapMemory(device_, gbufferMemory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, gbuffer.data(), pixels * sizeof(gpu::GBufferTexel));
    vkUnmapMemory(device_, gbufferMemory);
    const std::array<VkBuffer, 8> bound{gbufferBuffer, shadows.visibility, termBuffer, shadows.texels, VK_NULL_HANDLE,
                                        shadows.lights, shadows.momentsPositive, shadows.momentsNegative};
    std::array<VkDescriptorBufferInfo, 8> infos{};
    std::array<VkWriteDescriptorSet, 8> writes{};
    for (std::uint32_t b = 0; b < 8; ++b) {
      infos[b] = {bound[b], 0, VK_WHOLE_SIZE};
      writes[b].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
      writes[b].dstSet = set_;
      writes[b].dstBinding = b;
      writes[b].descriptorCount = 1;
      writes[b].descriptorType = b == 4 ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      if (b == 4) writes[b].pTexelBufferView = &shadows.viewTexels;
      else writes[b].pBufferInfo = &infos[b];
    }
    vkUpdateDescriptorSets(device_, std::uint32_t(writes.size()), writes.data(), 0, nullptr);
    VkCommandBufferAllocateInfo cai{};
    cai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    cai.commandPool = commandPool_;
    cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cai.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    check(vkAllocateCommandBuffers(device_, &cai, &cmd), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_, 0, 1, &set_, 0, nullptr);
    const std::uint32_t push[2] = {std::uint32_t(pixels), shadows.lightCount};
    vkCmdPushConstants(cmd, layout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, push);
    vkCmdDispatch(cmd, std::uint32_t((pixels + 63) / 64), 1, 1);
    VkMemoryBarrier toHost{};
    toHost.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    toHost.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0,
                         nullptr, 0, nullptr);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    VkSubmitInfo submit{};
    submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    check(vkQueueSubmit(host_.queue(), 1, &submit, VK_NULL_HANDLE), "vkQueueSubmit");
    check(vkQueueWaitIdle(host_.queue()), "vkQueueWaitIdle");
    vkFreeCommandBuffers(device_, commandPool_, 1, &cmd);
    std::vector<float> out(terms);
    check(vkMapMemory(device_, termMemory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    std::memcpy(out.data(), mapped, terms * sizeof(float));
    vkUnmapMemory(device_, termMemory);
    return out;
  }

 private:
  static void check(VkResult r, const char* call) { checkHostCall(r, call); }
  std::pair<VkBuffer, VkDeviceMemory> hostBuffer(std::size_t bytes) {
    VkBufferCreateInfo bci{};
    bci.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    bci.size = std::max<std::size_t>(bytes, 16);
    bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    VkBuffer buffer = VK_NULL_HANDLE;
    check(vkCreateBuffer(device_, &bci, nullptr, &buffer), "vkCreateBuffer");
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, buffer, &req);
    VkDeviceMemory memory = allocateHostMemory(
        host_, device_, req, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
        "a host-visible buffer");
    check(vkBindBufferMemory(device_, buffer, memory, 0), "vkBindBufferMemory");
    buffers_.push_back({buffer, memory});
    return {buffer, memory};
  }

  const HostEngine& host_;
  VkDevice device_;
  VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkShaderModule module_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  VkCommandPool commandPool_ = VK_NULL_HANDLE;
  std::vector<std::pair<VkBuffer, VkDeviceMemory>> buffers_;
};

// The host's shader, including the installed lighting/shared/shadows.glsl and reading the frame's buffers in
// place (nothing read back), gives every pixel's shadow term bit for bit as the library's lighting pass: the
// demo's three lights (a sun's pcf5 cascades with contact rays, a spot's poisson16, a point light's cube faces),
// after a first frame and after a camera move that scrolls the cascades; and with every light's filter EVSM (the
// moment store's buffers).
TEST(Embedding, AHostShaderGetsTheLibrarysShadowTermsFromItsBuffers) {
  dispatch.reset();
  Scene scene = test::demoScene("embedding_host_shadows", 64, 0.0f);
  HostEngine host;
  {
    VulkanOptions o;
    o.context = std::make_shared<VulkanContext>(host.handles());
    o.validation = true;
    std::unique_ptr<Tracer> tracer = makeVulkanTracer(o);
    FrameRenderer renderer(*tracer);
    HostShadowPass pass(host);
    // The demo with every light's filter EVSM: its terms read the moment store's two buffers.
    SceneDesc evsmDesc = parseSceneFile(writeDemoWorld(test::scratchDir("embedding_host_shadows_evsm")).back());
    for (LightDesc& l : evsmDesc.lights)
      if (l.shadow) {
        l.shadow->resolution = 64;
        l.shadow->filter = ShadowFilter::Evsm;
      }
    const Scene evsm = Scene::load(std::move(evsmDesc));
    for (int step = 0; step < 3; ++step) {
      if (step == 1) {
        CameraDesc camera = *scene.desc().camera;
        camera.position += glm::vec3(3.0f, 0.0f, 1.5f);
        camera.target += glm::vec3(3.0f, 0.0f, 1.5f);
        scene.setCamera(camera);
      }
      const RenderedFrame& frame = renderer.render(step == 2 ? evsm : scene, smallFrame());
      const VulkanShadows shadows = renderer.vulkanShadows();
      EXPECT_EQ(shadows.lightCount, 3u);
      EXPECT_EQ(shadows.viewCount, std::uint32_t(frame.views.size()));
      EXPECT_EQ(shadows.width * shadows.height, std::uint32_t(frame.gbuffer.texels.size()));
      const std::vector<float> terms = pass.run(shadows, frame.gbuffer.texels);
      ASSERT_EQ(terms.size(), frame.shadowTerms.size());
      std::size_t differ = 0, shadowed = 0;
      for (std::size_t i = 0; i < terms.size(); ++i) {
        differ += std::memcmp(&terms[i], &frame.shadowTerms[i], sizeof(float)) != 0;
        shadowed += frame.shadowTerms[i] < 1.0f;
      }
      EXPECT_EQ(differ, 0u) << "step " << step << ": of " << terms.size() << " terms";
      EXPECT_GT(shadowed, terms.size() / 20) << "step " << step << ": too few shadowed terms to show anything";
    }
    // A renderer on a CPU tracer has nothing on a device.
    std::unique_ptr<Tracer> cpu = makeCpuTracer();
    FrameRenderer cpuRenderer(*cpu);
    (void)cpuRenderer.render(scene, smallFrame());
    EXPECT_NE(errorOf([&] { (void)cpuRenderer.vulkanShadows(); }).find("not a Vulkan tracer"), std::string::npos);
    // Nor does a frame with ray-traced shadows.
    RenderOptions raytraced = smallFrame();
    raytraced.shadows = ShadowSource::Raytraced;
    (void)renderer.render(scene, raytraced);
    EXPECT_NE(errorOf([&] { (void)renderer.vulkanShadows(); }).find("no shadow maps"), std::string::npos);
  }
  host.destroy();
  const std::vector<std::string> messages = host.messages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages, the first: " << messages.front();
}

// The host engine's own G-buffer images (depth, normal, albedo) on its device: made from texels it computed,
// uploaded and left in SHADER_READ_ONLY_OPTIMAL, as a deferred renderer's G-buffer pass would leave them.
class HostGBufferImages {
 public:
  HostGBufferImages(const HostEngine& host, int width, int height) : host_(host), device_(host.device()),
                                                                     width_(width), height_(height) {
    VkCommandPoolCreateInfo cpci{};
    cpci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    cpci.queueFamilyIndex = host.queueFamily();
    check(vkCreateCommandPool(device_, &cpci, nullptr, &commandPool_), "vkCreateCommandPool");
  }
  ~HostGBufferImages() {
    for (const Made& m : made_) {
      vkDestroyImageView(device_, m.view, nullptr);
      vkDestroyImage(device_, m.image, nullptr);
      vkFreeMemory(device_, m.memory, nullptr);
    }
    vkDestroyCommandPool(device_, commandPool_, nullptr);
  }
  HostGBufferImages(const HostGBufferImages&) = delete;
  HostGBufferImages& operator=(const HostGBufferImages&) = delete;

  // An image of `format` holding `texels` (width x height, row 0 first), sampled in SHADER_READ_ONLY_OPTIMAL.
  template <typename T>
  HostImage image(VkFormat format, const std::vector<T>& texels) {
    Made m;
    VkImageCreateInfo ici{};
    ici.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
    ici.imageType = VK_IMAGE_TYPE_2D;
    ici.format = format;
    ici.extent = {std::uint32_t(width_), std::uint32_t(height_), 1};
    ici.mipLevels = 1;
    ici.arrayLayers = 1;
    ici.samples = VK_SAMPLE_COUNT_1_BIT;
    ici.tiling = VK_IMAGE_TILING_OPTIMAL;
    ici.usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
    ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    check(vkCreateImage(device_, &ici, nullptr, &m.image), "vkCreateImage");
    VkMemoryRequirements req{};
    vkGetImageMemoryRequirements(device_, m.image, &req);
    m.memory = allocate(req, 0);
    check(vkBindImageMemory(device_, m.image, m.memory, 0), "vkBindImageMemory");
    // Staging: a host-visible buffer with the texels.
    const VkDeviceSize bytes = texels.size() * sizeof(T);
    VkBufferCreateInfo bci{};
    bci.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    bci.size = bytes;
    bci.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
    VkBuffer staging = VK_NULL_HANDLE;
    check(vkCreateBuffer(device_, &bci, nullptr, &staging), "vkCreateBuffer");
    vkGetBufferMemoryRequirements(device_, staging, &req);
    VkDeviceMemory stagingMemory =
        allocate(req, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    check(vkBindBufferMemory(device_, staging, stagingMemory, 0), "vkBindBufferMemory");
    void* mapped = nullptr;
    check(vkMapMemory(device_, stagingMemory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, texels.data(), bytes);
    vkUnmapMemory(device_, stagingMemory);
    VkCommandBufferAllocateInfo cai{};
    cai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    cai.commandPool = commandPool_;
    cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cai.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    check(vkAllocateCommandBuffers(device_, &cai, &cmd), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
    VkImageMemoryBarrier toCopy{};
    toCopy.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    toCopy.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    toCopy.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    toCopy.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
    toCopy.srcQueueFamilyIndex = toCopy.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    toCopy.image = m.image;
    toCopy.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0,
                         nullptr, 1, &toCopy);
    VkBufferImageCopy copy{};
    copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    copy.imageExtent = ici.extent;
    vkCmdCopyBufferToImage(cmd, staging, m.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &copy);
    // To the layout the host states; the library's own barrier makes the copy visible to its pass.
    VkImageMemoryBarrier toRead = toCopy;
    toRead.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    toRead.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    toRead.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
    toRead.newLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr, 0,
                         nullptr, 1, &toRead);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    VkSubmitInfo submit{};
    submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    check(vkQueueSubmit(host_.queue(), 1, &submit, VK_NULL_HANDLE), "vkQueueSubmit");
    check(vkQueueWaitIdle(host_.queue()), "vkQueueWaitIdle");
    vkFreeCommandBuffers(device_, commandPool_, 1, &cmd);
    vkDestroyBuffer(device_, staging, nullptr);
    vkFreeMemory(device_, stagingMemory, nullptr);
    VkImageViewCreateInfo vci{};
    vci.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
    vci.image = m.image;
    vci.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vci.format = format;
    vci.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    check(vkCreateImageView(device_, &vci, nullptr, &m.view), "vkCreateImageView");
    made_.push_back(m);
    return HostImage{m.view, format, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  }

 private:
  struct Made {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
  };
  static void check(VkResult r, const char* call) { checkHostCall(r, call); }
  VkDeviceMemory allocate(const VkMemoryRequirements& req, VkMemoryPropertyFlags want) {
    return allocateHostMemory(host_, device_, req, want, "its image");
  }

  const HostEngine& host_;
  VkDevice device_;
  int width_, height_;
  VkCommandPool commandPool_ = VK_NULL_HANDLE;
  std::vector<Made> made_;
};

// The host's camera matrices for the library's camera, as a Vulkan engine writes them: a right-handed view
// (the camera looks down -z) and an infinite perspective with reversed depth (1 at the near plane, 0 at infinity)
// whose y points down the image.
void hostMatrices(const CameraFrame& c, glm::dmat4& worldToView, glm::dmat4& viewToClip) {
  worldToView = glm::dmat4(1.0);
  for (int i = 0; i < 3; ++i) {
    worldToView[i][0] = c.right[i];
    worldToView[i][1] = c.up[i];
    worldToView[i][2] = -c.forward[i];
  }
  worldToView[3] = glm::dvec4(-glm::dot(c.right, c.position), -glm::dot(c.up, c.position),
                              glm::dot(c.forward, c.position), 1.0);
  const double f = 1.0 / c.tanHalfFovY;
  viewToClip = glm::dmat4(0.0);
  viewToClip[0][0] = f / c.aspect;
  viewToClip[1][1] = -f;
  viewToClip[2][3] = -1.0;
  viewToClip[3][2] = c.nearPlane;
}

float relativeGap(const glm::vec3& a, const glm::vec3& b, float scale) {
  return glm::length(glm::dvec3(a) - glm::dvec3(b)) / (1.0f + scale);
}

// A host engine's own G-buffer, drawn by its own pass (here: the library's frame turned into the images a
// deferred renderer keeps, depth computed from each surface point with the host's own matrices in double),
// lights the frame: the imported texels are the surfaces the library itself traced to float precision, the
// device's import is the shared function's (vsImportTexel on the host, same inputs), and the frame's shadow
// terms and colour equal those of the library's own G-buffer but where the reconstructed position moved a
// receiver across a shadow's edge. No primary ray is traced. Bad input is refused naming the field, changing
// nothing; a CPU tracer is refused.
TEST(Embedding, TheHostsGBufferLightsTheFrameAsTheLibrarysOwn) {
  dispatch.reset();
  const Scene scene = test::demoScene("embedding_host_gbuffer", 64, 0.0f);
  HostEngine host;
  {
    VulkanOptions o;
    o.context = std::make_shared<VulkanContext>(host.handles());
    o.validation = true;
    std::unique_ptr<Tracer> tracer = makeVulkanTracer(o);
    FrameRenderer renderer(*tracer);
    const RenderOptions plain = smallFrame();
    const RenderedFrame own = renderer.render(scene, plain);
    const int width = own.width, height = own.height;
    const std::size_t pixels = own.gbuffer.texels.size();
    const CameraFrame camera = cameraFrame(*scene.desc().camera, width, height);

    HostGBuffer g;
    g.width = width;
    g.height = height;
    hostMatrices(camera, g.worldToView, g.viewToClip);
    g.skyDepth = 0.0f;
    std::vector<float> depth(pixels, 0.0f);
    std::vector<glm::vec4> normals(pixels, glm::vec4(0.0f)), viewNormals(pixels, glm::vec4(0.5f)),
        albedo(pixels, glm::vec4(0.0f));
    std::size_t hits = 0;
    for (std::size_t i = 0; i < pixels; ++i) {
      const gpu::GBufferTexel& t = own.gbuffer.texels[i];
      if (t.info.w == 0u) continue;
      ++hits;
      g.voxelSize = t.normal.w;  // the demo's voxels are all one size
      const glm::dvec4 view = g.worldToView * glm::dvec4(glm::dvec3(glm::vec3(t.position)), 1.0);
      const glm::dvec4 clip = g.viewToClip * view;
      depth[i] = float(clip.z / clip.w);
      normals[i] = glm::vec4(glm::vec3(t.normal), 0.0f);
      const glm::dvec3 n = glm::dmat3(g.worldToView) * glm::dvec3(glm::vec3(t.normal));
      viewNormals[i] = glm::vec4(glm::vec3(n * 0.5 + 0.5), 0.0f);
      albedo[i] = glm::vec4(glm::vec3(t.albedo), 1.0f);
    }
    ASSERT_GT(hits, pixels / 4);
    HostGBufferImages images(host, width, height);
    g.depth = images.image(VK_FORMAT_R32_SFLOAT, depth);
    g.normal = images.image(VK_FORMAT_R32G32B32A32_SFLOAT, normals);
    g.albedo = images.image(VK_FORMAT_R32G32B32A32_SFLOAT, albedo);
    const HostImage viewNormalImage = images.image(VK_FORMAT_R32G32B32A32_SFLOAT, viewNormals);

    RenderOptions withHost = plain;
    withHost.hostGBuffer = &g;
    const RenderedFrame hosted = renderer.render(scene, withHost);
    EXPECT_EQ(hosted.stats.primaryRays, 0u);
    ASSERT_EQ(hosted.gbuffer.texels.size(), pixels);
    // The device's import is the shared function's, and the surfaces are the library's own.
    const gpu::HostGBufferRecord record = hostGBufferRecord(g, width, height);
    std::size_t importGaps = 0, surfaceGaps = 0;
    for (std::size_t i = 0; i < pixels; ++i) {
      const gpu::GBufferTexel& a = hosted.gbuffer.texels[i];
      const gpu::GBufferTexel& b = own.gbuffer.texels[i];
      const gpu::GBufferTexel c = gpu::vsImportTexel(record, std::uint32_t(i), depth[i], normals[i], albedo[i]);
      const float distance = std::abs(b.position.w);
      if (a.info.w != c.info.w || relativeGap(glm::vec3(a.position), glm::vec3(c.position), distance) > 1e-6f ||
          std::abs(a.position.w - c.position.w) > 1e-6f * (1.0f + distance) ||
          relativeGap(glm::vec3(a.normal), glm::vec3(c.normal), 0.0f) > 1e-6f || a.normal.w != c.normal.w ||
          !test::sameBytes(std::vector<glm::vec4>{a.albedo}, std::vector<glm::vec4>{c.albedo}))
        ++importGaps;
      if (a.info.w != b.info.w ||
          (b.info.w != 0u && (relativeGap(glm::vec3(a.position), glm::vec3(b.position), distance) > 1e-5f ||
                              std::abs(a.position.w - b.position.w) > 1e-5f * (1.0f + distance) ||
                              relativeGap(glm::vec3(a.normal), glm::vec3(b.normal), 0.0f) > 1e-6f ||
                              glm::vec3(a.albedo) != glm::vec3(b.albedo))))
        ++surfaceGaps;
    }
    EXPECT_EQ(importGaps, 0u) << "of " << pixels << " texels";
    EXPECT_EQ(surfaceGaps, 0u) << "of " << pixels << " texels";
    ASSERT_EQ(hosted.shadowTerms.size(), own.shadowTerms.size());
    std::size_t termsDiffer = 0, shadowed = 0, colorsDiffer = 0;
    for (std::size_t i = 0; i < own.shadowTerms.size(); ++i) {
      termsDiffer += hosted.shadowTerms[i] != own.shadowTerms[i];
      shadowed += own.shadowTerms[i] < 1.0f;
    }
    for (std::size_t i = 0; i < pixels; ++i) colorsDiffer += glm::any(glm::greaterThan(
        glm::abs(hosted.color[i] - own.color[i]), glm::vec4(1e-3f * (1.0f + glm::length(own.color[i])))));
    EXPECT_GT(shadowed, own.shadowTerms.size() / 20);
    std::cout << "host G-buffer: " << termsDiffer << " of " << own.shadowTerms.size() << " shadow terms and "
              << colorsDiffer << " of " << pixels << " colours differ from the library's own G-buffer's\n";
    EXPECT_LE(termsDiffer, own.shadowTerms.size() / 200);
    EXPECT_LE(colorsDiffer, pixels / 100);

    // View-space normals stored unsigned: the same world normals.
    HostGBuffer viewSpace = g;
    viewSpace.normal = viewNormalImage;
    viewSpace.normalSpace = HostNormalSpace::View;
    viewSpace.normalEncoding = HostNormalEncoding::Unsigned;
    withHost.hostGBuffer = &viewSpace;
    const RenderedFrame turned = renderer.render(scene, withHost);
    std::size_t normalGaps = 0;
    for (std::size_t i = 0; i < pixels; ++i)
      normalGaps += relativeGap(glm::vec3(turned.gbuffer.texels[i].normal), glm::vec3(hosted.gbuffer.texels[i].normal),
                                0.0f) > 1e-5f;
    EXPECT_EQ(normalGaps, 0u);

    // Back to the library's own G-buffer: its frame again, bit for bit.
    const RenderedFrame back = renderer.render(scene, plain);
    EXPECT_TRUE(test::sameBytes(back.gbuffer.texels, own.gbuffer.texels));
    EXPECT_TRUE(test::sameBytes(back.shadowTerms, own.shadowTerms));
    EXPECT_TRUE(test::sameBytes(back.color, own.color));

    // Refused, naming the field, and changing nothing: the plain frame after them is a still frame.
    auto refused = [&](HostGBuffer bad) {
      RenderOptions o = plain;
      o.hostGBuffer = &bad;
      return errorOf([&] { (void)renderer.render(scene, o); });
    };
    HostGBuffer bad = g;
    bad.depth.view = VK_NULL_HANDLE;
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.depth.view"), std::string::npos) << refused(bad);
    bad = g;
    bad.width = width + 1;
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.width"), std::string::npos) << refused(bad);
    bad = g;
    bad.height = height - 1;
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.height"), std::string::npos) << refused(bad);
    bad = g;
    bad.normal.format = VK_FORMAT_R32G32B32A32_UINT;
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.normal.format"), std::string::npos) << refused(bad);
    bad = g;
    bad.albedo.layout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.albedo.layout"), std::string::npos) << refused(bad);
    bad = g;
    bad.worldToView[0][0] = 1.01;
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.worldToView"), std::string::npos) << refused(bad);
    bad = g;
    bad.viewToClip = glm::dmat4(0.0);
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.viewToClip"), std::string::npos) << refused(bad);
    bad = g;
    bad.voxelSize = std::nan("");
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.voxelSize"), std::string::npos) << refused(bad);
    bad = g;
    bad.normalSpace = static_cast<HostNormalSpace>(7);
    EXPECT_NE(refused(bad).find("RenderOptions.hostGBuffer.normalSpace"), std::string::npos) << refused(bad);
    const RenderedFrame still = renderer.render(scene, plain);
    EXPECT_FALSE(still.stats.full);
    EXPECT_EQ(still.stats.texelsTraced + still.stats.primaryRays + still.stats.visibilityRays + still.stats.pixelsShaded, 0u);
    EXPECT_EQ(still.stats.bytesUploaded + still.stats.bytesReadBack, 0u);
    EXPECT_TRUE(test::sameBytes(still.color, own.color));

    // The engine's view matrix computed in float (its rotation orthonormal to float precision only) is taken,
    // and gives the same frame to float precision.
    HostGBuffer floatView = g;
    floatView.worldToView = glm::dmat4(glm::mat4(g.worldToView));
    withHost.hostGBuffer = &floatView;
    const RenderedFrame inFloat = renderer.render(scene, withHost);
    EXPECT_EQ(inFloat.stats.primaryRays, 0u);
    std::size_t floatDiffer = 0;
    for (std::size_t i = 0; i < own.shadowTerms.size(); ++i) floatDiffer += inFloat.shadowTerms[i] != own.shadowTerms[i];
    EXPECT_LE(floatDiffer, own.shadowTerms.size() / 200);

    std::unique_ptr<Tracer> cpu = makeCpuTracer();
    FrameRenderer cpuRenderer(*cpu);
    EXPECT_NE(errorOf([&] { (void)cpuRenderer.render(scene, withHost); }).find("needs the Vulkan backend"),
              std::string::npos);
  }
  host.destroy();
  const std::vector<std::string> messages = host.messages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages, the first: " << messages.front();
}

// A scene update that fails part-way on the device (here: no memory for its staging buffer, after the box table's
// codes were already recomputed on the host) leaves the Vulkan tracer refusing to trace, saying why, rather than
// tracing a half-updated scene; a whole upload() then gives the edited scene's hits, as a new tracer's.
TEST(Embedding, AnUpdateThatFailsPartWayAsksForAWholeUpload) {
  dispatch.reset();
  Scene scene = test::demoScene("embedding_failed_update", 64, 0.0f);
  HostEngine host;
  {
    VulkanOptions o;
    o.context = std::make_shared<VulkanContext>(host.handles());
    o.validation = true;
    VulkanTracer tracer(o);
    tracer.upload(scene.data());
    std::size_t ground = scene.assetObjects()[0].first;
    for (std::size_t a = 0; a < scene.desc().assets.size(); ++a)
      if (scene.desc().assets[a].name == "ground") ground = scene.assetObjects()[a].first;
    const std::uint64_t revision = scene.revision();
    const VoxelBox bounds = scene.objects()[ground].brickmap.bounds();
    const glm::ivec3 at = (bounds.min + bounds.max) / 2;
    scene.fillVoxels(ground, VoxelBox{at - glm::ivec3(6), at + glm::ivec3(6)}, 0);
    std::vector<const SceneChange*> changes;
    ASSERT_TRUE(scene.changesSince(revision, changes));
    SceneDelta delta;
    for (const SceneChange* c : changes) delta.merge(c->arrays);
    ASSERT_FALSE(delta.editedBricks.empty());
    dispatch.failBufferCreation = true;
    const std::string failed = errorOf([&] { tracer.update(scene.data(), delta); });
    dispatch.failBufferCreation = false;
    EXPECT_NE(failed, "(no error)");
    const CameraFrame camera = cameraFrame(*scene.desc().camera, 96, 54);
    const gpu::CameraRays rays = cameraRaysOf(camera);
    std::vector<gpu::RayHit> hits(std::size_t(camera.width) * std::size_t(camera.height));
    const std::string refused = errorOf([&] { tracer.traceCamera(rays, {}, hits); });
    EXPECT_NE(refused.find("failed part-way"), std::string::npos) << refused;
    tracer.upload(scene.data());
    tracer.traceCamera(rays, {}, hits);
    VulkanOptions fresh;
    fresh.validation = true;
    VulkanTracer reference(fresh);
    reference.upload(scene.data());
    std::vector<gpu::RayHit> expected(hits.size());
    reference.traceCamera(rays, {}, expected);
    EXPECT_TRUE(test::sameBytes(hits, expected));
    EXPECT_TRUE(reference.validationMessages().empty());
  }
  host.destroy();
  const std::vector<std::string> messages = host.messages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages, the first: " << messages.front();
}

TEST(Embedding, DestroyingInTheDocumentedOrderLeaksNothing) {
  dispatch.reset();
  const Scene scene = test::demoScene("embedding_destroy", 32, 0.0f);
  {
    HostEngine host;
    (void)renderOn(std::make_shared<VulkanContext>(host.handles()), scene);
    // Every voxshadow object is gone; the host's device is still the host's, and usable.
    EXPECT_EQ(vkDeviceWaitIdle(host.device()), VK_SUCCESS);
    VkFenceCreateInfo fci{};
    fci.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    VkFence fence = VK_NULL_HANDLE;
    ASSERT_EQ(vkCreateFence(host.device(), &fci, nullptr, &fence), VK_SUCCESS);
    vkDestroyFence(host.device(), fence, nullptr);
    host.destroy();
    const std::vector<std::string> messages = host.messages();
    EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages, the first: " << messages.front();
  }
  // The same check sees an object left behind: a pipeline layout the host forgets is reported when its device
  // goes. Its driver memory is leaked on purpose: made while LeakSanitizer (in sanitized builds) looks away.
  HostEngine host;
  VkPipelineLayoutCreateInfo lci{};
  lci.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
  VkPipelineLayout forgotten = VK_NULL_HANDLE;
  if (__lsan_disable) __lsan_disable();
  const VkResult made = vkCreatePipelineLayout(host.device(), &lci, nullptr, &forgotten);
  if (__lsan_enable) __lsan_enable();
  ASSERT_EQ(made, VK_SUCCESS);
  host.destroy();
  const std::vector<std::string> messages = host.messages();
  ASSERT_FALSE(messages.empty()) << "the object tracker reported nothing for a leaked VkPipelineLayout";
  EXPECT_NE(messages.front().find("VkPipelineLayout"), std::string::npos) << messages.front();
}

}  // namespace
}  // namespace vs
