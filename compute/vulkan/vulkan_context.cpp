// vulkan_context.cpp: instance and device setup, device choice, validation capture, memory and submission.
#include "compute/vulkan/vulkan_context.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include <dlfcn.h>
#include <link.h>

#include "compute/shared/trace_interface.h"
#include "voxel/error.h"
#include "voxel/sanitizers.h"

namespace vs {
namespace {

// A physical device's queue families, in index order.
std::vector<VkQueueFamilyProperties> queueFamilies(const vk::Functions& fn, VkPhysicalDevice device) {
  std::uint32_t count = 0;
  fn.vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  fn.vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
  families.resize(count);
  return families;
}

// LeakSanitizer scans the globals of the libraries mapped when the process ends. The Vulkan loader unloads a
// driver at vkDestroyInstance, and memory that the driver keeps for the whole process behind one of its
// globals (lavapipe's per-L3-cache affinity masks on AMD Zen processors, 128 bytes each, allocated once) is
// then reported as leaked, from a module that no longer exists. In leak-checked builds every library loaded
// once an instance exists stays loaded, so such memory is seen for what it is, still reachable; memory that
// nothing points to is reported as before.
void keepLoadedLibrariesMapped() {
  if constexpr (kAddressSanitized) {
    std::vector<std::string> names;
    dl_iterate_phdr(
        [](dl_phdr_info* info, std::size_t, void* out) {
          if (info->dlpi_name && info->dlpi_name[0]) static_cast<std::vector<std::string>*>(out)->push_back(info->dlpi_name);
          return 0;
        },
        &names);
    // RTLD_NOLOAD only takes a reference to what is loaded already; RTLD_NODELETE keeps it past every dlclose.
    for (const std::string& name : names) (void)dlopen(name.c_str(), RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);
  }
}

// One refusal for a device, listing everything it lacks.
std::string cannotRun(const std::string& device, const std::vector<std::string>& missing) {
  std::string text = "Vulkan device " + device + " cannot run voxshadow; it lacks:";
  for (const std::string& m : missing) text += "\n  - " + m;
  return text;
}

std::string versionText(std::uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v));
}

const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
const char* kNoDevice = "no Vulkan device found (install mesa-vulkan-drivers for lavapipe)";
// Uploads larger than this go through the staging buffer in several submissions, bounding host memory.
constexpr VkDeviceSize kStagingBytes = VkDeviceSize(32) << 20;

bool envValidation() {
  const char* v = std::getenv("VOXSHADOW_VALIDATION");
  return v && std::string(v) == "1";
}

bool hasLayer(const char* name) {
  std::uint32_t count = 0;
  vkEnumerateInstanceLayerProperties(&count, nullptr);
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  for (const auto& l : layers)
    if (std::strcmp(l.layerName, name) == 0) return true;
  return false;
}

bool hasInstanceExtension(const char* layer, const char* name) {
  std::uint32_t count = 0;
  vkEnumerateInstanceExtensionProperties(layer, &count, nullptr);
  std::vector<VkExtensionProperties> exts(count);
  vkEnumerateInstanceExtensionProperties(layer, &count, exts.data());
  for (const auto& e : exts)
    if (std::strcmp(e.extensionName, name) == 0) return true;
  return false;
}

VkApplicationInfo appInfo() {
  auto app = vk::make<VkApplicationInfo>(VK_STRUCTURE_TYPE_APPLICATION_INFO);
  app.pApplicationName = "voxshadow";
  app.applicationVersion = VK_MAKE_VERSION(0, 1, 0);
  app.pEngineName = "voxshadow";
  app.engineVersion = VK_MAKE_VERSION(0, 1, 0);
  app.apiVersion = VK_API_VERSION_1_1;
  return app;
}

VulkanDeviceType toType(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return VulkanDeviceType::Discrete;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return VulkanDeviceType::Integrated;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return VulkanDeviceType::Virtual;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return VulkanDeviceType::Cpu;
    default: return VulkanDeviceType::Other;
  }
}

int typeRank(VulkanDeviceType t) {
  switch (t) {
    case VulkanDeviceType::Discrete: return 0;
    case VulkanDeviceType::Integrated: return 1;
    case VulkanDeviceType::Virtual: return 2;
    case VulkanDeviceType::Cpu: return 3;
    default: return 4;
  }
}

VulkanDeviceInfo describe(const vk::Functions& fn, VkPhysicalDevice pd, std::uint32_t index) {
  VulkanDeviceInfo info;
  info.index = index;
  VkPhysicalDeviceProperties base{};
  fn.vkGetPhysicalDeviceProperties(pd, &base);

  auto props = vk::make<VkPhysicalDeviceProperties2>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2);
  auto m3 = vk::make<VkPhysicalDeviceMaintenance3Properties>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES);
  auto driver = vk::make<VkPhysicalDeviceDriverProperties>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES);
  props.pNext = &m3;
  // Driver properties are core only from Vulkan 1.2; chaining them on older devices is invalid.
  if (base.apiVersion >= VK_API_VERSION_1_2) m3.pNext = &driver;
  fn.vkGetPhysicalDeviceProperties2(pd, &props);
  const VkPhysicalDeviceProperties& p = props.properties;

  info.name = p.deviceName;
  info.type = toType(p.deviceType);
  if (base.apiVersion >= VK_API_VERSION_1_2) {
    info.driverName = driver.driverName;
    info.driverInfo = driver.driverInfo;
  }
  info.apiVersion = p.apiVersion;
  info.driverVersion = p.driverVersion;
  std::copy(std::begin(p.pipelineCacheUUID), std::end(p.pipelineCacheUUID), info.pipelineCacheUuid.begin());
  info.maxStorageBufferRange = p.limits.maxStorageBufferRange;
  info.maxTexelBufferElements = p.limits.maxTexelBufferElements;
  info.minUniformBufferOffsetAlignment = std::max<std::uint64_t>(1, p.limits.minUniformBufferOffsetAlignment);
  info.maxMemoryAllocationSize = m3.maxMemoryAllocationSize;
  info.maxPerStageStorageBuffers = p.limits.maxPerStageDescriptorStorageBuffers;
  info.maxImageDimension2D = p.limits.maxImageDimension2D;
  info.maxImageArrayLayers = p.limits.maxImageArrayLayers;
  for (int i = 0; i < 3; ++i) info.maxWorkGroupCount[i] = p.limits.maxComputeWorkGroupCount[i];
  info.timestampPeriodNs = p.limits.timestampPeriod;
  VkPhysicalDeviceFeatures features{};
  fn.vkGetPhysicalDeviceFeatures(pd, &features);
  info.shaderFloat64 = features.shaderFloat64 == VK_TRUE;

  VkPhysicalDeviceMemoryProperties mem{};
  fn.vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  for (std::uint32_t h = 0; h < mem.memoryHeapCount; ++h)
    if (mem.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      info.deviceLocalBytes = std::max<std::uint64_t>(info.deviceLocalBytes, mem.memoryHeaps[h].size);

  const std::vector<VkQueueFamilyProperties> families = queueFamilies(fn, pd);
  const std::uint32_t familyCount = std::uint32_t(families.size());
  // Prefer a compute family without graphics (an async-compute queue), else any compute family.
  for (int pass = 0; pass < 2 && !info.hasComputeQueue; ++pass) {
    for (std::uint32_t f = 0; f < familyCount; ++f) {
      bool compute = families[f].queueFlags & VK_QUEUE_COMPUTE_BIT;
      bool graphics = families[f].queueFlags & VK_QUEUE_GRAPHICS_BIT;
      if (compute && (pass == 1 || !graphics)) {
        info.hasComputeQueue = true;
        info.computeQueueFamily = f;
        info.timestampValidBits = families[f].timestampValidBits;
        break;
      }
    }
  }
  return info;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string deviceList(const std::vector<VulkanDeviceInfo>& devices) {
  std::ostringstream out;
  for (const auto& d : devices) out << "\n  " << d.index << ": " << d.name << " (" << toString(d.type) << ")";
  return out.str();
}

// The instance's physical devices (into `handles`) and their descriptions, in the loader's order.
std::vector<VulkanDeviceInfo> enumerateDevices(const vk::Functions& fn, VkInstance instance,
                                               std::vector<VkPhysicalDevice>& handles) {
  std::uint32_t count = 0;
  vk::check(fn.vkEnumeratePhysicalDevices(instance, &count, nullptr), "vkEnumeratePhysicalDevices");
  handles.resize(count);
  vk::check(fn.vkEnumeratePhysicalDevices(instance, &count, handles.data()), "vkEnumeratePhysicalDevices");
  handles.resize(count);
  std::vector<VulkanDeviceInfo> devices;
  for (std::uint32_t i = 0; i < count; ++i) devices.push_back(describe(fn, handles[i], i));
  return devices;
}

}  // namespace

const char* toString(VulkanDeviceType type) {
  switch (type) {
    case VulkanDeviceType::Discrete: return "discrete GPU";
    case VulkanDeviceType::Integrated: return "integrated GPU";
    case VulkanDeviceType::Virtual: return "virtual GPU";
    case VulkanDeviceType::Cpu: return "CPU";
    default: return "other";
  }
}

std::vector<VulkanDeviceInfo> listVulkanDevices() {
  VkApplicationInfo app = appInfo();
  auto ci = vk::make<VkInstanceCreateInfo>(VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO);
  ci.pApplicationInfo = &app;
  VkInstance raw = VK_NULL_HANDLE;
  VkResult r = vkCreateInstance(&ci, nullptr, &raw);
  // The loader reports a missing driver as an incompatible one: that is "no device", not a failure.
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER) return {};
  vk::check(r, "vkCreateInstance");
  vk::Functions fn;
  const std::vector<std::string> missing = fn.loadInstance(vkGetInstanceProcAddr, raw);
  vk::UniqueInstance instance(raw, fn.vkDestroyInstance);
  if (!missing.empty()) throwRuntime("Vulkan: the loader has no " + missing.front());
  keepLoadedLibrariesMapped();
  std::vector<VkPhysicalDevice> handles;
  return enumerateDevices(fn, instance.get(), handles);
}

std::size_t chooseVulkanDevice(const std::vector<VulkanDeviceInfo>& devices, int deviceIndex,
                               const std::string& deviceName) {
  if (devices.empty()) throwRuntime(kNoDevice);
  if (deviceIndex >= 0) {
    if (static_cast<std::size_t>(deviceIndex) >= devices.size())
      throwBadInput("Vulkan device index " + std::to_string(deviceIndex) + " out of range; devices:" +
                    deviceList(devices));
    if (!devices[deviceIndex].hasComputeQueue)
      throwBadInput("Vulkan device " + devices[deviceIndex].name + " has no compute queue");
    return static_cast<std::size_t>(deviceIndex);
  }
  if (!deviceName.empty()) {
    std::string want = lower(deviceName);
    for (std::size_t i = 0; i < devices.size(); ++i)
      if (devices[i].hasComputeQueue && lower(devices[i].name).find(want) != std::string::npos) return i;
    throwBadInput("no Vulkan device matches '" + deviceName + "'; devices:" + deviceList(devices));
  }
  std::size_t best = devices.size();
  for (std::size_t i = 0; i < devices.size(); ++i) {
    if (!devices[i].hasComputeQueue || !devices[i].shaderFloat64) continue;
    if (best == devices.size() || typeRank(devices[i].type) < typeRank(devices[best].type)) best = i;
  }
  if (best == devices.size())
    throwRuntime(std::string(kNoDevice) + ": no device has both a compute queue and shaderFloat64, which the trace "
                 "shader needs; devices:" + deviceList(devices));
  return best;
}

std::vector<std::string> missingVulkanRequirements(const vk::Functions& fn, VkPhysicalDevice physicalDevice,
                                                   std::uint32_t instanceApiVersion,
                                                   const VkPhysicalDeviceFeatures& enabledFeatures,
                                                   std::uint32_t queueFamily,
                                                   const std::vector<std::string>& entryPointsMissing) {
  std::vector<std::string> missing;
  VkPhysicalDeviceProperties props{};
  fn.vkGetPhysicalDeviceProperties(physicalDevice, &props);
  // Instance-level 1.1 calls (vkGetPhysicalDeviceProperties2) need an instance made for 1.1, and the shaders
  // are SPIR-V 1.3 for a 1.1 device.
  if (instanceApiVersion < VK_API_VERSION_1_1)
    missing.push_back("Vulkan 1.1 on the instance (VulkanHostDevice::instanceApiVersion is " +
                      versionText(instanceApiVersion) + ")");
  if (props.apiVersion < VK_API_VERSION_1_1)
    missing.push_back("Vulkan 1.1 on the device (it reports " + versionText(props.apiVersion) + ")");
  // The trace shader divides and takes square roots through double, so that they round as the CPU's do
  // (compute/shared/lanes.h, VS_DIV).
  VkPhysicalDeviceFeatures supported{};
  fn.vkGetPhysicalDeviceFeatures(physicalDevice, &supported);
  if (!supported.shaderFloat64) missing.push_back("the feature shaderFloat64 (the device does not support it)");
  else if (!enabledFeatures.shaderFloat64)
    missing.push_back("the feature shaderFloat64 (supported, but not enabled when the VkDevice was created)");
  const std::vector<VkQueueFamilyProperties> families = queueFamilies(fn, physicalDevice);
  const std::uint32_t familyCount = std::uint32_t(families.size());
  if (queueFamily >= familyCount)
    missing.push_back("queue family " + std::to_string(queueFamily) + " (the device has " + std::to_string(familyCount) +
                      ")");
  else if (!(families[queueFamily].queueFlags & VK_QUEUE_COMPUTE_BIT))
    missing.push_back("VK_QUEUE_COMPUTE_BIT on queue family " + std::to_string(queueFamily));
  // The shadow array (R32F storage image) and the record arrays (texel buffers).
  VkFormatProperties r32f{};
  fn.vkGetPhysicalDeviceFormatProperties(physicalDevice, VK_FORMAT_R32_SFLOAT, &r32f);
  const VkFormatFeatureFlags imageNeeds = VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT | VK_FORMAT_FEATURE_TRANSFER_SRC_BIT |
                                          VK_FORMAT_FEATURE_TRANSFER_DST_BIT;
  if ((r32f.optimalTilingFeatures & imageNeeds) != imageNeeds)
    missing.push_back("VK_FORMAT_R32_SFLOAT as an optimal-tiling storage image with transfers");
  const std::pair<VkFormat, const char*> texelFormats[] = {{VK_FORMAT_R32_UINT, "VK_FORMAT_R32_UINT"},
                                                           {VK_FORMAT_R32_SINT, "VK_FORMAT_R32_SINT"},
                                                           {VK_FORMAT_R32G32B32A32_UINT, "VK_FORMAT_R32G32B32A32_UINT"}};
  for (const auto& [format, name] : texelFormats) {
    VkFormatProperties p{};
    fn.vkGetPhysicalDeviceFormatProperties(physicalDevice, format, &p);
    if (!(p.bufferFeatures & VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT))
      missing.push_back(std::string(name) + " as a uniform texel buffer");
  }
  const VkPhysicalDeviceLimits& limits = props.limits;
  if (limits.maxPerStageDescriptorStorageBuffers < gpu::VS_STORAGE_BUFFER_COUNT)
    missing.push_back("maxPerStageDescriptorStorageBuffers >= " + std::to_string(gpu::VS_STORAGE_BUFFER_COUNT) +
                      " (the device has " + std::to_string(limits.maxPerStageDescriptorStorageBuffers) + ")");
  if (limits.maxDescriptorSetStorageBuffers < gpu::VS_STORAGE_BUFFER_COUNT)
    missing.push_back("maxDescriptorSetStorageBuffers >= " + std::to_string(gpu::VS_STORAGE_BUFFER_COUNT) +
                      " (the device has " + std::to_string(limits.maxDescriptorSetStorageBuffers) + ")");
  for (const std::string& name : entryPointsMissing) missing.push_back("the entry point " + name);
  return missing;
}

VKAPI_ATTR VkBool32 VKAPI_CALL VulkanContext::onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                        VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                                        const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                        void* user) {
  auto* self = static_cast<VulkanContext*>(user);
  std::string text = (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) ? "error: " : "warning: ";
  if (data && data->pMessageIdName) text += std::string("[") + data->pMessageIdName + "] ";
  if (data && data->pMessage) text += data->pMessage;
  std::lock_guard lock(self->messagesMutex_);
  self->messages_.push_back(std::move(text));
  return VK_FALSE;
}

VulkanContext::VulkanContext(const VulkanContextOptions& options) {
  validation_ = options.validation.value_or(envValidation());
  std::vector<const char*> layers;
  std::vector<const char*> extensions;
  if (validation_) {
    if (!hasLayer(kValidationLayer))
      throwRuntime(std::string("Vulkan validation was requested (VOXSHADOW_VALIDATION=1 or the validation option) "
                               "but the layer ") + kValidationLayer +
                   " is not installed (Debian: vulkan-validationlayers)");
    if (!hasInstanceExtension(nullptr, VK_EXT_DEBUG_UTILS_EXTENSION_NAME) &&
        !hasInstanceExtension(kValidationLayer, VK_EXT_DEBUG_UTILS_EXTENSION_NAME))
      throwRuntime("Vulkan validation was requested but VK_EXT_debug_utils is not available");
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }

  auto messengerInfo = vk::make<VkDebugUtilsMessengerCreateInfoEXT>(VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT);
  messengerInfo.messageSeverity =
      VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messengerInfo.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                              VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                              VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messengerInfo.pfnUserCallback = &VulkanContext::onMessage;
  messengerInfo.pUserData = this;

  VkApplicationInfo app = appInfo();
  auto ci = vk::make<VkInstanceCreateInfo>(VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO);
  ci.pApplicationInfo = &app;
  ci.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  ci.ppEnabledLayerNames = layers.data();
  ci.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  ci.ppEnabledExtensionNames = extensions.data();
  // Chained so that messages from instance creation and destruction are captured too.
  if (validation_) ci.pNext = &messengerInfo;
  VkInstance rawInstance = VK_NULL_HANDLE;
  VkResult r = vkCreateInstance(&ci, nullptr, &rawInstance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER) throwRuntime(kNoDevice);
  vk::check(r, "vkCreateInstance");
  const std::vector<std::string> instanceMissing = fn_.loadInstance(vkGetInstanceProcAddr, rawInstance);
  instance_ = vk::UniqueInstance(rawInstance, fn_.vkDestroyInstance);
  instanceHandle_ = rawInstance;
  if (!instanceMissing.empty()) throwRuntime("Vulkan: the loader has no " + instanceMissing.front());
  keepLoadedLibrariesMapped();

  if (validation_) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        fn_.vkGetInstanceProcAddr(instanceHandle_, "vkCreateDebugUtilsMessengerEXT"));
    if (!create) throwRuntime("Vulkan validation was requested but vkCreateDebugUtilsMessengerEXT is missing");
    VkDebugUtilsMessengerEXT m = VK_NULL_HANDLE;
    vk::check(create(instanceHandle_, &messengerInfo, nullptr, &m), "vkCreateDebugUtilsMessengerEXT");
    messenger_ = vk::UniqueMessenger(instanceHandle_, m,
                                      reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(fn_.vkGetInstanceProcAddr(
                                          instanceHandle_, "vkDestroyDebugUtilsMessengerEXT")));
  }

  std::vector<VkPhysicalDevice> pds;
  std::vector<VulkanDeviceInfo> devices = enumerateDevices(fn_, instanceHandle_, pds);
  std::size_t chosen = chooseVulkanDevice(devices, options.deviceIndex, options.deviceName);
  physical_ = pds[chosen];
  info_ = devices[chosen];
  if (info_.apiVersion < VK_API_VERSION_1_1)
    throwRuntime("Vulkan device " + info_.name + " supports only Vulkan " +
                 std::to_string(VK_API_VERSION_MAJOR(info_.apiVersion)) + "." +
                 std::to_string(VK_API_VERSION_MINOR(info_.apiVersion)) + "; voxshadow needs 1.1");
  fn_.vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);
  // The trace shader divides and takes square roots through double, so that they round as the CPU's do
  // (compute/shared/lanes.h, VS_DIV).
  if (!info_.shaderFloat64)
    throwRuntime("Vulkan device " + info_.name + " lacks the feature shaderFloat64, which voxshadow's trace shader "
                 "needs to round divisions and square roots as the CPU does; use --backend cpu");
  VkPhysicalDeviceFeatures enabled{};
  enabled.shaderFloat64 = VK_TRUE;
  if (std::vector<std::string> missing =
          missingVulkanRequirements(fn_, physical_, appInfo().apiVersion, enabled, info_.computeQueueFamily, {});
      !missing.empty())
    throwRuntime(cannotRun(info_.name, missing));

  float priority = 1.0f;
  auto qci = vk::make<VkDeviceQueueCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO);
  qci.queueFamilyIndex = info_.computeQueueFamily;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  auto dci = vk::make<VkDeviceCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO);
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  dci.pEnabledFeatures = &enabled;
  VkDevice rawDevice = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateDevice(physical_, &dci, fn_.allocator, &rawDevice), "vkCreateDevice");
  // Loaded first, so that the device is destroyed through its own table whatever happens next.
  const std::vector<std::string> deviceMissing = fn_.loadDevice(rawDevice);
  if (!fn_.vkDestroyDevice)
    fn_.vkDestroyDevice =
        reinterpret_cast<PFN_vkDestroyDevice>(fn_.vkGetInstanceProcAddr(instanceHandle_, "vkDestroyDevice"));
  device_ = vk::UniqueDevice(fn_, rawDevice);
  deviceHandle_ = rawDevice;
  if (!deviceMissing.empty()) throwRuntime(cannotRun(info_.name, deviceMissing));
  fn_.vkGetDeviceQueue(deviceHandle_, info_.computeQueueFamily, 0, &queue_);
  createPoolAndFence();
}

VulkanContext::VulkanContext(const VulkanHostDevice& host) {
  // The handles first: nothing can be queried without them.
  std::vector<std::string> nullFields;
  if (!host.getInstanceProcAddr) nullFields.push_back("getInstanceProcAddr");
  if (host.instance == VK_NULL_HANDLE) nullFields.push_back("instance");
  if (host.physicalDevice == VK_NULL_HANDLE) nullFields.push_back("physicalDevice");
  if (host.device == VK_NULL_HANDLE) nullFields.push_back("device");
  if (host.queue == VK_NULL_HANDLE) nullFields.push_back("queue");
  if (!nullFields.empty()) {
    std::string list;
    for (const std::string& f : nullFields) list += (list.empty() ? "" : ", ") + f;
    throwBadInput("VulkanHostDevice: null " + list + " (every handle and getInstanceProcAddr must be the host's)");
  }
  // The host made the instance, so the drivers and layers are loaded now (see keepLoadedLibrariesMapped).
  keepLoadedLibrariesMapped();
  onHostDevice_ = true;
  instanceHandle_ = host.instance;
  deviceHandle_ = host.device;
  physical_ = host.physicalDevice;
  queue_ = host.queue;
  hostPipelineCache_ = host.pipelineCache;
  // Of the instance's entry points, a host's device needs the queries (not vkCreateDevice,
  // vkEnumeratePhysicalDevices or vkDestroyInstance, which only a context of its own calls). Without the 1.0
  // queries nothing else can be checked: the refusal names them alone.
  std::vector<std::string> entryPointsMissing;
  for (const std::string& name : fn_.loadInstance(host.getInstanceProcAddr, host.instance))
    if (name != "vkCreateDevice" && name != "vkEnumeratePhysicalDevices" && name != "vkDestroyInstance")
      entryPointsMissing.push_back(name);
  if (!fn_.vkGetPhysicalDeviceProperties || !fn_.vkGetPhysicalDeviceFeatures ||
      !fn_.vkGetPhysicalDeviceFormatProperties || !fn_.vkGetPhysicalDeviceQueueFamilyProperties ||
      !fn_.vkGetPhysicalDeviceMemoryProperties || !fn_.vkGetDeviceProcAddr) {
    std::vector<std::string> missing;
    for (const std::string& name : entryPointsMissing) missing.push_back("the entry point " + name);
    throwRuntime(cannotRun("(the host's, not queried)", missing));
  }
  fn_.allocator = host.allocator;
  for (const std::string& name : fn_.loadDevice(host.device)) entryPointsMissing.push_back(name);
  std::vector<std::string> missing = missingVulkanRequirements(fn_, physical_, host.instanceApiVersion,
                                                               host.enabledFeatures, host.queueFamily,
                                                               entryPointsMissing);
  if (!missing.empty()) {
    VkPhysicalDeviceProperties props{};
    fn_.vkGetPhysicalDeviceProperties(physical_, &props);
    throwRuntime(cannotRun(props.deviceName, missing));
  }
  // Only now: describing uses Vulkan 1.1 calls.
  info_ = describe(fn_, physical_, 0);
  // The host's device has no index in a list the library made; its queue family is the one it named.
  info_.computeQueueFamily = host.queueFamily;
  info_.timestampValidBits = queueFamilies(fn_, physical_)[host.queueFamily].timestampValidBits;
  fn_.vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);
  createPoolAndFence();
}

void VulkanContext::createPoolAndFence() {
  auto pci = vk::make<VkCommandPoolCreateInfo>(VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO);
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT | VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = info_.computeQueueFamily;
  VkCommandPool pool = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateCommandPool(deviceHandle_, &pci, fn_.allocator, &pool), "vkCreateCommandPool");
  commandPool_ = vk::UniqueCommandPool(fn_, deviceHandle_, pool);

  auto fci = vk::make<VkFenceCreateInfo>(VK_STRUCTURE_TYPE_FENCE_CREATE_INFO);
  VkFence fence = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateFence(deviceHandle_, &fci, fn_.allocator, &fence), "vkCreateFence");
  fence_ = vk::UniqueFence(fn_, deviceHandle_, fence);
}

VulkanContext::~VulkanContext() {
  // The shared objects (pipelines) go first, while the device they were made on is still there; outside the
  // lock, in case one of them asks the context for something as it goes.
  std::map<std::string, std::shared_ptr<void>> objects;
  {
    std::lock_guard lock(sharedMutex_);
    objects.swap(shared_);
  }
  objects.clear();
}

std::vector<std::string> VulkanContext::validationMessages() const {
  std::lock_guard lock(messagesMutex_);
  return messages_;
}

std::uint32_t VulkanContext::findMemoryType(std::uint32_t typeBits, VkMemoryPropertyFlags required,
                                            VkMemoryPropertyFlags preferred) const {
  for (int pass = 0; pass < 2; ++pass) {
    VkMemoryPropertyFlags want = pass == 0 ? (required | preferred) : required;
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i)
      if ((typeBits & (1u << i)) && (memory_.memoryTypes[i].propertyFlags & want) == want) return i;
  }
  throwRuntime("Vulkan device " + info_.name + " has no memory type with the required properties");
}

vk::Buffer VulkanContext::createBuffer(VkDeviceSize size, VkBufferUsageFlags usage, VkMemoryPropertyFlags required,
                                       VkMemoryPropertyFlags preferred, bool map) {
  if (size > info_.maxMemoryAllocationSize && info_.maxMemoryAllocationSize > 0)
    throwRuntime("Vulkan buffer of " + std::to_string(size) + " bytes exceeds the device's maxMemoryAllocationSize (" +
                 std::to_string(info_.maxMemoryAllocationSize) + " bytes) on " + info_.name);
  VkDevice dev = deviceHandle_;
  auto bci = vk::make<VkBufferCreateInfo>(VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO);
  bci.size = size;
  bci.usage = usage;
  bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  VkBuffer raw = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateBuffer(dev, &bci, fn_.allocator, &raw), "vkCreateBuffer");
  vk::Buffer out;
  out.buffer = vk::UniqueBuffer(fn_, dev, raw);
  out.size = size;
  VkMemoryRequirements req{};
  fn_.vkGetBufferMemoryRequirements(dev, raw, &req);
  auto ai = vk::make<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = findMemoryType(req.memoryTypeBits, required, preferred);
  VkDeviceMemory mem = VK_NULL_HANDLE;
  VkResult r = fn_.vkAllocateMemory(dev, &ai, fn_.allocator, &mem);
  if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY)
    throwRuntime("Vulkan device " + info_.name + " is out of memory allocating " + std::to_string(req.size) +
                 " bytes (device-local heap: " + std::to_string(info_.deviceLocalBytes) + " bytes)");
  vk::check(r, "vkAllocateMemory");
  out.memory = vk::UniqueMemory(fn_, dev, mem);
  vk::check(fn_.vkBindBufferMemory(dev, raw, mem, 0), "vkBindBufferMemory");
  if (map) vk::check(fn_.vkMapMemory(dev, mem, 0, VK_WHOLE_SIZE, 0, &out.mapped), "vkMapMemory");
  return out;
}

vk::Buffer VulkanContext::createDeviceBuffer(VkDeviceSize size, VkBufferUsageFlags usage) {
  return createBuffer(size, usage, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, false);
}

vk::Buffer VulkanContext::createHostBuffer(VkDeviceSize size, VkBufferUsageFlags usage) {
  return createBuffer(size, usage, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
                      VK_MEMORY_PROPERTY_HOST_CACHED_BIT, true);
}

std::shared_ptr<void> VulkanContext::shared(const std::string& key, const std::function<std::shared_ptr<void>()>& make) {
  std::lock_guard lock(sharedMutex_);
  std::shared_ptr<void>& slot = shared_[key];
  if (!slot) slot = make();
  return slot;
}

vk::UniqueBufferView VulkanContext::createTexelView(const vk::Buffer& buffer, VkFormat format) {
  auto ci = vk::make<VkBufferViewCreateInfo>(VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO);
  ci.buffer = buffer.get();
  ci.format = format;
  ci.range = VK_WHOLE_SIZE;
  VkBufferView view = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateBufferView(deviceHandle_, &ci, fn_.allocator, &view), "vkCreateBufferView");
  return vk::UniqueBufferView(fn_, deviceHandle_, view);
}

vk::Image VulkanContext::createStorageImage(std::uint32_t width, std::uint32_t height, std::uint32_t layers) {
  if (width > info_.maxImageDimension2D || height > info_.maxImageDimension2D || layers > info_.maxImageArrayLayers)
    throwRuntime("shadow image " + std::to_string(width) + "x" + std::to_string(height) + "x" +
                 std::to_string(layers) + " exceeds the device's maxImageDimension2D (" +
                 std::to_string(info_.maxImageDimension2D) + ") or maxImageArrayLayers (" +
                 std::to_string(info_.maxImageArrayLayers) + ") on " + info_.name);
  VkDevice dev = deviceHandle_;
  auto ici = vk::make<VkImageCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO);
  ici.imageType = VK_IMAGE_TYPE_2D;
  ici.format = VK_FORMAT_R32_SFLOAT;
  ici.extent = {width, height, 1};
  ici.mipLevels = 1;
  ici.arrayLayers = layers;
  ici.samples = VK_SAMPLE_COUNT_1_BIT;
  ici.tiling = VK_IMAGE_TILING_OPTIMAL;
  ici.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  ici.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  VkImage raw = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateImage(dev, &ici, fn_.allocator, &raw), "vkCreateImage");
  vk::Image out;
  out.image = vk::UniqueImage(fn_, dev, raw);
  out.extent = ici.extent;
  out.layers = layers;
  VkMemoryRequirements req{};
  fn_.vkGetImageMemoryRequirements(dev, raw, &req);
  auto ai = vk::make<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = findMemoryType(req.memoryTypeBits, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  VkDeviceMemory mem = VK_NULL_HANDLE;
  vk::check(fn_.vkAllocateMemory(dev, &ai, fn_.allocator, &mem), "vkAllocateMemory (shadow image)");
  out.memory = vk::UniqueMemory(fn_, dev, mem);
  vk::check(fn_.vkBindImageMemory(dev, raw, mem, 0), "vkBindImageMemory");

  auto vci = vk::make<VkImageViewCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO);
  vci.image = raw;
  vci.viewType = VK_IMAGE_VIEW_TYPE_2D_ARRAY;
  vci.format = VK_FORMAT_R32_SFLOAT;
  vci.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, layers};
  VkImageView view = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateImageView(dev, &vci, fn_.allocator, &view), "vkCreateImageView");
  out.view = vk::UniqueImageView(fn_, dev, view);

  // The image lives in GENERAL: written by the shader, read by copies, never sampled.
  submitAndWait([&](VkCommandBuffer cmd) {
    auto b = vk::make<VkImageMemoryBarrier>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER);
    b.srcAccessMask = 0;
    b.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT;
    b.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    b.newLayout = VK_IMAGE_LAYOUT_GENERAL;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = raw;
    b.subresourceRange = vci.subresourceRange;
    fn_.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0,
                         nullptr, 1, &b);
  });
  return out;
}

vk::UniqueCommandBuffer VulkanContext::allocateCommandBuffer() {
  auto ai = vk::make<VkCommandBufferAllocateInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO);
  ai.commandPool = commandPool_.get();
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  vk::check(fn_.vkAllocateCommandBuffers(deviceHandle_, &ai, &cmd), "vkAllocateCommandBuffers");
  return vk::UniqueCommandBuffer(fn_, deviceHandle_, commandPool_.get(), cmd);
}

void VulkanContext::submitAndWait(const std::function<void(VkCommandBuffer)>& record) {
  std::lock_guard<std::recursive_mutex> hold(submitMutex_);
  vk::UniqueCommandBuffer cmd = allocateCommandBuffer();
  auto bi = vk::make<VkCommandBufferBeginInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO);
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  vk::check(fn_.vkBeginCommandBuffer(cmd.get(), &bi), "vkBeginCommandBuffer");
  record(cmd.get());
  vk::check(fn_.vkEndCommandBuffer(cmd.get()), "vkEndCommandBuffer");
  VkCommandBuffer raw = cmd.get();
  auto si = vk::make<VkSubmitInfo>(VK_STRUCTURE_TYPE_SUBMIT_INFO);
  si.commandBufferCount = 1;
  si.pCommandBuffers = &raw;
  VkFence fence = fence_.get();
  vk::check(fn_.vkResetFences(deviceHandle_, 1, &fence), "vkResetFences");
  vk::check(fn_.vkQueueSubmit(queue_, 1, &si, fence), "vkQueueSubmit");
  vk::check(fn_.vkWaitForFences(deviceHandle_, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
}

void VulkanContext::upload(const vk::Buffer& dst, VkDeviceSize offset, const void* data, VkDeviceSize size) {
  if (size == 0) return;
  std::lock_guard<std::recursive_mutex> hold(submitMutex_);
  VkDeviceSize stagingSize = std::min(size, kStagingBytes);
  if (!staging_.buffer || staging_.size < stagingSize)
    staging_ = createHostBuffer(stagingSize, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  for (VkDeviceSize done = 0; done < size;) {
    VkDeviceSize n = std::min(size - done, staging_.size);
    std::memcpy(staging_.mapped, bytes + done, n);
    submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy copy{0, offset + done, n};
      fn_.vkCmdCopyBuffer(cmd, staging_.get(), dst.get(), 1, &copy);
    });
    done += n;
  }
}

vk::UniquePipelineLayout VulkanContext::createPipelineLayout(VkDescriptorSetLayout setLayout, std::uint32_t pushBytes) {
  VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, pushBytes};
  auto pl = vk::make<VkPipelineLayoutCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO);
  pl.setLayoutCount = 1;
  pl.pSetLayouts = &setLayout;
  pl.pushConstantRangeCount = pushBytes > 0 ? 1u : 0u;
  pl.pPushConstantRanges = pushBytes > 0 ? &range : nullptr;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  vk::check(fn_.vkCreatePipelineLayout(deviceHandle_, &pl, fn_.allocator, &layout), "vkCreatePipelineLayout");
  return vk::UniquePipelineLayout(fn_, deviceHandle_, layout);
}

vk::UniquePipeline VulkanContext::createComputePipeline(VkShaderModule shader, VkPipelineLayout layout,
                                                       const VkSpecializationInfo* constants, VkPipelineCache cache) {
  auto ci = vk::make<VkComputePipelineCreateInfo>(VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO);
  ci.stage = vk::make<VkPipelineShaderStageCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO);
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = shader;
  ci.stage.pName = "main";
  ci.stage.pSpecializationInfo = constants;
  ci.layout = layout;
  VkPipeline p = VK_NULL_HANDLE;
  if (cache == VK_NULL_HANDLE) cache = hostPipelineCache_;
  vk::check(fn_.vkCreateComputePipelines(deviceHandle_, cache, 1, &ci, fn_.allocator, &p), "vkCreateComputePipelines");
  return vk::UniquePipeline(fn_, deviceHandle_, p);
}

vk::UniqueShaderModule VulkanContext::createShaderModule(const std::uint32_t* code, std::size_t bytes) {
  auto ci = vk::make<VkShaderModuleCreateInfo>(VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO);
  ci.codeSize = bytes;
  ci.pCode = code;
  VkShaderModule m = VK_NULL_HANDLE;
  vk::check(fn_.vkCreateShaderModule(deviceHandle_, &ci, fn_.allocator, &m), "vkCreateShaderModule");
  return vk::UniqueShaderModule(fn_, deviceHandle_, m);
}

}  // namespace vs
