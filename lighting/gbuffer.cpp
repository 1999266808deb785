// gbuffer.cpp: primary rays, hit resolution and visibility rays.
#include "lighting/gbuffer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

#include "voxel/error.h"

namespace vs {

std::vector<gpu::TraceRay> primaryRays(const CameraFrame& camera) {
  std::vector<gpu::TraceRay> rays(std::size_t(camera.width) * std::size_t(camera.height));
  tbb::parallel_for(0, camera.height, [&](int y) {
    for (int x = 0; x < camera.width; ++x) {
      const glm::dvec3 d = pixelDirection(camera, x, y);
      // Between the near and far planes, as a rasteriser clips: the cascades' splits start at `near`, so
      // whatever the camera sees lies in one of them.
      const double forward = glm::dot(d, camera.forward);
      rays[std::size_t(y) * std::size_t(camera.width) + std::size_t(x)] = gpu::makeTraceRay(
          camera.position, d, float(camera.nearPlane / forward), float(camera.farPlane / forward));
    }
  });
  return rays;
}

namespace {

const glm::dvec3 kFaceNormals[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};

}  // namespace

GBuffer resolveGBuffer(const Scene& scene, const CameraFrame& camera, const std::vector<gpu::TraceRay>& rays,
                       const std::vector<gpu::RayHit>& hits) {
  GBuffer g;
  g.width = camera.width;
  g.height = camera.height;
  g.texels.assign(hits.size(), gpu::GBufferTexel{});
  // Per instance: the normal matrix and the voxel's world size.
  struct InstanceFrame {
    glm::dmat3 normalMatrix;
    double voxelSize;
    const std::vector<glm::vec3>* palette;
  };
  std::vector<InstanceFrame> frames;
  for (const SceneInstance& inst : scene.instances()) {
    const glm::dmat3 linear(inst.brickToWorld);
    frames.push_back({glm::transpose(glm::inverse(linear)), std::cbrt(std::abs(glm::determinant(linear))),
                      &scene.objects()[inst.object].palette});
  }
  tbb::parallel_for(std::size_t(0), hits.size(), [&](std::size_t i) {
    const gpu::RayHit& h = hits[i];
    if (h.hit == 0u) return;
    if (h.instance >= frames.size()) throwRuntime("G-buffer: a hit names instance " + std::to_string(h.instance));
    const InstanceFrame& f = frames[h.instance];
    const gpu::TraceRay& r = rays[i];
    const glm::dvec3 origin = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
    const glm::dvec3 dir(glm::vec3(r.direction));
    const glm::dvec3 p = origin + dir * double(h.t);
    const std::uint32_t face = std::uint32_t(h.voxel.w);
    glm::dvec3 n = face < 6u ? glm::normalize(f.normalMatrix * kFaceNormals[face]) : -glm::normalize(dir);
    gpu::GBufferTexel& t = g.texels[i];
    t.position = glm::vec4(glm::vec3(p), float(glm::dot(p - camera.position, camera.forward)));
    t.normal = glm::vec4(glm::vec3(n), float(f.voxelSize));
    const std::vector<glm::vec3>& palette = *f.palette;
    const glm::vec3 albedo = h.material < palette.size() ? palette[h.material] : glm::vec3(0.8f);
    t.albedo = glm::vec4(albedo, 1.0f);
    t.info = glm::uvec4(h.instance, h.material, face, 1u);
  });
  return g;
}

GBuffer traceGBuffer(const Scene& scene, const CameraFrame& camera, Tracer& tracer) {
  const std::vector<gpu::TraceRay> rays = primaryRays(camera);
  std::vector<gpu::RayHit> hits(rays.size());
  tracer.traceClosest(rays, hits);
  return resolveGBuffer(scene, camera, rays, hits);
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

std::vector<gpu::TraceRay> visibilityRays(const GBuffer& gbuffer, std::span<const gpu::ShadeLight> lights,
                                          std::span<const float> maxLength, const Aabb& worldBounds) {
  const std::size_t lightCount = lights.size();
  std::vector<gpu::TraceRay> rays(gbuffer.texels.size() * lightCount);
  const gpu::TraceRay empty = gpu::makeTraceRay(glm::dvec3(0.0), glm::dvec3(0.0, 1.0, 0.0), 1.0f, 0.0f);
  tbb::parallel_for(std::size_t(0), gbuffer.texels.size(), [&](std::size_t i) {
    const gpu::GBufferTexel& g = gbuffer.texels[i];
    for (std::size_t l = 0; l < lightCount; ++l) {
      gpu::TraceRay& ray = rays[i * lightCount + l];
      ray = empty;
      if (g.info.w == 0u || l >= maxLength.size() || maxLength[l] == 0.0f) continue;
      const gpu::ShadeLight& light = lights[l];
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
        if (!(length > 0.0)) continue;
        toLight = d / length;
      }
      if (!(glm::dot(n, toLight) > 0.0)) continue;
      if (maxLength[l] > 0.0f) length = std::min(length, double(maxLength[l]));
      ray = gpu::makeTraceRay(origin, toLight, 0.0f, float(length));
    }
  });
  return rays;
}

}  // namespace vs
