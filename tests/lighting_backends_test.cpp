// lighting_backends_test.cpp: the G-buffer and the lit image on both backends (Vulkan lavapipe or GPU against
// the CPU), every filter, bias and debug view, and the scene-file and CLI errors of the lighting options.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>
#include <OpenImageIO/imageio.h>

#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "lighting/deferred.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "lighting/vulkan_lighting.h"
#include "support/demo_frames.h"
#include "support/lighting_scenes.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace fs = std::filesystem;
using namespace vs;

namespace {

fs::path cityScene(const std::string& name, const nlohmann::json& shadow = nlohmann::json::object(),
                   const nlohmann::json& camera = nlohmann::json::object()) {
  const fs::path dir = test::scratchDir("lighting_backends");
  const fs::path vdb = dir / "city.vdb";
  if (!fs::exists(vdb)) test::writeBoxesVdb(vdb, test::cityBoxes());
  return test::writeLightingScene(dir, name, vdb, test::sunDirection(40.0), shadow, camera);
}

RenderedFrame render(const Scene& scene, Tracer& tracer, RenderOptions options = {}) {
  FrameRenderer renderer(tracer);
  return renderer.render(scene, options);
}

}  // namespace

// The G-buffer bit for bit, the shadow terms and the lit image from the Vulkan lighting shader against the
// CPU build of the same shading source.
TEST(LightingBackends, VulkanMatchesTheCpuPass) {
  VulkanOptions options;
  options.validation = true;
  std::unique_ptr<Tracer> vulkan = makeVulkanTracer(options);  // no device: fails here, loudly
  std::unique_ptr<Tracer> cpu = makeCpuTracer();
  for (const char* filter : {"hard", "pcf5", "poisson16", "pcss"}) {
    const Scene scene = Scene::load(cityScene(std::string("backends_") + filter, {{"filter", filter}, {"contact_shadow", 1.5}},
                                              {{"width", 200}, {"height", 150}}));
    vulkan->setScene(scene.data());
    cpu->setScene(scene.data());
    const RenderedFrame gpu = render(scene, *vulkan);
    const RenderedFrame host = render(scene, *cpu);
    ASSERT_EQ(gpu.gbuffer.texels.size(), host.gbuffer.texels.size());
    EXPECT_EQ(0, std::memcmp(gpu.gbuffer.texels.data(), host.gbuffer.texels.data(),
                             host.gbuffer.texels.size() * sizeof(gpu::GBufferTexel))) << filter;
    std::size_t hits = 0;
    for (const gpu::GBufferTexel& g : host.gbuffer.texels) hits += g.info.w;
    EXPECT_GT(hits, 10000u);
    double worst = 0.0;
    std::size_t termsDiffer = 0;
    for (std::size_t i = 0; i < host.color.size(); ++i)
      for (int c = 0; c < 4; ++c)
        worst = std::max(worst, double(std::abs(gpu.color[i][c] - host.color[i][c])) / std::max(1.0f, std::abs(host.color[i][c])));
    for (std::size_t i = 0; i < host.shadowTerms.size(); ++i) termsDiffer += gpu.shadowTerms[i] != host.shadowTerms[i];
    EXPECT_LE(worst, 1.0 / 255.0) << filter;
    // Trigonometry (the disc filters' rotation) may round differently on the device; the terms agree elsewhere.
    EXPECT_LE(termsDiffer, host.shadowTerms.size() / 1000) << filter;
    std::printf("%s: largest colour difference %.2e, %zu of %zu shadow terms differ\n", filter, worst, termsDiffer,
                host.shadowTerms.size());
  }
  EXPECT_TRUE(vulkan->vulkan()->validationMessages().empty());
}

// The G-buffer resolved on the device (VulkanLighting::resolveGBuffer) equals the host's resolve of the same
// hits bit for bit, whole and for listed pixels; the visibility rays made from the receivers it leaves on the
// device answer as those made from the host's receivers, and their answers spread on the device
// (spreadVisibility) as the host spreads them; bad device receivers are refused.
TEST(LightingBackends, TheDeviceResolvesTheGBufferAndSpreadsTheAnswersAsTheHost) {
  VulkanOptions options;
  options.validation = true;
  std::unique_ptr<Tracer> tracer = makeVulkanTracer(options);  // no device: fails here, loudly
  VulkanTracer& vulkan = *tracer->vulkan();
  const Scene scene = Scene::load(cityScene("device_resolve", {{"contact_shadow", 1.5}}, {{"width", 200}, {"height", 150}}));
  tracer->setScene(scene.data());
  const CameraFrame camera = cameraFrame(*scene.desc().camera);
  const std::size_t pixels = std::size_t(camera.width) * std::size_t(camera.height);
  VulkanLighting lighting(vulkan.sharedContext());
  EXPECT_EQ(lighting.receivers(pixels).buffer, VK_NULL_HANDLE) << "no receivers before a resolve";

  std::vector<gpu::RayHit> hits(pixels);
  tracer->traceCamera(cameraRaysOf(camera), {}, hits);
  GBuffer host;
  resolveGBuffer(scene, camera, hits, host);
  LightingTraffic traffic;
  lighting.resolveGBuffer(vulkan.lastCameraTrace(), gbufferTables(scene), host, &traffic);
  EXPECT_EQ(traffic.dispatches, 1);
  GBuffer device = host;
  std::fill(device.texels.begin(), device.texels.end(), gpu::GBufferTexel{});
  lighting.readGBuffer(device);
  EXPECT_TRUE(test::sameBytes(device.texels, host.texels));
  std::size_t hit = 0;
  for (const gpu::GBufferTexel& g : host.texels) hit += g.info.w;
  EXPECT_GT(hit, pixels / 4);

  // A camera moved a little: the listed pixels (every third one) resolved again into the held G-buffer.
  CameraFrame moved = camera;
  moved.position += glm::dvec3(0.37, 0.11, -0.23);
  std::vector<std::uint32_t> listed;
  for (std::uint32_t p = 0; p < pixels; p += 3) listed.push_back(p);
  std::vector<gpu::RayHit> listedHits(listed.size());
  tracer->traceCamera(cameraRaysOf(moved), listed, listedHits);
  GBuffer mixed = host;
  resolveGBufferPixels(scene, moved, listedHits, listed, mixed);
  traffic = {};
  lighting.resolveGBuffer(vulkan.lastCameraTrace(), gbufferTables(scene), mixed, &traffic);
  EXPECT_EQ(traffic.uploaded, 0u) << "the tables were already on the device";
  lighting.readGBuffer(device);
  EXPECT_TRUE(test::sameBytes(device.texels, mixed.texels));

  // Visibility rays from the device's receivers and from the host's, toward the sun (a contact length) and a
  // point above the city.
  std::vector<gpu::ShadeLight> lights(2);
  lights[0].info.x = gpu::VS_LIGHT_DIRECTIONAL;
  lights[0].direction = glm::vec4(glm::normalize(glm::vec3(-0.4f, -1.0f, -0.3f)), 0.0f);
  lights[1].info.x = gpu::VS_LIGHT_POINT;
  lights[1].position = glm::vec4(30.0f, 60.0f, 30.0f, 200.0f);
  const std::vector<float> lengths{1.5f, -1.0f};
  const VisibilitySetup setup = visibilitySetup(lights, lengths, scene.worldBounds());
  std::vector<std::uint32_t> spreadRows;
  for (const bool whole : {true, false}) {
    std::vector<std::uint32_t> some;
    if (!whole)
      for (std::uint32_t p = 1; p < pixels; p += 5) some.push_back(p);
    std::vector<gpu::VisibilityReceiver> receivers;
    visibilityReceivers(mixed, some, receivers);
    std::vector<std::uint32_t> fromHost(receivers.size() * lights.size()), fromDevice(fromHost.size(), 7u);
    tracer->traceVisibility(setup.frame, setup.lights, receivers, fromHost);
    DeviceReceivers onDevice = lighting.receivers(pixels);
    ASSERT_NE(onDevice.buffer, VK_NULL_HANDLE);
    onDevice.pixels = some;
    vulkan.traceVisibility(setup.frame, setup.lights, onDevice, fromDevice);
    EXPECT_EQ(fromDevice, fromHost) << (whole ? "every pixel" : "listed pixels");
    // The answers spread per pixel and light on the device, for a frame of three lights of which the second
    // has no ray, as the host spreads them (the rows of the pixels not traced are the last spread's).
    const std::vector<int> slots{0, -1, 1};
    if (whole) spreadRows.assign(pixels * slots.size(), 0u);
    for (std::size_t k = 0; k < receivers.size(); ++k) {
      const std::size_t p = whole ? k : some[k];
      for (std::size_t l = 0; l < slots.size(); ++l)
        spreadRows[p * slots.size() + l] =
            slots[l] < 0 ? 1u : fromHost[k * lights.size() + std::size_t(slots[l])] == 0u ? 1u : 0u;
    }
    traffic = {};
    lighting.spreadVisibility(vulkan.lastVisibilityTrace(), slots, pixels, spreadRows, &traffic);
    EXPECT_EQ(traffic.dispatches, 1) << "spread on the device";
    std::vector<std::uint32_t> spreadOnDevice(spreadRows.size(), 7u);
    lighting.readVisibility(spreadOnDevice);
    EXPECT_EQ(spreadOnDevice, spreadRows) << (whole ? "every pixel" : "listed pixels");
    EXPECT_GT(std::count(fromHost.begin(), fromHost.end(), 1u), 100) << "some rays are blocked";
    EXPECT_GT(std::count(fromHost.begin(), fromHost.end(), 0u), 100) << "some rays are clear";
  }

  DeviceReceivers bad = lighting.receivers(pixels);
  const std::vector<std::uint32_t> outside{std::uint32_t(pixels)};
  bad.pixels = outside;
  std::vector<std::uint32_t> answers(lights.size());
  EXPECT_THROW(vulkan.traceVisibility(setup.frame, setup.lights, bad, answers), Error);
  bad.pixels = {};
  bad.buffer = VK_NULL_HANDLE;
  answers.resize(pixels * lights.size());
  EXPECT_THROW(vulkan.traceVisibility(setup.frame, setup.lights, bad, answers), Error);
  // A trace that left no camera hits, and a G-buffer of another size than the trace's camera, are refused.
  EXPECT_THROW(lighting.resolveGBuffer(vulkan.lastCameraTrace(), gbufferTables(scene), mixed), Error);
  tracer->traceCamera(cameraRaysOf(camera), {}, hits);
  GBuffer other;
  other.width = camera.width / 2;
  other.height = camera.height;
  other.texels.resize(std::size_t(other.width) * std::size_t(other.height));
  EXPECT_THROW(lighting.resolveGBuffer(vulkan.lastCameraTrace(), gbufferTables(scene), other), Error);
  EXPECT_TRUE(vulkan.validationMessages().empty()) << vulkan.validationMessages().front();
}

namespace {

// Whether the renderer's layers, and the frame, equal what a new renderer traces from nothing.
void expectSameAsFreshRender(const Scene& scene, Tracer& tracer, const FrameRenderer& kept, const RenderedFrame& frame,
                             const RenderOptions& options, const std::string& step) {
  FrameRenderer fresh(tracer);
  const RenderedFrame truth = fresh.render(scene, options);
  EXPECT_EQ(truth.layersTraced, int(truth.views.size())) << step;
  const std::vector<ShadowLayer> keptLayers = kept.layers(), freshLayers = fresh.layers();
  ASSERT_EQ(keptLayers.size(), freshLayers.size()) << step;
  for (std::size_t i = 0; i < keptLayers.size(); ++i) {
    const ShadowLayer &a = keptLayers[i], &b = freshLayers[i];
    ASSERT_EQ(a.texels.size(), b.texels.size()) << step << ", layer " << i;
    EXPECT_EQ(0, std::memcmp(a.texels.data(), b.texels.data(), a.texels.size() * sizeof(float)))
        << step << ", layer " << i << " (" << truth.views[i].name << ")";
  }
  ASSERT_EQ(frame.color.size(), truth.color.size());
  EXPECT_EQ(0, std::memcmp(frame.color.data(), truth.color.data(), truth.color.size() * sizeof(glm::vec4))) << step;
  ASSERT_EQ(frame.gbuffer.texels.size(), truth.gbuffer.texels.size());
  EXPECT_EQ(0, std::memcmp(frame.gbuffer.texels.data(), truth.gbuffer.texels.data(),
                           truth.gbuffer.texels.size() * sizeof(gpu::GBufferTexel))) << step;
  EXPECT_EQ(frame.shadowTerms, truth.shadowTerms) << step;
}

// The demo scene with every layer at 128^2 and a 160x90 frame: a frame loop's ten layers, quick to trace.
Scene smallDemoScene(const std::string& dirName) {
  const std::vector<std::string> written = writeDemoWorld(test::scratchDir(dirName));
  SceneDesc desc = parseSceneFile(written.back());
  for (LightDesc& l : desc.lights)
    if (l.shadow) l.shadow->resolution = 128;
  return Scene::load(std::move(desc));
}

RenderOptions smallFrame() {
  RenderOptions options;
  options.width = 160;
  options.height = 90;
  return options;
}

}  // namespace

// A frame loop: a renderer traces only the texels a change touches, and what it keeps is what a new renderer
// traces. The demo scene (sun cascades, a spot lamp, a point torch's six faces) on both backends: unchanged
// (nothing traced), a sub-texel camera step (no texel: the cascades' windows stay), a large camera move (the
// cascades' exposed strips, nothing of the lamp or the torch), an instance moved (its footprints only), a
// frame with ray-traced shadows, and an invalidation (everything).
TEST(LightingFrames, OnlyChangedTexelsAreTracedAgain) {
  VulkanOptions vulkanOptions;
  vulkanOptions.validation = true;
  std::vector<std::unique_ptr<Tracer>> tracers;
  tracers.push_back(makeCpuTracer());
  tracers.push_back(makeVulkanTracer(vulkanOptions));  // no device: fails here, loudly
  for (const std::unique_ptr<Tracer>& tracer : tracers) {
    Scene scene = smallDemoScene("lighting_frames");
    const RenderOptions options = smallFrame();
    FrameRenderer renderer(*tracer);
    const std::string backend = tracer->backend();

    const RenderedFrame first = renderer.render(scene, options);
    ASSERT_EQ(first.views.size(), 10u);
    EXPECT_EQ(first.layersTraced, 10) << backend;
    EXPECT_TRUE(first.stats.full);
    EXPECT_EQ(first.stats.texelsTraced, first.stats.layerTexels);

    const RenderedFrame still = renderer.render(scene, options);
    EXPECT_EQ(still.layersTraced, 0) << backend << ": nothing changed";
    EXPECT_EQ(still.stats.texelsTraced + still.stats.primaryRays + still.stats.visibilityRays, 0u) << backend;
    EXPECT_EQ(still.stats.bytesUploaded + still.stats.bytesReadBack, 0u) << backend;
    EXPECT_EQ(still.stats.dispatches, 0) << backend;
    EXPECT_EQ(still.stats.pixelsShaded, 0u) << backend;
    expectSameAsFreshRender(scene, *tracer, renderer, still, options, backend + ", nothing changed");

    // A step of a sixteenth of the nearest cascade's texel: a window that moves does so by whole texels.
    CameraDesc camera = *scene.desc().camera;
    camera.position.x += float(first.views[0].texelWorld / 16.0);
    scene.setCamera(camera);
    const RenderedFrame step = renderer.render(scene, options);
    std::uint64_t strips = 0;
    for (std::size_t i = 0; i < step.views.size(); ++i) {
      const TexelRect a = windowRect(still.views[i]), b = windowRect(step.views[i]);
      const std::int64_t n = step.views[i].resolution;
      const std::int64_t dx = std::min<std::int64_t>(std::abs(b.x0 - a.x0), n), dy = std::min<std::int64_t>(std::abs(b.y0 - a.y0), n);
      strips += std::uint64_t(dx * n + dy * n - dx * dy);
      EXPECT_EQ(step.stats.layers[i].whole, false) << backend << ", " << step.views[i].name;
    }
    EXPECT_EQ(step.stats.texelsTraced, strips) << backend << ": exactly the exposed strips";
    expectSameAsFreshRender(scene, *tracer, renderer, step, options, backend + ", sub-texel step");

    camera.position += glm::vec3(-20.0f, 5.0f, 10.0f);
    camera.target += glm::vec3(-20.0f, 5.0f, 10.0f);
    scene.setCamera(camera);
    const RenderedFrame moved = renderer.render(scene, options);
    EXPECT_EQ(moved.layersTraced, 3) << backend << ": the three cascades, not the lamp or the torch";
    for (std::size_t i = 3; i < moved.views.size(); ++i) EXPECT_EQ(moved.stats.layers[i].texels, 0u) << moved.views[i].name;
    expectSameAsFreshRender(scene, *tracer, renderer, moved, options, backend + ", camera moved");

    // No call to the tracer: the renderer learns of the move from the scene.
    const std::size_t last = scene.instances().size() - 1;
    scene.moveInstance(last, glm::translate(scene.desc().instances[scene.instanceSources()[last]].transform,
                                            glm::dvec3(3.0, 0.0, -2.0)));
    const RenderedFrame instance = renderer.render(scene, options);
    EXPECT_GT(instance.stats.texelsTraced, 0u) << backend;
    EXPECT_LT(instance.stats.texelsTraced, instance.stats.layerTexels / 2) << backend << ": an instance's footprints";
    EXPECT_LT(instance.stats.primaryRays, std::uint64_t(options.width) * std::uint64_t(options.height)) << backend;
    expectSameAsFreshRender(scene, *tracer, renderer, instance, options, backend + ", instance moved");

    // A frame with ray-traced shadows needs no layers and leaves them for the next frame with maps.
    RenderOptions raytraced = options;
    raytraced.shadows = ShadowSource::Raytraced;
    EXPECT_EQ(renderer.render(scene, raytraced).layersTraced, 0) << backend;
    EXPECT_EQ(renderer.render(scene, options).layersTraced, 0) << backend << ": after a ray-traced frame";
    expectSameAsFreshRender(scene, *tracer, renderer, renderer.render(scene, options), options,
                            backend + ", after a ray-traced frame");

    renderer.invalidateLayers();
    EXPECT_EQ(renderer.render(scene, options).layersTraced, 10) << backend;
    if (VulkanTracer* vulkan = tracer->vulkan()) {
      EXPECT_TRUE(vulkan->validationMessages().empty());
    }
  }
}

// Lights that move in a frame loop: moving the lamp traces its one layer again, turning the sun its three
// cascades, a colour change none; what the renderer keeps equals a new renderer's trace, and the image follows
// the new colour.
TEST(LightingFrames, MovedLightsTraceTheirOwnLayersAgain) {
  std::unique_ptr<Tracer> tracer = makeCpuTracer();
  Scene scene = smallDemoScene("lighting_frames_lights");
  const RenderOptions options = smallFrame();
  FrameRenderer renderer(*tracer);
  const RenderedFrame first = renderer.render(scene, options);
  std::size_t sun = 0, lamp = 0;
  for (std::size_t l = 0; l < scene.desc().lights.size(); ++l) {
    if (scene.desc().lights[l].type == LightType::Directional) sun = l;
    if (scene.desc().lights[l].type == LightType::Spot) lamp = l;
  }
  const LightDesc lampBefore = scene.desc().lights[lamp];
  scene.moveLight(lamp, lampBefore.position + glm::vec3(1.5f, 0.0f, -1.0f), lampBefore.direction + glm::vec3(0.1f, 0.0f, 0.0f));
  const RenderedFrame lampMoved = renderer.render(scene, options);
  EXPECT_EQ(lampMoved.layersTraced, 1) << "the lamp's one layer";
  expectSameAsFreshRender(scene, *tracer, renderer, lampMoved, options, "lamp moved");
  EXPECT_NE(0, std::memcmp(lampMoved.color.data(), first.color.data(), first.color.size() * sizeof(glm::vec4)));

  scene.moveLight(sun, glm::vec3(0.0f), scene.desc().lights[sun].direction + glm::vec3(0.05f, 0.0f, 0.0f));
  const RenderedFrame sunMoved = renderer.render(scene, options);
  EXPECT_EQ(sunMoved.layersTraced, 3) << "the sun's three cascades";
  expectSameAsFreshRender(scene, *tracer, renderer, sunMoved, options, "sun turned");

  scene.setLightColor(lamp, glm::vec3(0.2f, 0.4f, 1.0f), 2.0f * lampBefore.intensity);
  const RenderedFrame recoloured = renderer.render(scene, options);
  EXPECT_EQ(recoloured.layersTraced, 0) << "a colour changes no layer";
  expectSameAsFreshRender(scene, *tracer, renderer, recoloured, options, "lamp recoloured");
  EXPECT_NE(0, std::memcmp(recoloured.color.data(), sunMoved.color.data(), sunMoved.color.size() * sizeof(glm::vec4)));
}

// Lights and instances moved at run time meet the limits a scene file's do; a refused move changes nothing.
TEST(LightingFrames, MovesBeyondTheLimitsAreRefused) {
  SceneDesc desc = parseSceneFile(cityScene("frames_limits"));
  // Millimetre voxels, so that a light 90 km away lies beyond the voxels rays stay exact within.
  desc.instances[0].transform = glm::scale(glm::dmat4(1.0), glm::dvec3(1e-3));
  LightDesc torch;
  torch.name = "torch";
  torch.type = LightType::Point;
  torch.position = glm::vec3(0.05f, 0.2f, 0.05f);
  torch.range = 1.0f;
  torch.shadow = ShadowDesc{};
  desc.lights.push_back(torch);
  Scene scene = Scene::load(std::move(desc));
  auto refused = [](auto&& call, const std::string& field) {
    try {
      call();
      ADD_FAILURE() << field << ": accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput);
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  const glm::vec3 before = scene.desc().lights[1].position;
  refused([&] { scene.moveLight(1, glm::vec3(9e4f, 0.0f, 0.0f), glm::vec3(0.0f)); }, "lights[1].position: the light is");
  refused([&] { scene.moveLight(1, glm::vec3(2e5f, 0.0f, 0.0f), glm::vec3(0.0f)); }, "lights[1] 'torch'.position");
  refused([&] { scene.moveLight(1, glm::vec3(std::nanf(""), 0.0f, 0.0f), glm::vec3(0.0f)); }, "'torch'.position");
  EXPECT_EQ(scene.desc().lights[1].position, before);
  refused([&] { scene.moveLight(0, glm::vec3(0.0f), glm::vec3(0.0f)); }, "lights[0] 'sun'.direction");
  refused([&] { scene.moveLight(2, glm::vec3(0.0f), glm::vec3(0.0f, -1.0f, 0.0f)); }, "out of range");
  refused([&] { scene.setLightColor(0, glm::vec3(-1.0f, 0.0f, 0.0f), 1.0f); }, "'sun'.color");
  refused([&] { scene.setLightColor(0, glm::vec3(1.0f), std::nanf("")); }, "'sun'.intensity");
  scene.moveLight(1, glm::vec3(0.1f, 0.3f, 0.1f), glm::vec3(0.0f));
  EXPECT_EQ(scene.desc().lights[1].position, glm::vec3(0.1f, 0.3f, 0.1f));

  const Aabb bounds = scene.worldBounds();
  refused([&] { scene.moveInstance(0, glm::translate(glm::dmat4(1.0), glm::dvec3(2e5, 0.0, 0.0)) *
                                          scene.desc().instances[0].transform); },
          "the world must lie within");
  refused([&] { scene.moveInstance(0, glm::translate(glm::dmat4(1.0), glm::dvec3(9e4, 0.0, 0.0)) *
                                          scene.desc().instances[0].transform); },
          "lights[1].position: the light is");
  EXPECT_EQ(scene.worldBounds().min, bounds.min);
  EXPECT_EQ(scene.worldBounds().max, bounds.max);
}

// The camera a frame loop sets is checked as the scene file's is, and a refused one leaves the old in place.
TEST(LightingFrames, InvalidCamerasAreRefused) {
  Scene scene = Scene::load(cityScene("frames_camera"));
  const CameraDesc good = *scene.desc().camera;
  auto refused = [&](CameraDesc c, const std::string& field) {
    try {
      scene.setCamera(c);
      ADD_FAILURE() << field << ": accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput);
      EXPECT_NE(std::string(e.what()).find("camera." + field + ":"), std::string::npos) << e.what();
    }
    EXPECT_EQ(scene.desc().camera->position, good.position);
  };
  CameraDesc c = good;
  c.target = c.position;
  refused(c, "target");
  c = good;
  c.position.y = std::nanf("");
  refused(c, "position");
  c = good;
  c.position.x = 2e5f;
  refused(c, "position");
  c = good;
  c.up = c.target - c.position;
  refused(c, "up");
  c = good;
  c.fovDeg = 180.0f;
  refused(c, "fov_deg");
  c = good;
  c.farPlane = c.nearPlane;
  refused(c, "far");
  c = good;
  c.nearPlane = -1.0f;
  refused(c, "near");
  c = good;
  c.width = 0;
  refused(c, "width");
  c = good;
  c.position += glm::vec3(1.0f);
  scene.setCamera(c);
  EXPECT_EQ(scene.desc().camera->position, c.position);
}

// Every filter: hard gives only 0 and 1; the others soften edges; pcss softens more with a larger light.
TEST(LightingFilters, EveryFilterShadesAndSoftensAsItShould) {
  std::unique_ptr<Tracer> cpu = makeCpuTracer();
  auto fractional = [&](const nlohmann::json& shadow, const std::string& name) {
    const Scene scene = Scene::load(cityScene(name, shadow, {{"width", 200}, {"height", 150}}));
    cpu->setScene(scene.data());
    const RenderedFrame f = render(scene, *cpu);
    std::size_t soft = 0, shadowed = 0;
    for (float s : f.shadowTerms) {
      EXPECT_GE(s, 0.0f);
      EXPECT_LE(s, 1.0f);
      soft += s > 0.0f && s < 1.0f;
      shadowed += s < 0.5f;
    }
    EXPECT_GT(shadowed, 300u) << name;
    return soft;
  };
  // Without a blend band (which mixes two cascades), hard shadows are 0 or 1.
  EXPECT_EQ(fractional({{"filter", "hard"}, {"cascade_blend", 0}}, "f_hard"), 0u);
  const std::size_t pcf3 = fractional({{"filter", "pcf3"}}, "f_pcf3");
  const std::size_t pcf5 = fractional({{"filter", "pcf5"}}, "f_pcf5");
  const std::size_t poisson = fractional({{"filter", "poisson16"}}, "f_poisson");
  const std::size_t pcssSmall = fractional({{"filter", "pcss"}, {"light_size", 0.2}}, "f_pcss_small");
  const std::size_t pcssLarge = fractional({{"filter", "pcss"}, {"light_size", 3.0}}, "f_pcss_large");
  EXPECT_GT(pcf3, 0u);
  EXPECT_GT(pcf5, pcf3);
  EXPECT_GT(poisson, 0u);
  EXPECT_GT(pcssLarge, pcssSmall);
  std::printf("soft pixels: pcf3 %zu, pcf5 %zu, poisson16 %zu, pcss %zu (light 0.2) / %zu (light 3)\n", pcf3, pcf5,
              poisson, pcssSmall, pcssLarge);
}

// Biases only ever move receivers toward the light: more bias, fewer shadowed receivers.
TEST(LightingFilters, LargerBiasesShadowLess) {
  std::unique_ptr<Tracer> cpu = makeCpuTracer();
  auto shadowed = [&](const nlohmann::json& shadow, const std::string& name) {
    const Scene scene = Scene::load(cityScene(name, shadow, {{"width", 200}, {"height", 150}}));
    cpu->setScene(scene.data());
    const RenderedFrame f = render(scene, *cpu);
    return std::count_if(f.shadowTerms.begin(), f.shadowTerms.end(), [](float s) { return s < 0.5f; });
  };
  const auto none = shadowed({{"normal_bias", 0}, {"slope_bias", 0}}, "b_none");
  const auto constant = shadowed({{"normal_bias", 0}, {"slope_bias", 0}, {"depth_bias", 0.5}}, "b_constant");
  const auto normal = shadowed({{"normal_bias", 4}, {"slope_bias", 0}}, "b_normal");
  const auto slope = shadowed({{"normal_bias", 0}, {"slope_bias", 4}}, "b_slope");
  EXPECT_LT(constant, none);
  EXPECT_LT(normal, none);
  EXPECT_LT(slope, none);
}

TEST(LightingDebug, EveryDebugViewShowsWhatItNames) {
  std::unique_ptr<Tracer> cpu = makeCpuTracer();
  const Scene scene = Scene::load(cityScene("debug", {{"filter", "pcf3"}}, {{"width", 160}, {"height", 120}}));
  cpu->setScene(scene.data());
  const RenderedFrame lit = render(scene, *cpu);
  RenderOptions o;
  o.debug = DebugView::Normals;
  const RenderedFrame normals = render(scene, *cpu, o);
  o.debug = DebugView::Shadow;
  const RenderedFrame shadow = render(scene, *cpu, o);
  o.debug = DebugView::Cascades;
  const RenderedFrame cascades = render(scene, *cpu, o);
  o.debug = DebugView::Layer;
  o.debugLayer = 2;
  const RenderedFrame layer = render(scene, *cpu, o);
  std::size_t tinted = 0;
  for (std::size_t i = 0; i < lit.color.size(); ++i) {
    const gpu::GBufferTexel& g = lit.gbuffer.texels[i];
    if (g.info.w == 0u) continue;
    for (int c = 0; c < 3; ++c) {
      EXPECT_FLOAT_EQ(normals.color[i][c], g.normal[c] * 0.5f + 0.5f);
      EXPECT_FLOAT_EQ(shadow.color[i][c], lit.shadowTerms[i]);
    }
    tinted += cascades.color[i] != lit.color[i];
  }
  EXPECT_GT(tinted, 1000u);
  // The layer view shows the third layer (sun.cascade2) scaled to the frame: NDC depths, 0..1, not all alike.
  float lo = 1.0f, hi = 0.0f;
  for (const glm::vec4& c : layer.color) {
    lo = std::min(lo, c.x);
    hi = std::max(hi, c.x);
  }
  EXPECT_LT(lo, hi);
  for (const glm::vec4& c : layer.color) {
    EXPECT_GE(c.x, 0.0f);
    EXPECT_LE(c.x, 1.0f);
  }
  o.debugLayer = 3;
  EXPECT_THROW(render(scene, *cpu, o), vs::Error);
}

TEST(LightingSceneFile, LightingKeysAreValidated) {
  const fs::path dir = test::scratchDir("lighting_keys");
  auto error = [&](const nlohmann::json& shadow, const std::string& type = "directional") {
    nlohmann::json light = {{"name", "l"}, {"type", type}, {"shadow", shadow}};
    if (type == "directional") light["direction"] = {0, -1, 0};
    else {
      light["position"] = {0, 5, 0};
      light["range"] = 20;
      if (type == "spot") {
        light["direction"] = {0, -1, 0};
        light["outer_cone_deg"] = 30;
      }
    }
    const nlohmann::json scene = {{"version", 1}, {"assets", nlohmann::json::object()}, {"lights", {light}}};
    try {
      parseSceneJson(scene.dump(), dir / "keys.json");
    } catch (const vs::Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_TRUE(test::contains(error({{"light_size", -1}}), "lights[0].shadow.light_size: must not be negative"));
  EXPECT_TRUE(test::contains(error({{"contact_shadow", "far"}}), "lights[0].shadow.contact_shadow: must be a number"));
  EXPECT_TRUE(test::contains(error({{"cascade_blend", 0.7}}), "lights[0].shadow.cascade_blend"));
  EXPECT_TRUE(test::contains(error({{"cascade_blend", 0.1}}, "spot"), "only directional lights have cascades"));
  EXPECT_TRUE(test::contains(error({{"slope_bias", 1e9}}), "lights[0].shadow.slope_bias: must be at most"));
  EXPECT_EQ(error({{"light_size", 2}, {"contact_shadow", 0.5}, {"cascade_blend", 0.2}, {"slope_bias", 2}}), "");
}

TEST(CliRender, WritesPngAndExrAndRefusesBadOptions) {
  const fs::path file = cityScene("cli", {}, {{"width", 96}, {"height", 64}});
  const fs::path dir = file.parent_path();
  std::string out;
  ASSERT_EQ(test::runCli("render " + test::quote(file) + " -o " + test::quote(dir / "city.png") + " --backend cpu", out), 0) << out;
  ASSERT_EQ(test::runCli("render " + test::quote(file) + " -o " + test::quote(dir / "city.exr") +
                         " --backend cpu --shadows raytraced", out), 0) << out;
  auto png = OIIO::ImageInput::open((dir / "city.png").string());
  ASSERT_TRUE(png);
  EXPECT_EQ(png->spec().width, 96);
  EXPECT_EQ(png->spec().nchannels, 3);
  auto exr = OIIO::ImageInput::open((dir / "city.exr").string());
  ASSERT_TRUE(exr);
  const std::vector<std::string>& names = exr->spec().channelnames;
  for (const char* n : {"R", "G", "B", "A", "position.X", "normal.Y", "albedo.R", "depth.Z", "instance.id", "shadow.sun"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  for (const char* debug : {"cascades", "shadow", "normals", "layer=1"})
    EXPECT_EQ(test::runCli("render " + test::quote(file) + " -o " + test::quote(dir / "debug.png") +
                           " --backend cpu --debug " + debug, out), 0) << debug << out;

  auto refused = [&](const std::string& args, const std::string& mention) {
    const int status = test::runCli("render " + args, out);
    EXPECT_EQ(status, 2) << args << "\n" << out;
    EXPECT_TRUE(test::contains(out, mention)) << args << "\n" << out;
  };
  const std::string scene = test::quote(file);
  refused(scene + " -o " + test::quote(dir / "x.tiff") + " --backend cpu", "must be a .png or .exr");
  refused(scene + " -o " + test::quote(dir / "x.png") + " --backend cpu --debug sideways", "--debug sideways");
  refused(scene + " -o " + test::quote(dir / "x.png") + " --backend cpu --debug layer=9", "shadow layers");
  refused(scene + " -o " + test::quote(dir / "x.png") + " --backend cpu --shadows soft", "--shadows");
  refused(scene + " -o " + test::quote(dir / "x.png") + " --backend cpu --width 20000", "--width");
  refused(scene + " -o " + test::quote(file) + " --backend cpu", "");
  EXPECT_FALSE(fs::exists(dir / "x.png"));
  EXPECT_FALSE(fs::exists(dir / "x.tiff"));
  // A scene without a camera has nothing to render from.
  nlohmann::json noCamera = nlohmann::json::parse(std::ifstream(file));
  noCamera.erase("camera");
  std::ofstream(dir / "nocamera.json") << noCamera.dump();
  refused(test::quote(dir / "nocamera.json") + " -o " + test::quote(dir / "x.png") + " --backend cpu", "camera");
}

// The device keeps the lighting pass's pipelines (VulkanContext::shared): a pass made for one frame and
// dropped, as the frame-loop tests' fresh renderers are, leaves them for the next, which compiles nothing.
TEST(LightingBackends, APassMadeAfterTheLastOneWentCompilesNothing) {
  VulkanOptions options;
  options.validation = true;
  std::unique_ptr<Tracer> vulkan = makeVulkanTracer(options);  // no device: fails here, loudly
  std::unique_ptr<Tracer> cpu = makeCpuTracer();
  const Scene scene = smallDemoScene("lighting_kept_pipelines");
  cpu->setScene(scene.data());
  FrameRenderer renderer(*cpu);
  const RenderedFrame frame = renderer.render(scene, smallFrame());
  const ShadeInputs inputs = makeShadeInputs(scene.desc(), frame.views, renderer.layers(), false);
  const gpu::ShadePush push = makeShadePush(scene.desc(), frame.width, frame.height, gpu::VS_SHADE_LIT, false);
  int compiled = 0;
  {
    VulkanLighting first(vulkan->vulkan()->sharedContext());
    for (int i = 0; i <= VulkanLighting::kCallsBeforeSpecializing; ++i) first.shade(inputs, push, frame.gbuffer, {});
    compiled = first.variantsCompiled();
  }
  ASSERT_EQ(compiled, 2) << "the general shader and the frame's variant";
  VulkanLighting second(vulkan->vulkan()->sharedContext());
  EXPECT_EQ(second.variantsCompiled(), compiled) << "the pipelines went with the last pass";
  const ShadeOutput again = second.shade(inputs, push, frame.gbuffer, {});
  EXPECT_EQ(second.variantsCompiled(), compiled);
  EXPECT_EQ(again.color.size(), std::size_t(frame.width) * std::size_t(frame.height));
  EXPECT_TRUE(vulkan->vulkan()->validationMessages().empty());
}

// The lighting shader's variants (lighting/lighting_variant.h): once a frame shape repeats, its specialised
// pipeline shades it with exactly the bits of the general shader, for every light kind and filter but EVSM
// (its variants run in the Evsm tests' frame loops), each debug mode and ray-traced shadows; a frame of more
// lights than the variants specialise stays on the general shader; and the CPU pass agrees as in
// VulkanMatchesTheCpuPass.
TEST(LightingBackends, ShaderVariantsShadeExactlyAsTheGeneralShader) {
  VulkanOptions options;
  options.validation = true;
  std::unique_ptr<Tracer> vulkan = makeVulkanTracer(options);  // no device: fails here, loudly
  std::unique_ptr<Tracer> cpu = makeCpuTracer();
  const Scene demo = smallDemoScene("lighting_variants");
  const RenderOptions frameSize = smallFrame();

  // The demo's lights (sun cascades with pcf5 and contact rays, a poisson16 spot, a pcf3 point light), the same
  // kinds with the other filters, and nine lights, one more than the variants specialise.
  auto withFilters = [&](std::initializer_list<ShadowFilter> filters, int copies) {
    SceneDesc desc = demo.desc();
    const std::vector<LightDesc> original = desc.lights;
    desc.lights.clear();
    for (int c = 0; c < copies; ++c)
      for (const LightDesc& l : original) {
        LightDesc copy = l;
        copy.name.append(1, '_').append(std::to_string(c));
        desc.lights.push_back(copy);
      }
    std::size_t i = 0;
    for (ShadowFilter f : filters) desc.lights[i++ % desc.lights.size()].shadow->filter = f;
    return desc;
  };
  struct Case {
    SceneDesc desc;
    std::vector<int> modes;
    bool specialised;
  };
  const std::vector<Case> cases = {
      {demo.desc(),
       {gpu::VS_SHADE_LIT, gpu::VS_SHADE_DEBUG_CASCADES, gpu::VS_SHADE_DEBUG_SHADOW, gpu::VS_SHADE_DEBUG_NORMALS},
       true},
      {withFilters({ShadowFilter::Pcss, ShadowFilter::Hard, ShadowFilter::Pcss}, 1), {gpu::VS_SHADE_LIT}, true},
      {withFilters({ShadowFilter::Hard, ShadowFilter::Pcf3, ShadowFilter::Pcf5, ShadowFilter::Poisson16,
                    ShadowFilter::Pcss, ShadowFilter::Pcf3, ShadowFilter::Hard, ShadowFilter::Poisson16,
                    ShadowFilter::Pcf5}, 3),
       {gpu::VS_SHADE_LIT}, false},
  };
  VulkanLighting lighting(vulkan->vulkan()->sharedContext());
  int expectedVariants = 0;
  for (const Case& c : cases) {
    const Scene scene = Scene::load(SceneDesc(c.desc));
    cpu->setScene(scene.data());
    FrameRenderer renderer(*cpu);
    const RenderedFrame frame = renderer.render(scene, frameSize);
    const std::vector<ShadowLayer> layers = renderer.layers();
    for (bool raytraced : {false, true}) {
      const ShadeInputs inputs = makeShadeInputs(scene.desc(), frame.views, layers, raytraced);
      // Visibility answers of every kind: rays clear and blocked in a fixed pattern.
      std::vector<std::uint32_t> visibility(frame.gbuffer.texels.size() * inputs.lights.size());
      for (std::size_t i = 0; i < visibility.size(); ++i) visibility[i] = (i * 2654435761u >> 7) & 1u;
      for (int mode : raytraced ? std::vector<int>{gpu::VS_SHADE_LIT} : c.modes) {
        const std::string what = std::to_string(inputs.lights.size()) + " lights, mode " + std::to_string(mode) +
                                 (raytraced ? ", ray-traced" : "");
        const gpu::ShadePush push = makeShadePush(scene.desc(), frame.width, frame.height, mode, raytraced);
        // The first calls of a shape run the general shader, the kCallsBeforeSpecializing-th its own variant.
        const ShadeOutput general = lighting.shade(inputs, push, frame.gbuffer, visibility);
        for (int call = 2; call < VulkanLighting::kCallsBeforeSpecializing; ++call)
          EXPECT_EQ(0, std::memcmp(lighting.shade(inputs, push, frame.gbuffer, visibility).color.data(),
                                   general.color.data(), general.color.size() * sizeof(glm::vec4))) << what;
        const int before = lighting.variantsCompiled();
        const ShadeOutput special = lighting.shade(inputs, push, frame.gbuffer, visibility);
        expectedVariants = std::max(expectedVariants, 1) + (c.specialised ? 1 : 0);
        EXPECT_EQ(lighting.variantsCompiled(), expectedVariants) << what;
        EXPECT_EQ(lighting.variantsCompiled() - before, c.specialised ? 1 : 0) << what;
        ASSERT_EQ(special.color.size(), general.color.size());
        EXPECT_EQ(0, std::memcmp(special.color.data(), general.color.data(), general.color.size() * sizeof(glm::vec4)))
            << what;
        EXPECT_EQ(special.shadowTerms, general.shadowTerms) << what;

        const ShadeOutput host = shadeOnCpu(inputs, push, frame.gbuffer, visibility);
        double worst = 0.0;
        std::size_t termsDiffer = 0;
        for (std::size_t i = 0; i < host.color.size(); ++i)
          for (int k = 0; k < 4; ++k)
            worst = std::max(worst, double(std::abs(special.color[i][k] - host.color[i][k])) /
                                        std::max(1.0f, std::abs(host.color[i][k])));
        for (std::size_t i = 0; i < host.shadowTerms.size(); ++i) termsDiffer += special.shadowTerms[i] != host.shadowTerms[i];
        EXPECT_LE(worst, 1.0 / 255.0) << what;
        EXPECT_LE(termsDiffer, host.shadowTerms.size() / 1000) << what;
        // Shadowed and lit receivers both occur, so the filters' code ran. (A variant whose constants were
        // ignored would pass as the general shader: the speed-up, in BENCHMARKS.md, shows they are not.)
        EXPECT_GT(std::count(special.shadowTerms.begin(), special.shadowTerms.end(), 0.0f), 100) << what;
        EXPECT_GT(std::count(special.shadowTerms.begin(), special.shadowTerms.end(), 1.0f), 100) << what;
      }
    }
  }
  // A lighting pass that does not specialise keeps to its general shader, which it shares with the pass above
  // (one device, pipelines compiled once).
  VulkanLighting plain(vulkan->vulkan()->sharedContext(), false);
  const int compiledBefore = plain.variantsCompiled();
  EXPECT_EQ(compiledBefore, lighting.variantsCompiled());
  const Scene scene = Scene::load(SceneDesc(cases[0].desc));
  cpu->setScene(scene.data());
  FrameRenderer renderer(*cpu);
  const RenderedFrame frame = renderer.render(scene, frameSize);
  const ShadeInputs inputs = makeShadeInputs(scene.desc(), frame.views, renderer.layers(), false);
  const gpu::ShadePush push = makeShadePush(scene.desc(), frame.width, frame.height, gpu::VS_SHADE_LIT, false);
  for (int i = 0; i <= VulkanLighting::kCallsBeforeSpecializing; ++i) plain.shade(inputs, push, frame.gbuffer, {});
  EXPECT_EQ(plain.variantsCompiled(), compiledBefore);
  EXPECT_TRUE(vulkan->vulkan()->validationMessages().empty());
}
