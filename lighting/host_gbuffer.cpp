#include "lighting/host_gbuffer.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "compute/vulkan/vulkan_context.h"
#include "voxel/error.h"

namespace vs {
namespace {

[[noreturn]] void refuse(const std::string& field, const std::string& problem) {
  throwBadInput("RenderOptions.hostGBuffer." + field + ": " + problem);
}

bool finite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

bool integerFormat(VkFormat f) {
  switch (f) {
    case VK_FORMAT_R8_UINT: case VK_FORMAT_R8_SINT: case VK_FORMAT_R8G8_UINT: case VK_FORMAT_R8G8_SINT:
    case VK_FORMAT_R8G8B8_UINT: case VK_FORMAT_R8G8B8_SINT: case VK_FORMAT_B8G8R8_UINT: case VK_FORMAT_B8G8R8_SINT:
    case VK_FORMAT_R8G8B8A8_UINT: case VK_FORMAT_R8G8B8A8_SINT: case VK_FORMAT_B8G8R8A8_UINT:
    case VK_FORMAT_B8G8R8A8_SINT: case VK_FORMAT_A8B8G8R8_UINT_PACK32: case VK_FORMAT_A8B8G8R8_SINT_PACK32:
    case VK_FORMAT_A2R10G10B10_UINT_PACK32: case VK_FORMAT_A2R10G10B10_SINT_PACK32:
    case VK_FORMAT_A2B10G10R10_UINT_PACK32: case VK_FORMAT_A2B10G10R10_SINT_PACK32: case VK_FORMAT_R16_UINT:
    case VK_FORMAT_R16_SINT: case VK_FORMAT_R16G16_UINT: case VK_FORMAT_R16G16_SINT: case VK_FORMAT_R16G16B16_UINT:
    case VK_FORMAT_R16G16B16_SINT: case VK_FORMAT_R16G16B16A16_UINT: case VK_FORMAT_R16G16B16A16_SINT:
    case VK_FORMAT_R32_UINT: case VK_FORMAT_R32_SINT: case VK_FORMAT_R32G32_UINT: case VK_FORMAT_R32G32_SINT:
    case VK_FORMAT_R32G32B32_UINT: case VK_FORMAT_R32G32B32_SINT: case VK_FORMAT_R32G32B32A32_UINT:
    case VK_FORMAT_R32G32B32A32_SINT: case VK_FORMAT_R64_UINT: case VK_FORMAT_R64_SINT: case VK_FORMAT_R64G64_UINT:
    case VK_FORMAT_R64G64_SINT: case VK_FORMAT_R64G64B64_UINT: case VK_FORMAT_R64G64B64_SINT:
    case VK_FORMAT_R64G64B64A64_UINT: case VK_FORMAT_R64G64B64A64_SINT: case VK_FORMAT_S8_UINT:
      return true;
    default:
      return false;
  }
}

// Whether the device samples `format` as floats with optimal tiling (an integer format reads as integers).
void checkHostImage(const VulkanContext& context, const HostImage& image, const char* name) {
  const std::string field = std::string("RenderOptions.hostGBuffer.") + name;
  if (image.layout != VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL && image.layout != VK_IMAGE_LAYOUT_GENERAL &&
      image.layout != VK_IMAGE_LAYOUT_DEPTH_STENCIL_READ_ONLY_OPTIMAL)
    throwBadInput(field + ".layout: " + std::to_string(int(image.layout)) +
                  " is none of SHADER_READ_ONLY_OPTIMAL, DEPTH_STENCIL_READ_ONLY_OPTIMAL and GENERAL");
  VkFormatProperties props{};
  context.functions().vkGetPhysicalDeviceFormatProperties(context.physicalDevice(), image.format, &props);
  if (image.format == VK_FORMAT_UNDEFINED || !(props.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT))
    throwBadInput(field + ".format: " + std::to_string(int(image.format)) + " is not sampled with optimal tiling by " +
                  context.info().name);
  if (integerFormat(image.format))
    throwBadInput(field + ".format: " + std::to_string(int(image.format)) +
                  " is an integer format; the pass reads floats (UNORM, SNORM, SFLOAT, SRGB or depth)");
}

}  // namespace

void checkHostGBuffer(const VulkanContext& context, const HostGBuffer& host, int width, int height) {
  (void)hostGBufferRecord(host, width, height);
  checkHostImage(context, host.depth, "depth");
  checkHostImage(context, host.normal, "normal");
  if (host.albedo.view != VK_NULL_HANDLE) checkHostImage(context, host.albedo, "albedo");
}

gpu::HostGBufferRecord hostGBufferRecord(const HostGBuffer& host, int width, int height) {
  if (host.width != width)
    refuse("width", std::to_string(host.width) + " for a frame " + std::to_string(width) + " pixels wide");
  if (host.height != height)
    refuse("height", std::to_string(host.height) + " for a frame " + std::to_string(height) + " pixels high");
  if (host.depth.view == VK_NULL_HANDLE) refuse("depth.view", "a null VkImageView (the depth image is required)");
  if (host.normal.view == VK_NULL_HANDLE) refuse("normal.view", "a null VkImageView (the normal image is required)");
  if (host.normalEncoding != HostNormalEncoding::Signed && host.normalEncoding != HostNormalEncoding::Unsigned)
    refuse("normalEncoding", std::to_string(int(host.normalEncoding)) + " is no HostNormalEncoding (Signed or Unsigned)");
  if (host.normalSpace != HostNormalSpace::World && host.normalSpace != HostNormalSpace::View)
    refuse("normalSpace", std::to_string(int(host.normalSpace)) + " is no HostNormalSpace (World or View)");
  if (!std::isfinite(host.skyDepth)) refuse("skyDepth", "not a finite number");
  if (!std::isfinite(host.voxelSize) || host.voxelSize <= 0.0)
    refuse("voxelSize", "must be finite and above 0, not " + std::to_string(host.voxelSize));
  if (!finite(host.worldToView)) refuse("worldToView", "holds a value that is not finite");
  if (!finite(host.viewToClip)) refuse("viewToClip", "holds a value that is not finite");
  // A rigid map: orthonormal columns of its rotation, (0, 0, 0, 1) as its last row. The tolerance admits a view
  // matrix an engine computed in float (a few units in the last place of each entry), not a scale or a shear.
  const glm::dmat3 rotation(host.worldToView);
  const glm::dmat3 gram = glm::transpose(rotation) * rotation;
  double off = std::max({std::abs(host.worldToView[0][3]), std::abs(host.worldToView[1][3]),
                         std::abs(host.worldToView[2][3]), std::abs(host.worldToView[3][3] - 1.0)});
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) off = std::max(off, std::abs(gram[c][r] - (c == r ? 1.0 : 0.0)));
  if (off > 1e-4) refuse("worldToView", "not a rotation and a translation (scale, shear or projection in it)");
  const double det = glm::determinant(host.viewToClip);
  if (!std::isfinite(det) || std::abs(det) < 1e-300) refuse("viewToClip", "not invertible");

  const glm::dmat4 clipToView = glm::inverse(host.viewToClip);
  const glm::dmat4 viewToWorld = glm::inverse(host.worldToView);
  // The forward axis: through the centre of the image, away from the eye (two depths of the centre's line,
  // summed: for a perspective both lie on the ray from the eye, for an orthographic one both in front of it).
  auto unproject = [&](double depth) {
    const glm::dvec4 v = clipToView * glm::dvec4(0.0, 0.0, depth, 1.0);
    return glm::dvec3(v) / v.w;
  };
  const glm::dvec3 along = unproject(0.25) + unproject(0.75);
  if (!std::isfinite(along.x + along.y + along.z) || glm::length(along) == 0.0)
    refuse("viewToClip", "maps no line through the image's centre in front of the eye");
  const glm::dvec3 forward = glm::normalize(along);

  gpu::HostGBufferRecord r{};
  r.clipToView = glm::mat4(clipToView);
  r.viewToWorld = glm::mat4(glm::dmat4(glm::dmat3(viewToWorld)));
  glm::vec3 high, low;
  gpu::splitToFloats(glm::dvec3(viewToWorld[3]), high, low);
  r.eyeHigh = glm::vec4(high, float(host.voxelSize));
  r.eyeLow = glm::vec4(low, host.skyDepth);
  r.forward = glm::vec4(glm::vec3(forward), 0.0f);
  std::uint32_t flags = 0;
  if (host.normalSpace == HostNormalSpace::View) flags |= gpu::VS_HOST_GBUFFER_VIEW_NORMALS;
  if (host.albedo.view != VK_NULL_HANDLE) flags |= gpu::VS_HOST_GBUFFER_ALBEDO;
  r.info = glm::uvec4(std::uint32_t(width), std::uint32_t(height),
                      host.normalEncoding == HostNormalEncoding::Unsigned ? gpu::VS_HOST_NORMAL_UNSIGNED
                                                                          : gpu::VS_HOST_NORMAL_SIGNED,
                      flags);
  return r;
}

}  // namespace vs
