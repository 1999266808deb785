// vulkan_lighting.cpp: the lighting pipeline, its buffers and one dispatch per frame.
#include "lighting/vulkan_lighting.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <mutex>

#include "deferred_lighting.spv.h"
#include "deferred_lighting_variant.spv.h"
#include "evsm_moments.spv.h"
#include "gbuffer_import.spv.h"
#include "gbuffer_resolve.spv.h"
#include "visibility_spread.spv.h"
#include "lighting/host_gbuffer.h"
#include "lighting/lighting_variant.h"
#include "lighting/shared/lighting_interface.h"
#include "voxel/error.h"

namespace vs {

namespace {

VkDescriptorType lightingDescriptorType(std::uint32_t b) {
  return b == gpu::VS_LIGHTING_BINDING_VIEWS ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
}

// One memory barrier: the writes of `srcAccess` at `srcStages` made available to `dstAccess` at `dstStages`.
void memoryBarrier(const VulkanContext& context, VkCommandBuffer cmd, VkPipelineStageFlags srcStages,
                   VkAccessFlags srcAccess, VkPipelineStageFlags dstStages, VkAccessFlags dstAccess) {
  auto barrier = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
  barrier.srcAccessMask = srcAccess;
  barrier.dstAccessMask = dstAccess;
  context.functions().vkCmdPipelineBarrier(cmd, srcStages, dstStages, 0, 1, &barrier, 0, nullptr, 0, nullptr);
}

// The host's and earlier shaders' writes (the trace's, the helper passes'), before a pass's shaders read them.
void barrierBeforeShaders(const VulkanContext& context, VkCommandBuffer cmd) {
  memoryBarrier(context, cmd, VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_ACCESS_HOST_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_ACCESS_SHADER_READ_BIT);
}

// Whatever the host's own work wrote before (its G-buffer images: attachments, transfers, shaders), before a
// pass's shaders read it.
void barrierBeforeHostImages(const VulkanContext& context, VkCommandBuffer cmd) {
  memoryBarrier(context, cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_ACCESS_MEMORY_WRITE_BIT,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
}

// One binding of a helper pass: a storage buffer, or an image view read through the pass's immutable sampler.
struct HelperBinding {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkImageView image = VK_NULL_HANDLE;
  VkImageLayout layout = VK_IMAGE_LAYOUT_UNDEFINED;
  HelperBinding(VkBuffer b) : buffer(b) {}
  HelperBinding(VkImageView view, VkImageLayout l) : image(view), layout(l) {}
  VkDescriptorType type() const {
    return image ? VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  }
};

// The lighting pass's pipelines on one device, compiled once and shared by every VulkanLighting on it
// (VulkanContext::shared): a renderer made for one frame, or a second renderer, compiles nothing again, where
// one compile of the general shader takes a few hundred milliseconds on llvmpipe. The context owns it and
// destroys it before its device, so it holds the context by reference only.
struct LightingPipelines {
  VulkanContext& context;
  std::mutex mutex;  // guards the variants and the moment pipeline, made by whichever pass asks first
  // The general lighting shader's layouts, which serve its variants too, and the shader's pipeline.
  vk::UniqueDescriptorSetLayout setLayout;
  vk::UniquePipelineLayout layout;
  std::shared_ptr<vk::UniquePipeline> generalPipeline;
  vk::UniqueShaderModule module;         // the general lighting shader
  vk::UniqueShaderModule variantModule;  // the build its variants specialise, made with the first variant
  // The specialised variants (lighting_variant.h), the least recently used first. A frame loop whose lights
  // keep their kinds and filters uses one. Held by shared pointer: a dispatch keeps the one it records.
  std::vector<std::pair<LightingVariant, std::shared_ptr<vk::UniquePipeline>>> variants;
  int compiled = 0;
  // The moment pass: the same descriptor set layout, its own push block; made with the first EVSM work (a
  // compile that frames without EVSM do not pay for).
  vk::UniquePipelineLayout momentLayout;
  vk::UniquePipeline momentPipeline;
  vk::UniqueShaderModule momentModule;
  // The passes that bring a trace's results into the lighting pass's buffers on the device (the G-buffer
  // resolve, the spread of visibility answers): each has its own set of storage buffers and push block, and is
  // made on its first use.
  struct HelperPass {
    vk::UniqueDescriptorSetLayout setLayout;
    vk::UniquePipelineLayout layout;
    vk::UniquePipeline pipeline;
    vk::UniqueShaderModule module;
  };
  // The import's immutable sampler (nearest texel; texelFetch reads by texel anyway), made with the pass;
  // declared before the passes, whose set layouts use it, so that it is destroyed after them.
  vk::UniqueSampler nearest;
  HelperPass resolve, spread, import;

  // At most this many specialised variants are kept: a caller that keeps switching lights' filters recompiles,
  // it does not grow without bound.
  static constexpr std::size_t kKeptVariants = 8;

  explicit LightingPipelines(VulkanContext& c) : context(c) {
    VkDevice dev = context.device();
    std::array<VkDescriptorSetLayoutBinding, gpu::VS_LIGHTING_BINDING_COUNT> bindings{};
    for (std::uint32_t b = 0; b < gpu::VS_LIGHTING_BINDING_COUNT; ++b)
      bindings[b] = {b, lightingDescriptorType(b), 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
    auto dl = vk::make<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
    dl.bindingCount = std::uint32_t(bindings.size());
    dl.pBindings = bindings.data();
    VkDescriptorSetLayout made = VK_NULL_HANDLE;
    vk::check(context.functions().vkCreateDescriptorSetLayout(dev, &dl, context.functions().allocator, &made), "vkCreateDescriptorSetLayout");
    setLayout = vk::UniqueDescriptorSetLayout(context.functions(), dev, made);
    module = context.createShaderModule(deferred_lighting, sizeof deferred_lighting);
    layout = context.createPipelineLayout(setLayout.get(), sizeof(gpu::ShadePush));
    generalPipeline = std::make_shared<vk::UniquePipeline>(context.createComputePipeline(module.get(), layout.get()));
    compiled = 1;
  }

  bool made(const LightingVariant& shape) {
    std::lock_guard lock(mutex);
    return std::any_of(variants.begin(), variants.end(), [&](const auto& v) { return v.first == shape; });
  }

  // The pipeline of `variant` (LightingVariant{}: the general shader), a specialised one compiled on its first
  // use and moved to the back of the list (most recently used) on each.
  std::shared_ptr<vk::UniquePipeline> pipelineOf(const LightingVariant& variant) {
    if (variant == LightingVariant{}) return generalPipeline;
    std::lock_guard lock(mutex);
    auto it = std::find_if(variants.begin(), variants.end(), [&](const auto& v) { return v.first == variant; });
    if (it != variants.end()) {
      std::rotate(it, it + 1, variants.end());
      return variants.back().second;
    }
    if (!variantModule)
      variantModule = context.createShaderModule(deferred_lighting_variant, sizeof deferred_lighting_variant);
    const auto constants = variant.constants();
    std::array<VkSpecializationMapEntry, gpu::VS_LIGHTING_SPEC_COUNT> entries{};
    for (std::uint32_t i = 0; i < entries.size(); ++i)
      entries[i] = {i, std::uint32_t(i * sizeof(std::int32_t)), sizeof(std::int32_t)};
    VkSpecializationInfo info{std::uint32_t(entries.size()), entries.data(), sizeof constants, constants.data()};
    auto made = std::make_shared<vk::UniquePipeline>(context.createComputePipeline(variantModule.get(), layout.get(), &info));
    ++compiled;
    if (variants.size() == kKeptVariants) variants.erase(variants.begin());
    variants.emplace_back(variant, std::move(made));
    return variants.back().second;
  }

  // `pass`, made now if it was not: `bindings` storage buffers, a push block of `pushBytes`.
  const HelperPass& helper(HelperPass& pass, const std::uint32_t* code, std::size_t codeBytes, std::uint32_t bindings,
                           std::uint32_t pushBytes) {
    const std::vector<VkDescriptorType> types(bindings, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
    return helper(pass, code, codeBytes, types, pushBytes);
  }
  // `pass`, made now if it was not: a binding of each type in `types` (combined image samplers read through
  // `nearest`), a push block of `pushBytes` (0: none).
  const HelperPass& helper(HelperPass& pass, const std::uint32_t* code, std::size_t codeBytes,
                           std::span<const VkDescriptorType> types, std::uint32_t pushBytes) {
    std::lock_guard lock(mutex);
    if (pass.pipeline) return pass;
    const auto bindings = std::uint32_t(types.size());
    if (!nearest && std::find(types.begin(), types.end(), VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER) != types.end()) {
      auto si = vk::make<VkSamplerCreateInfo>(VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO);
      si.magFilter = VK_FILTER_NEAREST;
      si.minFilter = VK_FILTER_NEAREST;
      si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
      si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
      si.maxLod = 0.0f;
      VkSampler made = VK_NULL_HANDLE;
      vk::check(context.functions().vkCreateSampler(context.device(), &si, context.functions().allocator, &made),
                "vkCreateSampler");
      nearest = vk::UniqueSampler(context.functions(), context.device(), made);
    }
    const VkSampler sampler = nearest.get();
    std::vector<VkDescriptorSetLayoutBinding> layoutBindings(bindings);
    for (std::uint32_t b = 0; b < bindings; ++b)
      layoutBindings[b] = {b, types[b], 1, VK_SHADER_STAGE_COMPUTE_BIT,
                           types[b] == VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER ? &sampler : nullptr};
    auto dl = vk::make<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
    dl.bindingCount = bindings;
    dl.pBindings = layoutBindings.data();
    VkDescriptorSetLayout made = VK_NULL_HANDLE;
    vk::check(context.functions().vkCreateDescriptorSetLayout(context.device(), &dl, context.functions().allocator, &made),
              "vkCreateDescriptorSetLayout");
    pass.setLayout = vk::UniqueDescriptorSetLayout(context.functions(), context.device(), made);
    pass.module = context.createShaderModule(code, codeBytes);
    pass.layout = context.createPipelineLayout(pass.setLayout.get(), pushBytes);
    pass.pipeline = context.createComputePipeline(pass.module.get(), pass.layout.get());
    return pass;
  }

  void makeMomentPipeline() {
    std::lock_guard lock(mutex);
    if (momentPipeline) return;
    momentModule = context.createShaderModule(evsm_moments, sizeof evsm_moments);
    momentLayout = context.createPipelineLayout(setLayout.get(), sizeof(gpu::EvsmPush));
    momentPipeline = context.createComputePipeline(momentModule.get(), momentLayout.get());
  }
};

}  // namespace

struct VulkanLighting::Impl {
  std::shared_ptr<VulkanContext> owner;  // first member: the device outlives every resource below
  VulkanContext& context;
  std::shared_ptr<LightingPipelines> pipelines;  // this device's, shared with every pass on it
  LightingVariant wantedVariant;  // this call's: LightingVariant{} is the general shader
  LightingVariant lastShape;  // the frame shape of the last call, asked for callsOfShape calls in a row
  int callsOfShape = 0;
  bool specialize = true;
  vk::UniqueDescriptorPool descriptorPool;
  VkDescriptorSet descriptorSet = VK_NULL_HANDLE;
  // Host-visible buffers in binding order; each grows to the largest frame so far.
  std::array<vk::Buffer, gpu::VS_LIGHTING_BINDING_COUNT> buffers;
  // The view records' buffer as the shader reads it (VS_LIGHTING_BINDING_VIEWS), made again with the buffer.
  vk::UniqueBufferView viewTexels;
  // A buffer was replaced outside sizeFor (the resolve's G-buffer, the spread's answers): the set is written
  // again before it is used.
  bool descriptorsStale = false;

  // Each helper pass's descriptor set (LightingPipelines::HelperPass), allocated with its first run.
  struct HelperSet {
    vk::UniqueDescriptorPool pool;
    VkDescriptorSet set = VK_NULL_HANDLE;
  };
  HelperSet resolveSet, spreadSet, importSet;
  vk::Buffer importRecord;  // the host G-buffer's record (HostGBufferRecord)
  // The G-buffer resolve's tables (the last ones written, compared before writing again), and how many pixels'
  // texels the G-buffer buffer holds whole, as the host's G-buffer has them (0: not whole, or unknown).
  vk::Buffer resolveInstances, resolvePalette;
  std::vector<gpu::GBufferInstance> heldInstances;
  std::vector<glm::vec4> heldPalette;
  bool tablesHeld = false;
  std::size_t gbufferHeld = 0;
  // The visibility receivers the resolve writes beside the G-buffer, and how many pixels' it holds whole, as
  // vsReceiverOf the G-buffer the pass holds (0: not whole: a G-buffer written from the host since).
  vk::Buffer receivers;
  std::size_t receiversHeld = 0;
  // How many answers (pixels x lights) the visibility buffer holds whole, as the host's answers are (0: not
  // whole, or unknown); the light slots the spread last read.
  std::size_t visibilityHeld = 0;
  vk::Buffer spreadSlots;

  explicit Impl(std::shared_ptr<VulkanContext> c) : owner(std::move(c)), context(*owner) {
    pipelines = std::static_pointer_cast<LightingPipelines>(context.shared("lighting pipelines", [&] {
      return std::static_pointer_cast<void>(std::make_shared<LightingPipelines>(context));
    }));
    VkDevice dev = context.device();
    const std::array<VkDescriptorPoolSize, 2> sizes{{{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, gpu::VS_LIGHTING_BINDING_COUNT - 1},
                                                     {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 1}}};
    auto dp = vk::make<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
    dp.maxSets = 1;
    dp.poolSizeCount = std::uint32_t(sizes.size());
    dp.pPoolSizes = sizes.data();
    VkDescriptorPool pool = VK_NULL_HANDLE;
    vk::check(context.functions().vkCreateDescriptorPool(dev, &dp, context.functions().allocator, &pool), "vkCreateDescriptorPool");
    descriptorPool = vk::UniqueDescriptorPool(context.functions(), dev, pool);
    VkDescriptorSetLayout setLayout = pipelines->setLayout.get();
    auto ai = vk::make<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
    ai.descriptorPool = pool;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &setLayout;
    vk::check(context.functions().vkAllocateDescriptorSets(dev, &ai, &descriptorSet), "vkAllocateDescriptorSets");
  }
  // Binding b holds at least `bytes` (never 0: an empty array binds a 16-byte buffer); true when it was replaced.
  bool reserve(std::uint32_t b, std::size_t bytes) {
    const VkDeviceSize need = std::max<VkDeviceSize>(16, VkDeviceSize(bytes));
    if (buffers[b].buffer && buffers[b].size >= need) return false;
    if (b == gpu::VS_LIGHTING_BINDING_VIEWS) {
      const std::uint64_t texels = need / 16;
      if (texels > context.info().maxTexelBufferElements)
        throwRuntime("lighting: " + std::to_string(texels / gpu::VS_SHADE_VIEW_TEXELS) + " shadow views need " +
                     std::to_string(texels) + " texels of a texel buffer, more than maxTexelBufferElements (" +
                     std::to_string(context.info().maxTexelBufferElements) + ") of " + context.info().name +
                     "; use fewer shadowed lights or --backend cpu");
      buffers[b] = context.createHostBuffer(need, VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT);
      viewTexels = context.createTexelView(buffers[b], VK_FORMAT_R32G32B32A32_UINT);
      return true;
    }
    const VkDeviceSize maxRange = context.info().maxStorageBufferRange;
    if (need > maxRange)
      throwRuntime("lighting: a " + std::to_string(need) + "-byte buffer exceeds maxStorageBufferRange (" +
                   std::to_string(maxRange) + ") of " + context.info().name + "; render smaller or use --backend cpu");
    // The layer store is also where traced texels are copied on the device (VulkanTracer::traceInto).
    const VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
        (b == gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS ? VkBufferUsageFlags(VK_BUFFER_USAGE_TRANSFER_DST_BIT) : VkBufferUsageFlags(0));
    buffers[b] = context.createHostBuffer(need, usage);
    if (b == gpu::VS_LIGHTING_BINDING_GBUFFER) gbufferHeld = 0;
    if (b == gpu::VS_LIGHTING_BINDING_VISIBILITY) visibilityHeld = 0;
    return true;
  }

  void fill(std::uint32_t b, const void* data, std::size_t bytes) {
    reserve(b, bytes);
    if (bytes) std::memcpy(buffers[b].mapped, data, bytes);
  }

  void writeDescriptors() {
    std::array<VkDescriptorBufferInfo, gpu::VS_LIGHTING_BINDING_COUNT> infos{};
    std::array<VkWriteDescriptorSet, gpu::VS_LIGHTING_BINDING_COUNT> writes{};
    const VkBufferView viewHandle = viewTexels.get();
    for (std::uint32_t b = 0; b < gpu::VS_LIGHTING_BINDING_COUNT; ++b) {
      infos[b] = {buffers[b].get(), 0, VK_WHOLE_SIZE};
      writes[b] = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
      writes[b].dstSet = descriptorSet;
      writes[b].dstBinding = b;
      writes[b].descriptorCount = 1;
      writes[b].descriptorType = lightingDescriptorType(b);
      if (b == gpu::VS_LIGHTING_BINDING_VIEWS) writes[b].pTexelBufferView = &viewHandle;
      else writes[b].pBufferInfo = &infos[b];
    }
    context.functions().vkUpdateDescriptorSets(context.device(), std::uint32_t(writes.size()), writes.data(), 0, nullptr);
  }

  bool holdsStore(std::size_t texels) const {
    return heldSizes.size() == 6 && heldSizes[3] == texels && buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS].buffer;
  }
  bool holdsMoments(std::size_t texels) const { return heldSizes.size() == 6 && heldSizes[5] == texels; }

  // The moment pass's work of the current call, recorded before the lighting dispatch (null: none).
  const MomentWork* momentWork = nullptr;

  // Pixels shaded, moments computed and dispatches recorded by the current call.
  std::size_t shadedPixels = 0;
  std::size_t momentTexels = 0;
  int dispatches = 0;

  // The sizes the buffers' contents were last written for (pixels, lights, views, texels, visibility answers);
  // moment texels); empty when they hold no whole frame (none yet, replaced, or a pass that failed half-way).
  std::vector<std::size_t> heldSizes;

  // Every buffer sized for the frame; true when every one was kept (so their contents are the last frame's).
  bool sizeFor(const ShadeInputs& inputs, std::size_t pixels, std::size_t visibility) {
    const std::size_t lights = inputs.lights.size();
    // A replaced buffer needs its descriptor rewritten; a kept one is written over in place.
    bool replaced = !buffers[0].buffer;
    auto sized = [&](std::uint32_t b, std::size_t bytes) { replaced = reserve(b, bytes) || replaced; };
    sized(gpu::VS_LIGHTING_BINDING_GBUFFER, pixels * sizeof(gpu::GBufferTexel));
    sized(gpu::VS_LIGHTING_BINDING_LIGHTS, lights * sizeof(gpu::ShadeLight));
    sized(gpu::VS_LIGHTING_BINDING_VIEWS, inputs.views.size() * sizeof(gpu::ShadeView));
    sized(gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS, inputs.shadowTexels.size() * sizeof(float));
    sized(gpu::VS_LIGHTING_BINDING_VISIBILITY, visibility * sizeof(std::uint32_t));
    sized(gpu::VS_LIGHTING_BINDING_SHADOW_TERMS, pixels * lights * sizeof(float));
    sized(gpu::VS_LIGHTING_BINDING_COLOR, pixels * sizeof(glm::vec4));
    sized(gpu::VS_LIGHTING_BINDING_PIXELS, pixels * sizeof(std::uint32_t));
    sized(gpu::VS_LIGHTING_BINDING_MOMENTS, inputs.momentTexels * sizeof(glm::vec2));
    sized(gpu::VS_LIGHTING_BINDING_MOMENTS_NEGATIVE, inputs.momentTexels * sizeof(glm::vec2));
    // The moment pass's inputs: sized for each call's work (reserveMomentWork); bound from the start.
    sized(gpu::VS_LIGHTING_BINDING_EVSM_VIEWS, 0);
    sized(gpu::VS_LIGHTING_BINDING_EVSM_JOBS, 0);
    sized(gpu::VS_LIGHTING_BINDING_EVSM_BORDER, 0);
    sized(gpu::VS_LIGHTING_BINDING_EVSM_SCRATCH, 0);
    sized(gpu::VS_LIGHTING_BINDING_EVSM_SCRATCH_NEGATIVE, 0);
    if (replaced || descriptorsStale) writeDescriptors();
    descriptorsStale = false;
    return !replaced;
  }

  static std::vector<std::size_t> sizesOf(const ShadeInputs& inputs, std::size_t pixels, std::size_t visibility) {
    return {pixels, inputs.lights.size(), inputs.views.size(), inputs.shadowTexels.size(), visibility,
            inputs.momentTexels};
  }

  // The variant this call's lights and push block want (made on the first dispatch that shades with it): the
  // frame shape's own once it repeated often enough or is already made (by any pass on the device), else the
  // general one.
  void chooseVariant(const ShadeInputs& inputs, const gpu::ShadePush& push) {
    const LightingVariant shape = specialize ? LightingVariant::of(inputs.lights, push) : LightingVariant{};
    callsOfShape = shape == lastShape ? callsOfShape + 1 : 1;
    lastShape = shape;
    wantedVariant = callsOfShape >= VulkanLighting::kCallsBeforeSpecializing || pipelines->made(shape)
        ? shape : LightingVariant{};
  }

  // Writes the moment pass's records (the store's buffers were sized by sizeFor); the pass itself is recorded
  // with the next dispatch.
  void writeMomentWork(const MomentWork* work, LightingTraffic& traffic) {
    momentWork = work && !work->empty() ? work : nullptr;
    if (!momentWork) return;
    pipelines->makeMomentPipeline();
    bool replaced = false;
    auto put = [&](std::uint32_t b, const void* data, std::size_t bytes) {
      replaced = reserve(b, bytes) || replaced;
      if (bytes) std::memcpy(buffers[b].mapped, data, bytes);
      traffic.uploaded += bytes;
    };
    put(gpu::VS_LIGHTING_BINDING_EVSM_VIEWS, work->views.data(), work->views.size() * sizeof(gpu::EvsmView));
    put(gpu::VS_LIGHTING_BINDING_EVSM_JOBS, work->jobs.data(), work->jobs.size() * sizeof(gpu::EvsmJob));
    put(gpu::VS_LIGHTING_BINDING_EVSM_BORDER, work->border.data(), work->border.size() * sizeof(std::int32_t));
    replaced = reserve(gpu::VS_LIGHTING_BINDING_EVSM_SCRATCH, work->scratchTexels * sizeof(glm::vec2)) || replaced;
    replaced = reserve(gpu::VS_LIGHTING_BINDING_EVSM_SCRATCH_NEGATIVE, work->scratchTexels * sizeof(glm::vec2)) || replaced;
    if (replaced) writeDescriptors();
  }

  void writeRecords(const ShadeInputs& inputs, LightingTraffic& traffic) {
    fill(gpu::VS_LIGHTING_BINDING_LIGHTS, inputs.lights.data(), inputs.lights.size() * sizeof(gpu::ShadeLight));
    fill(gpu::VS_LIGHTING_BINDING_VIEWS, inputs.views.data(), inputs.views.size() * sizeof(gpu::ShadeView));
    traffic.uploaded += inputs.lights.size() * sizeof(gpu::ShadeLight) + inputs.views.size() * sizeof(gpu::ShadeView);
  }

  ShadeOutput shade(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                    std::span<const std::uint32_t> rayVisibility, LightingTraffic& traffic, bool storeInPlace,
                    const MomentWork* moments, bool readColor, bool readTerms, bool gbufferOnDevice,
                    bool visibilityOnDevice) {
    std::vector<std::uint32_t> clear;
    rayVisibility = checkShadeSizes(inputs, push, gbuffer, rayVisibility, clear);
    const std::size_t pixels = gbuffer.texels.size();
    if (storeInPlace && !holdsStore(inputs.shadowTexels.size()))
      throwRuntime("lighting: the layer store was to be read in place, but the pass holds no store of " +
                   std::to_string(inputs.shadowTexels.size()) + " texels");
    heldSizes.clear();
    // A kept store keeps its buffer: sizing for the same texel count replaces no buffer of it.
    sizeFor(inputs, pixels, rayVisibility.size());
    writeGBuffer(gbuffer, gbufferOnDevice, traffic);
    writeRecords(inputs, traffic);
    if (!storeInPlace) {
      fill(gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS, inputs.shadowTexels.data(), inputs.shadowTexels.size() * sizeof(float));
      traffic.uploaded += inputs.shadowTexels.size() * sizeof(float);
    }
    writeVisibility(rayVisibility, visibilityOnDevice, traffic);
    if (inputs.momentTexels > 0 && (!moments || moments->vertical != inputs.momentTexels))
      throwBadInput("lighting: a frame with EVSM layers needs the work of its whole moment store");
    writeMomentWork(moments, traffic);
    chooseVariant(inputs, push);
    dispatch(push);
    // Visibility answers made up here (`clear`) are as good as given ones: the next frame has the same.
    heldSizes = sizesOf(inputs, pixels, rayVisibility.size());
    ShadeOutput out;
    readResults(readColor ? &out.color : nullptr, readTerms ? &out.shadowTerms : nullptr, traffic);
    return out;
  }

  // The host's G-buffer into the pass's buffer (sized), unless the device resolve left it there whole
  // (resolveGBuffer, `onDevice`).
  void writeGBuffer(const GBuffer& gbuffer, bool onDevice, LightingTraffic& traffic) {
    const std::size_t pixels = gbuffer.texels.size();
    if (onDevice && gbufferHeld == pixels) return;
    fill(gpu::VS_LIGHTING_BINDING_GBUFFER, gbuffer.texels.data(), pixels * sizeof(gpu::GBufferTexel));
    traffic.uploaded += pixels * sizeof(gpu::GBufferTexel);
    gbufferHeld = pixels;
    receiversHeld = 0;
  }

  void resolveGBuffer(const CameraTraceBuffers& trace, const GBufferTables& tables, const GBuffer& current,
                      LightingTraffic& traffic) {
    const std::size_t pixels = current.texels.size();
    if (pixels == 0 || pixels != std::size_t(current.width) * std::size_t(current.height))
      throwBadInput("lighting: the G-buffer to resolve into has " + std::to_string(pixels) + " texels for " +
                    std::to_string(current.width) + "x" + std::to_string(current.height) + " pixels");
    if (trace.rays == 0 || !trace.hits || !trace.camera)
      throwBadInput("lighting: no camera trace's hits to resolve (VulkanTracer::lastCameraTrace right after traceCamera)");
    if (trace.pixels != pixels || trace.rays > pixels)
      throwBadInput("lighting: a camera trace of " + std::to_string(trace.rays) + " rays over " +
                    std::to_string(trace.pixels) + " pixels to resolve into a G-buffer of " + std::to_string(pixels));
    const VkDeviceSize bytes = pixels * sizeof(gpu::GBufferTexel);
    // A new buffer (the frame outgrew every earlier one, so the next shading call, seeing other sizes than the
    // held frame's, writes and shades it whole): the lighting set must bind it.
    if (reserve(gpu::VS_LIGHTING_BINDING_GBUFFER, bytes)) descriptorsStale = true;
    if (gbufferHeld != pixels && trace.listed) {
      // The listed pixels would update a G-buffer the pass does not hold whole: the host's copy goes up whole.
      std::memcpy(buffers[gpu::VS_LIGHTING_BINDING_GBUFFER].mapped, current.texels.data(), bytes);
      traffic.uploaded += bytes;
      gbufferHeld = pixels;
      receiversHeld = 0;
      return;
    }
    const VkDeviceSize receiverBytes = pixels * sizeof(gpu::VisibilityReceiver);
    if (!receivers.buffer || receivers.size < receiverBytes) {
      receiversHeld = 0;
      receivers = vk::Buffer{};
      receivers = context.createDeviceBuffer(receiverBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    }
    // A listed trace updates receivers held whole; a whole one makes them whole.
    const bool receiversWhole = !trace.listed || receiversHeld == pixels;
    gbufferHeld = 0;  // until the resolve has run
    receiversHeld = 0;
    const LightingPipelines::HelperPass& pass = pipelines->helper(
        pipelines->resolve, gbuffer_resolve, sizeof gbuffer_resolve, gpu::VS_RESOLVE_BINDING_COUNT, sizeof(gpu::ResolvePush));
    // The tables change with the scene's instances and palettes only: written when they differ.
    const bool sameTables = tablesHeld && heldInstances.size() == tables.instances.size() &&
                            heldPalette.size() == tables.palette.size() &&
                            std::memcmp(heldInstances.data(), tables.instances.data(),
                                        tables.instances.size() * sizeof(gpu::GBufferInstance)) == 0 &&
                            std::memcmp(heldPalette.data(), tables.palette.data(), tables.palette.size() * sizeof(glm::vec4)) == 0;
    if (!sameTables) {
      tablesHeld = false;
      auto put = [&](vk::Buffer& b, const void* data, std::size_t size) {
        const VkDeviceSize need = std::max<VkDeviceSize>(16, size);
        if (!b.buffer || b.size < need) b = context.createHostBuffer(need, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
        if (size) std::memcpy(b.mapped, data, size);
        traffic.uploaded += size;
      };
      put(resolveInstances, tables.instances.data(), tables.instances.size() * sizeof(gpu::GBufferInstance));
      put(resolvePalette, tables.palette.data(), tables.palette.size() * sizeof(glm::vec4));
      heldInstances = tables.instances;
      heldPalette = tables.palette;
      tablesHeld = true;
    }
    gpu::ResolvePush push{};
    push.camera = trace.record;
    push.counts = glm::uvec4(std::uint32_t(trace.rays), std::uint32_t(tables.instances.size()), 0u, 0u);
    const std::array<VkBuffer, gpu::VS_RESOLVE_BINDING_COUNT> bound{
        trace.hits, trace.camera, resolveInstances.get(), resolvePalette.get(),
        buffers[gpu::VS_LIGHTING_BINDING_GBUFFER].get(), receivers.get()};
    runHelper(pass, resolveSet, bound, &push, sizeof push, trace.rays, gpu::VS_RESOLVE_GROUP_SIZE);
    ++traffic.dispatches;
    gbufferHeld = pixels;
    if (receiversWhole) receiversHeld = pixels;
  }

  void importGBuffer(const HostGBuffer& host, int width, int height, LightingTraffic& traffic) {
    checkHostGBuffer(context, host, width, height);
    const gpu::HostGBufferRecord record = hostGBufferRecord(host, width, height);
    const std::size_t pixels = std::size_t(width) * std::size_t(height);
    if (pixels == 0) throwBadInput("RenderOptions.hostGBuffer.width: a frame of no pixels");
    // A new G-buffer buffer: the lighting set must bind it (the next shading call writes and shades whole).
    if (reserve(gpu::VS_LIGHTING_BINDING_GBUFFER, pixels * sizeof(gpu::GBufferTexel))) descriptorsStale = true;
    const VkDeviceSize receiverBytes = pixels * sizeof(gpu::VisibilityReceiver);
    if (!receivers.buffer || receivers.size < receiverBytes) {
      receiversHeld = 0;
      receivers = vk::Buffer{};
      receivers = context.createDeviceBuffer(receiverBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    }
    if (!importRecord.buffer)
      importRecord = context.createHostBuffer(sizeof record, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    std::memcpy(importRecord.mapped, &record, sizeof record);
    traffic.uploaded += sizeof record;
    gbufferHeld = 0;  // until the import has run
    receiversHeld = 0;
    constexpr VkDescriptorType image = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    constexpr VkDescriptorType storage = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    static constexpr std::array<VkDescriptorType, gpu::VS_IMPORT_BINDING_COUNT> types{image, image, image,
                                                                                     storage, storage, storage};
    const LightingPipelines::HelperPass& pass =
        pipelines->helper(pipelines->import, gbuffer_import, sizeof gbuffer_import, types, 0);
    // Without an albedo image the normal image fills its binding (the pass reads white instead).
    const HostImage& albedo = host.albedo.view ? host.albedo : host.normal;
    const std::array<HelperBinding, gpu::VS_IMPORT_BINDING_COUNT> bound{
        HelperBinding(host.depth.view, host.depth.layout), HelperBinding(host.normal.view, host.normal.layout),
        HelperBinding(albedo.view, albedo.layout), HelperBinding(importRecord.get()),
        HelperBinding(buffers[gpu::VS_LIGHTING_BINDING_GBUFFER].get()), HelperBinding(receivers.get())};
    runHelper(pass, importSet, bound, nullptr, 0, (std::uint32_t(width) + gpu::VS_IMPORT_GROUP_WIDTH - 1) / gpu::VS_IMPORT_GROUP_WIDTH,
              (std::uint32_t(height) + gpu::VS_IMPORT_GROUP_HEIGHT - 1) / gpu::VS_IMPORT_GROUP_HEIGHT, true);
    ++traffic.dispatches;
    gbufferHeld = pixels;
    receiversHeld = pixels;
  }

  // Runs a helper pass over `invocations` (rows of workgroups along y past maxComputeWorkGroupCount[0]) with
  // `bound` at its bindings, in one submission: the host's and earlier shaders' writes before it, its writes
  // visible to later shaders and host reads.
  void runHelper(const LightingPipelines::HelperPass& pass, HelperSet& helperSet, std::span<const VkBuffer> bound,
                 const void* push, std::uint32_t pushBytes, std::uint64_t invocations, std::uint32_t groupSize) {
    const std::vector<HelperBinding> bindings(bound.begin(), bound.end());
    if (invocations == 0) throwBadInput("lighting: a helper pass over no invocations");
    const std::uint64_t groups = (invocations + groupSize - 1) / groupSize;
    const std::uint32_t groupsX = std::uint32_t(std::min<std::uint64_t>(groups, context.info().maxWorkGroupCount[0]));
    runHelper(pass, helperSet, bindings, push, pushBytes, groupsX, std::uint32_t((groups + groupsX - 1) / groupsX),
              false);
  }
  // The same over groupsX x groupsY workgroups, with images among the bindings; `afterHostWork`: the barrier
  // before it waits for every earlier write on the queue (the host's own images), not only the host's and the
  // shaders'.
  void runHelper(const LightingPipelines::HelperPass& pass, HelperSet& helperSet, std::span<const HelperBinding> bound,
                 const void* push, std::uint32_t pushBytes, std::uint32_t groupsX, std::uint32_t groupsY,
                 bool afterHostWork) {
    VkDevice dev = context.device();
    if (!helperSet.pool) {
      std::vector<VkDescriptorPoolSize> sizes;
      for (const HelperBinding& b : bound) {
        auto it = std::find_if(sizes.begin(), sizes.end(), [&](const VkDescriptorPoolSize& s) { return s.type == b.type(); });
        if (it == sizes.end()) sizes.push_back({b.type(), 1});
        else ++it->descriptorCount;
      }
      auto dp = vk::make<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
      dp.maxSets = 1;
      dp.poolSizeCount = std::uint32_t(sizes.size());
      dp.pPoolSizes = sizes.data();
      VkDescriptorPool pool = VK_NULL_HANDLE;
      vk::check(context.functions().vkCreateDescriptorPool(dev, &dp, context.functions().allocator, &pool), "vkCreateDescriptorPool");
      helperSet.pool = vk::UniqueDescriptorPool(context.functions(), dev, pool);
      const VkDescriptorSetLayout setLayout = pass.setLayout.get();
      auto ai = vk::make<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
      ai.descriptorPool = pool;
      ai.descriptorSetCount = 1;
      ai.pSetLayouts = &setLayout;
      vk::check(context.functions().vkAllocateDescriptorSets(dev, &ai, &helperSet.set), "vkAllocateDescriptorSets");
    }
    std::vector<VkDescriptorBufferInfo> infos(bound.size());
    std::vector<VkDescriptorImageInfo> images(bound.size());
    std::vector<VkWriteDescriptorSet> writes(bound.size());
    for (std::size_t b = 0; b < bound.size(); ++b) {
      writes[b] = vk::make<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
      writes[b].dstSet = helperSet.set;
      writes[b].dstBinding = std::uint32_t(b);
      writes[b].descriptorCount = 1;
      writes[b].descriptorType = bound[b].type();
      if (bound[b].image) {
        images[b] = {VK_NULL_HANDLE, bound[b].image, bound[b].layout};  // the set layout's immutable sampler
        writes[b].pImageInfo = &images[b];
      } else {
        infos[b] = {bound[b].buffer, 0, VK_WHOLE_SIZE};
        writes[b].pBufferInfo = &infos[b];
      }
    }
    context.functions().vkUpdateDescriptorSets(dev, std::uint32_t(writes.size()), writes.data(), 0, nullptr);
    const VkPipelineLayout layout = pass.layout.get();
    context.submitAndWait([&](VkCommandBuffer cmd) {
      if (afterHostWork) barrierBeforeHostImages(context, cmd);
      else barrierBeforeShaders(context, cmd);
      context.functions().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pass.pipeline.get());
      context.functions().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &helperSet.set, 0, nullptr);
      if (pushBytes > 0)
        context.functions().vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, pushBytes, push);
      context.functions().vkCmdDispatch(cmd, groupsX, groupsY, 1);
      // Its writes to the later passes and to host reads.
      memoryBarrier(context, cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                    VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                    VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_HOST_READ_BIT);
    });
  }

  // The host's answers per pixel and light into the pass's buffer (sized), unless the device's spread left them
  // there whole (spreadVisibility, `onDevice`).
  void writeVisibility(std::span<const std::uint32_t> answers, bool onDevice, LightingTraffic& traffic) {
    if (onDevice && visibilityHeld == answers.size() && !answers.empty()) return;
    fill(gpu::VS_LIGHTING_BINDING_VISIBILITY, answers.data(), answers.size() * sizeof(std::uint32_t));
    traffic.uploaded += answers.size() * sizeof(std::uint32_t);
    visibilityHeld = answers.size();
  }

  void spreadVisibility(const VisibilityTraceBuffers& trace, std::span<const int> slots, std::size_t pixels,
                        std::span<const std::uint32_t> current, LightingTraffic& traffic) {
    const std::size_t lights = slots.size();
    if (current.size() != pixels * lights || pixels == 0 || lights == 0)
      throwBadInput("lighting: " + std::to_string(current.size()) + " visibility answers for " + std::to_string(pixels) +
                    " pixels and " + std::to_string(lights) + " lights");
    std::uint32_t traced = 0;
    for (int j : slots)
      if (j >= 0) traced = std::max(traced, std::uint32_t(j) + 1);
    if (trace.receivers > 0 && (trace.pixels != pixels || trace.receivers > pixels || trace.lights != traced))
      throwBadInput("lighting: a visibility trace of " + std::to_string(trace.receivers) + " receivers of " +
                    std::to_string(trace.pixels) + " pixels toward " + std::to_string(trace.lights) +
                    " lights to spread over " + std::to_string(pixels) + " pixels and " + std::to_string(traced) +
                    " traced lights");
    if (reserve(gpu::VS_LIGHTING_BINDING_VISIBILITY, current.size() * sizeof(std::uint32_t))) descriptorsStale = true;
    const bool whole = trace.receivers == pixels && !trace.listed;
    if (trace.receivers == 0 || (!whole && visibilityHeld != current.size())) {
      // No trace on the device to spread, or one that would update rows the pass does not hold whole: the
      // host's answers go up whole.
      writeVisibility(current, false, traffic);
      return;
    }
    visibilityHeld = 0;  // until the spread has run
    const LightingPipelines::HelperPass& pass = pipelines->helper(
        pipelines->spread, visibility_spread, sizeof visibility_spread, gpu::VS_SPREAD_BINDING_COUNT, sizeof(gpu::SpreadPush));
    const VkDeviceSize slotBytes = std::max<VkDeviceSize>(16, slots.size_bytes());
    if (!spreadSlots.buffer || spreadSlots.size < slotBytes)
      spreadSlots = context.createHostBuffer(slotBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    std::memcpy(spreadSlots.mapped, slots.data(), slots.size_bytes());
    traffic.uploaded += slots.size_bytes();
    gpu::SpreadPush push{};
    // The pixel list follows the trace's record and its lights.
    const std::uint32_t listStart =
        trace.listed ? gpu::VS_VISIBILITY_RECORD_WORDS + gpu::VS_VISIBILITY_LIGHT_WORDS * trace.lights : 0u;
    push.counts = glm::uvec4(std::uint32_t(trace.receivers), trace.lights, std::uint32_t(lights), listStart);
    const std::array<VkBuffer, gpu::VS_SPREAD_BINDING_COUNT> bound{
        trace.answers, trace.source, spreadSlots.get(), buffers[gpu::VS_LIGHTING_BINDING_VISIBILITY].get()};
    runHelper(pass, spreadSet, bound, &push, sizeof push, trace.receivers, gpu::VS_SPREAD_GROUP_SIZE);
    ++traffic.dispatches;
    visibilityHeld = current.size();
  }

  static void checkTexelRanges(std::span<const std::pair<std::size_t, std::size_t>> ranges, std::size_t texels) {
    for (const auto& [first, count] : ranges)
      if (first > texels || count > texels - first)
        throwBadInput("lighting: texel range [" + std::to_string(first) + ", +" + std::to_string(count) +
                      ") lies outside the layer store of " + std::to_string(texels));
  }
  // Ranges [first, first + count) of `store` into the layer store's buffer, which holds as many texels.
  void writeTexelRanges(std::span<const float> store, std::span<const std::pair<std::size_t, std::size_t>> ranges,
                        LightingTraffic& traffic) {
    auto* texels = static_cast<float*>(buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS].mapped);
    for (const auto& [first, count] : ranges) {
      std::memcpy(texels + first, store.data() + first, count * sizeof(float));
      traffic.uploaded += count * sizeof(float);
    }
  }

  // The held frame's whole colour and terms into those given.
  void readResults(std::vector<glm::vec4>* color, std::vector<float>* terms, LightingTraffic& traffic) const {
    if (heldSizes.size() != 6) throwRuntime("lighting: the pass holds no whole frame to read back");
    const std::size_t pixels = heldSizes[0], lights = heldSizes[1];
    if (color) {
      color->resize(pixels);
      std::memcpy(color->data(), buffers[gpu::VS_LIGHTING_BINDING_COLOR].mapped, pixels * sizeof(glm::vec4));
      traffic.readBack += pixels * sizeof(glm::vec4);
    }
    if (terms) {
      terms->resize(pixels * lights);
      if (!terms->empty())
        std::memcpy(terms->data(), buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TERMS].mapped, terms->size() * sizeof(float));
      traffic.readBack += terms->size() * sizeof(float);
    }
  }

  void shadeChanged(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                    std::span<const std::uint32_t> rayVisibility, const ShadeChanges& changes, ShadeOutput& out,
                    LightingTraffic& traffic) {
    std::vector<std::uint32_t> clear;
    rayVisibility = checkShadeSizes(inputs, push, gbuffer, rayVisibility, clear);
    const std::size_t pixels = gbuffer.texels.size();
    const std::size_t lights = inputs.lights.size();
    const std::vector<std::size_t> sizes = sizesOf(inputs, pixels, rayVisibility.size());
    if (changes.storeInPlace && !changes.texelRanges.empty())
      throwBadInput("lighting: texel ranges given for a store read in place");
    if (sizes != heldSizes || (changes.readColor && out.color.size() != pixels) ||
        (changes.readTerms && out.shadowTerms.size() != pixels * lights)) {
      MomentWork wholeWork;
      if (inputs.momentTexels > 0) {
        if (!changes.wholeMoments) throwBadInput("lighting: a frame with EVSM layers needs its whole moment work");
        wholeWork = changes.wholeMoments();
      }
      ShadeOutput whole = shade(inputs, push, gbuffer, rayVisibility, traffic, changes.storeInPlace, &wholeWork,
                                changes.readColor, changes.readTerms, changes.gbufferOnDevice,
                                changes.visibilityOnDevice);
      if (changes.readColor) out.color.swap(whole.color);
      if (changes.readTerms) out.shadowTerms.swap(whole.shadowTerms);
      return;
    }
    checkTexelRanges(changes.texelRanges, inputs.shadowTexels.size());
    if (!changes.allPixels) {
      for (std::uint32_t p : changes.pixels)
        if (p >= pixels) throwBadInput("lighting: changed pixel " + std::to_string(p) + " outside the frame");
      if (changes.inputPixels.size() > changes.pixels.size())
        throwBadInput("lighting: more pixels with changed inputs than pixels shaded");
      for (std::uint32_t p : changes.inputPixels)
        if (p >= pixels) throwBadInput("lighting: changed pixel " + std::to_string(p) + " outside the frame");
    }
    // From here the buffers are written: a failure leaves them holding no whole frame.
    heldSizes.clear();
    writeRecords(inputs, traffic);
    writeMomentWork(changes.moments, traffic);
    chooseVariant(inputs, push);
    writeTexelRanges(inputs.shadowTexels, changes.texelRanges, traffic);
    if (changes.allPixels) {
      writeGBuffer(gbuffer, changes.gbufferOnDevice, traffic);
      writeVisibility(rayVisibility, changes.visibilityOnDevice, traffic);
      dispatch(push);
      heldSizes = sizes;
      readResults(changes.readColor ? &out.color : nullptr, changes.readTerms ? &out.shadowTerms : nullptr, traffic);
      return;
    }
    const std::size_t perPixel = rayVisibility.size() / std::max<std::size_t>(1, pixels);
    // Where the pass holds no whole G-buffer or answers of this frame (a resolve or spread that failed half-way),
    // the host's go up whole; else the device's are in place (gbufferOnDevice, visibilityOnDevice) or the
    // changed pixels' are written.
    const bool gbufferRows = !changes.gbufferOnDevice && gbufferHeld == pixels;
    const bool visibilityRows = !changes.visibilityOnDevice && visibilityHeld == rayVisibility.size();
    if (gbufferHeld != pixels) writeGBuffer(gbuffer, false, traffic);
    if (visibilityHeld != rayVisibility.size()) writeVisibility(rayVisibility, false, traffic);
    if (gbufferRows && !changes.inputPixels.empty()) receiversHeld = 0;
    auto* g = static_cast<gpu::GBufferTexel*>(buffers[gpu::VS_LIGHTING_BINDING_GBUFFER].mapped);
    auto* v = static_cast<std::uint32_t*>(buffers[gpu::VS_LIGHTING_BINDING_VISIBILITY].mapped);
    for (std::uint32_t p : changes.inputPixels) {
      if (gbufferRows) g[p] = gbuffer.texels[p];
      if (visibilityRows)
        for (std::size_t l = 0; l < perPixel; ++l) v[p * perPixel + l] = rayVisibility[p * perPixel + l];
    }
    traffic.uploaded += changes.inputPixels.size() * ((gbufferRows ? sizeof(gpu::GBufferTexel) : 0) +
                                                      (visibilityRows ? perPixel * sizeof(std::uint32_t) : 0));
    // Only the listed pixels are shaded again: every other pixel's inputs are the last frame's, and so are the
    // colour and terms the buffers keep for it. A list of most of the frame costs more than the frame (one more
    // read per pixel, scattered), and one too long for a row of workgroups cannot be dispatched as one.
    const std::size_t groupSize = std::size_t(gpu::VS_LIGHTING_GROUP_WIDTH) * gpu::VS_LIGHTING_GROUP_HEIGHT;
    const std::size_t listGroups = (changes.pixels.size() + groupSize - 1) / groupSize;
    if (changes.pixels.empty()) {
      // Nothing to shade: the kept colours stand; the moments of changed texels are still brought up to date.
      if (momentWork) dispatch(push, false);
    } else if (2 * changes.pixels.size() <= pixels && listGroups <= context.info().maxWorkGroupCount[0]) {
      std::memcpy(buffers[gpu::VS_LIGHTING_BINDING_PIXELS].mapped, changes.pixels.data(),
                  changes.pixels.size() * sizeof(std::uint32_t));
      traffic.uploaded += changes.pixels.size() * sizeof(std::uint32_t);
      gpu::ShadePush listed = push;
      listed.flags.y = int(changes.pixels.size());
      dispatch(listed);
    } else {
      dispatch(push);
    }
    const auto* color = static_cast<const glm::vec4*>(buffers[gpu::VS_LIGHTING_BINDING_COLOR].mapped);
    const auto* terms = static_cast<const float*>(buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TERMS].mapped);
    if (changes.readColor) {
      for (std::uint32_t p : changes.pixels) out.color[p] = color[p];
      traffic.readBack += changes.pixels.size() * sizeof(glm::vec4);
    }
    if (changes.readTerms) {
      for (std::uint32_t p : changes.pixels)
        for (std::size_t l = 0; l < lights; ++l) out.shadowTerms[p * lights + l] = terms[p * lights + l];
      traffic.readBack += changes.pixels.size() * lights * sizeof(float);
    }
    heldSizes = sizes;
  }

  // Records the moment pass (when the call has work) and, unless `shade` is false, the lighting pass over the
  // push block's pixels, in one submission.
  void dispatch(const gpu::ShadePush& push, bool shade = true) {
    const std::uint32_t groupSize = gpu::VS_LIGHTING_GROUP_WIDTH * gpu::VS_LIGHTING_GROUP_HEIGHT;
    std::uint32_t groupsX = (std::uint32_t(push.size.x) + gpu::VS_LIGHTING_GROUP_WIDTH - 1) / gpu::VS_LIGHTING_GROUP_WIDTH;
    std::uint32_t groupsY = (std::uint32_t(push.size.y) + gpu::VS_LIGHTING_GROUP_HEIGHT - 1) / gpu::VS_LIGHTING_GROUP_HEIGHT;
    if (push.flags.y > 0) {
      groupsX = (std::uint32_t(push.flags.y) + groupSize - 1) / groupSize;
      groupsY = 1;
    }
    if (shade) {
      shadedPixels += push.flags.y > 0 ? std::size_t(push.flags.y) : std::size_t(push.size.x) * std::size_t(push.size.y);
      ++dispatches;
    }
    // Held for the dispatch: another pass on the device may drop it from the kept variants meanwhile.
    const std::shared_ptr<vk::UniquePipeline> shadePipeline = shade ? pipelines->pipelineOf(wantedVariant) : nullptr;
    const VkPipelineLayout layout = pipelines->layout.get();
    const MomentWork* moments = momentWork;
    momentWork = nullptr;
    if (moments) {
      dispatches += 2;
      momentTexels += moments->vertical;
    }
    context.submitAndWait([&](VkCommandBuffer cmd) {
      // The host's writes above (and the trace's, into the store, and the resolve's, into the G-buffer), before
      // the shaders read them.
      barrierBeforeShaders(context, cmd);
      if (moments) recordMoments(cmd, *moments);
      if (shade) {
        context.functions().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadePipeline->get());
        context.functions().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &descriptorSet, 0, nullptr);
        context.functions().vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(gpu::ShadePush), &push);
        context.functions().vkCmdDispatch(cmd, groupsX, groupsY, 1);
      }
      auto toHost = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
      toHost.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0,
                           nullptr, 0, nullptr);
    });
  }

  // The moment pass: horizontal sums into the scratch, then vertical sums into the moment store, each pass one
  // dispatch over a flat index of its jobs' texels (rows of maxWorkGroupCount[0] groups).
  void recordMoments(VkCommandBuffer cmd, const MomentWork& work) {
    auto between = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
    between.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    between.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    const VkPipelineLayout momentLayout = pipelines->momentLayout.get();
    context.functions().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelines->momentPipeline.get());
    context.functions().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, momentLayout, 0, 1, &descriptorSet, 0, nullptr);
    const std::uint32_t maxGroups = std::min<std::uint32_t>(context.info().maxWorkGroupCount[0], 65535u);
    for (int pass = 0; pass < 2; ++pass) {
      const std::size_t invocations = pass == 0 ? work.horizontal : work.vertical;
      const std::size_t groups = (invocations + gpu::VS_EVSM_GROUP_SIZE - 1) / gpu::VS_EVSM_GROUP_SIZE;
      const std::uint32_t groupsX = std::uint32_t(std::min<std::size_t>(groups, maxGroups));
      const std::uint32_t groupsY = std::uint32_t((groups + groupsX - 1) / groupsX);
      gpu::EvsmPush push{};
      push.pass = glm::ivec4(pass, int(work.jobs.size()), int(invocations), int(groupsX * gpu::VS_EVSM_GROUP_SIZE));
      context.functions().vkCmdPushConstants(cmd, momentLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, &push);
      context.functions().vkCmdDispatch(cmd, groupsX, groupsY, 1);
      context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                           &between, 0, nullptr, 0, nullptr);
    }
  }
};

bool VulkanLighting::holdsStore(std::size_t texels) const { return impl_->holdsStore(texels); }

void VulkanLighting::resolveGBuffer(const CameraTraceBuffers& trace, const GBufferTables& tables, const GBuffer& current,
                                    LightingTraffic* traffic) {
  LightingTraffic t;
  impl_->resolveGBuffer(trace, tables, current, t);
  if (traffic) {
    traffic->uploaded += t.uploaded;
    traffic->dispatches += t.dispatches;
  }
}

void VulkanLighting::spreadVisibility(const VisibilityTraceBuffers& trace, std::span<const int> slots, std::size_t pixels,
                                      std::span<const std::uint32_t> current, LightingTraffic* traffic) {
  LightingTraffic t;
  impl_->spreadVisibility(trace, slots, pixels, current, t);
  if (traffic) {
    traffic->uploaded += t.uploaded;
    traffic->dispatches += t.dispatches;
  }
}

void VulkanLighting::importGBuffer(const HostGBuffer& host, int width, int height, LightingTraffic* traffic) {
  LightingTraffic t;
  impl_->importGBuffer(host, width, height, t);
  if (traffic) {
    traffic->uploaded += t.uploaded;
    traffic->dispatches += t.dispatches;
  }
}

DeviceReceivers VulkanLighting::receivers(std::size_t pixels) const {
  if (pixels == 0 || impl_->receiversHeld != pixels) return {};
  return {impl_->receivers.get(), pixels, {}};
}

void VulkanLighting::readVisibility(std::span<std::uint32_t> out, LightingTraffic* traffic) const {
  if (out.empty() || impl_->visibilityHeld != out.size())
    throwBadInput("lighting: the pass holds no visibility answers of " + std::to_string(out.size()) + " to read");
  std::memcpy(out.data(), impl_->buffers[gpu::VS_LIGHTING_BINDING_VISIBILITY].mapped, out.size_bytes());
  if (traffic) traffic->readBack += out.size_bytes();
}

void VulkanLighting::readGBuffer(GBuffer& out, LightingTraffic* traffic) const {
  const std::size_t pixels = impl_->gbufferHeld;
  if (pixels == 0 || pixels != out.texels.size())
    throwBadInput("lighting: the pass holds no whole G-buffer of " + std::to_string(out.texels.size()) + " texels to read");
  std::memcpy(out.texels.data(), impl_->buffers[gpu::VS_LIGHTING_BINDING_GBUFFER].mapped, pixels * sizeof(gpu::GBufferTexel));
  if (traffic) traffic->readBack += pixels * sizeof(gpu::GBufferTexel);
}

VkBuffer VulkanLighting::storeTarget(std::size_t texels) const {
  if (!impl_->holdsStore(texels))
    throwRuntime("lighting: no layer store of " + std::to_string(texels) + " texels is held to trace into");
  return impl_->buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS].get();
}

void VulkanLighting::readMoments(std::span<glm::vec4> out, LightingTraffic* traffic) const {
  if (!impl_->holdsMoments(out.size()))
    throwBadInput("lighting: the pass holds no moment store of " + std::to_string(out.size()) + " texels to read");
  const auto* positive = static_cast<const glm::vec2*>(impl_->buffers[gpu::VS_LIGHTING_BINDING_MOMENTS].mapped);
  const auto* negative = static_cast<const glm::vec2*>(impl_->buffers[gpu::VS_LIGHTING_BINDING_MOMENTS_NEGATIVE].mapped);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = glm::vec4(positive[i], negative[i]);
  if (traffic) traffic->readBack += out.size() * sizeof(glm::vec4);
}

void VulkanLighting::writeStore(std::span<const float> store,
                                std::span<const std::pair<std::size_t, std::size_t>> ranges, LightingTraffic* traffic) {
  if (!impl_->holdsStore(store.size()))
    throwBadInput("lighting: the pass holds no layer store of " + std::to_string(store.size()) + " texels to write");
  Impl::checkTexelRanges(ranges, store.size());
  LightingTraffic t;
  impl_->writeTexelRanges(store, ranges, t);
  if (traffic) traffic->uploaded += t.uploaded;
}

VulkanShadows VulkanLighting::shadows(int width, int height) const {
  const Impl& p = *impl_;
  if (p.heldSizes.size() != 6 || p.heldSizes[0] != std::size_t(width) * std::size_t(height))
    throwRuntime("lighting: the pass holds no whole frame of " + std::to_string(width) + "x" + std::to_string(height) +
                 " pixels");
  // An empty submission whose barrier orders every earlier write on the queue (the host's to mapped memory,
  // the trace and lighting passes') before every later read.
  p.context.submitAndWait([&](VkCommandBuffer cmd) {
    auto all = vk::make<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
    all.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT;
    all.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT;
    p.context.functions().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                                               VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1, &all, 0, nullptr, 0, nullptr);
  });
  VulkanShadows out;
  out.texels = p.buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS].get();
  out.views = p.buffers[gpu::VS_LIGHTING_BINDING_VIEWS].get();
  out.viewTexels = p.viewTexels.get();
  out.lights = p.buffers[gpu::VS_LIGHTING_BINDING_LIGHTS].get();
  out.momentsPositive = p.buffers[gpu::VS_LIGHTING_BINDING_MOMENTS].get();
  out.momentsNegative = p.buffers[gpu::VS_LIGHTING_BINDING_MOMENTS_NEGATIVE].get();
  out.gbuffer = p.buffers[gpu::VS_LIGHTING_BINDING_GBUFFER].get();
  out.visibility = p.buffers[gpu::VS_LIGHTING_BINDING_VISIBILITY].get();
  out.viewCount = std::uint32_t(p.heldSizes[2]);
  out.lightCount = std::uint32_t(p.heldSizes[1]);
  out.width = std::uint32_t(width);
  out.height = std::uint32_t(height);
  return out;
}

void VulkanLighting::readResults(std::vector<glm::vec4>* color, std::vector<float>* terms,
                                 LightingTraffic* traffic) const {
  LightingTraffic t;
  impl_->readResults(color, terms, t);
  if (traffic) traffic->readBack += t.readBack;
}

void VulkanLighting::readStore(std::span<float> out, LightingTraffic* traffic) const {
  if (!impl_->holdsStore(out.size()))
    throwBadInput("lighting: the pass holds no layer store of " + std::to_string(out.size()) + " texels to read");
  if (!out.empty())
    std::memcpy(out.data(), impl_->buffers[gpu::VS_LIGHTING_BINDING_SHADOW_TEXELS].mapped, out.size() * sizeof(float));
  if (traffic) traffic->readBack += out.size() * sizeof(float);
}

VulkanLighting::VulkanLighting(std::shared_ptr<VulkanContext> context, bool specialize)
    : impl_(std::make_unique<Impl>(std::move(context))) {
  impl_->specialize = specialize;
}
int VulkanLighting::variantsCompiled() const {
  std::lock_guard lock(impl_->pipelines->mutex);
  return impl_->pipelines->compiled;
}
VulkanLighting::~VulkanLighting() = default;
ShadeOutput VulkanLighting::shade(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                                  std::span<const std::uint32_t> rayVisibility, LightingTraffic* traffic,
                                  const MomentWork* moments, bool readColor, bool readTerms, bool gbufferOnDevice,
                                  bool visibilityOnDevice) {
  LightingTraffic t;
  impl_->shadedPixels = 0;
  impl_->momentTexels = 0;
  impl_->dispatches = 0;
  ShadeOutput out =
      impl_->shade(inputs, push, gbuffer, rayVisibility, t, false, moments, readColor, readTerms, gbufferOnDevice,
                   visibilityOnDevice);
  t.pixelsShaded = impl_->shadedPixels;
  t.momentTexels = impl_->momentTexels;
  t.dispatches = impl_->dispatches;
  if (traffic) *traffic = t;
  return out;
}

void VulkanLighting::shadeChanged(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                                  std::span<const std::uint32_t> rayVisibility, const ShadeChanges& changes,
                                  ShadeOutput& out, LightingTraffic* traffic) {
  LightingTraffic t;
  impl_->shadedPixels = 0;
  impl_->momentTexels = 0;
  impl_->dispatches = 0;
  impl_->shadeChanged(inputs, push, gbuffer, rayVisibility, changes, out, t);
  t.pixelsShaded = impl_->shadedPixels;
  t.momentTexels = impl_->momentTexels;
  t.dispatches = impl_->dispatches;
  if (traffic) *traffic = t;
}

}  // namespace vs
