// Compiles the shared core's arithmetic in a consumer's own translation unit (linked with voxshadow::exact_fp,
// as the README asks) and checks that its camera rays are the library's, bit for bit: the flags reach this
// file, and the library's copy of the arithmetic is not replaced by this one or the reverse. Built for the
// build machine's processor, where that has fused multiply-adds, so that contraction would show.
// Usage: core_rays
#include <cstdio>
#include <cstring>
#include <vector>

#include "compute/shared/camera_rays.h"
#include "compute/tracer.h"

int main() {
  vs::gpu::CameraRays camera{};
  camera.originHigh = glm::vec4(1234.5f, -87.25f, 3.0f, 0.7f);  // w: tan of the half field of view, across
  camera.originLow = glm::vec4(1.0e-5f, -2.0e-5f, 3.0e-6f, 0.45f);  // w: the same, down
  camera.forward = glm::vec4(glm::normalize(glm::vec3(0.3f, -0.2f, -1.0f)), 0.05f);
  camera.right = glm::vec4(glm::normalize(glm::cross(glm::vec3(camera.forward), glm::vec3(0, 1, 0))), 500.0f);
  camera.up = glm::vec4(glm::cross(glm::vec3(camera.right), glm::vec3(camera.forward)), 0.0f);
  camera.size = glm::uvec4(37, 23, 0, 0);
  const std::vector<vs::gpu::TraceRay> library = vs::cameraRays(camera);
  std::size_t different = 0;
  for (std::uint32_t pixel = 0; pixel < 37u * 23u; ++pixel) {
    const vs::gpu::TraceRay mine = vs::gpu::vsCameraRay(camera, pixel);
    if (std::memcmp(&mine, &library[pixel], sizeof mine) != 0) ++different;
  }
  std::printf("core_rays: %zu of %zu camera rays differ from the library's\n", different, library.size());
  return different == 0 && library.size() == 37u * 23u ? 0 : 1;
}
