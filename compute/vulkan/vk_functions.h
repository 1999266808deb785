// vk_functions.h: the Vulkan entry points voxshadow calls, loaded per context through a vkGetInstanceProcAddr
// (the loader's, or a host engine's), so that the library calls exactly what the host would: its layers, its
// wrappers, its loader. Nothing in the library calls a Vulkan prototype for instance or device work.
#ifndef VOXSHADOW_VK_FUNCTIONS_H
#define VOXSHADOW_VK_FUNCTIONS_H

#include <string>
#include <vector>

#include <vulkan/vulkan.h>

namespace vs::vk {

// Instance-level entry points: loaded with vkGetInstanceProcAddr(instance, name).
#define VS_VK_INSTANCE_FUNCTIONS(X)          \
  X(vkDestroyInstance)                       \
  X(vkEnumeratePhysicalDevices)              \
  X(vkGetPhysicalDeviceProperties)           \
  X(vkGetPhysicalDeviceProperties2)          \
  X(vkGetPhysicalDeviceFeatures)             \
  X(vkGetPhysicalDeviceFormatProperties)     \
  X(vkGetPhysicalDeviceMemoryProperties)     \
  X(vkGetPhysicalDeviceQueueFamilyProperties) \
  X(vkCreateDevice)                          \
  X(vkGetDeviceProcAddr)

// Device-level entry points: loaded with vkGetDeviceProcAddr(device, name), so that a call goes straight to
// the device's driver (through its layers) without the loader's trampoline.
#define VS_VK_DEVICE_FUNCTIONS(X)   \
  X(vkDestroyDevice)                \
  X(vkDeviceWaitIdle)               \
  X(vkGetDeviceQueue)               \
  X(vkQueueSubmit)                  \
  X(vkCreateFence)                  \
  X(vkDestroyFence)                 \
  X(vkResetFences)                  \
  X(vkWaitForFences)                \
  X(vkCreateBuffer)                 \
  X(vkDestroyBuffer)                \
  X(vkCreateBufferView)             \
  X(vkDestroyBufferView)            \
  X(vkCreateImage)                  \
  X(vkDestroyImage)                 \
  X(vkCreateImageView)              \
  X(vkDestroyImageView)             \
  X(vkCreateSampler)                \
  X(vkDestroySampler)               \
  X(vkAllocateMemory)               \
  X(vkFreeMemory)                   \
  X(vkMapMemory)                    \
  X(vkBindBufferMemory)             \
  X(vkBindImageMemory)              \
  X(vkGetBufferMemoryRequirements)  \
  X(vkGetImageMemoryRequirements)   \
  X(vkCreateShaderModule)           \
  X(vkDestroyShaderModule)          \
  X(vkCreatePipelineCache)          \
  X(vkDestroyPipelineCache)         \
  X(vkGetPipelineCacheData)         \
  X(vkCreatePipelineLayout)         \
  X(vkDestroyPipelineLayout)        \
  X(vkCreateComputePipelines)       \
  X(vkDestroyPipeline)              \
  X(vkCreateDescriptorSetLayout)    \
  X(vkDestroyDescriptorSetLayout)   \
  X(vkCreateDescriptorPool)         \
  X(vkDestroyDescriptorPool)        \
  X(vkAllocateDescriptorSets)       \
  X(vkUpdateDescriptorSets)         \
  X(vkCreateCommandPool)            \
  X(vkDestroyCommandPool)           \
  X(vkAllocateCommandBuffers)       \
  X(vkFreeCommandBuffers)           \
  X(vkBeginCommandBuffer)           \
  X(vkEndCommandBuffer)             \
  X(vkCreateQueryPool)              \
  X(vkDestroyQueryPool)             \
  X(vkGetQueryPoolResults)          \
  X(vkCmdBindPipeline)              \
  X(vkCmdBindDescriptorSets)        \
  X(vkCmdPushConstants)             \
  X(vkCmdDispatch)                  \
  X(vkCmdPipelineBarrier)           \
  X(vkCmdCopyBuffer)                \
  X(vkCmdCopyImageToBuffer)         \
  X(vkCmdResetQueryPool)            \
  X(vkCmdWriteTimestamp)

// One context's table. Precondition for every call through it: the instance (and device) it was loaded for
// are alive. `allocator` is what every create and destroy passes (null: the driver's).
struct Functions {
#define VS_VK_MEMBER(name) PFN_##name name = nullptr;
  VS_VK_INSTANCE_FUNCTIONS(VS_VK_MEMBER)
  VS_VK_DEVICE_FUNCTIONS(VS_VK_MEMBER)
#undef VS_VK_MEMBER
  PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr = nullptr;
  const VkAllocationCallbacks* allocator = nullptr;

  // Loads the instance-level entry points; returns the names it could not load (empty: all loaded).
  std::vector<std::string> loadInstance(PFN_vkGetInstanceProcAddr getInstanceProcAddr, VkInstance instance);
  // Loads the device-level entry points (after loadInstance); returns the names it could not load.
  std::vector<std::string> loadDevice(VkDevice device);
};

}  // namespace vs::vk

#endif
