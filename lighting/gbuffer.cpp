// gbuffer.cpp: primary rays, hit resolution and visibility rays.
#include "lighting/gbuffer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

#include "compute/shared/camera_rays.h"
#include "compute/shared/visibility_rays.h"
#include "lighting/shared/gbuffer_resolve.h"
#include "voxel/error.h"

namespace vs {

namespace {

const glm::dvec3 kFaceNormals[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};

gpu::GBufferTexel resolveHit(const GBufferTables& tables, const gpu::CameraRays& rays, std::uint32_t pixel,
                             const gpu::RayHit& h) {
  if (h.hit == 0u) return gpu::vsResolveHit(rays, pixel, h, gpu::GBufferInstance{}, glm::vec3(0.0f));
  if (h.instance >= tables.instances.size()) throwRuntime("G-buffer: a hit names instance " + std::to_string(h.instance));
  const gpu::GBufferInstance& inst = tables.instances[h.instance];
  const int slot = gpu::vsPaletteSlot(inst, h.material);
  const glm::vec3 albedo = slot >= 0 ? glm::vec3(tables.palette[std::size_t(slot)]) : glm::vec3(gpu::VS_MISSING_ALBEDO);
  return gpu::vsResolveHit(rays, pixel, h, inst, albedo);
}

}  // namespace

GBufferTables gbufferTables(const Scene& scene) {
  GBufferTables tables;
  std::vector<std::uint32_t> firstColour;
  for (const VoxelObject& object : scene.objects()) {
    firstColour.push_back(std::uint32_t(tables.palette.size()));
    for (const glm::vec3& c : object.palette) tables.palette.push_back(glm::vec4(c, 1.0f));
  }
  for (const SceneInstance& inst : scene.instances()) {
    // The faces' normals through the inverse transpose, and the voxel's world size, in double, rounded once.
    const glm::dmat3 linear(inst.brickToWorld);
    const glm::dmat3 normalMatrix = glm::transpose(glm::inverse(linear));
    const float voxelSize = float(std::cbrt(std::abs(glm::determinant(linear))));
    gpu::GBufferInstance g{};
    for (int face = 0; face < 6; ++face)
      g.faceNormals[face] = glm::vec4(glm::vec3(glm::normalize(normalMatrix * kFaceNormals[face])), voxelSize);
    g.palette = glm::uvec4(firstColour[inst.object], std::uint32_t(scene.objects()[inst.object].palette.size()), 0u, 0u);
    tables.instances.push_back(g);
  }
  return tables;
}

void resolveGBuffer(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits, GBuffer& g) {
  resolveGBuffer(gbufferTables(scene), camera, hits, g);
}

void resolveGBuffer(const GBufferTables& tables, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                    GBuffer& g) {
  const std::size_t count = std::size_t(camera.width) * std::size_t(camera.height);
  if (hits.size() != count)
    throwBadInput("G-buffer: " + std::to_string(hits.size()) + " hits for " + std::to_string(count) + " pixels");
  g.width = camera.width;
  g.height = camera.height;
  g.texels.resize(count);
  const gpu::CameraRays rays = cameraRaysOf(camera);
  tbb::parallel_for(std::size_t(0), count, [&](std::size_t i) {
    g.texels[i] = resolveHit(tables, rays, std::uint32_t(i), hits[i]);
  });
}

void resolveGBufferPixels(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                          std::span<const std::uint32_t> pixels, GBuffer& g) {
  resolveGBufferPixels(gbufferTables(scene), camera, hits, pixels, g);
}

void resolveGBufferPixels(const GBufferTables& tables, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                          std::span<const std::uint32_t> pixels, GBuffer& g) {
  if (hits.size() != pixels.size() || g.width != camera.width || g.height != camera.height ||
      g.texels.size() != std::size_t(camera.width) * std::size_t(camera.height))
    throwBadInput("G-buffer: hits, pixels and the G-buffer disagree on sizes");
  const gpu::CameraRays rays = cameraRaysOf(camera);
  for (std::uint32_t p : pixels)
    if (p >= g.texels.size()) throwBadInput("G-buffer: pixel " + std::to_string(p) + " outside the frame");
  tbb::parallel_for(std::size_t(0), pixels.size(), [&](std::size_t k) {
    g.texels[pixels[k]] = resolveHit(tables, rays, pixels[k], hits[k]);
  });
}

GBuffer traceGBuffer(const Scene& scene, const CameraFrame& camera, Tracer& tracer) {
  std::vector<gpu::RayHit> hits(std::size_t(camera.width) * std::size_t(camera.height));
  tracer.traceCamera(cameraRaysOf(camera), {}, hits);
  GBuffer g;
  resolveGBuffer(scene, camera, hits, g);
  return g;
}

VisibilitySetup visibilitySetup(std::span<const gpu::ShadeLight> lights, std::span<const float> maxLength,
                                const Aabb& worldBounds) {
  VisibilitySetup setup;
  // An empty world box (its min at +infinity) as a finite empty one: rays toward a direction then have no length.
  const bool empty = worldBounds.empty();
  setup.frame.boundsMin = glm::vec4(empty ? glm::vec3(1.0f) : worldBounds.min, 0.0f);
  setup.frame.boundsMax = glm::vec4(empty ? glm::vec3(0.0f) : worldBounds.max, 0.0f);
  setup.lights.resize(lights.size());
  for (std::size_t l = 0; l < lights.size(); ++l) {
    gpu::VisibilityLight& v = setup.lights[l];
    const float length = l < maxLength.size() ? maxLength[l] : 0.0f;
    if (lights[l].info.x == gpu::VS_LIGHT_DIRECTIONAL) {
      // The light's direction is the way its light travels: the rays go the other way.
      const glm::dvec3 toLight = -glm::normalize(glm::dvec3(glm::vec3(lights[l].direction)));
      v.target = glm::vec4(gpu::roundedToFloat(toLight), length);
      v.kind = glm::vec4(gpu::VS_VISIBILITY_TOWARD_DIRECTION, 0.0f, 0.0f, 0.0f);
    } else {
      // Receivers beyond the light's range get no ray: the pass does not read their answers.
      v.target = glm::vec4(glm::vec3(lights[l].position), length);
      v.kind = glm::vec4(gpu::VS_VISIBILITY_TOWARD_POINT, lights[l].position.w, 0.0f, 0.0f);
    }
  }
  return setup;
}

gpu::VisibilityReceiver visibilityReceiver(const gpu::GBufferTexel& texel) { return gpu::vsReceiverOf(texel); }

void visibilityReceivers(const GBuffer& gbuffer, std::span<const std::uint32_t> pixels,
                         std::vector<gpu::VisibilityReceiver>& receivers) {
  const std::size_t count = pixels.empty() ? gbuffer.texels.size() : pixels.size();
  receivers.resize(count);
  tbb::parallel_for(std::size_t(0), count, [&](std::size_t k) {
    receivers[k] = visibilityReceiver(gbuffer.texels[pixels.empty() ? k : pixels[k]]);
  });
}

std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds) {
  const VisibilitySetup setup = visibilitySetup(lights, maxLength, worldBounds);
  std::vector<gpu::VisibilityReceiver> receivers;
  visibilityReceivers(gbuffer, {}, receivers);
  std::vector<gpu::TraceRay> rays;
  visibilityRays(setup.frame, setup.lights, receivers, rays);
  return rays;
}

namespace {

// Whether segment o + t d, t in [t0, t1], meets the box (double slabs).
bool segmentMeetsBox(const glm::dvec3& o, const glm::dvec3& d, double t0, double t1, const Aabb& box) {
  for (int a = 0; a < 3; ++a) {
    const double lo = double(box.min[a]), hi = double(box.max[a]);
    if (d[a] == 0.0) {
      if (o[a] < lo || o[a] > hi) return false;
      continue;
    }
    double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

void markVisibilityRaysMeeting(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                               std::span<const float> maxLength, const Aabb& worldBounds, std::span<const Aabb> boxes,
                               std::vector<std::uint8_t>& marks) {
  if (boxes.empty()) return;
  // Boxes grown by a little more than float rounding of the rays' ends, so a ray grazing one is counted.
  std::vector<Aabb> grown(boxes.begin(), boxes.end());
  for (Aabb& b : grown) {
    const glm::vec3 pad = (glm::abs(b.min) + glm::abs(b.max) + (b.max - b.min)) * 1e-5f + glm::vec3(1e-4f);
    b.min -= pad;
    b.max += pad;
  }
  const VisibilitySetup setup = visibilitySetup(lights, maxLength, worldBounds);
  tbb::parallel_for(std::size_t(0), gbuffer.texels.size(), [&](std::size_t i) {
    if (marks[i] || gbuffer.texels[i].info.w == 0u) return;
    const gpu::VisibilityReceiver receiver = visibilityReceiver(gbuffer.texels[i]);
    for (const gpu::VisibilityLight& light : setup.lights) {
      if (light.target.w == 0.0f) continue;
      const gpu::TraceRay r = gpu::vsVisibilityRay(setup.frame, light, receiver);
      const double tMin = double(r.originHigh.w), tMax = double(r.originLow.w);
      if (!(tMax >= tMin)) continue;  // an empty ray: nothing it answers can change
      const glm::dvec3 o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
      const glm::dvec3 d(glm::vec3(r.direction));
      for (const Aabb& b : grown)
        if (segmentMeetsBox(o, d, tMin, tMax, b)) {
          marks[i] = 1;
          return;
        }
    }
  });
}

}  // namespace vs
