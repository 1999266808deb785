// vulkan_context.h: the Vulkan instance, the chosen device and its compute queue, validation capture,
// and the buffer/image/submit primitives the trace passes are built from.
#ifndef VOXSHADOW_VULKAN_CONTEXT_H
#define VOXSHADOW_VULKAN_CONTEXT_H

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <vulkan/vulkan.h>

#include "compute/vulkan/vk_functions.h"
#include "compute/vulkan/vk_raii.h"

namespace vs {

enum class VulkanDeviceType { Discrete, Integrated, Virtual, Cpu, Other };
const char* toString(VulkanDeviceType type);

struct VulkanDeviceInfo {
  std::uint32_t index = 0;  // position in vkEnumeratePhysicalDevices order
  std::string name;
  VulkanDeviceType type = VulkanDeviceType::Other;
  std::string driverName;  // e.g. "llvmpipe"; empty when the driver does not report it
  std::string driverInfo;
  std::uint32_t apiVersion = 0;
  std::uint32_t driverVersion = 0;
  std::array<std::uint8_t, VK_UUID_SIZE> pipelineCacheUuid{};
  std::uint64_t maxStorageBufferRange = 0;
  std::uint64_t maxTexelBufferElements = 0;
  std::uint64_t minUniformBufferOffsetAlignment = 1;
  std::uint64_t maxMemoryAllocationSize = 0;
  std::uint64_t deviceLocalBytes = 0;  // size of the largest device-local heap
  std::uint32_t maxPerStageStorageBuffers = 0;
  std::uint32_t maxImageDimension2D = 0;
  std::uint32_t maxImageArrayLayers = 0;
  std::array<std::uint32_t, 3> maxWorkGroupCount{};
  std::uint32_t timestampValidBits = 0;  // of the compute queue family; 0: no GPU timings
  float timestampPeriodNs = 0.0f;
  std::uint32_t computeQueueFamily = 0;
  bool hasComputeQueue = false;
  // The trace shader needs it (compute/shared/lanes.h, VS_DIV): Intel's Xe and Arc GPUs and MoltenVK lack it.
  bool shaderFloat64 = false;
};

// Every physical device the Vulkan loader sees, in enumeration order.
// Throws vs::Error(Runtime) when Vulkan itself cannot start; an empty list when it starts with no device.
std::vector<VulkanDeviceInfo> listVulkanDevices();

// The device a choice picks: deviceIndex >= 0 picks that index; else a non-empty deviceName picks the first
// device whose name contains it (case-insensitive); else the best by type (discrete > integrated > virtual >
// CPU) among those that also have shaderFloat64, so that a GPU without it leaves the choice to lavapipe (a
// device named by index or name is taken as named, and VulkanContext refuses it naming the feature). Only
// devices with a compute queue qualify. Throws vs::Error(Runtime) "no Vulkan device found ..." when
// the list is empty, vs::Error(BadInput) when the index or name matches nothing (the message lists devices).
std::size_t chooseVulkanDevice(const std::vector<VulkanDeviceInfo>& devices, int deviceIndex,
                               const std::string& deviceName);

struct VulkanContextOptions {
  int deviceIndex = -1;
  std::string deviceName;
  // Unset: on when the environment has VOXSHADOW_VALIDATION=1.
  std::optional<bool> validation;
};

// A host engine's Vulkan objects, for a VulkanContext that works on the host's device (README "Embedding in an
// engine"). The library calls Vulkan only through `getInstanceProcAddr` (and the vkGetDeviceProcAddr it
// returns), creates its own objects on `device` with `allocator`, and destroys only those: every handle here
// stays the host's and must outlive every voxshadow object made on the context.
struct VulkanHostDevice {
  PFN_vkGetInstanceProcAddr getInstanceProcAddr = nullptr;  // the host's: its loader, layers or wrapper
  VkInstance instance = VK_NULL_HANDLE;
  // VkApplicationInfo::apiVersion the instance was created with (instance-level 1.1 calls need >= 1.1).
  std::uint32_t instanceApiVersion = 0;
  VkPhysicalDevice physicalDevice = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  // The features the host enabled in vkCreateDevice (the library cannot query them): shaderFloat64 is needed.
  VkPhysicalDeviceFeatures enabledFeatures{};
  std::uint32_t queueFamily = 0;   // a family with VK_QUEUE_COMPUTE_BIT, that `queue` belongs to
  // Where the library submits the work of its calls and waits for it (a queue the host leaves to the library,
  // or one the host does not use from another thread while a voxshadow call runs: Vulkan requires queue
  // submissions to be externally synchronised).
  VkQueue queue = VK_NULL_HANDLE;
  const VkAllocationCallbacks* allocator = nullptr;  // optional: for every object the library creates
  VkPipelineCache pipelineCache = VK_NULL_HANDLE;    // optional: compiles go through it (no cache file)
};

// What a device lacks for voxshadow, one entry per missing requirement (an empty list: it has all of them),
// each naming the requirement and what the device has: API version, feature, queue, format, limit, entry point.
// `functions` must hold the instance-level entry points; device-level ones missing are listed when
// `deviceFunctionsMissing` names them.
std::vector<std::string> missingVulkanRequirements(const vk::Functions& functions, VkPhysicalDevice physicalDevice,
                                                   std::uint32_t instanceApiVersion,
                                                   const VkPhysicalDeviceFeatures& enabledFeatures,
                                                   std::uint32_t queueFamily,
                                                   const std::vector<std::string>& entryPointsMissing);

// Owns (standalone) or borrows (a host's device) the instance, device and compute queue; owns one command pool. Not copyable or movable (the debug
// messenger points at it). Threads: submitAndWait and upload run one after another (a mutex over the queue,
// the pool, the fence and the staging buffer), validationMessages and shared may be called from any thread;
// the create* calls make objects of their own and may too (Vulkan's object creation is thread-safe).
class VulkanContext {
 public:
  // Throws vs::Error(Runtime) when no device exists, when validation is requested but
  // VK_LAYER_KHRONOS_validation or VK_EXT_debug_utils is missing, or when device creation fails.
  explicit VulkanContext(const VulkanContextOptions& options = {});
  // On a host engine's device. Throws vs::Error(BadInput) naming the null handle or function when one is
  // missing, and vs::Error(Runtime) listing every requirement the device lacks (missingVulkanRequirements),
  // before it creates anything. Destroys nothing of the host's.
  explicit VulkanContext(const VulkanHostDevice& host);
  ~VulkanContext();
  VulkanContext(const VulkanContext&) = delete;
  VulkanContext& operator=(const VulkanContext&) = delete;

  const VulkanDeviceInfo& info() const { return info_; }
  VkInstance instance() const { return instanceHandle_; }
  VkPhysicalDevice physicalDevice() const { return physical_; }
  VkDevice device() const { return deviceHandle_; }
  VkQueue queue() const { return queue_; }
  // The entry points every Vulkan call of the library goes through (loaded for this instance and device).
  const vk::Functions& functions() const { return fn_; }
  // True when made from a VulkanHostDevice: the instance and device are the host's.
  bool onHostDevice() const { return onHostDevice_; }
  // The host's pipeline cache (VK_NULL_HANDLE: none given, or standalone).
  VkPipelineCache hostPipelineCache() const { return hostPipelineCache_; }
  bool validationEnabled() const { return validation_; }
  // Every warning and error the validation layer (or loader) reported so far, oldest first.
  std::vector<std::string> validationMessages() const;

  // Buffer creation. Preconditions: size > 0. Throws vs::Error(Runtime) when no memory type fits.
  vk::Buffer createDeviceBuffer(VkDeviceSize size, VkBufferUsageFlags usage);
  vk::Buffer createHostBuffer(VkDeviceSize size, VkBufferUsageFlags usage);  // host-visible, coherent, mapped
  // A texel view of the whole buffer. Precondition: it was created with a texel-buffer usage and its size is a
  // multiple of the format's texel size, at most maxTexelBufferElements texels.
  vk::UniqueBufferView createTexelView(const vk::Buffer& buffer, VkFormat format);
  // An R32F 2D-array storage image in VK_IMAGE_LAYOUT_GENERAL. Preconditions: width, height, layers > 0.
  vk::Image createStorageImage(std::uint32_t width, std::uint32_t height, std::uint32_t layers);

  // Records through `record` into a fresh command buffer, submits it and waits for completion. The queue,
  // command pool and fence are the context's: submissions from several threads run one after another (a
  // mutex; `record` may submit again from the same thread).
  void submitAndWait(const std::function<void(VkCommandBuffer)>& record);
  // Copies bytes into a device buffer through a staging buffer, as submitAndWait does (one at a time).
  // Precondition: offset + size <= dst.size.
  void upload(const vk::Buffer& dst, VkDeviceSize offset, const void* data, VkDeviceSize size);

  vk::UniqueShaderModule createShaderModule(const std::uint32_t* code, std::size_t bytes);
  // A compute pipeline layout over one descriptor set layout, with a push block of `pushBytes` (0: none).
  vk::UniquePipelineLayout createPipelineLayout(VkDescriptorSetLayout setLayout, std::uint32_t pushBytes);
  // A compute pipeline of `shader`'s "main" with `layout`, its specialisation constants given (null: the
  // shader's defaults), through `cache` (VK_NULL_HANDLE: the host's pipeline cache on a host's device, else none).
  vk::UniquePipeline createComputePipeline(VkShaderModule shader, VkPipelineLayout layout,
                                           const VkSpecializationInfo* constants = nullptr,
                                           VkPipelineCache cache = VK_NULL_HANDLE);

  // An object every user of this device shares (compiled pipelines), named by `key`: the one an earlier call
  // made, else a new one from `make`, whose type is the caller's. The context keeps it until the context itself
  // is destroyed, and destroys it first, while the device is still there: a renderer made for one frame on a
  // tracer that outlives it (a test's fresh renderer, a tool's renderer per view) finds the pipelines the last
  // one compiled. The object must therefore hold no owning reference to the context (a cycle that would keep
  // both alive); a plain reference is safe. `make` must not call shared() (the lock is held).
  std::shared_ptr<void> shared(const std::string& key, const std::function<std::shared_ptr<void>()>& make);

 private:
  vk::UniqueCommandBuffer allocateCommandBuffer();
  std::uint32_t findMemoryType(std::uint32_t typeBits, VkMemoryPropertyFlags required,
                               VkMemoryPropertyFlags preferred) const;
  vk::Buffer createBuffer(VkDeviceSize size, VkBufferUsageFlags usage, VkMemoryPropertyFlags required,
                          VkMemoryPropertyFlags preferred, bool map);
  static VKAPI_ATTR VkBool32 VKAPI_CALL onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                  VkDebugUtilsMessageTypeFlagsEXT types,
                                                  const VkDebugUtilsMessengerCallbackDataEXT* data, void* user);

  void createPoolAndFence();

  vk::Functions fn_;  // first: every handle below is destroyed through it
  bool onHostDevice_ = false;
  VkPipelineCache hostPipelineCache_ = VK_NULL_HANDLE;
  VkInstance instanceHandle_ = VK_NULL_HANDLE;
  VkDevice deviceHandle_ = VK_NULL_HANDLE;
  bool validation_ = false;
  std::mutex sharedMutex_;
  std::map<std::string, std::shared_ptr<void>> shared_;
  mutable std::mutex messagesMutex_;
  std::vector<std::string> messages_;
  vk::UniqueInstance instance_;  // standalone only
  vk::UniqueMessenger messenger_;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VulkanDeviceInfo info_;
  VkPhysicalDeviceMemoryProperties memory_{};
  vk::UniqueDevice device_;  // standalone only
  VkQueue queue_ = VK_NULL_HANDLE;
  vk::UniqueCommandPool commandPool_;
  vk::UniqueFence fence_;
  vk::Buffer staging_;
  // Guards the queue, the command pool, the fence and the staging buffer (Vulkan leaves their
  // synchronisation to the application).
  std::recursive_mutex submitMutex_;
};

}  // namespace vs

#endif
