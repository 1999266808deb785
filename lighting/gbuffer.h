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

// What resolving a scene's hits reads besides the hits (lighting/shared/gbuffer_resolve.h): one record per
// instance (its faces' world normals through its inverse transpose, its voxel's world size, where its object's
// colours start) and every object's palette, one after another.
struct GBufferTables {
  std::vector<gpu::GBufferInstance> instances;
  std::vector<glm::vec4> palette;
};
GBufferTables gbufferTables(const Scene& scene);

// Traces the primary rays (Tracer::traceCamera: made where they are traced) and resolves each hit into world
// position, view depth, world face normal, the voxel's palette colour and instance (vsResolveHit: the function
// the device's resolve runs). Preconditions: tracer.setScene(scene.data()) was called for this scene.
GBuffer traceGBuffer(const Scene& scene, const CameraFrame& camera, Tracer& tracer);

// The same from closest-hit records already traced (hits[i] that of pixel i's primary ray), written into g
// (its storage reused: a frame loop allocates nothing here). Each pixel's ray is made again from the camera
// (cameraRaysOf, vsCameraRay): the ray that was traced, bit for bit.
void resolveGBuffer(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits, GBuffer& g);
// The same with the scene's tables made already (gbufferTables).
void resolveGBuffer(const GBufferTables& tables, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                    GBuffer& g);

// Resolves the closest hits of the given pixels' primary rays (hits[k] that of pixels[k]) into those texels of
// g, leaving the others as they are. Preconditions: g sized for the camera; hits and pixels of one length
// (else vs::Error(BadInput)).
void resolveGBufferPixels(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                          std::span<const std::uint32_t> pixels, GBuffer& g);
void resolveGBufferPixels(const GBufferTables& tables, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                          std::span<const std::uint32_t> pixels, GBuffer& g);

// The visibility rays of a frame's lights (compute/shared/visibility_rays.h): the record and one light record
// per light, toward the light (spot, point: its position; directional: out of the world bounds), at most
// maxLength[light] long (< 0: unbounded; 0, or no entry: the light needs no ray); a spot or point light's
// range in kind.y, so that receivers beyond it get no ray.
struct VisibilitySetup {
  gpu::VisibilityRays frame{};
  std::vector<gpu::VisibilityLight> lights;
};
VisibilitySetup visibilitySetup(std::span<const gpu::ShadeLight> lights, std::span<const float> maxLength,
                                const Aabb& worldBounds);
// A G-buffer texel as the receiver of visibility rays: its rays start off its face by a thousandth of its
// voxel; a texel without a hit receives no ray (gpu::vsReceiverOf, which the device's resolve runs too).
gpu::VisibilityReceiver visibilityReceiver(const gpu::GBufferTexel& texel);
// The receivers of the given pixels (row-major indices) into `receivers` (resized, its storage reused); every
// pixel's when `pixels` is empty.
void visibilityReceivers(const GBuffer& gbuffer, std::span<const std::uint32_t> pixels,
                         std::vector<gpu::VisibilityReceiver>& receivers);

// One visibility ray per pixel and light (pixel * lights + light), as Tracer::traceVisibility makes them for
// visibilitySetup and visibilityReceivers: pixels without a hit, facing away from the light, beyond its range,
// or of a light that needs no ray get an empty ray (tMax < tMin: clear).
std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds);

// Sets marks[i] (one per pixel, sized as the G-buffer) for every pixel whose visibility ray toward some light
// (as visibilityRays makes it) meets one of the world boxes: the pixels whose answers a change inside those
// boxes can alter. Pixels already marked are left as they are.
void markVisibilityRaysMeeting(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                               std::span<const float> maxLength, const Aabb& worldBounds, std::span<const Aabb> boxes,
                               std::vector<std::uint8_t>& marks);

}  // namespace vs

#endif
