// vk_functions.cpp: loading a context's entry points.
#include "compute/vulkan/vk_functions.h"

namespace vs::vk {

std::vector<std::string> Functions::loadInstance(PFN_vkGetInstanceProcAddr getInstanceProcAddr, VkInstance instance) {
  std::vector<std::string> missing;
  vkGetInstanceProcAddr = getInstanceProcAddr;
#define VS_VK_LOAD(name)                                                                       \
  name = reinterpret_cast<PFN_##name>(getInstanceProcAddr(instance, #name));                   \
  if (!name) missing.push_back(#name);
  VS_VK_INSTANCE_FUNCTIONS(VS_VK_LOAD)
#undef VS_VK_LOAD
  return missing;
}

std::vector<std::string> Functions::loadDevice(VkDevice device) {
  std::vector<std::string> missing;
  if (!vkGetDeviceProcAddr) return {"vkGetDeviceProcAddr"};
#define VS_VK_LOAD(name)                                                                       \
  name = reinterpret_cast<PFN_##name>(vkGetDeviceProcAddr(device, #name));                     \
  if (!name) missing.push_back(#name);
  VS_VK_DEVICE_FUNCTIONS(VS_VK_LOAD)
#undef VS_VK_LOAD
  return missing;
}

}  // namespace vs::vk
