// cmd_bench_embree.cpp: `voxshadow bench --embree`: the backends against the Embree peer on the same rays.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include "compute/cpu/lane_tracer.h"
#include "compute/cpu/scene_arrays.h"
#include "compute/shared/camera_rays.h"
#include "compute/tracer.h"
#include "lighting/camera.h"
#include "lighting/light_views.h"
#include "lighting/scene.h"
#include "tools/bench_embree.h"
#include "tools/peer/embree_peer.h"
#include "voxel/brickmap.h"
#include "voxel/city512.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace vs::cli {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double medianOf(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Seconds of a backend's trace: GPU timestamps where the device has them (the dispatches alone), else the
// call's host time, as the rest of `bench` counts them.
double traceSeconds(const TraceStats& t) { return (t.gpuMs > 0.0 ? t.gpuMs : t.wallMs) * 1e-3; }

// The rays of one scene that every tracer traces.
struct RaySet {
  std::vector<gpu::TraceView> views;       // shadow texels (the backends trace the views themselves)
  std::vector<gpu::TraceRay> texelRays;    // the same texels' rays, in 4x2 texel blocks, for Embree
  std::vector<gpu::TraceRay> primary;      // a camera's rays, in 4x2 pixel blocks
  std::vector<gpu::TraceRay> visibility;   // from each primary hit toward the sun
};

// Appends the w x h grid of rays ray(x, y) in 4 x 2 blocks (rtcIntersect8's coherent packets), row by row of
// blocks; a block's cells past the grid's edge are left out.
void appendInBlocks(int w, int h, const std::function<gpu::TraceRay(int, int)>& ray, std::vector<gpu::TraceRay>& out) {
  for (int by = 0; by < h; by += 2)
    for (int bx = 0; bx < w; bx += 4)
      for (int y = by; y < std::min(by + 2, h); ++y)
        for (int x = bx; x < std::min(bx + 4, w); ++x) out.push_back(ray(x, y));
}

// Each view's texel rays as the trace kernels make them (vsViewRay), as TraceRays from their double origin.
void appendTexelRays(const SceneData& scene, std::span<const gpu::TraceView> views, std::vector<gpu::TraceRay>& out) {
  gpu::SceneArrays arrays(scene);
  for (const gpu::TraceView& view : views) {
    const int w = view.rect.z - view.rect.x, h = view.rect.w - view.rect.y;
    appendInBlocks(w, h, [&](int x, int y) {
      gpu::SceneArrays::WorldRay r;
      arrays.vsViewRay(view, glm::ivec2(view.rect.x + x, view.rect.y + y), r);
      const glm::dvec3 origin =
          glm::dvec3(glm::vec3(r.eyeHigh)) + glm::dvec3(glm::vec3(r.eyeLow)) + glm::dvec3(glm::vec3(r.start));
      return gpu::makeTraceRay(origin, glm::dvec3(glm::vec3(r.d)), r.tMin, r.tMax);
    }, out);
  }
}

// The camera's rays in 4 x 2 pixel blocks, and from each of their closest hits (traced by `tracer`) a ray
// toward the sun, from just before the hit's entry point, to the end of the scene.
void appendCameraRays(const CameraFrame& camera, const glm::dvec3& toSun, Tracer& tracer, RaySet& set) {
  const gpu::CameraRays record = cameraRaysOf(camera);
  appendInBlocks(camera.width, camera.height, [&](int x, int y) {
    return gpu::vsCameraRay(record, std::uint32_t(y) * std::uint32_t(camera.width) + std::uint32_t(x));
  }, set.primary);
  std::vector<gpu::RayHit> hits(set.primary.size());
  tracer.traceClosest(set.primary, hits);
  for (std::size_t i = 0; i < hits.size(); ++i) {
    if (!hits[i].hit) continue;
    const gpu::TraceRay& r = set.primary[i];
    const glm::dvec3 o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
    const glm::dvec3 d(glm::vec3(r.direction));
    set.visibility.push_back(gpu::makeTraceRay(o + d * (double(hits[i].t) - 1e-3), toSun, 0.0f, 1e30f));
  }
}

struct Backend {
  std::string name;  // "cpu" or "vulkan"
  Tracer* tracer;
};

// One scene: the Embree peer built, then per ray kind every tracer's median and the paired ratios.
void compareScene(const char* sceneName, std::span<const Brickmap* const> brickmaps, const SceneData& scene,
                  const RaySet& rays, std::span<const Backend> backends, const EmbreeBenchOptions& opt) {
  auto t0 = Clock::now();
  EmbreePeer peer(brickmaps, scene);
  std::printf("%s: Embree peer: %llu rectangles, %llu triangles, meshed and built (quality HIGH) in %.2f s\n",
              sceneName, static_cast<unsigned long long>(peer.rectangleCount()),
              static_cast<unsigned long long>(peer.triangleCount()), secondsSince(t0));
  std::vector<gpu::RayHit> peerHits;
  std::vector<std::uint32_t> peerAnswers;
  struct Query {
    const char* name;
    std::function<double(const std::vector<gpu::TraceRay>&)> run;  // seconds of one call
  };
  const Query intersect1{"intersect1", [&](const std::vector<gpu::TraceRay>& r) {
                           peerHits.resize(r.size());
                           auto t = Clock::now();
                           peer.intersect(r, peerHits, false, opt.threads);
                           return secondsSince(t);
                         }};
  const Query intersect8{"intersect8", [&](const std::vector<gpu::TraceRay>& r) {
                           peerHits.resize(r.size());
                           auto t = Clock::now();
                           peer.intersect(r, peerHits, true, opt.threads);
                           return secondsSince(t);
                         }};
  const Query occluded8{"occluded8", [&](const std::vector<gpu::TraceRay>& r) {
                          peerAnswers.resize(r.size());
                          auto t = Clock::now();
                          peer.occluded8(r, peerAnswers, opt.threads);
                          return secondsSince(t);
                        }};
  struct Kind {
    const char* name;
    const std::vector<gpu::TraceRay>* rays;  // what Embree traces
    std::vector<Query> queries;
    std::function<double(Tracer&)> ours;  // seconds of one backend call
  };
  std::vector<ShadowLayer> layers;
  std::vector<gpu::RayHit> hits(rays.primary.size());
  std::vector<std::uint32_t> occluded(rays.visibility.size());
  const std::vector<Kind> kinds = {
      {"shadow", &rays.texelRays, {intersect1, intersect8},
       [&](Tracer& t) { return traceSeconds(t.traceShadow(rays.views, layers)); }},
      {"primary", &rays.primary, {intersect1, intersect8},
       [&](Tracer& t) { return traceSeconds(t.traceClosest(rays.primary, hits)); }},
      {"visibility", &rays.visibility, {intersect1, intersect8, occluded8},
       [&](Tracer& t) { return traceSeconds(t.traceAny(rays.visibility, occluded)); }},
  };
  for (const Kind& kind : kinds) {
    const double count = double(kind.rays->size());
    for (const Query& q : kind.queries) {
      q.run(*kind.rays);  // warm-up
      std::vector<double> s;
      for (int r = 0; r < opt.reps; ++r) s.push_back(q.run(*kind.rays));
      std::printf("%-9s %-10s embree %-10s %9.4f s %9.2f Mrays/s\n", sceneName, kind.name, q.name, medianOf(s),
                  count / medianOf(s) / 1e6);
    }
    for (const Backend& b : backends) {
      kind.ours(*b.tracer);  // warm-up
      std::vector<double> s;
      for (int r = 0; r < opt.reps; ++r) s.push_back(kind.ours(*b.tracer));
      std::printf("%-9s %-10s %-17s %9.4f s %9.2f Mrays/s  (%s)\n", sceneName, kind.name, b.name.c_str(),
                  medianOf(s), count / medianOf(s) / 1e6, b.tracer->deviceName().c_str());
    }
    // The ratios, each of `reps` pairs run back to back: Embree's seconds over the backend's.
    for (const Backend& b : backends)
      for (const Query& q : kind.queries) {
        std::vector<double> ratios;
        for (int r = 0; r < opt.reps; ++r) {
          const double ours = kind.ours(*b.tracer);
          ratios.push_back(q.run(*kind.rays) / ours);
        }
        std::printf("vs-embree %s %s %s / %s: %.2fx (median of %d pairs)\n", sceneName, kind.name, b.name.c_str(),
                    q.name, medianOf(ratios), opt.reps);
      }
  }
}

}  // namespace

void runEmbreeBench(const EmbreeBenchOptions& opt) {
  std::unique_ptr<Tracer> cpu = makeCpuTracer({CpuTracePath::Interleaved, opt.threads});
  std::unique_ptr<Tracer> vulkan = opt.vulkan ? makeVulkanTracer() : nullptr;
  std::printf("cpu: interleaved tiles, %s, %d threads; Embree %s\n", laneWidthName(widestLaneWidth()),
              opt.threads, EmbreePeer::version());
  std::vector<Backend> backends = {{"cpu", cpu.get()}};
  if (vulkan) backends.push_back({"vulkan", vulkan.get()});

  {  // city512: one instance; the calibration sun of DESIGN.md §10 and a camera over the city from a corner.
    std::printf("city512: generating voxels...\n");
    const Brickmap brickmap = Brickmap::build(city512Voxels());
    const Brickmap* objects[] = {&brickmap};
    const SceneInstance instance{0u, glm::dmat4(1.0)};
    const SceneData scene = SceneData::build(objects, std::span<const SceneInstance>(&instance, 1));
    for (const Backend& b : backends) b.tracer->setScene(scene);
    RaySet rays;
    rays.views.push_back(city512CalibrationView(opt.resolution));
    appendTexelRays(scene, rays.views, rays.texelRays);
    CameraDesc camera;
    camera.position = glm::vec3(700.0f, 300.0f, 760.0f);
    camera.target = glm::vec3(256.0f, 30.0f, 256.0f);
    camera.up = glm::vec3(0.0f, 1.0f, 0.0f);
    camera.fovDeg = 60.0f;
    camera.nearPlane = 1e-3f;
    camera.farPlane = 4000.0f;
    appendCameraRays(cameraFrame(camera, 1280, 720), glm::normalize(glm::dvec3(0.4, 1.0, 0.3)), *cpu, rays);
    std::printf("city512: %zu shadow texels (%dx%d sun), %zu primary rays (1280x720), %zu visibility rays; %d "
                "threads, median of %d\n",
                rays.texelRays.size(), opt.resolution, opt.resolution, rays.primary.size(), rays.visibility.size(),
                opt.threads, opt.reps);
    compareScene("city512", objects, scene, rays, backends, opt);
  }
  {  // The demo scene: 13 instances of 6 objects, its lights' views and its camera at 1280x720.
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("voxshadow-bench-embree-" + std::to_string(::getpid()));
    const std::vector<std::string> written = writeDemoWorld(dir);
    const Scene scene = Scene::load(std::filesystem::path(written.back()));
    std::filesystem::remove_all(dir);
    for (const Backend& b : backends) b.tracer->setScene(scene.data());
    RaySet rays;
    const CameraFrame camera = cameraFrame(*scene.desc().camera, 1280, 720);
    glm::dvec3 toSun(0.0, 1.0, 0.0);
    for (const LightView& v : buildLightViews(scene.desc(), scene.worldBounds(), &camera)) rays.views.push_back(v.trace);
    for (const LightDesc& l : scene.desc().lights)
      if (l.type == LightType::Directional) {
        toSun = -glm::normalize(glm::dvec3(l.direction));
        break;
      }
    appendTexelRays(scene.data(), rays.views, rays.texelRays);
    appendCameraRays(camera, toSun, *cpu, rays);
    std::printf("demo: %zu instances, %zu shadow texels (%zu views), %zu primary rays, %zu visibility rays\n",
                scene.data().instances.size(), rays.texelRays.size(), rays.views.size(), rays.primary.size(),
                rays.visibility.size());
    std::vector<const Brickmap*> objects;
    for (const VoxelObject& o : scene.objects()) objects.push_back(&o.brickmap);
    compareScene("demo", objects, scene.data(), rays, backends, opt);
  }
}

}  // namespace vs::cli
