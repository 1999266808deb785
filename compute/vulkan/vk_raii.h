// vk_raii.h: move-only owners of Vulkan handles, so every exit path (including exceptions) releases them.
#ifndef VOXSHADOW_VK_RAII_H
#define VOXSHADOW_VK_RAII_H

#include <cstddef>
#include <cstdint>
#include <utility>

#include <vulkan/vulkan.h>

#include "compute/vulkan/vk_functions.h"

namespace vs::vk {

// A zeroed Vulkan info struct with its sType set (brace-init with only sType trips -Wmissing-field-initializers).
template <typename T>
T make(VkStructureType type) {
  T value{};
  value.sType = type;
  return value;
}

// Throws vs::Error(Runtime) naming the call and the VkResult when result is not VK_SUCCESS.
void check(VkResult result, const char* call);
const char* resultName(VkResult result);

// How each device-level handle type is destroyed, through the context's table.
template <typename T>
struct DeviceDestroyer;
#define VS_VK_DESTROYER(Type, fn)                                                                   \
  template <>                                                                                       \
  struct DeviceDestroyer<Type> {                                                                    \
    static void destroy(const Functions& f, VkDevice device, Type handle) { f.fn(device, handle, f.allocator); } \
  }
VS_VK_DESTROYER(VkBuffer, vkDestroyBuffer);
VS_VK_DESTROYER(VkDeviceMemory, vkFreeMemory);
VS_VK_DESTROYER(VkImage, vkDestroyImage);
VS_VK_DESTROYER(VkImageView, vkDestroyImageView);
VS_VK_DESTROYER(VkSampler, vkDestroySampler);
VS_VK_DESTROYER(VkBufferView, vkDestroyBufferView);
VS_VK_DESTROYER(VkShaderModule, vkDestroyShaderModule);
VS_VK_DESTROYER(VkPipeline, vkDestroyPipeline);
VS_VK_DESTROYER(VkPipelineLayout, vkDestroyPipelineLayout);
VS_VK_DESTROYER(VkPipelineCache, vkDestroyPipelineCache);
VS_VK_DESTROYER(VkDescriptorSetLayout, vkDestroyDescriptorSetLayout);
VS_VK_DESTROYER(VkDescriptorPool, vkDestroyDescriptorPool);
VS_VK_DESTROYER(VkCommandPool, vkDestroyCommandPool);
VS_VK_DESTROYER(VkQueryPool, vkDestroyQueryPool);
VS_VK_DESTROYER(VkFence, vkDestroyFence);
#undef VS_VK_DESTROYER

// One device-level handle and the device that destroys it. Precondition: the device and the table outlive it.
template <typename T>
class DeviceObject {
 public:
  DeviceObject() = default;
  DeviceObject(const Functions& functions, VkDevice device, T handle)
      : functions_(&functions), device_(device), handle_(handle) {}
  DeviceObject(const DeviceObject&) = delete;
  DeviceObject& operator=(const DeviceObject&) = delete;
  DeviceObject(DeviceObject&& o) noexcept
      : functions_(std::exchange(o.functions_, nullptr)),
        device_(std::exchange(o.device_, VK_NULL_HANDLE)),
        handle_(std::exchange(o.handle_, VK_NULL_HANDLE)) {}
  DeviceObject& operator=(DeviceObject&& o) noexcept {
    if (this != &o) {
      reset();
      functions_ = std::exchange(o.functions_, nullptr);
      device_ = std::exchange(o.device_, VK_NULL_HANDLE);
      handle_ = std::exchange(o.handle_, VK_NULL_HANDLE);
    }
    return *this;
  }
  ~DeviceObject() { reset(); }

  void reset() {
    if (handle_ != VK_NULL_HANDLE) DeviceDestroyer<T>::destroy(*functions_, device_, handle_);
    handle_ = VK_NULL_HANDLE;
  }
  T get() const { return handle_; }
  explicit operator bool() const { return handle_ != VK_NULL_HANDLE; }

 private:
  const Functions* functions_ = nullptr;
  VkDevice device_ = VK_NULL_HANDLE;
  T handle_ = VK_NULL_HANDLE;
};

using UniqueBuffer = DeviceObject<VkBuffer>;
using UniqueMemory = DeviceObject<VkDeviceMemory>;
using UniqueImage = DeviceObject<VkImage>;
using UniqueImageView = DeviceObject<VkImageView>;
using UniqueSampler = DeviceObject<VkSampler>;
using UniqueBufferView = DeviceObject<VkBufferView>;
using UniqueShaderModule = DeviceObject<VkShaderModule>;
using UniquePipeline = DeviceObject<VkPipeline>;
using UniquePipelineLayout = DeviceObject<VkPipelineLayout>;
using UniquePipelineCache = DeviceObject<VkPipelineCache>;
using UniqueDescriptorSetLayout = DeviceObject<VkDescriptorSetLayout>;
using UniqueDescriptorPool = DeviceObject<VkDescriptorPool>;
using UniqueCommandPool = DeviceObject<VkCommandPool>;
using UniqueQueryPool = DeviceObject<VkQueryPool>;
using UniqueFence = DeviceObject<VkFence>;

class UniqueInstance {
 public:
  UniqueInstance() = default;
  // `destroy` is the instance's own vkDestroyInstance (loaded for it).
  UniqueInstance(VkInstance instance, PFN_vkDestroyInstance destroy) : instance_(instance), destroy_(destroy) {}
  UniqueInstance(const UniqueInstance&) = delete;
  UniqueInstance& operator=(const UniqueInstance&) = delete;
  UniqueInstance(UniqueInstance&& o) noexcept
      : instance_(std::exchange(o.instance_, VK_NULL_HANDLE)), destroy_(std::exchange(o.destroy_, nullptr)) {}
  UniqueInstance& operator=(UniqueInstance&& o) noexcept {
    if (this != &o) {
      reset();
      instance_ = std::exchange(o.instance_, VK_NULL_HANDLE);
      destroy_ = std::exchange(o.destroy_, nullptr);
    }
    return *this;
  }
  ~UniqueInstance() { reset(); }
  void reset() {
    if (instance_ != VK_NULL_HANDLE && destroy_) destroy_(instance_, nullptr);
    instance_ = VK_NULL_HANDLE;
  }
  VkInstance get() const { return instance_; }

 private:
  VkInstance instance_ = VK_NULL_HANDLE;
  PFN_vkDestroyInstance destroy_ = nullptr;
};

// Waits for the device to go idle before destroying it, so no queued work outlives it.
class UniqueDevice {
 public:
  UniqueDevice() = default;
  UniqueDevice(const Functions& functions, VkDevice device) : functions_(&functions), device_(device) {}
  UniqueDevice(const UniqueDevice&) = delete;
  UniqueDevice& operator=(const UniqueDevice&) = delete;
  UniqueDevice(UniqueDevice&& o) noexcept
      : functions_(std::exchange(o.functions_, nullptr)), device_(std::exchange(o.device_, VK_NULL_HANDLE)) {}
  UniqueDevice& operator=(UniqueDevice&& o) noexcept {
    if (this != &o) {
      reset();
      functions_ = std::exchange(o.functions_, nullptr);
      device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    }
    return *this;
  }
  ~UniqueDevice() { reset(); }
  void reset() {
    if (device_ != VK_NULL_HANDLE) {
      if (functions_->vkDeviceWaitIdle) functions_->vkDeviceWaitIdle(device_);
      if (functions_->vkDestroyDevice) functions_->vkDestroyDevice(device_, functions_->allocator);
    }
    device_ = VK_NULL_HANDLE;
  }
  VkDevice get() const { return device_; }

 private:
  const Functions* functions_ = nullptr;
  VkDevice device_ = VK_NULL_HANDLE;
};

// The debug-utils messenger; destroyed through the instance's extension entry point.
class UniqueMessenger {
 public:
  UniqueMessenger() = default;
  // `destroy` is the instance's vkDestroyDebugUtilsMessengerEXT.
  UniqueMessenger(VkInstance instance, VkDebugUtilsMessengerEXT messenger, PFN_vkDestroyDebugUtilsMessengerEXT destroy)
      : instance_(instance), messenger_(messenger), destroy_(destroy) {}
  UniqueMessenger(const UniqueMessenger&) = delete;
  UniqueMessenger& operator=(const UniqueMessenger&) = delete;
  UniqueMessenger(UniqueMessenger&& o) noexcept
      : instance_(std::exchange(o.instance_, VK_NULL_HANDLE)),
        messenger_(std::exchange(o.messenger_, VK_NULL_HANDLE)),
        destroy_(std::exchange(o.destroy_, nullptr)) {}
  UniqueMessenger& operator=(UniqueMessenger&& o) noexcept {
    if (this != &o) {
      reset();
      instance_ = std::exchange(o.instance_, VK_NULL_HANDLE);
      messenger_ = std::exchange(o.messenger_, VK_NULL_HANDLE);
      destroy_ = std::exchange(o.destroy_, nullptr);
    }
    return *this;
  }
  ~UniqueMessenger() { reset(); }
  void reset() {
    if (messenger_ != VK_NULL_HANDLE && destroy_) destroy_(instance_, messenger_, nullptr);
    messenger_ = VK_NULL_HANDLE;
  }

 private:
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  PFN_vkDestroyDebugUtilsMessengerEXT destroy_ = nullptr;
};

// A primary command buffer, returned to its pool on destruction. Precondition: the pool outlives it.
class UniqueCommandBuffer {
 public:
  UniqueCommandBuffer() = default;
  UniqueCommandBuffer(const Functions& functions, VkDevice device, VkCommandPool pool, VkCommandBuffer cmd)
      : functions_(&functions), device_(device), pool_(pool), cmd_(cmd) {}
  UniqueCommandBuffer(const UniqueCommandBuffer&) = delete;
  UniqueCommandBuffer& operator=(const UniqueCommandBuffer&) = delete;
  UniqueCommandBuffer(UniqueCommandBuffer&& o) noexcept
      : functions_(std::exchange(o.functions_, nullptr)),
        device_(std::exchange(o.device_, VK_NULL_HANDLE)),
        pool_(std::exchange(o.pool_, VK_NULL_HANDLE)),
        cmd_(std::exchange(o.cmd_, VK_NULL_HANDLE)) {}
  UniqueCommandBuffer& operator=(UniqueCommandBuffer&& o) noexcept {
    if (this != &o) {
      reset();
      functions_ = std::exchange(o.functions_, nullptr);
      device_ = std::exchange(o.device_, VK_NULL_HANDLE);
      pool_ = std::exchange(o.pool_, VK_NULL_HANDLE);
      cmd_ = std::exchange(o.cmd_, VK_NULL_HANDLE);
    }
    return *this;
  }
  ~UniqueCommandBuffer() { reset(); }
  void reset() {
    if (cmd_ != VK_NULL_HANDLE) functions_->vkFreeCommandBuffers(device_, pool_, 1, &cmd_);
    cmd_ = VK_NULL_HANDLE;
  }
  VkCommandBuffer get() const { return cmd_; }

 private:
  const Functions* functions_ = nullptr;
  VkDevice device_ = VK_NULL_HANDLE;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkCommandBuffer cmd_ = VK_NULL_HANDLE;
};

// A buffer with its own memory; `mapped` is non-null for host-visible buffers (persistently mapped).
struct Buffer {
  UniqueBuffer buffer;
  UniqueMemory memory;
  VkDeviceSize size = 0;
  void* mapped = nullptr;
  VkBuffer get() const { return buffer.get(); }
};

// A 2D-array image with its memory and a view over all layers.
struct Image {
  UniqueImage image;
  UniqueMemory memory;
  UniqueImageView view;
  VkExtent3D extent{0, 0, 1};
  std::uint32_t layers = 0;
  VkImage get() const { return image.get(); }
};

// A compute pipeline and everything it owns.
struct ComputePipeline {
  UniqueDescriptorSetLayout setLayout;
  UniquePipelineLayout layout;
  UniquePipeline pipeline;
};

}  // namespace vs::vk

#endif
