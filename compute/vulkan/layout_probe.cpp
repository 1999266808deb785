// layout_probe.cpp: runs the sentinel-writing probe shader and decodes where each sentinel landed.
#include "compute/vulkan/layout_probe.h"

#include <array>
#include <cstring>

#include "layout_probe.spv.h"
#include "voxel/error.h"

namespace vs {
namespace {

constexpr std::uint32_t kStructs = 14;
// Generous: two elements of the largest record (TraceView, 192 bytes) even if GLSL padded them.
constexpr VkDeviceSize kProbeBytes = 1024;
const char* kNames[kStructs] = {"Region", "Sector", "Brick", "ObjectRecord", "BvhNode", "Affine", "InstanceRecord",
                                "TraceView", "TraceRay", "RayHit", "CameraRays", "VisibilityRays",
                                "VisibilityLight", "VisibilityReceiver"};

}  // namespace

LayoutProbeResult probeGpuLayouts(const VulkanOptions& options) {
  LayoutProbeResult result;
  VulkanContext context(VulkanContextOptions{options.deviceIndex, options.deviceName, options.validation});
  result.device = context.info().name;
  VkDevice dev = context.device();

  std::array<vk::Buffer, kStructs> buffers;
  std::vector<char> zeros(kProbeBytes, 0);
  for (auto& b : buffers) {
    b = context.createHostBuffer(kProbeBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    std::memcpy(b.mapped, zeros.data(), kProbeBytes);
  }

  std::array<VkDescriptorSetLayoutBinding, kStructs> bindings{};
  for (std::uint32_t i = 0; i < kStructs; ++i)
    bindings[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
  vk::ComputePipeline pipeline;
  auto dl = vk::make<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
  dl.bindingCount = kStructs;
  dl.pBindings = bindings.data();
  VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
  vk::check(context.functions().vkCreateDescriptorSetLayout(dev, &dl, context.functions().allocator, &setLayout), "vkCreateDescriptorSetLayout");
  pipeline.setLayout = vk::UniqueDescriptorSetLayout(context.functions(), dev, setLayout);
  pipeline.layout = context.createPipelineLayout(setLayout, 0);
  vk::UniqueShaderModule module = context.createShaderModule(layout_probe, sizeof(layout_probe));
  pipeline.pipeline = context.createComputePipeline(module.get(), pipeline.layout.get());

  VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kStructs};
  auto dp = vk::make<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
  dp.maxSets = 1;
  dp.poolSizeCount = 1;
  dp.pPoolSizes = &size;
  VkDescriptorPool rawPool = VK_NULL_HANDLE;
  vk::check(context.functions().vkCreateDescriptorPool(dev, &dp, context.functions().allocator, &rawPool), "vkCreateDescriptorPool");
  vk::UniqueDescriptorPool pool(context.functions(), dev, rawPool);
  auto ai = vk::make<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
  ai.descriptorPool = rawPool;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &setLayout;
  VkDescriptorSet set = VK_NULL_HANDLE;
  vk::check(context.functions().vkAllocateDescriptorSets(dev, &ai, &set), "vkAllocateDescriptorSets");
  std::array<VkDescriptorBufferInfo, kStructs> infos{};
  std::array<VkWriteDescriptorSet, kStructs> writes{};
  for (std::uint32_t i = 0; i < kStructs; ++i) {
    infos[i] = {buffers[i].get(), 0, VK_WHOLE_SIZE};
    writes[i] = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
    writes[i].dstSet = set;
    writes[i].dstBinding = i;
    writes[i].descriptorCount = 1;
    writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    writes[i].pBufferInfo = &infos[i];
  }
  context.functions().vkUpdateDescriptorSets(dev, kStructs, writes.data(), 0, nullptr);

  context.submitAndWait([&](VkCommandBuffer cmd) {
    context.functions().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.pipeline.get());
    context.functions().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout.get(), 0, 1, &set, 0, nullptr);
    context.functions().vkCmdDispatch(cmd, 1, 1, 1);
    auto toHost = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
    toHost.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0,
                         nullptr, 0, nullptr);
  });

  // Sentinel layout (layout_probe.comp): 0x40000000 | struct << 16 | element << 8 | scalar.
  for (std::uint32_t s = 0; s < kStructs; ++s) {
    GpuStructLayout out;
    out.name = kNames[s];
    out.stride = -1;
    std::array<std::int64_t, 2> firstScalar{-1, -1};
    std::vector<std::int64_t> offsets;
    const auto* words = static_cast<const std::uint32_t*>(buffers[s].mapped);
    for (std::size_t w = 0; w < kProbeBytes / 4; ++w) {
      std::uint32_t v = words[w];
      if ((v & 0xff000000u) != 0x40000000u || ((v >> 16) & 0xffu) != s) continue;
      std::uint32_t e = (v >> 8) & 0xffu, k = v & 0xffu;
      if (e > 1) continue;
      if (k == 0) firstScalar[e] = std::int64_t(w * 4);
      if (e == 0) {
        if (offsets.size() <= k) offsets.resize(k + 1, -1);
        offsets[k] = std::int64_t(w * 4);
      }
    }
    if (firstScalar[0] >= 0 && firstScalar[1] >= 0) out.stride = firstScalar[1] - firstScalar[0];
    out.scalarOffsets = std::move(offsets);
    result.layouts.push_back(std::move(out));
  }
  result.validationMessages = context.validationMessages();
  return result;
}

}  // namespace vs
