// vulkan_shadows.h: a frame's shadows where they are, on the Vulkan device, for a host engine's own shader
// (README "Embedding in an engine"). The shader includes lighting/shared/shadows.glsl (installed under
// include/voxshadow/) and binds these buffers in that file's order; its vsShadowTerm is the library's own, so the
// host's terms equal the library's lighting pass's bit for bit on the same device.
#ifndef VOXSHADOW_VULKAN_SHADOWS_H
#define VOXSHADOW_VULKAN_SHADOWS_H

#include <cstdint>

#include <vulkan/vulkan.h>

namespace vs {

// Buffers of the renderer's lighting pass on the tracer's device (VulkanContext::device()), each bound whole
// (VK_WHOLE_SIZE). They are the renderer's: valid until its next render() or its destruction, and rewritten by
// the next render(), so a host that reads them in its own submission finishes with them before it renders the
// next frame. When FrameRenderer::vulkanShadows() returns, every write to them is done: the host's writes to
// their host-coherent memory, and the library's submissions on the queue, which it waited for; the last of them
// ended with a memory barrier from compute-shader and transfer writes to every read (VK_ACCESS_MEMORY_READ_BIT at
// VK_PIPELINE_STAGE_ALL_COMMANDS_BIT), so a later submission on the same queue may read them without one.
struct VulkanShadows {
  VkBuffer texels = VK_NULL_HANDLE;          // storage buffer (float): every layer, ShadeView.info.x onwards
  VkBuffer views = VK_NULL_HANDLE;           // the ShadeView records (lighting/shared/shading_layout.h)
  VkBufferView viewTexels = VK_NULL_HANDLE;  // `views` as a uniform texel buffer (RGBA32UI): shadows.glsl's +1
  VkBuffer lights = VK_NULL_HANDLE;          // storage buffer: ShadeLight per light of the scene, in scene order
  VkBuffer momentsPositive = VK_NULL_HANDLE; // storage buffers: the EVSM moment store's halves (a 16-byte
  VkBuffer momentsNegative = VK_NULL_HANDLE; //   placeholder each where no light uses EVSM)
  // The frame's own inputs, which a host with its own G-buffer does not need: GBufferTexel per pixel
  // (row-major), and the contact rays' answers (uint per pixel and light, pixel * lightCount + light; 1 clear).
  VkBuffer gbuffer = VK_NULL_HANDLE;
  VkBuffer visibility = VK_NULL_HANDLE;
  std::uint32_t viewCount = 0;
  std::uint32_t lightCount = 0;
  std::uint32_t width = 0;   // the frame's size in pixels
  std::uint32_t height = 0;
};

}  // namespace vs

#endif
