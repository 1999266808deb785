// Embedding in an engine (README "Embedding in an engine"): a host that made its own Vulkan instance and device
// (validation layer and its own messenger on) hands them to a VulkanContext. Frames traced and lit on the
// host's device equal those of the library's own device bit for bit, every call goes through the host's
// vkGetInstanceProcAddr, a device lacking what the library needs is refused with one message naming each
// missing thing, and destroying the library's objects and then the host's leaves nothing for the layer's
// object tracker to report.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <vulkan/vulkan.h>

#include "compute/vulkan/vulkan_context.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/renderer.h"
#include "support/demo_frames.h"
#include "voxel/error.h"

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
        "maxPerStageDescriptorStorageBuffers >= 29 (the device has 4)", "the entry point vkCmdDispatch"})
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
