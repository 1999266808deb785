// host_gbuffer.h: a host engine's own G-buffer as the input of a frame's lighting (README "Embedding in an
// engine", the host's G-buffer): its depth, normal and (optionally) albedo images on the tracer's device, read in
// place by the import pass (lighting/shared/gbuffer_import.h) instead of the library's primary rays.
#ifndef VOXSHADOW_HOST_GBUFFER_H
#define VOXSHADOW_HOST_GBUFFER_H

#include <glm/glm.hpp>
#include <vulkan/vulkan.h>

#include "lighting/shared/shading_layout.h"

namespace vs {

class VulkanContext;  // compute/vulkan/vulkan_context.h

// How the normal image holds each pixel's normal.
enum class HostNormalEncoding {
  Signed,    // the normal as it is (a float or SNORM format)
  Unsigned,  // n * 0.5 + 0.5 (a UNORM format)
};
enum class HostNormalSpace {
  World,
  View,  // the host's view space (worldToView's)
};

// One image of the host's G-buffer: a view of a 2D image of the frame's size, made for sampling (usage
// VK_IMAGE_USAGE_SAMPLED_BIT; for a depth/stencil format, a view of the depth aspect alone), in `layout` while
// the library reads it: VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, DEPTH_STENCIL_READ_ONLY_OPTIMAL or GENERAL.
// `format`: the image view's, a format the device can sample with optimal tiling, read as floats (not an
// integer format).
struct HostImage {
  VkImageView view = VK_NULL_HANDLE;
  VkFormat format = VK_FORMAT_UNDEFINED;
  VkImageLayout layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
};

// A frame's G-buffer drawn by the host (RenderOptions::hostGBuffer), with Vulkan's conventions: row 0 of each
// image at NDC y = -1, its depth the value the viewport wrote after the perspective divide (minDepth 0, maxDepth
// 1). A pixel whose depth equals `skyDepth` has no surface. The images were written by work the host submitted
// to the library's queue before render() (the library's first command waits for every earlier write on that
// queue), or by work that has completed.
struct HostGBuffer {
  int width = 0, height = 0;  // the images' size: the frame's (RenderOptions::width and height, or the camera's)
  HostImage depth;            // depth in the red (or depth) channel
  HostImage normal;           // the surface's normal in red, green and blue
  HostNormalEncoding normalEncoding = HostNormalEncoding::Signed;
  HostNormalSpace normalSpace = HostNormalSpace::World;
  HostImage albedo;           // optional (a null view: white): linear albedo in red, green and blue
  // The host's matrices as its G-buffer pass used them: worldToView a rotation and a translation (no scale; each
  // entry of its rotation's R^T R within 1e-4 of the identity's, so a matrix computed in float passes),
  // viewToClip its projection (reversed or infinite depth included). The frame's cascades are fitted to the
  // scene's camera, which should be the same camera: receivers outside every cascade are lit.
  glm::dmat4 worldToView{1.0};
  glm::dmat4 viewToClip{1.0};
  float skyDepth = 1.0f;     // the depth the host clears to: 1, or 0 with reversed depth
  double voxelSize = 1.0;    // the world size of a voxel at the receivers: contact rays start 1/1000 of it off
};

// The import pass's record of `host` for a frame of width x height pixels: the inverse projection and the
// view-to-world rotation inverted in double, the eye split into two floats, the camera's forward axis in view
// space. Throws vs::Error(BadInput) naming the field ("RenderOptions.hostGBuffer.<field>: ...") for a null depth
// or normal view, a width or height other than the frame's, an enumerator out of range, non-finite or degenerate matrices
// (worldToView not a rotation and translation, viewToClip not invertible), a non-finite skyDepth, or a voxelSize
// that is not finite and positive. The formats and layouts are checked against the device by the import
// (VulkanLighting::importGBuffer).
gpu::HostGBufferRecord hostGBufferRecord(const HostGBuffer& host, int width, int height);

// hostGBufferRecord's checks, and each image's against the device of `context`: a layout the pass reads from
// (SHADER_READ_ONLY_OPTIMAL, DEPTH_STENCIL_READ_ONLY_OPTIMAL or GENERAL), a format the device samples with optimal
// tiling, not an integer format. Throws vs::Error(BadInput) naming the field.
void checkHostGBuffer(const VulkanContext& context, const HostGBuffer& host, int width, int height);

}  // namespace vs

#endif
