// voxshadow info --devices: the Vulkan devices bake --device chooses from, and the limits the trace depends on.
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "compute/vulkan/vulkan_context.h"
#include "tools/commands.h"
#include "voxel/error.h"

namespace vs::cli {

namespace {

std::string version(std::uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

double mib(std::uint64_t bytes) { return double(bytes) / (1024.0 * 1024.0); }

}  // namespace

void printVulkanDevices(bool asJson) {
  std::vector<VulkanDeviceInfo> devices = listVulkanDevices();
  std::size_t chosen = devices.size();
  if (!devices.empty()) {
    try {
      chosen = chooseVulkanDevice(devices, -1, "");
    } catch (const Error&) {
      // No device with a compute queue: none is the default.
    }
  }
  if (asJson) {
    nlohmann::json all = nlohmann::json::array();
    for (const VulkanDeviceInfo& d : devices) {
      all.push_back({{"index", d.index},
                     {"name", d.name},
                     {"type", toString(d.type)},
                     {"driver", d.driverName},
                     {"driverInfo", d.driverInfo},
                     {"apiVersion", version(d.apiVersion)},
                     {"default", d.index == chosen},
                     {"computeQueue", d.hasComputeQueue},
                     {"maxStorageBufferRange", d.maxStorageBufferRange},
                     {"maxTexelBufferElements", d.maxTexelBufferElements},
                     {"maxMemoryAllocationSize", d.maxMemoryAllocationSize},
                     {"deviceLocalBytes", d.deviceLocalBytes},
                     {"maxPerStageStorageBuffers", d.maxPerStageStorageBuffers},
                     {"maxImageDimension2D", d.maxImageDimension2D},
                     {"maxImageArrayLayers", d.maxImageArrayLayers},
                     {"maxWorkGroupCount", d.maxWorkGroupCount},
                     {"timestampValidBits", d.timestampValidBits},
                     {"timestampPeriodNs", d.timestampPeriodNs}});
    }
    std::cout << all.dump(2) << "\n";
    return;
  }
  if (devices.empty()) {
    std::printf("no Vulkan device found\n");
    return;
  }
  for (const VulkanDeviceInfo& d : devices) {
    std::printf("device %u: %s%s\n", d.index, d.name.c_str(), d.index == chosen ? "  (default)" : "");
    std::printf("  type %s, Vulkan %s, driver %s%s%s\n", toString(d.type), version(d.apiVersion).c_str(),
                d.driverName.empty() ? "(unnamed)" : d.driverName.c_str(), d.driverInfo.empty() ? "" : " ",
                d.driverInfo.c_str());
    std::printf("  compute queue %s, timestamps %s\n", d.hasComputeQueue ? "yes" : "no",
                d.timestampValidBits > 0 ? "yes" : "no");
    std::printf("  maxStorageBufferRange %.1f MiB, maxMemoryAllocationSize %.1f MiB, device-local heap %.1f MiB\n",
                mib(d.maxStorageBufferRange), mib(d.maxMemoryAllocationSize), mib(d.deviceLocalBytes));
    std::printf("  maxTexelBufferElements %llu\n", static_cast<unsigned long long>(d.maxTexelBufferElements));
    std::printf("  storage buffers per stage %u, image 2D %u, array layers %u, workgroups %u x %u x %u\n",
                d.maxPerStageStorageBuffers, d.maxImageDimension2D, d.maxImageArrayLayers, d.maxWorkGroupCount[0],
                d.maxWorkGroupCount[1], d.maxWorkGroupCount[2]);
  }
}

}  // namespace vs::cli
