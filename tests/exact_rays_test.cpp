// exact_rays_test.cpp: shadow texels near and far from the world origin against an independent double-precision
// reference (support/exact_reference.h): its own rays from each view's stored eye and eyeToClip, its own
// transforms, its own voxel walk.
//
// What "agree" means. A float direction carries a relative error of a few 2^-24, so a float ray's position
// across its length is uncertain by about 2^-21 of the distance it has travelled (the lateral uncertainty, in
// voxels of the object it reaches). Every texel must then agree with the reference: the same hit or miss, and a
// depth within 1e-3 voxel plus one ulp of the stored float plus the lateral uncertainty (the depth a shifted ray
// sees on a surface inclined by up to 45 degrees). A disagreement beyond that is allowed only where the
// reference verifies an edge or corner contact: the exact ray passes a solid voxel within the same tolerance
// while crossing at most that much of it. Near the origin the lateral term is below 1e-4 voxel; 10^5 units
// from 0.01-unit voxels it is some 5 voxels, still far below the errors of a ray unprojected through a float
// inverse of worldToClip (hundreds of voxels there).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include <glm/gtc/matrix_transform.hpp>

#include "compute/cpu/cpu_tracer.h"
#include "lighting/light_views.h"
#include "lighting/scene.h"
#include "support/exact_reference.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"
#include "voxel/demo_world.h"

namespace vs {
namespace {

struct Tally {
  std::size_t texels = 0, hits = 0, ties = 0, failures = 0;
  double worstExcessVoxels = 0.0;  // largest depth error beyond the stored float's ulp, among agreeing hits
};

// Compares every texel of `views` (as traced into `layers`) with the reference. voxelsPerUnit: voxels per world
// unit of the scene's objects (all of one size here), for the lateral uncertainty.
Tally compareWithExact(const test::TestScene& scene, const std::vector<LightView>& views,
                       const std::vector<ShadowLayer>& layers, double voxelsPerUnit, const std::string& label) {
  auto objects = scene.brickmapPointers();
  test::ExactReference reference(objects, scene.instances);
  Tally tally;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const LightView& v = views[i];
    const bool ndc = v.encoding == gpu::VS_ENCODING_NDC_DEPTH;
    const float miss = ndc ? 1.0f : v.range;
    for (int y = 0; y < v.resolution; ++y)
      for (int x = 0; x < v.resolution; ++x) {
        ++tally.texels;
        test::ExactRay ray = test::exactTexelRay(v.eye, v.eyeToClip, ndc, v.range, v.resolution, v.resolution, x, y);
        test::ExactHit ref = reference.trace(ray);
        float ours = layers[i].texels[std::size_t(y) * std::size_t(v.resolution) + std::size_t(x)];
        bool hit = ours < miss;
        if (!hit && !ref.hit) continue;
        double t = ref.hit ? ref.t : double(ours);
        double travelled = glm::length(ray.o - v.eye) + t * glm::length(ray.d);
        double lateral = std::ldexp(travelled * voxelsPerUnit, -21);
        double perT = glm::length(ray.d) * voxelsPerUnit;
        double ulp = double(std::nextafter(ours, std::numeric_limits<float>::infinity()) - ours) * perT;
        double allowed = 1e-3 + ulp + lateral;
        double err = hit && ref.hit ? std::abs(double(ours) - ref.t) * ref.voxelsPerT : 0.0;
        if (hit && ref.hit) {
          ++tally.hits;
          if (err <= allowed) {
            tally.worstExcessVoxels = std::max(tally.worstExcessVoxels, std::max(0.0, err - ulp));
            continue;
          }
        }
        double nearer = hit && ref.hit ? std::min(double(ours), ref.t) : t;
        if (reference.grazesNear(ray, nearer, allowed, 1e-3 + lateral)) {
          ++tally.ties;
          continue;
        }
        if (++tally.failures <= 5)
          std::printf("  %s view %s texel (%d %d): ours %s %.9g, reference %s %.9g (voxel %d %d %d), %.3g voxel "
                      "apart, allowed %.3g\n",
                      label.c_str(), v.name.c_str(), x, y, hit ? "hit" : "miss", double(ours),
                      ref.hit ? "hit" : "miss", ref.t, ref.voxel.x, ref.voxel.y, ref.voxel.z, err, allowed);
      }
  }
  std::printf("%s: %zu texels, %zu hits on both sides, %zu verified edge ties, %zu disagreements; worst depth error "
              "beyond the float's ulp %.3g voxel\n",
              label.c_str(), tally.texels, tally.hits, tally.ties, tally.failures, tally.worstExcessVoxels);
  return tally;
}

std::vector<ShadowLayer> traceViews(const SceneData& scene, const std::vector<LightView>& views) {
  std::vector<gpu::TraceView> records;
  for (const LightView& v : views) records.push_back(v.trace);
  std::vector<ShadowLayer> layers;
  traceCpu(scene, records, layers);
  return layers;
}

LightDesc spotLight(const std::string& name, glm::dvec3 position, glm::dvec3 target, double outerDeg, double range,
                    int resolution) {
  LightDesc l;
  l.name = name;
  l.type = LightType::Spot;
  l.position = glm::vec3(position);
  l.direction = glm::vec3(glm::normalize(target - glm::dvec3(l.position)));
  l.outerConeDeg = float(outerDeg);
  l.innerConeDeg = float(outerDeg * 0.5);
  l.range = float(range);
  l.shadow = ShadowDesc{};
  l.shadow->resolution = resolution;
  return l;
}

LightDesc pointLight(const std::string& name, glm::dvec3 position, double range, int resolution) {
  LightDesc l;
  l.name = name;
  l.type = LightType::Point;
  l.position = glm::vec3(position);
  l.range = float(range);
  l.shadow = ShadowDesc{};
  l.shadow->resolution = resolution;
  return l;
}

LightDesc sunLight(glm::vec3 direction, int resolution) {
  LightDesc l;
  l.name = "sun";
  l.type = LightType::Directional;
  l.direction = glm::normalize(direction);
  l.shadow = ShadowDesc{};
  l.shadow->resolution = resolution;
  return l;
}

// A plate of 512 x 512 x 2 voxels of `voxelSize` units, centred on `centre`, tilted 30 degrees about x.
test::TestScene finePlate(glm::dvec3 centre, double voxelSize) {
  test::TestScene scene;
  scene.name = "fine plate";
  scene.brickmaps.push_back(test::boxObject({0, 0, 0}, {512, 2, 512}));
  glm::dmat4 m = glm::translate(glm::dmat4(1.0), centre) * glm::rotate(glm::dmat4(1.0), glm::radians(30.0), {1, 0, 0}) *
                 glm::scale(glm::dmat4(1.0), glm::dvec3(voxelSize)) * glm::translate(glm::dmat4(1.0), {-256, -1, -256});
  scene.instances.push_back({0u, m});
  scene.finish();
  return scene;
}

// Narrow spot cones aimed at a plate of 0.01-unit voxels from 10 to 10^5 units away, the cone fitted to the
// plate (down to a hundredth of a degree), and a 1 degree cone at 100 units.
TEST(ExactRays, SpotConesAtAFinePlate) {
  const double voxel = 0.01;
  test::TestScene scene = finePlate(glm::dvec3(0.0), voxel);
  const glm::dvec3 toLight = glm::normalize(glm::dvec3(0.3, 1.0, 0.2));
  SceneDesc desc;
  for (double distance : {10.0, 100.0, 1e3, 1e4, 1e5}) {
    double outer = glm::degrees(std::atan(3.0 / distance));
    desc.lights.push_back(spotLight("cone" + std::to_string(int(distance)), toLight * distance, glm::dvec3(0.0),
                                    outer, distance * 1.5, 128));
  }
  desc.lights.push_back(spotLight("narrow100", toLight * 100.0, glm::dvec3(0.0), 1.0, 150.0, 128));
  std::vector<LightView> views = buildLightViews(desc, scene.data.worldBounds);
  std::vector<ShadowLayer> layers = traceViews(scene.data, views);
  Tally tally = compareWithExact(scene, views, layers, 1.0 / voxel, "fine plate");
  EXPECT_EQ(tally.failures, 0u);
  EXPECT_LE(double(tally.ties), 2e-3 * double(tally.texels));
  EXPECT_GT(tally.hits, tally.texels / 2);  // every cone sees the plate
}

// Scenes moved 10^4 and 10^5 units from the origin (an open world's far corner), lit by a sun, a spot and a
// point light placed relative to them, agree with the reference as they do at the origin.
void expectTranslatedSceneExact(test::TestScene (*make)(), double offset, int resolution) {
  test::TestScene scene = make();
  const glm::dvec3 shift(offset, 0.37 * offset, -0.61 * offset);
  for (SceneInstance& inst : scene.instances) inst.brickToWorld = glm::translate(glm::dmat4(1.0), shift) * inst.brickToWorld;
  scene.finish();
  const Aabb& b = scene.data.worldBounds;
  glm::dvec3 centre = (glm::dvec3(b.min) + glm::dvec3(b.max)) * 0.5, size = glm::dvec3(b.max) - glm::dvec3(b.min);
  SceneDesc desc;
  desc.lights.push_back(sunLight({-0.4f, -1.0f, -0.3f}, resolution));
  glm::dvec3 spotAt = centre + glm::dvec3(0.3, 0.9, 0.2) * glm::length(size);
  desc.lights.push_back(spotLight("spot", spotAt, centre, 35.0, 3.0 * glm::length(size), resolution));
  desc.lights.push_back(pointLight("point", centre + glm::dvec3(0.1, 0.45, 0.05) * size, 2.0 * glm::length(size),
                                   resolution / 2));
  std::vector<LightView> views = buildLightViews(desc, b);
  std::vector<ShadowLayer> layers = traceViews(scene.data, views);
  Tally tally = compareWithExact(scene, views, layers, 1.0, scene.name + " +" + std::to_string(int(offset)));
  EXPECT_EQ(tally.failures, 0u) << scene.name << " at " << offset;
  EXPECT_LE(double(tally.ties), 2e-3 * double(tally.texels)) << scene.name << " at " << offset;
  EXPECT_GT(tally.hits, tally.texels / 10) << scene.name << " at " << offset;
}

TEST(ExactRays, FloorSceneAtTheOriginAndFarFromIt) {
  for (double offset : {0.0, 1e4, 1e5}) expectTranslatedSceneExact(test::floorScene, offset, 128);
}

TEST(ExactRays, City512FarFromTheOrigin) {
  for (double offset : {1e4, 1e5}) expectTranslatedSceneExact(test::city512Scene, offset, 96);
}

// The demo scene's own lamp, a 1024^2 spot, and its torch: every texel agrees with the reference.
TEST(ExactRays, DemoSceneLampAndTorch) {
  auto dir = test::scratchDir("exact_rays_demo");
  Scene loaded = Scene::load(writeDemoWorld(dir).back());
  test::TestScene scene;
  scene.name = "demo";
  for (const VoxelObject& object : loaded.objects()) scene.brickmaps.push_back(std::make_unique<Brickmap>(object.brickmap));
  scene.instances.assign(loaded.instances().begin(), loaded.instances().end());
  scene.finish();
  std::vector<LightView> views;
  for (const LightView& v : loaded.lightViews())
    if (v.light != "sun") views.push_back(v);
  ASSERT_EQ(views.size(), 7u);  // the lamp and the torch's six faces
  ASSERT_EQ(views[0].resolution, 1024);
  std::vector<ShadowLayer> layers = traceViews(scene.data, views);
  double voxelsPerUnit = 1.0 / glm::length(glm::dvec3(scene.instances[0].brickToWorld[0]));
  Tally tally = compareWithExact(scene, views, layers, voxelsPerUnit, "demo lamp and torch");
  EXPECT_EQ(tally.failures, 0u);
  EXPECT_LE(double(tally.ties), 1e-3 * double(tally.texels));
  EXPECT_LE(tally.worstExcessVoxels, 1e-3 + 1e-4);
}

}  // namespace
}  // namespace vs
