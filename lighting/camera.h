// camera.h: the scene camera's frame and rays (DESIGN.md §7): what the G-buffer's primary rays and the
// cascades' frustum slices are made from. Everything in double, so that a camera far from the origin keeps
// its pixel rays exact (the rays are eye-relative, as the shadow texels' are).
#ifndef VOXSHADOW_CAMERA_H
#define VOXSHADOW_CAMERA_H

#include <glm/glm.hpp>

#include "compute/shared/trace_rays.h"
#include "lighting/scene_file.h"

namespace vs {

struct CameraFrame {
  glm::dvec3 position{0.0};
  glm::dvec3 forward{0.0, 0.0, -1.0};  // unit, toward the target
  glm::dvec3 right{1.0, 0.0, 0.0};     // unit
  glm::dvec3 up{0.0, 1.0, 0.0};        // unit, orthogonal to forward and right
  double tanHalfFovY = 0.57735;        // vertical field of view
  double aspect = 16.0 / 9.0;          // width / height
  double nearPlane = 0.1, farPlane = 1000.0;
  int width = 1280, height = 720;
};

// Preconditions: the camera as parseSceneJson returns it (position != target, up not parallel to the view,
// 0 < fov < 180, 0 < near < far, sizes >= 1). width/height override the camera's own when > 0.
CameraFrame cameraFrame(const CameraDesc& camera, int width = 0, int height = 0);

// The unit direction of pixel (x, y)'s centre; row 0 is the top of the image.
glm::dvec3 pixelDirection(const CameraFrame& camera, int x, int y);

// The record the tracers make this camera's primary rays from (compute/shared/camera_rays.h): the position
// split into two floats, the basis, the planes and the tangents rounded to float. Its rays follow
// pixelDirection to float precision.
gpu::CameraRays cameraRaysOf(const CameraFrame& camera);

}  // namespace vs

#endif
