// gbuffer.cpp: primary rays, hit resolution and visibility rays.
#include "lighting/gbuffer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

#include "voxel/error.h"

namespace vs {

std::vector<gpu::TraceRay> primaryRays(const CameraFrame& camera) { return cameraRays(cameraRaysOf(camera)); }

std::vector<gpu::TraceRay> primaryRays(const CameraFrame& camera, std::span<const std::uint32_t> pixels) {
  return cameraRays(cameraRaysOf(camera), pixels);
}

namespace {

const glm::dvec3 kFaceNormals[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};

}  // namespace

namespace {

// Per instance: the normal matrix, the voxel's world size and the palette.
struct InstanceFrame {
  glm::dmat3 normalMatrix;
  double voxelSize;
  const std::vector<glm::vec3>* palette;
};

std::vector<InstanceFrame> instanceFrames(const Scene& scene) {
  std::vector<InstanceFrame> frames;
  for (const SceneInstance& inst : scene.instances()) {
    const glm::dmat3 linear(inst.brickToWorld);
    frames.push_back({glm::transpose(glm::inverse(linear)), std::cbrt(std::abs(glm::determinant(linear))),
                      &scene.objects()[inst.object].palette});
  }
  return frames;
}

gpu::GBufferTexel resolveHit(const std::vector<InstanceFrame>& frames, const CameraFrame& camera,
                             const gpu::CameraRays& rays, std::uint32_t pixel, const gpu::RayHit& h) {
  gpu::GBufferTexel t{};
  if (h.hit == 0u) return t;
  const gpu::TraceRay r = gpu::vsCameraRay(rays, pixel);
  if (h.instance >= frames.size()) throwRuntime("G-buffer: a hit names instance " + std::to_string(h.instance));
  const InstanceFrame& f = frames[h.instance];
  const glm::dvec3 origin = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
  const glm::dvec3 dir(glm::vec3(r.direction));
  const glm::dvec3 p = origin + dir * double(h.t);
  const std::uint32_t face = std::uint32_t(h.voxel.w);
  glm::dvec3 n = face < 6u ? glm::normalize(f.normalMatrix * kFaceNormals[face]) : -glm::normalize(dir);
  t.position = glm::vec4(glm::vec3(p), float(glm::dot(p - camera.position, camera.forward)));
  t.normal = glm::vec4(glm::vec3(n), float(f.voxelSize));
  const std::vector<glm::vec3>& palette = *f.palette;
  const glm::vec3 albedo = h.material < palette.size() ? palette[h.material] : glm::vec3(0.8f);
  t.albedo = glm::vec4(albedo, 1.0f);
  t.info = glm::uvec4(h.instance, h.material, face, 1u);
  return t;
}

}  // namespace

void resolveGBuffer(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits, GBuffer& g) {
  const std::size_t count = std::size_t(camera.width) * std::size_t(camera.height);
  if (hits.size() != count)
    throwBadInput("G-buffer: " + std::to_string(hits.size()) + " hits for " + std::to_string(count) + " pixels");
  g.width = camera.width;
  g.height = camera.height;
  g.texels.resize(count);
  const std::vector<InstanceFrame> frames = instanceFrames(scene);
  const gpu::CameraRays rays = cameraRaysOf(camera);
  tbb::parallel_for(std::size_t(0), count, [&](std::size_t i) {
    g.texels[i] = resolveHit(frames, camera, rays, std::uint32_t(i), hits[i]);
  });
}

void resolveGBufferPixels(const Scene& scene, const CameraFrame& camera, std::span<const gpu::RayHit> hits,
                          std::span<const std::uint32_t> pixels, GBuffer& g) {
  if (hits.size() != pixels.size() || g.width != camera.width || g.height != camera.height ||
      g.texels.size() != std::size_t(camera.width) * std::size_t(camera.height))
    throwBadInput("G-buffer: hits, pixels and the G-buffer disagree on sizes");
  const std::vector<InstanceFrame> frames = instanceFrames(scene);
  const gpu::CameraRays rays = cameraRaysOf(camera);
  for (std::uint32_t p : pixels)
    if (p >= g.texels.size()) throwBadInput("G-buffer: pixel " + std::to_string(p) + " outside the frame");
  tbb::parallel_for(std::size_t(0), pixels.size(), [&](std::size_t k) {
    g.texels[pixels[k]] = resolveHit(frames, camera, rays, pixels[k], hits[k]);
  });
}

GBuffer traceGBuffer(const Scene& scene, const CameraFrame& camera, Tracer& tracer) {
  std::vector<gpu::RayHit> hits(std::size_t(camera.width) * std::size_t(camera.height));
  tracer.traceCamera(cameraRaysOf(camera), {}, hits);
  GBuffer g;
  resolveGBuffer(scene, camera, hits, g);
  return g;
}

namespace {

// Where the ray o + t d leaves the box (double slabs); 0 when it starts outside and misses it.
double exitDistance(const glm::dvec3& o, const glm::dvec3& d, const Aabb& box) {
  if (box.empty()) return 0.0;
  double tExit = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) continue;
    const double t0 = (double(box.min[a]) - o[a]) / d[a], t1 = (double(box.max[a]) - o[a]) / d[a];
    tExit = std::min(tExit, std::max(t0, t1));
  }
  return std::max(tExit, 0.0);
}

}  // namespace

namespace {

gpu::TraceRay visibilityRay(const gpu::GBufferTexel& g, const gpu::ShadeLight& light, float maxLength,
                            const Aabb& worldBounds) {
  const gpu::TraceRay empty = gpu::makeTraceRay(glm::dvec3(0.0), glm::dvec3(0.0, 1.0, 0.0), 1.0f, 0.0f);
  if (g.info.w == 0u || maxLength == 0.0f) return empty;
  const glm::dvec3 n(glm::vec3(g.normal));
  const glm::dvec3 origin = glm::dvec3(glm::vec3(g.position)) + n * (1e-3 * double(g.normal.w));
  glm::dvec3 toLight;
  double length;
  if (light.info.x == gpu::VS_LIGHT_DIRECTIONAL) {
    toLight = -glm::normalize(glm::dvec3(glm::vec3(light.direction)));
    length = exitDistance(origin, toLight, worldBounds);
  } else {
    const glm::dvec3 d = glm::dvec3(glm::vec3(light.position)) - origin;
    length = glm::length(d);
    if (!(length > 0.0)) return empty;
    toLight = d / length;
  }
  if (!(glm::dot(n, toLight) > 0.0)) return empty;
  if (maxLength > 0.0f) length = std::min(length, double(maxLength));
  return gpu::makeTraceRay(origin, toLight, 0.0f, float(length));
}

}  // namespace

std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds) {
  std::vector<gpu::TraceRay> rays;
  visibilityRays(gbuffer, lights, maxLength, worldBounds, rays);
  return rays;
}

void visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights, std::span<const float> maxLength,
                    const Aabb& worldBounds, std::vector<gpu::TraceRay>& rays) {
  const std::size_t lightCount = lights.size();
  rays.resize(gbuffer.texels.size() * lightCount);
  tbb::parallel_for(std::size_t(0), gbuffer.texels.size(), [&](std::size_t i) {
    for (std::size_t l = 0; l < lightCount; ++l)
      rays[i * lightCount + l] =
          visibilityRay(gbuffer.texels[i], lights[l], l < maxLength.size() ? maxLength[l] : 0.0f, worldBounds);
  });
}

std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds,
                                          std::span<const std::uint32_t> pixels) {
  const std::size_t lightCount = lights.size();
  std::vector<gpu::TraceRay> rays(pixels.size() * lightCount);
  tbb::parallel_for(std::size_t(0), pixels.size(), [&](std::size_t k) {
    for (std::size_t l = 0; l < lightCount; ++l)
      rays[k * lightCount + l] = visibilityRay(gbuffer.texels[pixels[k]], lights[l],
                                               l < maxLength.size() ? maxLength[l] : 0.0f, worldBounds);
  });
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
  const std::size_t lightCount = lights.size();
  tbb::parallel_for(std::size_t(0), gbuffer.texels.size(), [&](std::size_t i) {
    if (marks[i] || gbuffer.texels[i].info.w == 0u) return;
    for (std::size_t l = 0; l < lightCount; ++l) {
      const float length = l < maxLength.size() ? maxLength[l] : 0.0f;
      if (length == 0.0f) continue;
      const gpu::TraceRay r = visibilityRay(gbuffer.texels[i], lights[l], length, worldBounds);
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
