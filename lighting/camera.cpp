// camera.cpp: the camera frame and its pixel rays.
#include "lighting/camera.h"

#include <cmath>

namespace vs {

CameraFrame cameraFrame(const CameraDesc& camera, int width, int height) {
  CameraFrame f;
  f.position = glm::dvec3(camera.position);
  f.forward = glm::normalize(glm::dvec3(camera.target) - f.position);
  f.right = glm::normalize(glm::cross(f.forward, glm::dvec3(camera.up)));
  f.up = glm::cross(f.right, f.forward);
  f.tanHalfFovY = std::tan(glm::radians(double(camera.fovDeg)) * 0.5);
  f.width = width > 0 ? width : camera.width;
  f.height = height > 0 ? height : camera.height;
  f.aspect = double(f.width) / double(f.height);
  f.nearPlane = camera.nearPlane;
  f.farPlane = camera.farPlane;
  return f;
}

glm::dvec3 pixelDirection(const CameraFrame& camera, int x, int y) {
  const double sx = ((double(x) + 0.5) / double(camera.width) * 2.0 - 1.0) * camera.tanHalfFovY * camera.aspect;
  const double sy = (1.0 - (double(y) + 0.5) / double(camera.height) * 2.0) * camera.tanHalfFovY;
  return glm::normalize(camera.forward + camera.right * sx + camera.up * sy);
}

gpu::CameraRays cameraRaysOf(const CameraFrame& camera) {
  gpu::CameraRays r{};
  glm::vec3 high, low;
  gpu::splitToFloats(camera.position, high, low);
  r.originHigh = glm::vec4(high, float(camera.tanHalfFovY * camera.aspect));
  r.originLow = glm::vec4(low, float(camera.tanHalfFovY));
  r.forward = glm::vec4(glm::vec3(camera.forward), float(camera.nearPlane));
  r.right = glm::vec4(glm::vec3(camera.right), float(camera.farPlane));
  r.up = glm::vec4(glm::vec3(camera.up), 0.0f);
  r.size = glm::uvec4(std::uint32_t(camera.width), std::uint32_t(camera.height), 0u, 0u);
  return r;
}

}  // namespace vs
