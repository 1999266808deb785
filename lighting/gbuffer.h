// gbuffer.h: the G-buffer of a camera view, from one primary ray per pixel (the shared closest-hit kind,
// DESIGN.md §6-7), and the visibility rays toward the lights that ray-traced and contact shadows answer.
#ifndef VOXSHADOW_GBUFFER_H
#define VOXSHADOW_GBUFFER_H

#include <cstdint>
#include <span>
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
// eye), through the pixel centre, from the near plane to the far plane (clipped as a rasteriser clips). The
// rays Tracer::traceCamera traces for cameraRaysOf(camera), bit for bit (compute/shared/camera_rays.h).
std::vector<gpu::TraceRay> primaryRays(const CameraFrame& camera);

// The primary rays of the given pixels (row-major indices), in their order.
std::vector<gpu::TraceRay> primaryRays(const CameraFrame& camera, std::span<const std::uint32_t> pixels);

// Traces the primary rays (Tracer::traceCamera: made where they are traced) and resolves each hit into world position (origin + t * direction in double),
// world face normal (the entry face through the instance's inverse transpose), the voxel's palette colour, view
// depth and instance. Preconditions: tracer.setScene(scene.data()) was called for this scene.
GBuffer traceGBuffer(const Scene& scene, const CameraFrame& camera, Tracer& tracer);

// The same from closest-hit records already traced (hits[i] that of pixel i's primary ray), written into g
// (its storage reused: a frame loop allocates nothing here). Each pixel's ray is made again from the camera
// (cameraRaysOf, vsCameraRay): the ray that was traced, bit for bit.
void resolveGBuffer(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits, GBuffer& g);

// Resolves the closest hits of the given pixels' primary rays (hits[k] that of pixels[k]) into those texels of
// g, leaving the others as they are. Preconditions: g sized for the camera; hits and pixels of one length
// (else vs::Error(BadInput)).
void resolveGBufferPixels(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                          std::span<const std::uint32_t> pixels, GBuffer& g);

// One visibility ray per pixel and light (pixel * lights + light), toward the light: from the receiver moved
// off its face by a thousandth of its voxel, to the light (spot, point) or out of the scene bounds
// (directional), at most maxLength[light] long (< 0: unbounded; 0: the light needs no ray). Pixels without a
// hit, facing away from the light, or of a light that needs no ray get an empty ray (tMax < tMin: clear).
std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds);
// The same into `rays` (resized; its storage reused).
void visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights, std::span<const float> maxLength,
                    const Aabb& worldBounds, std::vector<gpu::TraceRay>& rays);
// The same for the given pixels only: ray k * lights + l is pixel pixels[k]'s ray toward light l.
std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds,
                                          std::span<const std::uint32_t> pixels);

// Sets marks[i] (one per pixel, sized as the G-buffer) for every pixel whose visibility ray toward some light
// (as visibilityRays makes it) meets one of the world boxes: the pixels whose answers a change inside those
// boxes can alter. Pixels already marked are left as they are.
void markVisibilityRaysMeeting(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                               std::span<const float> maxLength, const Aabb& worldBounds, std::span<const Aabb> boxes,
                               std::vector<std::uint8_t>& marks);

}  // namespace vs

#endif
