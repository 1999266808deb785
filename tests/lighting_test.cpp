// lighting_test.cpp: cascades, the G-buffer and the deferred lighting pass, measured against the ray-traced
// truth (one exact visibility ray per pixel and light): agreement, acne, peter-panning, shimmer, seams, and
// the Vulkan pass against the CPU pass.
#include <algorithm>
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "lighting/cascades.h"
#include "lighting/deferred.h"
#include "lighting/cpu_shading.h"
#include "lighting/gbuffer.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "support/lighting_scenes.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace fs = std::filesystem;
using namespace vs;

namespace {

struct TruthComparison {
  int receivers = 0;        // pixels with a hit that face the light
  int falselyLit = 0;       // the maps say lit (> 0.5), the truth says shadowed
  int falselyShadowed = 0;  // the maps say shadowed (< 0.5), the truth says lit: acne
  double differing() const { return receivers ? double(falselyLit + falselyShadowed) / receivers : 0.0; }
};

std::unique_ptr<Tracer> cpuTracer() { return makeCpuTracer({CpuTracePath::Interleaved, 0}); }

RenderedFrame renderWith(const Scene& scene, Tracer& tracer, ShadowSource source, int width = 0, int height = 0) {
  FrameRenderer renderer(tracer);
  RenderOptions options;
  options.shadows = source;
  options.width = width;
  options.height = height;
  return renderer.render(scene, options);
}

// Light `light`'s term per receiver pixel, maps against truth.
TruthComparison compareWithTruth(const RenderedFrame& maps, const RenderedFrame& truth, std::size_t light,
                                 const glm::dvec3& toLight) {
  TruthComparison c;
  const std::size_t lights = maps.lightNames.size();
  for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
    const gpu::GBufferTexel& g = maps.gbuffer.texels[i];
    if (g.info.w == 0u || !(glm::dot(glm::dvec3(glm::vec3(g.normal)), toLight) > 0.0)) continue;
    ++c.receivers;
    const bool mapLit = maps.shadowTerms[i * lights + light] > 0.5f;
    const bool trueLit = truth.shadowTerms[i * lights + light] > 0.5f;
    if (mapLit && !trueLit) ++c.falselyLit;
    if (!mapLit && trueLit) ++c.falselyShadowed;
  }
  return c;
}

RenderedFrame renderWithLayers(const Scene& scene, Tracer& tracer, std::vector<ShadowLayer>& layers) {
  FrameRenderer renderer(tracer);
  RenderOptions options;
  options.shadows = ShadowSource::Maps;
  RenderedFrame frame = renderer.render(scene, options);
  layers = renderer.layers();
  return frame;
}

enum class FalseShadow { SelfShadowed, BesideAnEdge };

bool insideBoxes(const test::VoxelBoxSet& set, const glm::dvec3& q) {
  for (const auto& [lo, hi] : set.boxes)  // voxel i spans [i - 0.5, i + 0.5]
    if (q.x > lo.x - 0.5 && q.x < hi.x + 0.5 && q.y > lo.y - 0.5 && q.y < hi.y + 0.5 && q.z > lo.z - 0.5 &&
        q.z < hi.z + 0.5)
      return true;
  return false;
}

// Why the maps shadow a receiver that the truth lights (hard filter, a directional light), found apart from
// the shading code and in double: the cascade by the view depth and the lateral check, the texel that the
// filter reads, its ray rebuilt from the view's stored matrix, and where that ray meets the receiver's plane.
// Self-shadowed: the texel's hit lies on the receiver's plane (a bias too small for its depth), or the ray meets
// the plane inside the solid (at a concave corner, where the neighbouring face answers for the receiver).
// Beside an edge: the ray meets the plane at a real surface point and a caster in front of that point shadows
// it, rightly; the receiver lies within the texel of that shadow's edge (aliasing, which the agreement test
// bounds). In a cascade blend band both cascades' texels are read; either one self-shadowed counts.
FalseShadow whyShadowed(const RenderedFrame& frame, const std::vector<ShadowLayer>& layers,
                        const test::VoxelBoxSet& solid, std::size_t pixel) {
  const gpu::GBufferTexel& g = frame.gbuffer.texels[pixel];
  const glm::dvec3 p(glm::vec3(g.position)), n(glm::vec3(g.normal));
  const double viewDepth = g.position.w, voxel = g.normal.w;
  bool self = false, chosen = false;
  for (std::size_t v = 0; v < frame.views.size() && !chosen; ++v) {
    const LightView& view = frame.views[v];
    if (view.cascade >= 0 && !(viewDepth >= view.splitNear && viewDepth < view.splitFar)) continue;
    const glm::dvec4 clip = view.eyeToClip * glm::dvec4(p - view.eye, 1.0);
    const glm::dvec2 texel = (glm::dvec2(clip) / clip.w * 0.5 + 0.5) * double(view.resolution);
    if (texel.x < 0.5 || texel.y < 0.5 || texel.x > view.resolution - 0.5 || texel.y > view.resolution - 0.5) continue;
    chosen = !(view.cascade >= 0 && viewDepth > view.splitFar - 0.1 * (view.splitFar - view.splitNear));
    const int tx = int(std::floor(texel.x)), ty = int(std::floor(texel.y));
    const float stored = layers[v].texels[std::size_t(ty) * std::size_t(view.resolution) + std::size_t(tx)];
    if (stored >= view.range) continue;
    const glm::dmat4 clipToEye = glm::inverse(view.eyeToClip);
    const double nx = (tx + 0.5) / view.resolution * 2.0 - 1.0, ny = (ty + 0.5) / view.resolution * 2.0 - 1.0;
    const glm::dvec4 nearH = clipToEye * glm::dvec4(nx, ny, 0.0, 1.0), farH = clipToEye * glm::dvec4(nx, ny, 1.0, 1.0);
    const glm::dvec3 start = view.eye + glm::dvec3(nearH) / nearH.w, d = view.eye + glm::dvec3(farH) / farH.w - start;
    const glm::dvec3 hit = start + double(stored) * d;
    const glm::dvec3 onPlane = start + (glm::dot(n, p - start) / glm::dot(n, d)) * d;
    if (glm::dot(n, hit - p) < 0.01 * voxel || insideBoxes(solid, onPlane + n * (0.01 * voxel))) self = true;
  }
  return self ? FalseShadow::SelfShadowed : FalseShadow::BesideAnEdge;
}

Scene loadWithFilter(const fs::path& file, ShadowFilter filter, int minResolution = 0) {
  SceneDesc desc = parseSceneFile(file);
  for (LightDesc& l : desc.lights)
    if (l.shadow) {
      l.shadow->filter = filter;
      l.shadow->resolution = std::max(l.shadow->resolution, minResolution);
    }
  return Scene::load(std::move(desc));
}

fs::path sceneOf(const std::string& dirName, const test::VoxelBoxSet& boxes, const glm::dvec3& sun,
                 const nlohmann::json& shadow = nlohmann::json::object(),
                 const nlohmann::json& camera = nlohmann::json::object(), const std::string& name = "scene") {
  const fs::path dir = test::scratchDir(dirName);
  const fs::path vdb = dir / "world.vdb";
  if (!fs::exists(vdb)) test::writeBoxesVdb(vdb, boxes);
  return test::writeLightingScene(dir, name, vdb, sun, shadow, camera);
}

}  // namespace

TEST(Cascades, SplitsBlendUniformAndLogarithmic) {
  const std::vector<double> uniform = cascadeSplits(1.0, 100.0, 4, 0.0);
  const std::vector<double> logarithmic = cascadeSplits(1.0, 100.0, 4, 1.0);
  ASSERT_EQ(uniform.size(), 5u);
  EXPECT_DOUBLE_EQ(uniform[2], 50.5);
  EXPECT_NEAR(logarithmic[2], 10.0, 1e-9);
  const std::vector<double> mixed = cascadeSplits(1.0, 100.0, 4, 0.5);
  EXPECT_NEAR(mixed[2], 0.5 * 50.5 + 0.5 * 10.0, 1e-9);
  for (std::size_t i = 1; i < mixed.size(); ++i) EXPECT_LT(mixed[i - 1], mixed[i]);
  EXPECT_EQ(mixed.front(), 1.0);
  EXPECT_EQ(mixed.back(), 100.0);
}

TEST(Cascades, SphereHoldsTheSliceAndIgnoresTheCameraRotation) {
  CameraDesc desc;
  desc.position = glm::vec3(10, 20, 30);
  desc.target = glm::vec3(0, 0, 0);
  desc.fovDeg = 60;
  const CameraFrame a = cameraFrame(desc, 640, 360);
  desc.target = glm::vec3(40, -5, 10);
  const CameraFrame b = cameraFrame(desc, 640, 360);
  const glm::dvec3 sun = test::sunDirection(40.0);
  const Aabb bounds{glm::vec3(-50.0f), glm::vec3(50.0f)};
  const CascadeFit fa = fitCascade(a, 5.0, 40.0, sun, 1024, bounds);
  const CascadeFit fb = fitCascade(b, 5.0, 40.0, sun, 1024, bounds);
  EXPECT_EQ(fa.diameter, fb.diameter);
  EXPECT_EQ(fa.texelWorld, fb.texelWorld);
  // Every corner of the slice projects inside the layer.
  for (int corner = 0; corner < 8; ++corner) {
    const double z = corner & 4 ? 40.0 : 5.0;
    const double sx = (corner & 1 ? 1.0 : -1.0) * a.tanHalfFovY * a.aspect * z;
    const double sy = (corner & 2 ? 1.0 : -1.0) * a.tanHalfFovY * z;
    const glm::dvec3 p = a.position + a.forward * z + a.right * sx + a.up * sy;
    const glm::dvec4 clip = fa.worldToClip * glm::dvec4(p, 1.0);
    EXPECT_LE(std::abs(clip.x), 1.0 + 2.0 / 1024) << corner;
    EXPECT_LE(std::abs(clip.y), 1.0 + 2.0 / 1024) << corner;
    EXPECT_GE(clip.z, 0.0);
    EXPECT_LE(clip.z, 1.0);
  }
  // The light-space centre lies on whole texels.
  const double tx = fa.snappedCentre.x / fa.texelWorld, ty = fa.snappedCentre.y / fa.texelWorld;
  EXPECT_EQ(tx, std::round(tx));
  EXPECT_EQ(ty, std::round(ty));
}

TEST(Cascades, SceneWithACameraBakesCascadeLayersAndOthersKeepTheirs) {
  const fs::path file = sceneOf("cascade_layers", test::floorBoxes(), test::sunDirection(45.0));
  const Scene scene = Scene::load(file);
  const std::vector<LightView> views = scene.lightViews();
  ASSERT_EQ(views.size(), 3u);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(views[std::size_t(c)].name, "sun.cascade" + std::to_string(c));
    EXPECT_EQ(views[std::size_t(c)].cascade, c);
    if (c > 0) {
      EXPECT_EQ(views[std::size_t(c)].splitNear, views[std::size_t(c) - 1].splitFar);
    }
  }
  EXPECT_EQ(views.back().splitFar, 160.0);  // max_distance, nearer than the camera's far plane
}

// Agreement with the ray-traced truth, with the hard filter and at least one shadow texel per pixel: at most
// 0.5% of receivers differ (the errors lie along shadow edges, within a texel of them).
TEST(LightingTruth, CityAtThreeElevationsAgreesWithRayTracedShadows) {
  auto tracer = cpuTracer();
  for (double elevation : {20.0, 45.0, 70.0}) {
    const glm::dvec3 sun = test::sunDirection(elevation);
    const fs::path file = sceneOf("truth_city", test::cityBoxes(), sun, {{"resolution", 2048}}, {},
                                  "e" + std::to_string(int(elevation)));
    const Scene scene = Scene::load(file);
    tracer->setScene(scene.data());
    const RenderedFrame maps = renderWith(scene, *tracer, ShadowSource::Maps);
    const RenderedFrame truth = renderWith(scene, *tracer, ShadowSource::Raytraced);
    const TruthComparison c = compareWithTruth(maps, truth, 0, -sun);
    EXPECT_GT(c.receivers, 30000);
    EXPECT_LE(c.differing(), 0.005) << "elevation " << elevation << ": " << c.falselyLit << " falsely lit, "
                                    << c.falselyShadowed << " falsely shadowed of " << c.receivers;
    std::printf("city, sun at %.0f deg: %d falsely lit, %d falsely shadowed of %d receivers (%.3f%%)\n", elevation,
                c.falselyLit, c.falselyShadowed, c.receivers, 100.0 * c.differing());
  }
}

namespace {

// How many of light `light`'s shadow texels fall on the surface that pixel g shows: the pixel's footprint on the
// surface over a texel's (both grow as their rays graze it), with the texel of the view that covers g (the
// cascade holding its view depth; spot and point texels grow with the distance from the light).
double texelsPerPixel(const RenderedFrame& frame, const CameraFrame& camera, int light, const gpu::GBufferTexel& g,
                      const glm::dvec3& toLight) {
  const glm::dvec3 p(glm::vec3(g.position)), n(glm::vec3(g.normal));
  double texel = 0.0;
  for (const LightView& view : frame.views) {
    if (view.lightIndex != light) continue;
    if (view.cascade >= 0 && !(g.position.w >= view.splitNear && g.position.w < view.splitFar)) continue;
    texel = view.encoding == gpu::VS_ENCODING_NDC_DEPTH ? view.texelWorld : view.texelWorld * glm::length(view.eye - p);
    break;
  }
  if (texel <= 0.0) return 0.0;
  const double pixel = 2.0 * camera.tanHalfFovY * g.position.w / camera.height;
  const double facingCamera = std::abs(glm::dot(n, glm::normalize(camera.position - p)));
  const double facingLight = glm::dot(n, toLight);
  return (pixel * pixel / facingCamera) / (texel * texel / facingLight);
}

}  // namespace

// The demo scene at its camera's own 1280 x 720, hard-filtered: its own layers (sun cascades 2048^2, lamp
// 1024^2, torch 6 x 512^2), and every layer raised to at least 1024^2. Its sun is low enough to throw long shadows
// across the relief, whose edges a smaller frame resolves into fewer pixels than their length in texels, so the
// bar is measured where the picture is made.
TEST(LightingTruth, DemoSceneAgreesWithRayTracedShadows) {
  const fs::path dir = test::scratchDir("truth_demo");
  const std::vector<std::string> written = writeDemoWorld(dir);
  const int width = 1280, height = 720;  // the demo camera's own frame
  auto tracer = cpuTracer();
  const Scene own = loadWithFilter(written.back(), ShadowFilter::Hard);
  tracer->setScene(own.data());
  const RenderedFrame truth = renderWith(own, *tracer, ShadowSource::Raytraced, width, height);
  const CameraFrame camera = cameraFrame(*own.desc().camera, width, height);
  for (int minResolution : {0, 1024}) {
    const Scene scene = loadWithFilter(written.back(), ShadowFilter::Hard, minResolution);
    tracer->setScene(scene.data());
    const RenderedFrame maps = renderWith(scene, *tracer, ShadowSource::Maps, width, height);
    for (std::size_t l = 0; l < scene.desc().lights.size(); ++l) {
      const LightDesc& light = scene.desc().lights[l];
      // Per pixel, the direction to a spot or point light differs; count receivers by the truth's own test.
      // Receivers with less than one shadow texel per pixel (the far cascade, or lit at a grazing angle) are
      // counted apart: the bar holds where the layers resolve what the pixels show.
      TruthComparison c, sparse;
      const std::size_t lights = maps.lightNames.size();
      for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
        const gpu::GBufferTexel& g = maps.gbuffer.texels[i];
        glm::dvec3 toLight;
        if (!test::receivesLight(light, g, toLight)) continue;
        const bool mapLit = maps.shadowTerms[i * lights + l] > 0.5f, trueLit = truth.shadowTerms[i * lights + l] > 0.5f;
        TruthComparison& counted = texelsPerPixel(maps, camera, int(l), g, toLight) >= 1.0 ? c : sparse;
        ++counted.receivers;
        counted.falselyLit += mapLit && !trueLit;
        counted.falselyShadowed += !mapLit && trueLit;
      }
      const double bound = 0.005;
      EXPECT_GT(c.receivers, 1000) << light.name;
      EXPECT_LE(c.differing(), bound) << light.name << ", layers of at least " << minResolution << ": " << c.falselyLit
                                      << " falsely lit, " << c.falselyShadowed << " falsely shadowed of " << c.receivers;
      std::printf("demo, %s, layers of at least %d: %d falsely lit, %d falsely shadowed of %d receivers (%.3f%%); "
                  "below one texel per pixel: %d of %d (%.3f%%)\n",
                  light.name.c_str(), minResolution, c.falselyLit, c.falselyShadowed, c.receivers,
                  100.0 * c.differing(), sparse.falselyLit + sparse.falselyShadowed, sparse.receivers,
                  100.0 * sparse.differing());
    }
  }
}

// A light's culling volume: a receiver that faces a spot or point light but lies beyond its range or outside
// its cone gets no light from it, and its shadow term is 1 (no layer read, no ray's answer used), in both
// shadow sources; the demo's torch (range 25) faces most of the frame from outside its range.
TEST(LightingTruth, ALightThatDoesNotReachAReceiverLeavesItLit) {
  const fs::path dir = test::scratchDir("unreached");
  const std::vector<std::string> written = writeDemoWorld(dir);
  auto tracer = cpuTracer();
  const Scene scene = Scene::load(written.back());
  tracer->setScene(scene.data());
  for (ShadowSource source : {ShadowSource::Maps, ShadowSource::Raytraced}) {
    const RenderedFrame frame = renderWith(scene, *tracer, source, 320, 180);
    const std::size_t lights = frame.lightNames.size();
    for (std::size_t l = 0; l < lights; ++l) {
      const LightDesc& light = scene.desc().lights[l];
      if (light.type == LightType::Directional) continue;
      int unreached = 0, notLit = 0;
      for (std::size_t i = 0; i < frame.gbuffer.texels.size(); ++i) {
        const gpu::GBufferTexel& g = frame.gbuffer.texels[i];
        if (g.info.w == 0u) continue;
        const glm::dvec3 p(glm::vec3(g.position));
        const glm::dvec3 toLight = glm::normalize(glm::dvec3(light.position) - p);
        if (!(glm::dot(glm::dvec3(glm::vec3(g.normal)), toLight) > 0.0)) continue;
        // Clear of the boundaries by a margin that float rounding cannot cross.
        const bool beyond = glm::length(glm::dvec3(light.position) - p) > double(light.range) * 1.001;
        const bool outside = light.type == LightType::Spot &&
                             glm::dot(-toLight, glm::dvec3(light.direction)) <
                                 std::cos(glm::radians(double(light.outerConeDeg))) - 1e-3;
        if (!beyond && !outside) continue;
        ++unreached;
        notLit += frame.shadowTerms[i * lights + l] != 1.0f;
      }
      EXPECT_GT(unreached, 1000) << light.name;
      EXPECT_EQ(notLit, 0) << light.name << (source == ShadowSource::Maps ? ", maps" : ", ray-traced") << ": of "
                           << unreached << " receivers the light does not reach";
    }
    // Visibility rays skip the receivers beyond a light's range (VisibilityLight.kind.y): each ray skipped is
    // one whose answer the pass does not read (the light's attenuation there is 0 in the pass's own floats).
    const ShadeInputs records = makeShadeRecords(scene.desc(), {}, source == ShadowSource::Raytraced);
    const std::vector<float> unbounded(records.lights.size(), -1.0f);
    VisibilitySetup ranged = visibilitySetup(records.lights, unbounded, scene.worldBounds());
    VisibilitySetup everywhere = ranged;
    for (gpu::VisibilityLight& l : everywhere.lights) l.kind.y = 0.0f;
    std::vector<gpu::VisibilityReceiver> receivers;
    visibilityReceivers(frame.gbuffer, {}, receivers);
    std::vector<gpu::TraceRay> rangedRays, allRays;
    visibilityRays(ranged.frame, ranged.lights, receivers, rangedRays);
    visibilityRays(everywhere.frame, everywhere.lights, receivers, allRays);
    gpu::CpuShading shading{};
    int skipped = 0, skippedButLit = 0;
    for (std::size_t k = 0; k < receivers.size(); ++k)
      for (std::size_t l = 0; l < lights; ++l) {
        const gpu::TraceRay& a = rangedRays[k * lights + l];
        const gpu::TraceRay& b = allRays[k * lights + l];
        const bool aEmpty = a.originLow.w < a.originHigh.w, bEmpty = b.originLow.w < b.originHigh.w;
        if (aEmpty == bEmpty) {
          EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "receiver " << k << ", light " << l;
          continue;
        }
        ++skipped;
        glm::vec3 toLight;
        float distance = 0.0f;
        skippedButLit += shading.vsLightGeometry(records.lights[l], glm::vec3(frame.gbuffer.texels[k].position), toLight,
                                                 distance) != 0.0f;
      }
    EXPECT_GT(skipped, 1000);
    EXPECT_EQ(skippedButLit, 0) << "of " << skipped << " rays skipped";
  }
}

// The visibility stage traces rays toward the lights that have them only and spreads their answers back to
// each pixel and light: with the demo's lights in another order (the sun, the one light with contact rays,
// last instead of first), every light's shadow term is the same bit for bit.
TEST(LightingTruth, ShadowTermsDoNotDependOnTheLightsOrder) {
  const fs::path dir = test::scratchDir("light_order");
  const std::vector<std::string> written = writeDemoWorld(dir);
  const SceneDesc desc = parseSceneFile(written.back());
  SceneDesc rotated = desc;
  std::rotate(rotated.lights.begin(), rotated.lights.begin() + 1, rotated.lights.end());
  ASSERT_TRUE(rotated.lights.back().shadow && rotated.lights.back().shadow->contactShadow > 0.0f);
  const Scene first = Scene::load(SceneDesc(desc)), last = Scene::load(std::move(rotated));
  auto tracer = cpuTracer();
  tracer->setScene(first.data());
  const RenderedFrame a = renderWith(first, *tracer, ShadowSource::Maps, 320, 180);
  tracer->setScene(last.data());
  const RenderedFrame b = renderWith(last, *tracer, ShadowSource::Maps, 320, 180);
  const std::size_t lights = desc.lights.size(), pixels = a.gbuffer.texels.size();
  ASSERT_EQ(a.shadowTerms.size(), pixels * lights);
  ASSERT_EQ(b.shadowTerms.size(), pixels * lights);
  std::size_t differ = 0, sunShadowed = 0;
  for (std::size_t i = 0; i < pixels; ++i)
    for (std::size_t l = 0; l < lights; ++l) {
      const std::size_t moved = (l + lights - 1) % lights;  // light l of the demo is light `moved` of the rotated
      differ += std::memcmp(&a.shadowTerms[i * lights + l], &b.shadowTerms[i * lights + moved], sizeof(float)) != 0;
    }
  // The sun shadows part of the frame (its maps, its contact rays, faces turned away). Checked that answers
  // spread to the wrong light make about 200 terms differ.
  for (std::size_t i = 0; i < pixels; ++i) sunShadowed += a.shadowTerms[i * lights] == 0.0f;
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(sunShadowed, pixels / 100);
}

namespace {

struct FalseShadows {
  int receivers = 0, selfShadowed = 0, besideEdges = 0;
  int falselyLit = 0;  // the other side of the same edges, for comparison
};

// The receivers that the maps (hard filter) shadow and the truth lights, by why (whyShadowed).
FalseShadows falseShadows(const Scene& scene, Tracer& tracer, const test::VoxelBoxSet& boxes, const glm::dvec3& sun) {
  tracer.setScene(scene.data());
  std::vector<ShadowLayer> layers;
  const RenderedFrame maps = renderWithLayers(scene, tracer, layers);
  const RenderedFrame truth = renderWith(scene, tracer, ShadowSource::Raytraced);
  const TruthComparison c = compareWithTruth(maps, truth, 0, -sun);
  FalseShadows f;
  f.receivers = c.receivers;
  f.falselyLit = c.falselyLit;
  for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
    const gpu::GBufferTexel& g = maps.gbuffer.texels[i];
    if (g.info.w == 0u || !(glm::dot(glm::dvec3(glm::vec3(g.normal)), -sun) > 0.0)) continue;
    if (!(maps.shadowTerms[i] < 0.5f && truth.shadowTerms[i] > 0.5f)) continue;
    if (whyShadowed(maps, layers, boxes, i) == FalseShadow::SelfShadowed) ++f.selfShadowed;
    else ++f.besideEdges;
  }
  EXPECT_EQ(f.selfShadowed + f.besideEdges, c.falselyShadowed);
  return f;
}

}  // namespace

// Acne: no receiver that the truth says is lit is shadowed by its own surface, with the default biases, on a
// flat floor and on a staircase terrain, for the sun at 10, 20, ..., 90 degrees. Receivers that the maps
// shadow and the truth lights are either self-shadowed (the texel they read hit their own plane, or met it
// inside the solid at a concave corner) or lie within a texel of a real shadow's edge (edge aliasing, which the
// agreement tests bound): the first kind is acne and must not occur; the second is counted and bounded here
// too, so that it stays a thin line. Without biases the same count finds acne everywhere: it can fail.
TEST(LightingTruth, DefaultBiasesGiveNoAcne) {
  auto tracer = cpuTracer();
  for (const auto& [name, boxes] : {std::pair{std::string("floor"), test::floorBoxes()},
                                    std::pair{std::string("terrain"), test::terrainBoxes()}}) {
    for (int elevation = 10; elevation <= 90; elevation += 10) {
      const glm::dvec3 sun = test::sunDirection(double(elevation));
      const Scene scene = Scene::load(sceneOf("acne_" + name, boxes, sun, {}, {}, "e" + std::to_string(elevation)));
      const FalseShadows f = falseShadows(scene, *tracer, boxes, sun);
      EXPECT_GT(f.receivers, 10000);
      EXPECT_EQ(f.selfShadowed, 0) << name << ", sun at " << elevation << " degrees: " << f.selfShadowed << " of "
                                   << f.receivers << " lit receivers shadowed by their own surface";
      // Edge aliasing: under 1% of the receivers (the terrain's step edges at 10 degrees: 0.9%); none on the floor.
      EXPECT_LE(f.besideEdges, name == "floor" ? 0 : f.receivers / 100) << name << ", sun at " << elevation;
      std::printf("%s, sun at %d deg: %d self-shadowed, %d beside shadow edges (and %d falsely lit), of %d receivers\n",
                  name.c_str(), elevation, f.selfShadowed, f.besideEdges, f.falselyLit, f.receivers);
    }
  }
  const glm::dvec3 sun = test::sunDirection(30.0);
  const Scene unbiased = Scene::load(sceneOf("acne_terrain", test::terrainBoxes(), sun,
                                             {{"normal_bias", 0}, {"slope_bias", 0}}, {}, "unbiased"));
  const FalseShadows f = falseShadows(unbiased, *tracer, test::terrainBoxes(), sun);
  // Cascade texels are traced from their pages' eyes and compared along rays rebuilt from the window's, so
  // rounding differs between the two a little, and acne without biases is rarer than where both were one ray;
  // it must still be found.
  EXPECT_GT(f.selfShadowed, f.receivers / 1000) << "without biases, rounding alone shadows a face with itself";
}

// The flat floor, which casts no shadow on itself, stays lit under every filter with the default biases.
TEST(LightingTruth, EveryFilterLeavesTheFloorLit) {
  auto tracer = cpuTracer();
  for (const char* filter : {"pcf3", "pcf5", "poisson16", "pcss"}) {
    for (int elevation = 10; elevation <= 90; elevation += 20) {
      const glm::dvec3 sun = test::sunDirection(double(elevation));
      const Scene scene = Scene::load(sceneOf("acne_floor", test::floorBoxes(), sun, {{"filter", filter}}, {},
                                              std::string(filter) + "_e" + std::to_string(elevation)));
      tracer->setScene(scene.data());
      const RenderedFrame maps = renderWith(scene, *tracer, ShadowSource::Maps);
      int receivers = 0, shadowed = 0;
      for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
        const gpu::GBufferTexel& g = maps.gbuffer.texels[i];
        if (g.info.w == 0u || g.normal.y < 0.99f) continue;
        ++receivers;
        shadowed += maps.shadowTerms[i] < 1.0f;
      }
      EXPECT_GT(receivers, 10000);
      EXPECT_EQ(shadowed, 0) << filter << ", sun at " << elevation << " degrees";
    }
  }
}

namespace {

// 2D distance (x, z) from a world point to the footprint [lo, hi] of a box.
double footprintDistance(const glm::dvec3& p, const glm::dvec2& lo, const glm::dvec2& hi) {
  const double dx = std::max({lo.x - p.x, 0.0, p.x - hi.x}), dz = std::max({lo.y - p.z, 0.0, p.z - hi.y});
  return std::sqrt(dx * dx + dz * dz);
}

// The floor pixels along the box's base on its shadow side (within 3 voxels) that the maps light and the truth
// shadows:
// how far from the footprint the farthest one lies, and how many there are.
std::pair<double, int> contactGap(const RenderedFrame& maps, const RenderedFrame& truth) {
  const glm::dvec2 lo(41.5, 41.5), hi(53.5, 53.5);  // voxels 42..53 cover [41.5, 53.5]
  double farthest = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
    const gpu::GBufferTexel& g = maps.gbuffer.texels[i];
    if (g.info.w == 0u || g.normal.y < 0.99f || std::abs(g.position.y - 3.5f) > 1e-3f) continue;
    const glm::dvec3 p(glm::vec3(g.position));
    const double d = footprintDistance(p, lo, hi);
    // Beside the two faces the shadow falls from (+x, +z), away from the corners, where the shadow's sides
    // begin and hard shadows alias along the silhouette instead.
    const bool besideX = p.x > hi.x && p.z > lo.y + 2.0 && p.z < hi.y - 2.0;
    const bool besideZ = p.z > hi.y && p.x > lo.x + 2.0 && p.x < hi.x - 2.0;
    if (d > 3.0 || !(besideX || besideZ)) continue;
    if (maps.shadowTerms[i] > 0.5f && truth.shadowTerms[i] <= 0.5f) {
      farthest = std::max(farthest, d);
      ++count;
    }
  }
  return {farthest, count};
}

}  // namespace

// Peter-panning: where a box stands on the floor, its shadow reaches within one voxel of the contact edge with
// the default biases, and all the way with contact shadows.
TEST(LightingTruth, ShadowsReachTheContactEdge) {
  auto tracer = cpuTracer();
  const nlohmann::json closeUp = {{"position", {75, 30, 80}}, {"target", {48, 4, 48}}};
  for (double elevation : {30.0, 60.0}) {
    const glm::dvec3 sun = test::sunDirection(elevation, 215.0);  // the shadow falls toward the camera
    const std::string tag = "e" + std::to_string(int(elevation));
    const Scene plain = Scene::load(sceneOf("contact", test::floorWithBoxBoxes(), sun, {}, closeUp, tag));
    const Scene contact = Scene::load(
        sceneOf("contact", test::floorWithBoxBoxes(), sun, {{"contact_shadow", 2.0}}, closeUp, tag + "_contact"));
    tracer->setScene(plain.data());
    const RenderedFrame truth = renderWith(plain, *tracer, ShadowSource::Raytraced);
    const RenderedFrame maps = renderWith(plain, *tracer, ShadowSource::Maps);
    tracer->setScene(contact.data());
    const RenderedFrame withContact = renderWith(contact, *tracer, ShadowSource::Maps);
    const auto [gap, count] = contactGap(maps, truth);
    EXPECT_LE(gap, 1.0) << "sun at " << elevation << ": " << count << " floor pixels lit up to " << gap << " voxels out";
    const auto [contactGapSize, contactCount] = contactGap(withContact, truth);
    EXPECT_EQ(contactCount, 0) << "sun at " << elevation << ", contact shadows: up to " << contactGapSize;
    // The contact ray only adds shadow where the truth has it.
    for (std::size_t i = 0; i < truth.shadowTerms.size(); ++i) {
      if (withContact.shadowTerms[i] < maps.shadowTerms[i]) {
        EXPECT_EQ(truth.shadowTerms[i], 0.0f) << i;
      }
    }
  }
}

// Shimmer (DESIGN.md §11): a cascade's layer is a ring over a world-fixed texel grid, so every texel that two
// camera positions' windows share is bit-identical in both, whether the camera moved by a fraction of a texel
// or scrolled the window by whole texels; a window that did not move leaves the shadow term at fixed world
// points unchanged.
TEST(LightingCascades, EveryCascadeTexelIsBitIdenticalAcrossAnyScroll) {
  const glm::dvec3 sun = test::sunDirection(40.0);
  const fs::path file = sceneOf("shimmer", test::cityBoxes(), sun, {{"filter", "pcf3"}, {"resolution", 512}});
  const Scene scene = Scene::load(file);
  auto tracer = cpuTracer();
  tracer->setScene(scene.data());
  const CameraFrame start = cameraFrame(*scene.desc().camera);
  const std::vector<LightView> views0 = buildLightViews(scene.desc(), scene.worldBounds(), &start);
  std::vector<ShadowLayer> layers0;
  traceLayers(*tracer, views0, layers0);
  const ShadeInputs inputs0 = makeShadeInputs(scene.desc(), views0, layers0, false);
  FrameRenderer renderer(*tracer);
  const RenderedFrame frame = renderer.render(scene, {});
  std::vector<gpu::GBufferTexel> points;
  for (const gpu::GBufferTexel& g : frame.gbuffer.texels)
    if (g.info.w != 0u) points.push_back(g);
  ASSERT_GT(points.size(), 10000u);
  int still = 0, scrolled = 0;
  std::uint64_t shared = 0;
  // Steps of 1/16 texel, then of 1.5, 7 and 40 texels (of the first cascade) across the ground.
  const double texel = views0[0].texelWorld;
  for (double step : {texel / 16.0, 2.0 * texel / 16.0, 3.0 * texel / 16.0, 1.5 * texel, 7.0 * texel, 40.0 * texel}) {
    CameraFrame moved = start;
    moved.position += glm::dvec3(step, 0.0, -0.5 * step);
    const std::vector<LightView> views = buildLightViews(scene.desc(), scene.worldBounds(), &moved);
    std::vector<ShadowLayer> layers;
    traceLayers(*tracer, views, layers);
    bool anyScrolled = false;
    ASSERT_EQ(views.size(), views0.size());
    for (std::size_t c = 0; c < views.size(); ++c) {
      ASSERT_TRUE(sameGrid(views[c], views0[c])) << "the grid must not follow the camera";
      const TexelRect w0 = windowRect(views0[c]), w = windowRect(views[c]);
      if (w0.x0 == w.x0 && w0.y0 == w.y0) ++still;
      else anyScrolled = true, ++scrolled;
      const int n = views[c].resolution;
      std::size_t differ = 0;
      for (std::int64_t gy = std::max(w0.y0, w.y0); gy < std::min(w0.y1, w.y1); ++gy)
        for (std::int64_t gx = std::max(w0.x0, w.x0); gx < std::min(w0.x1, w.x1); ++gx) {
          const std::size_t at = std::size_t(((gy % n) + n) % n) * std::size_t(n) + std::size_t(((gx % n) + n) % n);
          differ += std::memcmp(&layers[c].texels[at], &layers0[c].texels[at], sizeof(float)) != 0;
          ++shared;
        }
      EXPECT_EQ(differ, 0u) << "step " << step << ", cascade " << c;
    }
    if (anyScrolled) continue;
    const ShadeInputs inputs = makeShadeInputs(scene.desc(), views, layers, false);
    for (const gpu::GBufferTexel& g : points) ASSERT_EQ(shadowTermAt(inputs, 0, g), shadowTermAt(inputs0, 0, g)) << step;
  }
  EXPECT_GT(still, 0);
  EXPECT_GT(scrolled, 0);
  std::printf("18 cascade windows over 6 camera steps: %d still, %d scrolled; %llu shared texels, all bit-identical\n",
              still, scrolled, static_cast<unsigned long long>(shared));
}

// Seams: at each cascade boundary the shadow term just inside the blend band equals the next cascade's just
// past it (to 0.05); without a band the two cascades' filters disagree there by more.
TEST(LightingCascades, BlendBandHidesTheSeams) {
  const glm::dvec3 sun = test::sunDirection(35.0);
  auto measure = [&](double blend) {
    // Close enough that the camera sees the ground on both sides of the boundaries (at about 10 and 26).
    const fs::path file = sceneOf("seams", test::cityBoxes(), sun,
                                  {{"filter", "pcf5"}, {"cascade_blend", blend}, {"max_distance", 80}},
                                  {{"position", {66, 20, 70}}}, "blend" + std::to_string(int(blend * 100)));
    const Scene scene = Scene::load(file);
    auto tracer = cpuTracer();
    tracer->setScene(scene.data());
    FrameRenderer renderer(*tracer);
    const RenderedFrame frame = renderer.render(scene, {});
    const ShadeInputs inputs = makeShadeInputs(scene.desc(), frame.views, renderer.layers(), false);
    double worst = 0.0;
    std::size_t probed = 0;
    for (std::size_t c = 0; c + 1 < frame.views.size(); ++c) {
      const double boundary = frame.views[c].splitFar;
      for (gpu::GBufferTexel g : frame.gbuffer.texels) {
        // Points the camera sees near the boundary (inside both cascades' spheres), each shaded as if its view
        // depth lay just inside the boundary and just past it. Within 20% of the boundary's depth they include
        // penumbrae, where the two cascades' kernels differ.
        if (g.info.w == 0u || std::abs(double(g.position.w) - boundary) > 0.2 * boundary) continue;
        ++probed;
        g.position.w = float(boundary * (1.0 - 1e-6));
        const float inside = shadowTermAt(inputs, 0, g);
        g.position.w = float(boundary * (1.0 + 1e-6));
        const float past = shadowTermAt(inputs, 0, g);
        worst = std::max(worst, double(std::abs(inside - past)));
      }
    }
    EXPECT_GT(probed, 1000u);
    return worst;
  };
  const double blended = measure(0.1), unblended = measure(0.0);
  EXPECT_LE(blended, 0.05);
  EXPECT_GT(unblended, 0.05);
  std::printf("largest shadow-term step across a cascade boundary: %.4f with a 10%% band, %.4f without\n", blended,
              unblended);
}

// Primary rays start at the camera's near plane, as a rasteriser clips: what lies nearer is not seen, so every
// pixel with a hit lies at or past `near`, inside the first cascade's split range, and its sun shadow agrees
// with the ray-traced truth as everywhere else. (Unclipped, the nearer ground fell in no cascade and was lit.)
TEST(LightingCascades, GeometryNearerThanTheNearPlaneIsClipped) {
  const glm::dvec3 sun = test::sunDirection(30.0);
  const double nearPlane = 80.0;  // the camera is about 63 units from the nearest ground and 110 from its target
  // The city test's layers, with the cascades reaching the far plane: every receiver lies in one.
  const fs::path file = sceneOf("near_clip", test::cityBoxes(), sun, {{"resolution", 2048}, {"max_distance", 300}},
                                {{"near", nearPlane}});
  const Scene scene = Scene::load(file);
  auto tracer = cpuTracer();
  tracer->setScene(scene.data());
  const RenderedFrame maps = renderWith(scene, *tracer, ShadowSource::Maps);
  const RenderedFrame truth = renderWith(scene, *tracer, ShadowSource::Raytraced);
  ASSERT_FALSE(maps.views.empty());
  const double firstSplit = maps.views.front().splitNear;
  EXPECT_EQ(firstSplit, nearPlane);
  int seen = 0, nearer = 0;
  for (const gpu::GBufferTexel& g : maps.gbuffer.texels) {
    if (g.info.w == 0u) continue;
    ++seen;
    nearer += double(g.position.w) < nearPlane * (1.0 - 1e-5);
  }
  EXPECT_GT(seen, 10000);
  EXPECT_EQ(nearer, 0) << "pixels nearer than the near plane";
  // A solid that the near plane cuts shows its cut (entry face VS_FACE_NONE, at the near plane): its inside
  // has no light to agree about, so those pixels are left out of the comparison, and there are some.
  RenderedFrame uncut = maps;
  int cut = 0;
  for (gpu::GBufferTexel& g : uncut.gbuffer.texels)
    if (g.info.w != 0u && g.info.z == gpu::VS_FACE_NONE) g.info.w = 0u, ++cut;
  EXPECT_GT(cut, 100);
  const TruthComparison c = compareWithTruth(uncut, truth, 0, -sun);
  EXPECT_GT(c.receivers, 10000);
  EXPECT_LE(c.differing(), 0.005) << c.falselyLit << " falsely lit, " << c.falselyShadowed << " falsely shadowed of "
                                  << c.receivers;
  std::printf("near plane at %.0f: %d pixels seen, %d on cut solids; %d falsely lit, %d falsely shadowed of %d "
              "receivers (%.3f%%)\n", nearPlane, seen, cut, c.falselyLit, c.falselyShadowed, c.receivers,
              100.0 * c.differing());
}

// Options that name nothing drawable are refused before any work, naming the field, and the renderer keeps
// what it had: a cast from an unchecked integer, a negative size (0 alone means the camera's), a size past the
// image limit that every other path keeps.
TEST(LightingFrames, OptionsOutOfRangeAreRefused) {
  const fs::path file = sceneOf("render_options", test::floorWithBoxBoxes(), test::sunDirection(40.0));
  const Scene scene = Scene::load(file);
  auto tracer = cpuTracer();
  tracer->setScene(scene.data());
  FrameRenderer renderer(*tracer);
  const RenderedFrame first = renderer.render(scene, {});
  ASSERT_EQ(first.layersTraced, 3);
  const std::vector<ShadowLayer> layers = renderer.layers();
  struct Bad {
    RenderOptions options;
    std::string field;
  };
  std::vector<Bad> bad(8);
  bad[0].options.debug = DebugView(77), bad[0].field = "RenderOptions.debug: 77";
  bad[1].options.shadows = ShadowSource(9), bad[1].field = "RenderOptions.shadows: 9";
  bad[2].options.width = -1, bad[2].field = "RenderOptions.width";
  bad[3].options.height = -640, bad[3].field = "RenderOptions.height";
  bad[4].options.width = 100000, bad[4].options.height = 10, bad[4].field = "RenderOptions.width";
  bad[5].options.height = 16385, bad[5].field = "RenderOptions.height";
  bad[6].options.debug = DebugView::Layer, bad[6].options.debugLayer = -1, bad[6].field = "RenderOptions.debugLayer";
  bad[7].options.debug = DebugView::Layer, bad[7].options.debugLayer = 3, bad[7].field = "--debug layer=3";
  for (const Bad& b : bad) {
    try {
      renderer.render(scene, b.options);
      ADD_FAILURE() << b.field << ": rendered";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput);
      EXPECT_NE(std::string(e.what()).find(b.field), std::string::npos) << e.what();
    }
  }
  // The layers are still the first frame's, and still hold: the next frame traces none.
  ASSERT_EQ(renderer.layers().size(), layers.size());
  for (std::size_t i = 0; i < layers.size(); ++i) EXPECT_EQ(renderer.layers()[i].texels, layers[i].texels);
  const RenderedFrame again = renderer.render(scene, {});
  EXPECT_EQ(again.layersTraced, 0);
  EXPECT_EQ(again.color, first.color);
}
