// gbuffer.h: the G-buffer of a camera view, from one primary ray per pixel (the shared closest-hit kind,
// DESIGN.md §6-7), and the visibility rays toward the lights that ray-traced and contact shadows answer.
#ifndef VOXSHADOW_GBUFFER_H
#define VOXSHADOW_GBUFFER_H

#include <cstdint>
#include <vector>

#include "compute/tracer.h"
#include "lighting/camera.h"
#include "lighting/scene.h"
#include "lighting/shared/shading_layout.h"

namespace vs {

struct GBuffer {
  int width = 0, height = 0;
  std::vector<gpu::GBufferTexel> texels;  // row 0 at the top
};

// The primary ray of every pixel, row by row: from the camera position (split into two floats, as a view's
// eye), through the pixel centre, from the near plane to the far plane (clipped as a rasteriser clips).
std::vector<gpu::TraceRay> primaryRays(const CameraFrame& camera);

// Traces the primary rays and resolves each hit into world position (origin + t * direction in double),
// world face normal (the entry face through the instance's inverse transpose), the voxel's palette colour, view
// depth and instance. Preconditions: tracer.setScene(scene.data()) was called for this scene.
GBuffer traceGBuffer(const Scene& scene, const CameraFrame& camera, Tracer& tracer);

// The same from closest-hit records already traced (rays as primaryRays gives them).
GBuffer resolveGBuffer(const Scene& scene, const CameraFrame& camera, const std::vector<gpu::TraceRay>& rays,
                       const std::vector<gpu::RayHit>& hits);

// One visibility ray per pixel and light (pixel * lights + light), toward the light: from the receiver moved
// off its face by a thousandth of its voxel, to the light (spot, point) or out of the scene bounds
// (directional), at most maxLength[light] long (< 0: unbounded; 0: the light needs no ray). Pixels without a
// hit, facing away from the light, or of a light that needs no ray get an empty ray (tMax < tMin: clear).
std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds);

}  // namespace vs

#endif
