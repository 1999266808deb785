// vulkan_lighting.h: the deferred lighting pass on a Vulkan device (lighting/shaders/deferred_lighting.comp),
// the shader build of lighting/shared/shading.h; shadeOnCpu (lighting/deferred.h) is its C++ build.
#ifndef VOXSHADOW_VULKAN_LIGHTING_H
#define VOXSHADOW_VULKAN_LIGHTING_H

#include <memory>
#include <span>

#include "compute/vulkan/vulkan_context.h"
#include "lighting/deferred.h"

namespace vs {

class VulkanLighting {
 public:
  // Creates the pipeline on `context`'s device. Preconditions: context outlives this object.
  explicit VulkanLighting(VulkanContext& context);
  ~VulkanLighting();

  // The pass over one frame: the same inputs and results as shadeOnCpu. Buffers grow as frames need and are
  // kept for the next frame. Throws vs::Error(BadInput) as shadeOnCpu does, vs::Error(Runtime) on device errors.
  ShadeOutput shade(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                    std::span<const std::uint32_t> rayVisibility);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vs

#endif
