// host_engine.cpp: an example host engine that embeds voxshadow (README "Embedding in an engine"), built
// against the installed package alone (tools/examples/CMakeLists.txt; ctest example_host_engine builds and runs
// it). It makes its own Vulkan instance (with the validation layer and its own messenger where the layer is
// installed) and device, hands them to voxshadow, renders the demo world's frames there while its camera moves,
// and lights each frame with its own compute shader (host_engine.comp), which reads voxshadow's shadows in place
// through the installed GLSL include. It checks that its image equals the library's own lit image bit for bit,
// writes the last one as a PNG, and exits non-zero on any difference or validation message.
//
//   host_engine <output.png> [--frames N] [--size WxH] [--require-validation]
// --require-validation: fail where the validation layer is not installed (ctest passes it; the layer's silence
// is half of what the example shows).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <vulkan/vulkan.h>

#include "compute/vulkan/vulkan_context.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/deferred.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "lighting/scene_file.h"
#include "lighting/vulkan_shadows.h"
#include "voxel/demo_world.h"
#include "host_engine.spv.h"  // host_engine.comp

namespace {

void check(VkResult r, const char* call) {
  if (r != VK_SUCCESS) throw std::runtime_error(std::string(call) + " failed (" + std::to_string(int(r)) + ")");
}

// The engine's Vulkan: its instance, device and compute queue, made as it likes; voxshadow gets their handles.
class Engine {
 public:
  Engine() {
    std::uint32_t layerCount = 0;
    vkEnumerateInstanceLayerProperties(&layerCount, nullptr);
    std::vector<VkLayerProperties> layers(layerCount);
    vkEnumerateInstanceLayerProperties(&layerCount, layers.data());
    for (const VkLayerProperties& l : layers)
      if (std::strcmp(l.layerName, "VK_LAYER_KHRONOS_validation") == 0) validation_ = true;
    VkDebugUtilsMessengerCreateInfoEXT messenger{};
    messenger.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
    messenger.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    messenger.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT;
    messenger.pfnUserCallback = &Engine::onMessage;
    messenger.pUserData = this;
    VkApplicationInfo app{};
    app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
    app.pApplicationName = "host_engine";
    app.apiVersion = VK_API_VERSION_1_1;
    const char* layer = "VK_LAYER_KHRONOS_validation";
    const char* extension = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
    VkInstanceCreateInfo ici{};
    ici.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    ici.pApplicationInfo = &app;
    if (validation_) {
      ici.pNext = &messenger;
      ici.enabledLayerCount = 1;
      ici.ppEnabledLayerNames = &layer;
      ici.enabledExtensionCount = 1;
      ici.ppEnabledExtensionNames = &extension;
    }
    check(vkCreateInstance(&ici, nullptr, &instance_), "vkCreateInstance");
    if (validation_) {
      auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
      check(create(instance_, &messenger, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
    }
    // The first device with a compute queue and shaderFloat64 (voxshadow's requirement, README).
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
    if (physical_ == VK_NULL_HANDLE) throw std::runtime_error("no Vulkan device with compute and shaderFloat64");
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{};
    qci.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
    qci.queueFamilyIndex = family_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    enabled_.shaderFloat64 = VK_TRUE;
    VkDeviceCreateInfo dci{};
    dci.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    dci.pEnabledFeatures = &enabled_;
    check(vkCreateDevice(physical_, &dci, nullptr, &device_), "vkCreateDevice");
    vkGetDeviceQueue(device_, family_, 0, &queue_);
  }
  ~Engine() {
    // The documented order's end: voxshadow's objects are gone; the device, then the instance.
    vkDestroyDevice(device_, nullptr);
    if (messenger_) {
      auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
      destroy(instance_, messenger_, nullptr);
    }
    vkDestroyInstance(instance_, nullptr);
  }
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  vs::VulkanHostDevice handles() const {
    vs::VulkanHostDevice h;
    h.getInstanceProcAddr = &vkGetInstanceProcAddr;
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
  std::uint32_t family() const { return family_; }
  VkQueue queue() const { return queue_; }
  bool validation() const { return validation_; }
  std::vector<std::string> messages() {
    std::lock_guard lock(mutex_);
    return messages_;
  }

 private:
  static VKAPI_ATTR VkBool32 VKAPI_CALL onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT,
                                                  VkDebugUtilsMessageTypeFlagsEXT,
                                                  const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    auto* self = static_cast<Engine*>(user);
    std::lock_guard lock(self->mutex_);
    self->messages_.push_back(data && data->pMessage ? data->pMessage : "(no text)");
    return VK_FALSE;
  }
  bool validation_ = false;
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

// The engine's deferred pass (host_engine.comp): its own G-buffer, contact answers and image in its bindings
// 0..2, voxshadow's shadows (VulkanShadows) in 3..7, as the installed shadows.glsl names them.
class LightingPass {
 public:
  explicit LightingPass(const Engine& engine) : engine_(engine), device_(engine.device()) {
    VkDescriptorSetLayoutBinding bindings[8]{};
    for (std::uint32_t b = 0; b < 8; ++b) {
      bindings[b].binding = b;
      bindings[b].descriptorType = b == 4 ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      bindings[b].descriptorCount = 1;
      bindings[b].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    VkDescriptorSetLayoutCreateInfo dli{};
    dli.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    dli.bindingCount = 8;
    dli.pBindings = bindings;
    check(vkCreateDescriptorSetLayout(device_, &dli, nullptr, &setLayout_), "vkCreateDescriptorSetLayout");
    const VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(Push)};
    VkPipelineLayoutCreateInfo pli{};
    pli.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &setLayout_;
    pli.pushConstantRangeCount = 1;
    pli.pPushConstantRanges = &range;
    check(vkCreatePipelineLayout(device_, &pli, nullptr, &layout_), "vkCreatePipelineLayout");
    VkShaderModuleCreateInfo smi{};
    smi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    smi.codeSize = sizeof host_engine_shader;
    smi.pCode = host_engine_shader;
    check(vkCreateShaderModule(device_, &smi, nullptr, &module_), "vkCreateShaderModule");
    VkComputePipelineCreateInfo cpi{};
    cpi.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    cpi.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cpi.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cpi.stage.module = module_;
    cpi.stage.pName = "main";
    cpi.layout = layout_;
    check(vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &cpi, nullptr, &pipeline_), "vkCreateComputePipelines");
    const VkDescriptorPoolSize sizes[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 7},
                                           {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 1}};
    VkDescriptorPoolCreateInfo dpi{};
    dpi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    dpi.maxSets = 1;
    dpi.poolSizeCount = 2;
    dpi.pPoolSizes = sizes;
    check(vkCreateDescriptorPool(device_, &dpi, nullptr, &pool_), "vkCreateDescriptorPool");
    VkDescriptorSetAllocateInfo dai{};
    dai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    dai.descriptorPool = pool_;
    dai.descriptorSetCount = 1;
    dai.pSetLayouts = &setLayout_;
    check(vkAllocateDescriptorSets(device_, &dai, &set_), "vkAllocateDescriptorSets");
    VkCommandPoolCreateInfo cpci{};
    cpci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    cpci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    cpci.queueFamilyIndex = engine.family();
    check(vkCreateCommandPool(device_, &cpci, nullptr, &commandPool_), "vkCreateCommandPool");
  }
  ~LightingPass() {
    if (image_) vkDestroyBuffer(device_, image_, nullptr);
    if (imageMemory_) vkFreeMemory(device_, imageMemory_, nullptr);
    vkDestroyCommandPool(device_, commandPool_, nullptr);
    vkDestroyDescriptorPool(device_, pool_, nullptr);
    vkDestroyPipeline(device_, pipeline_, nullptr);
    vkDestroyShaderModule(device_, module_, nullptr);
    vkDestroyPipelineLayout(device_, layout_, nullptr);
    vkDestroyDescriptorSetLayout(device_, setLayout_, nullptr);
  }
  LightingPass(const LightingPass&) = delete;
  LightingPass& operator=(const LightingPass&) = delete;

  // The lit image of the frame whose shadows (and G-buffer and contact answers) voxshadow left on the device,
  // with the scene's ambient light and sky (push.ambient, push.sky).
  std::vector<float> light(const vs::VulkanShadows& shadows, const vs::gpu::ShadePush& scenePush) {
    const std::size_t pixels = std::size_t(shadows.width) * shadows.height;
    reserveImage(pixels * 4 * sizeof(float));
    const VkBuffer bound[8] = {shadows.gbuffer, shadows.visibility, image_, shadows.texels, VK_NULL_HANDLE,
                               shadows.lights, shadows.momentsPositive, shadows.momentsNegative};
    VkDescriptorBufferInfo infos[8]{};
    VkWriteDescriptorSet writes[8]{};
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
    vkUpdateDescriptorSets(device_, 8, writes, 0, nullptr);
    Push push{};
    std::memcpy(push.ambient, &scenePush.ambient, sizeof push.ambient);
    std::memcpy(push.sky, &scenePush.sky, sizeof push.sky);
    push.size[0] = shadows.width;
    push.size[1] = shadows.height;
    push.size[2] = shadows.lightCount;
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
    vkCmdPushConstants(cmd, layout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, &push);
    vkCmdDispatch(cmd, (shadows.width + 7) / 8, (shadows.height + 7) / 8, 1);
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
    // voxshadow submitted its frame on this queue and waited for it (standalone submission, README): the
    // engine's work that reads its buffers follows on the same queue.
    check(vkQueueSubmit(engine_.queue(), 1, &submit, VK_NULL_HANDLE), "vkQueueSubmit");
    check(vkQueueWaitIdle(engine_.queue()), "vkQueueWaitIdle");
    vkFreeCommandBuffers(device_, commandPool_, 1, &cmd);
    std::vector<float> out(pixels * 4);
    void* mapped = nullptr;
    check(vkMapMemory(device_, imageMemory_, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    std::memcpy(out.data(), mapped, out.size() * sizeof(float));
    vkUnmapMemory(device_, imageMemory_);
    return out;
  }

 private:
  struct Push {
    float ambient[4];
    float sky[4];
    std::uint32_t size[4];
  };
  void reserveImage(std::size_t bytes) {
    if (image_ && imageBytes_ >= bytes) return;
    if (image_) vkDestroyBuffer(device_, image_, nullptr);
    if (imageMemory_) vkFreeMemory(device_, imageMemory_, nullptr);
    VkBufferCreateInfo bci{};
    bci.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    bci.size = bytes;
    bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    check(vkCreateBuffer(device_, &bci, nullptr, &image_), "vkCreateBuffer");
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, image_, &req);
    VkPhysicalDeviceMemoryProperties props{};
    vkGetPhysicalDeviceMemoryProperties(engine_.physicalDevice(), &props);
    const VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    std::uint32_t type = props.memoryTypeCount;
    for (std::uint32_t t = 0; t < props.memoryTypeCount && type == props.memoryTypeCount; ++t)
      if ((req.memoryTypeBits & (1u << t)) && (props.memoryTypes[t].propertyFlags & want) == want) type = t;
    if (type == props.memoryTypeCount) throw std::runtime_error("no host-visible memory for the image");
    VkMemoryAllocateInfo mai{};
    mai.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    mai.allocationSize = req.size;
    mai.memoryTypeIndex = type;
    check(vkAllocateMemory(device_, &mai, nullptr, &imageMemory_), "vkAllocateMemory");
    check(vkBindBufferMemory(device_, image_, imageMemory_, 0), "vkBindBufferMemory");
    imageBytes_ = bytes;
  }

  const Engine& engine_;
  VkDevice device_;
  VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkShaderModule module_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  VkCommandPool commandPool_ = VK_NULL_HANDLE;
  VkBuffer image_ = VK_NULL_HANDLE;
  VkDeviceMemory imageMemory_ = VK_NULL_HANDLE;
  std::size_t imageBytes_ = 0;
};

// The image as an 8-bit sRGB PNG (Reinhard, then the sRGB curve).
void writePng(const std::filesystem::path& path, const std::vector<float>& rgba, int width, int height) {
  std::vector<unsigned char> bytes(std::size_t(width) * std::size_t(height) * 3);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const float linear = rgba[(i / 3) * 4 + i % 3];
    const float mapped = linear / (1.0f + linear);
    const float encoded = mapped <= 0.0031308f ? 12.92f * mapped : 1.055f * std::pow(mapped, 1.0f / 2.4f) - 0.055f;
    bytes[i] = static_cast<unsigned char>(std::lround(std::clamp(encoded, 0.0f, 1.0f) * 255.0f));
  }
  const std::filesystem::path partial = path.string() + ".partial";
  auto out = OIIO::ImageOutput::create(path.string());
  if (!out) throw std::runtime_error(path.string() + ": no image writer for this file name");
  const OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  if (!out->open(partial.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT8, bytes.data()) || !out->close())
    throw std::runtime_error(path.string() + ": " + out->geterror());
  std::filesystem::rename(partial, path);  // nothing half-written under the name asked for
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc < 2) {
      std::fprintf(stderr, "usage: host_engine <output.png> [--frames N] [--size WxH] [--require-validation]\n");
      return 2;
    }
    const std::filesystem::path output = argv[1];
    int frames = 3, width = 320, height = 180;
    bool requireValidation = false;
    for (int i = 2; i < argc; ++i) {
      const std::string flag = argv[i];
      const bool hasValue = i + 1 < argc;
      if (flag == "--require-validation") {
        requireValidation = true;
      } else if (flag == "--frames" && hasValue) {
        frames = std::atoi(argv[++i]);
      } else if (flag == "--size" && hasValue && std::sscanf(argv[i + 1], "%dx%d", &width, &height) == 2) {
        ++i;
      } else {
        std::fprintf(stderr, "host_engine: unknown option %s\n", argv[i]);
        return 2;
      }
    }
    if (frames < 1 || width < 1 || height < 1 || width > 4096 || height > 4096) {
      std::fprintf(stderr, "host_engine: --frames must be at least 1 and --size within 1x1..4096x4096\n");
      return 2;
    }
    Engine engine;
    if (requireValidation && !engine.validation()) {
      std::fprintf(stderr, "host_engine: --require-validation, but VK_LAYER_KHRONOS_validation is not installed\n");
      return 1;
    }
    std::size_t differing = 0, compared = 0;
    {
      // voxshadow on the engine's device: the context, a tracer and a frame renderer.
      vs::VulkanOptions options;
      options.context = std::make_shared<vs::VulkanContext>(engine.handles());
      std::unique_ptr<vs::Tracer> tracer = vs::makeVulkanTracer(options);
      vs::FrameRenderer renderer(*tracer);
      LightingPass pass(engine);

      // The demo world, with smaller shadow maps than its file's (an example should run in seconds on a CPU).
      const std::filesystem::path dir = output.parent_path().empty() ? std::filesystem::path(".") : output.parent_path();
      vs::SceneDesc desc = vs::parseSceneFile(vs::writeDemoWorld(dir / "host_engine_world").back());
      for (vs::LightDesc& l : desc.lights)
        if (l.shadow) l.shadow->resolution = std::min(l.shadow->resolution, 512);
      vs::Scene scene = vs::Scene::load(std::move(desc));
      vs::RenderOptions frameOptions;
      frameOptions.width = width;
      frameOptions.height = height;
      frameOptions.readShadowTerms = false;  // the engine's pass computes them; the colour is read to compare
      std::vector<float> image;
      for (int f = 0; f < frames; ++f) {
        if (f > 0) {  // the camera walks a little each frame: the cascades scroll, the frame redoes what moved
          vs::CameraDesc camera = *scene.desc().camera;
          camera.position += glm::vec3(0.75f, 0.0f, 0.25f);
          camera.target += glm::vec3(0.75f, 0.0f, 0.25f);
          scene.setCamera(camera);
        }
        const vs::RenderedFrame& frame = renderer.render(scene, frameOptions);
        const vs::VulkanShadows shadows = renderer.vulkanShadows();
        const vs::gpu::ShadePush scenePush = vs::makeShadePush(scene.desc(), width, height, 0, false);
        image = pass.light(shadows, scenePush);
        const std::size_t pixels = std::size_t(width) * std::size_t(height);
        if (frame.color.size() != pixels) throw std::runtime_error("the library's frame has no colour to compare");
        std::size_t differ = 0;
        for (std::size_t p = 0; p < pixels; ++p)
          differ += std::memcmp(&image[p * 4], &frame.color[p], 4 * sizeof(float)) != 0;
        std::printf("host_engine: frame %d: %zu layers traced, %llu texels; %zu of %zu pixels differ from the "
                    "library's own image\n", f, std::size_t(frame.stats.layersTraced),
                    static_cast<unsigned long long>(frame.stats.texelsTraced), differ, pixels);
        differing += differ;
        compared += pixels;
      }
      writePng(output, image, width, height);
    }  // voxshadow's objects go before the engine's device and instance (README's order)
    const std::vector<std::string> messages = engine.messages();
    for (const std::string& m : messages) std::fprintf(stderr, "host_engine: validation: %s\n", m.c_str());
    std::printf("host_engine: wrote %s; %zu of %zu pixels differ; validation layer %s, %zu messages\n",
                output.string().c_str(), differing, compared, engine.validation() ? "on" : "not installed",
                messages.size());
    return differing == 0 && messages.empty() ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "host_engine: %s\n", e.what());
    return 1;
  }
}
