// The frame loop of DESIGN.md §11 on both backends: a renderer kept across seeded random frames of camera
// moves, instance moves, voxel edits, light changes, added and removed instances and lights equals, bit for
// bit, a new renderer on a tracer of its own after every frame; an invalidation one texel too small is caught;
// the counts follow what changed; a long loop's memory stays flat.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <malloc.h>
#include <random>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "compute/cpu/cpu_tracer.h"
#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "support/demo_frames.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace vs {
namespace {

// The demo scene with every layer at 128^2 (the sun's cascades, the lamp, the torch's six faces) and a 160x90
// frame: a whole frame from nothing costs little, so that every frame can be compared with one.
// evsm: every shadowed light filters with EVSM (a blur of 2 texels), whose moments the frame loop keeps too.
Scene smallScene(const std::string& dir, int resolution = 128, bool evsm = false) {
  const std::vector<std::string> written = writeDemoWorld(test::scratchDir(dir));
  SceneDesc desc = parseSceneFile(written.back());
  for (LightDesc& l : desc.lights)
    if (l.shadow) {
      l.shadow->resolution = resolution;
      if (evsm) {
        l.shadow->filter = ShadowFilter::Evsm;
        l.shadow->evsmBlur = 2;
      }
    }
  return Scene::load(std::move(desc));
}

RenderOptions smallFrame(int width = 160, int height = 90) {
  RenderOptions o;
  o.width = width;
  o.height = height;
  return o;
}

// `reference`: a Vulkan tracer that a new renderer binds every frame: it walks the hierarchy and builds no box
// table on each upload (the shader gives the same texels either way: vulkan_trace_test), while the kept
// renderer's tracer keeps its box table through the scene's deltas.
std::unique_ptr<Tracer> makeTracer(const std::string& backend, bool reference = false) {
  if (backend == "cpu") return makeCpuTracer({CpuTracePath::Interleaved, 2});
  VulkanOptions o;
  o.validation = true;
  o.boxTable = !reference;
  return makeVulkanTracer(o);  // no device: fails here, loudly
}

// A two-coloured 12^3 actor with a hollow, built in memory.
std::size_t addActor(Scene& scene) {
  std::vector<SolidVoxel> voxels;
  for (int z = 0; z < 12; ++z)
    for (int y = 0; y < 12; ++y)
      for (int x = 0; x < 12; ++x)
        if (!(x > 3 && x < 8 && z > 3 && z < 8)) voxels.push_back({{x, y, z}, std::uint8_t(y < 6 ? 1 : 2)});
  return scene.addObject(Brickmap::build(voxels), {glm::vec3(0.0f), {0.9f, 0.2f, 0.2f}, {0.2f, 0.3f, 0.9f}},
                         glm::scale(glm::dmat4(1.0), glm::dvec3(0.5)));
}

// A spot light pointing down from `position`, with a 64^2 shadow layer: the light a game adds.
LightDesc shadowedSpot(const glm::vec3& position) {
  LightDesc l;
  l.type = LightType::Spot;
  l.position = position;
  l.direction = glm::vec3(0.1f, -1.0f, 0.05f);
  l.range = 40.0f;
  l.outerConeDeg = 35.0f;
  l.intensity = 300.0f;
  l.shadow = ShadowDesc{};
  l.shadow->resolution = 64;
  return l;
}

// How many bytes of a frame differ from a new renderer's, per part.
struct Differences {
  std::size_t layers = 0, gbuffer = 0, color = 0, terms = 0, moments = 0;
  // Vulkan: whether the G-buffer the lighting pass reads on the device, resolved there, differs from the frame's.
  std::size_t deviceGBuffer = 0;
  bool any() const { return layers + gbuffer + color + terms + moments + deviceGBuffer > 0; }
};

Differences compareWithFresh(const Scene& scene, Tracer& freshTracer, const FrameRenderer& kept,
                             const RenderedFrame& frame, const RenderOptions& options) {
  FrameRenderer fresh(freshTracer);
  RenderOptions truthOptions = options;
  truthOptions.readGBuffer = true;
  const RenderedFrame& truth = fresh.render(scene, truthOptions);
  Differences d;
  const std::vector<ShadowLayer> a = kept.layers(), b = fresh.layers();
  if (a.size() != b.size()) d.layers = 1;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
    if (a[i].texels.size() != b[i].texels.size() ||
        std::memcmp(a[i].texels.data(), b[i].texels.data(), a[i].texels.size() * sizeof(float)) != 0) {
      ++d.layers;
      if (std::getenv("VOXSHADOW_FRAME_LOOP_DETAIL")) {
        std::size_t n = 0, first = 0;
        for (std::size_t k = 0; k < a[i].texels.size() && k < b[i].texels.size(); ++k)
          if (std::memcmp(&a[i].texels[k], &b[i].texels[k], 4) != 0 && n++ == 0) first = k;
        std::printf("  layer %s: %zu texels differ, first at %zu (%g vs %g)\n", frame.views[i].name.c_str(), n, first,
                    a[i].texels[first], b[i].texels[first]);
      }
    }
  // (Empty arrays, such as the moments of a view without EVSM, have no data pointer to compare.)
  auto bytesDiffer = [](const auto& x, const auto& y) {
    return x.size() != y.size() || (!x.empty() && std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) != 0);
  };
  // A Vulkan frame that was not asked for its G-buffer hands back none; its device G-buffer is compared below.
  const bool gbufferRead = options.readGBuffer || !freshTracer.vulkan();
  d.gbuffer = gbufferRead ? bytesDiffer(frame.gbuffer.texels, truth.gbuffer.texels) : !frame.gbuffer.texels.empty();
  if (d.gbuffer && std::getenv("VOXSHADOW_FRAME_LOOP_DETAIL"))
    for (std::size_t k = 0, n = 0; k < truth.gbuffer.texels.size() && n < 3; ++k) {
      const gpu::GBufferTexel &x = frame.gbuffer.texels[k], &y = truth.gbuffer.texels[k];
      if (std::memcmp(&x, &y, sizeof x) == 0) continue;
      ++n;
      std::printf("  pixel %zu (%zu, %zu): kept instance %u hit %u pos %.9g %.9g %.9g depth %.9g; new instance %u hit %u "
                  "pos %.9g %.9g %.9g depth %.9g\n",
                  k, k % 160, k / 160, x.info.x, x.info.w, x.position.x, x.position.y, x.position.z, x.position.w,
                  y.info.x, y.info.w, y.position.x, y.position.y, y.position.z, y.position.w);
    }
  if (freshTracer.vulkan()) d.deviceGBuffer = bytesDiffer(kept.deviceGBuffer().texels, truth.gbuffer.texels);
  d.color = bytesDiffer(frame.color, truth.color);
  d.terms = bytesDiffer(frame.shadowTerms, truth.shadowTerms);
  // EVSM moments: the kept ones, updated only around what was traced, against a new renderer's whole pass.
  const std::vector<std::vector<glm::vec4>> ma = kept.moments(), mb = fresh.moments();
  if (ma.size() != mb.size()) d.moments = 1;
  for (std::size_t i = 0; i < ma.size() && i < mb.size(); ++i) {
    if (!bytesDiffer(ma[i], mb[i])) continue;
    ++d.moments;
    if (std::getenv("VOXSHADOW_FRAME_LOOP_DETAIL")) {
      std::size_t n = 0;
      for (std::size_t k = 0; k < ma[i].size() && k < mb[i].size(); ++k) n += std::memcmp(&ma[i][k], &mb[i][k], 16) != 0;
      std::printf("  moments of %s: %zu texels differ\n", frame.views[i].name.c_str(), n);
    }
  }
  return d;
}

// One seeded game: each frame makes a random set of changes, each kind of change the API has.
struct Game {
  Scene scene;
  std::mt19937 rng;
  bool evsm = false;
  std::size_t ground = 0, actor = 0;
  std::vector<std::size_t> crateObjects;
  std::vector<std::size_t> addedInstances;
  std::vector<std::size_t> addedLights;
  double texel = 0.1;
  int refused = 0;
  std::string last;  // the frame's changes, for messages

  Game(const std::string& dir, unsigned seed, int resolution = 128, bool evsm = false)
      : scene(smallScene(dir, resolution, evsm)), rng(seed), evsm(evsm) {
    for (std::size_t a = 0; a < scene.desc().assets.size(); ++a) {
      const Scene::ObjectRange r = scene.assetObjects()[a];
      if (scene.desc().assets[a].name == "ground") ground = r.first;
      if (scene.desc().assets[a].name == "crates")
        for (std::size_t o = r.first; o < r.first + r.count; ++o) crateObjects.push_back(o);
    }
    actor = addActor(scene);
  }

  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  int pick(int n) { return int(rng() % unsigned(n)); }

  void moveCamera(const glm::dvec3& by) {
    CameraDesc c = *scene.desc().camera;
    c.position += glm::vec3(by);
    c.target += glm::vec3(by);
    scene.setCamera(c);
  }

  std::size_t randomActiveInstance() {
    std::vector<std::size_t> active;
    for (std::size_t i = 1; i < scene.instances().size(); ++i)
      if (scene.instanceActive(i)) active.push_back(i);
    return active.empty() ? 0 : active[std::size_t(pick(int(active.size())))];
  }

  void step() {
    last.clear();
    const int changes = 1 + pick(3);
    for (int k = 0; k < changes; ++k) {
      try {
        change();
      } catch (const Error&) {
        ++refused;  // a refused change changes nothing: the comparison below shows it
        last += " (refused)";
      }
    }
  }

  void change() {
    const int r = pick(100);
    if (r < 16) {
      last += " camera/8";
      moveCamera(glm::dvec3(uniform(-1, 1), uniform(-0.3, 0.3), uniform(-1, 1)) * (texel / 8.0));
    } else if (r < 26) {
      last += " camera-pan";
      moveCamera(glm::dvec3(texel * double(1 + pick(4)) * (pick(2) ? 1 : -1), 0.0, texel * double(pick(3) - 1)));
    } else if (r < 29) {
      last += " camera-jump";
      CameraDesc c = *scene.desc().camera;
      c.position = glm::vec3(float(uniform(-40, 80)), float(uniform(15, 60)), float(uniform(-40, 90)));
      c.target = glm::vec3(float(uniform(0, 40)), 0.0f, float(uniform(10, 50)));
      scene.setCamera(c);
    } else if (r < 44) {
      const std::size_t i = randomActiveInstance();
      last += " move" + std::to_string(i);
      const glm::dmat4 t = glm::translate(glm::dmat4(1.0), glm::dvec3(uniform(-1.5, 1.5), uniform(-0.2, 0.2), uniform(-1.5, 1.5)));
      scene.moveInstance(i, t * glm::rotate(glm::dmat4(1.0), uniform(-0.1, 0.1), glm::dvec3(0, 1, 0)) * scene.instanceTransform(i));
    } else if (r < 58) {
      // Digging and building on the ground (brick space of the ground object).
      const VoxelBox bounds = scene.objects()[ground].brickmap.bounds();
      const glm::ivec3 size = bounds.max - bounds.min;
      const glm::ivec3 at = bounds.min + glm::ivec3(pick(size.x), pick(std::max(1, size.y)), pick(size.z));
      const int side = pick(8) == 0 ? 8 : 4;
      const std::uint8_t material = pick(3) == 0 ? std::uint8_t(1 + pick(3)) : std::uint8_t(0);
      last += " fill" + std::to_string(side) + "m" + std::to_string(material);
      scene.fillVoxels(ground, VoxelBox{at, at + side}, material);
    } else if (r < 62) {
      last += " voxels";
      std::vector<SolidVoxel> voxels;
      for (int n = 0; n < 6; ++n) voxels.push_back({{pick(14) - 1, pick(14) - 1, pick(14) - 1}, std::uint8_t(pick(3))});
      scene.setVoxels(actor, voxels);
    } else if (r < 70) {
      const std::size_t l = std::size_t(pick(int(scene.desc().lights.size())));
      const LightDesc& light = scene.desc().lights[l];
      last += " light" + std::to_string(l);
      const glm::vec3 dir = glm::normalize(light.direction + glm::vec3(float(uniform(-0.1, 0.1)), 0.0f, float(uniform(-0.1, 0.1))));
      scene.moveLight(l, light.position + glm::vec3(float(uniform(-1, 1)), float(uniform(-0.5, 0.5)), float(uniform(-1, 1))), dir);
    } else if (r < 75) {
      const std::size_t object = pick(2) ? actor : crateObjects[std::size_t(pick(int(crateObjects.size())))];
      const glm::dmat4 t = glm::translate(glm::dmat4(1.0), glm::dvec3(uniform(5, 45), uniform(-1, 2), uniform(20, 55)));
      const std::size_t i = scene.addInstance(object, t);
      last += " add" + std::to_string(i);
      addedInstances.push_back(i);
    } else if (r < 79) {
      if (addedInstances.empty()) return;
      const std::size_t k = std::size_t(pick(int(addedInstances.size())));
      last += " remove" + std::to_string(addedInstances[k]);
      scene.removeInstance(addedInstances[k]);
      addedInstances.erase(addedInstances.begin() + std::ptrdiff_t(k));
    } else if (r < 83) {
      const std::size_t i = randomActiveInstance();
      const std::size_t object = pick(2) ? actor : crateObjects[std::size_t(pick(int(crateObjects.size())))];
      last += " switch" + std::to_string(i);
      if (i != 0) scene.setInstanceObject(i, object);
    } else if (r < 86) {
      if (addedLights.size() < 2) {
        LightDesc l = shadowedSpot(glm::vec3(float(uniform(0, 40)), float(uniform(10, 25)), float(uniform(20, 50))));
        l.shadow->filter = pick(2) ? ShadowFilter::Pcf5 : ShadowFilter::Poisson16;
        // In an EVSM game, an added EVSM layer moves every later view's moments in the store.
        if (evsm && pick(2)) l.shadow->filter = ShadowFilter::Evsm;
        l.name = "spot" + std::to_string(rng() % 100000);
        addedLights.push_back(scene.addLight(l));
        last += " add-light";
      } else {
        last += " remove-light";
        scene.removeLight(addedLights.back());
        addedLights.pop_back();
      }
    } else if (r < 89) {
      const std::size_t l = std::size_t(pick(int(scene.desc().lights.size())));
      last += " toggle" + std::to_string(l);
      scene.setLightEnabled(l, !scene.desc().lights[l].enabled);
    } else if (r < 91) {
      const std::size_t l = std::size_t(pick(int(scene.desc().lights.size())));
      last += " colour" + std::to_string(l);
      scene.setLightColor(l, glm::vec3(float(uniform(0.2, 1)), float(uniform(0.2, 1)), float(uniform(0.2, 1))),
                          scene.desc().lights[l].intensity);
    } else {
      last += " nothing";
    }
  }
};

// Runs `frames` random frames; returns the frames that differed from a new renderer.
int playAndCompare(const std::string& backend, unsigned seed, int frames, double margin, bool stopAtFirst,
                   bool evsm = false) {
  Game game("frame_loop_" + backend + std::to_string(seed) + (evsm ? "_evsm" : ""), seed, 128, evsm);
  std::unique_ptr<Tracer> kept = makeTracer(backend), fresh = makeTracer(backend, backend == "vulkan");
  FrameRenderer renderer(*kept);
  renderer.setFootprintMargin(margin);
  const RenderOptions options = smallFrame();
  game.texel = renderer.render(game.scene, options).views.at(0).texelWorld;
  int differing = 0;
  std::uint64_t traced = 0, all = 0;
  double keptMs = 0.0, freshMs = 0.0;
  RenderOptions raytraced = options, layerView = options, quiet = options;
  raytraced.shadows = ShadowSource::Raytraced;
  layerView.debug = DebugView::Layer;
  quiet.readColor = quiet.readShadowTerms = quiet.readGBuffer = false;
  // Every third frame does not ask for its G-buffer: on Vulkan a frame that redoes every pixel then leaves it on
  // the device, and a later frame that redoes some reads it back first to find them.
  RenderOptions noGBuffer = options;
  noGBuffer.readGBuffer = false;
  for (int f = 0; f < frames; ++f) {
    game.step();
    // Now and then a frame that reads nothing back (a host that shades with the device's shadows), then
    // another change: the next frame, which asks, must still give the whole image.
    if (f % 9 == 4) {
      const RenderedFrame& unread = renderer.render(game.scene, quiet);
      if (backend == "vulkan") {
        EXPECT_TRUE(unread.color.empty() && unread.shadowTerms.empty()) << "frame " << f;
      }
      game.step();
    }
    // Now and then a frame of another kind in between (one without shadow maps, one that shows a layer): the
    // layers kept across it, which Vulkan keeps on the device, must still equal a new renderer's after it.
    if (f % 50 == 25) renderer.render(game.scene, raytraced);
    if (f % 50 == 40 && !game.scene.lightViews().empty()) renderer.render(game.scene, layerView);
    const auto t0 = std::chrono::steady_clock::now();
    const RenderOptions& asked = f % 3 == 1 ? noGBuffer : options;
    const RenderedFrame& frame = renderer.render(game.scene, asked);
    const auto t1 = std::chrono::steady_clock::now();
    keptMs += std::chrono::duration<double, std::milli>(t1 - t0).count();
    traced += frame.stats.texelsTraced;
    all += frame.stats.layerTexels;
    const Differences d = compareWithFresh(game.scene, *fresh, renderer, frame, asked);
    freshMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
    if (d.any()) {
      ++differing;
      if (margin >= 1.0)
        ADD_FAILURE() << backend << " frame " << f << " (" << game.last << "): " << d.layers << " layers, "
                      << d.gbuffer << " G-buffer, " << d.deviceGBuffer << " device G-buffer, " << d.color << " colour, " << d.terms << " terms, " << d.moments
                      << " moment layers differ";
      if (stopAtFirst) break;
    }
  }
  for (Tracer* t : {kept.get(), fresh.get()}) {
    if (VulkanTracer* v = t->vulkan()) {
      EXPECT_TRUE(v->validationMessages().empty()) << v->validationMessages().front();
    }
  }
  std::printf("%s%s, seed %u, margin %g: %d frames, %d refused changes, %d differed from a new renderer; %.2f%% of "
              "layer texels traced; %.0f ms kept frames, %.0f ms new renderers\n",
              backend.c_str(), evsm ? " (EVSM)" : "", seed, margin, frames, game.refused, differing, all ? 100.0 * double(traced) / double(all) : 0.0,
              keptMs, freshMs);
  return differing;
}

// 500 frames; VOXSHADOW_FRAME_LOOP_FRAMES sets another count (the sanitizer run's shorter one).
int randomFrames() {
  const char* env = std::getenv("VOXSHADOW_FRAME_LOOP_FRAMES");
  return env ? std::max(1, std::atoi(env)) : 500;
}

TEST(FrameLoop, RandomFramesEqualANewRendererOnTheCpu) { EXPECT_EQ(playAndCompare("cpu", 7, randomFrames(), 1.0, false), 0); }

TEST(FrameLoop, RandomFramesEqualANewRendererOnVulkan) {
  EXPECT_EQ(playAndCompare("vulkan", 11, randomFrames(), 1.0, false), 0);
}

// The same with every light on EVSM: the moments, updated only around the traced rectangles (the cascades'
// rings blurred across their wrap, the torch's faces across their edges), equal a new renderer's whole pass.
TEST(FrameLoop, RandomFramesKeepEvsmMomentsOnTheCpu) {
  EXPECT_EQ(playAndCompare("cpu", 5, std::min(randomFrames(), 200), 1.0, false, true), 0);
}

TEST(FrameLoop, RandomFramesKeepEvsmMomentsOnVulkan) {
  EXPECT_EQ(playAndCompare("vulkan", 13, std::min(randomFrames(), 200), 1.0, false, true), 0);
}

// The same comparison notices an invalidation one texel too small on every side.
TEST(FrameLoop, AnInvalidationOneTexelTooSmallIsCaught) {
  EXPECT_GT(playAndCompare("cpu", 7, 500, 0.0 - 1.0, true), 0);
}

// On Vulkan a frame that asks for no image reads none of it back: a pan reads back exactly the colour and terms
// fewer than the same pan that asks; a still frame that asks after it reads the whole image, which equals the
// other renderer's. The CPU backend fills both whatever is asked.
// A kept renderer whose frames outgrow the lighting pass's buffers (a larger frame; in ray-traced mode a light
// beyond the most seen so far) keeps rendering, and equals a new renderer, on both backends.
TEST(FrameLoop, GrownFramesAndAddedLightsKeepRendering) {
  for (const std::string backend : {"cpu", "vulkan"}) {
    Game game("frame_loop_grown_" + backend, 5);
    std::unique_ptr<Tracer> kept = makeTracer(backend), fresh = makeTracer(backend, backend == "vulkan");
    FrameRenderer renderer(*kept);
    auto expectFresh = [&](const RenderOptions& options, const std::string& step) {
      const RenderedFrame& frame = renderer.render(game.scene, options);
      FrameRenderer other(*fresh);
      const RenderedFrame& truth = other.render(game.scene, options);
      EXPECT_TRUE(test::sameBytes(frame.gbuffer.texels, truth.gbuffer.texels)) << backend << ", " << step;
      EXPECT_TRUE(test::sameBytes(frame.color, truth.color)) << backend << ", " << step;
      EXPECT_TRUE(test::sameBytes(frame.shadowTerms, truth.shadowTerms)) << backend << ", " << step;
    };
    expectFresh(smallFrame(96, 54), "first frame");
    game.scene.fillVoxels(game.ground, VoxelBox{{40, 4, 40}, {44, 8, 44}}, 0);
    expectFresh(smallFrame(96, 54), "a hole");
    EXPECT_NO_THROW(expectFresh(smallFrame(), "a larger frame")) << backend;
    RenderOptions raytraced = smallFrame();
    raytraced.shadows = ShadowSource::Raytraced;
    expectFresh(raytraced, "ray-traced");
    LightDesc spot = shadowedSpot(glm::vec3(20.0f, 15.0f, 35.0f));
    spot.name = "added-spot";
    game.scene.addLight(spot);
    EXPECT_NO_THROW(expectFresh(raytraced, "a light added, ray-traced")) << backend;
    EXPECT_NO_THROW(expectFresh(smallFrame(), "with maps again")) << backend;
    if (VulkanTracer* v = kept->vulkan()) {
      EXPECT_TRUE(v->validationMessages().empty()) << v->validationMessages().front();
    }
  }
}

TEST(FrameLoop, AFrameThatAsksForNoImageReadsNoneBack) {
  Game game("frame_loop_readback", 3);
  std::unique_ptr<Tracer> tracer = makeTracer("vulkan");
  FrameRenderer asking(*tracer), quiet(*tracer);
  const RenderOptions options = smallFrame();
  RenderOptions none = options;
  none.readColor = none.readShadowTerms = false;
  const double texel = asking.render(game.scene, options).views.at(0).texelWorld;
  EXPECT_TRUE(quiet.render(game.scene, none).color.empty());
  game.moveCamera(glm::dvec3(texel * 2.0, 0.0, texel));
  const RenderedFrame a = asking.render(game.scene, options);
  const RenderedFrame& b = quiet.render(game.scene, none);
  const std::uint64_t pixels = std::uint64_t(a.width) * std::uint64_t(a.height);
  const std::uint64_t image = pixels * sizeof(glm::vec4) + a.shadowTerms.size() * sizeof(float);
  ASSERT_EQ(a.color.size(), pixels);
  EXPECT_TRUE(b.color.empty());
  EXPECT_TRUE(b.shadowTerms.empty());
  EXPECT_EQ(b.stats.pixelsShaded, a.stats.pixelsShaded);
  EXPECT_EQ(b.stats.bytesReadBack + image, a.stats.bytesReadBack);
  // Nothing changed since: the asking renderer reads nothing back, the other one the whole image.
  EXPECT_EQ(asking.render(game.scene, options).stats.bytesReadBack, 0u);
  const RenderedFrame& c = quiet.render(game.scene, options);
  EXPECT_EQ(c.stats.bytesReadBack, image);
  EXPECT_EQ(c.stats.pixelsShaded, 0u);
  EXPECT_TRUE(test::sameBytes(c.color, a.color));
  EXPECT_TRUE(test::sameBytes(c.shadowTerms, a.shadowTerms));
  // Colour alone.
  RenderOptions colourOnly = options;
  colourOnly.readShadowTerms = false;
  const RenderedFrame& d = quiet.render(game.scene, colourOnly);
  EXPECT_TRUE(test::sameBytes(d.color, a.color));
  EXPECT_TRUE(d.shadowTerms.empty());
  EXPECT_EQ(d.stats.bytesReadBack, 0u);
  // The CPU backend's frames have both.
  std::unique_ptr<Tracer> cpu = makeTracer("cpu");
  FrameRenderer host(*cpu);
  const RenderedFrame& e = host.render(game.scene, none);
  EXPECT_EQ(e.color.size(), pixels);
  EXPECT_EQ(e.shadowTerms.size(), a.shadowTerms.size());
  test::expectNoValidationMessages(*tracer);
}

// A window's exposed strips, and no more, for a pan of k whole texels along x and y.
TEST(FrameLoop, APanTracesExactlyTheExposedStrips) {
  Game game("frame_loop_pan", 1);
  std::unique_ptr<Tracer> tracer = makeTracer("cpu");
  FrameRenderer renderer(*tracer);
  const RenderOptions options = smallFrame();
  std::vector<LightView> before = renderer.render(game.scene, options).views;
  for (int k : {1, 2, 3, 4, 7}) {
    game.moveCamera(glm::dvec3(before[0].texelWorld * k, 0.0, before[0].texelWorld * 0.5 * k));
    const RenderedFrame& frame = renderer.render(game.scene, options);
    for (std::size_t i = 0; i < frame.views.size(); ++i) {
      const TexelRect a = windowRect(before[i]), b = windowRect(frame.views[i]);
      const std::int64_t n = frame.views[i].resolution;
      const std::int64_t dx = std::min<std::int64_t>(std::abs(b.x0 - a.x0), n), dy = std::min<std::int64_t>(std::abs(b.y0 - a.y0), n);
      EXPECT_EQ(frame.stats.layers[i].texels, std::uint64_t(dx * n + dy * n - dx * dy)) << frame.views[i].name << ", pan " << k;
      if (!isRingView(frame.views[i])) {
        EXPECT_EQ(frame.stats.layers[i].texels, 0u) << frame.views[i].name;
      }
    }
    before = frame.views;
  }
}

// A moved actor traces no texel outside the footprints of its old and new boxes, each grown by a texel.
TEST(FrameLoop, AMovedActorTracesOnlyItsFootprints) {
  Game game("frame_loop_actor", 2);
  std::unique_ptr<Tracer> tracer = makeTracer("cpu");
  FrameRenderer renderer(*tracer);
  const RenderOptions options = smallFrame();
  const std::size_t i = game.scene.addInstance(game.actor, glm::translate(glm::dmat4(1.0), glm::dvec3(20, 0, 40)));
  renderer.render(game.scene, options);
  for (int s = 0; s < 5; ++s) {
    const Aabb old = game.scene.data().instanceBounds[i];
    game.scene.moveInstance(i, glm::translate(glm::dmat4(1.0), glm::dvec3(0.25, 0, 0)) * game.scene.instanceTransform(i));
    const Aabb now = game.scene.data().instanceBounds[i];
    const RenderedFrame& frame = renderer.render(game.scene, options);
    EXPECT_GT(frame.stats.texelsTraced, 0u);
    for (std::size_t v = 0; v < frame.views.size(); ++v) {
      const LightView& view = frame.views[v];
      // The footprint, computed here on its own: corner texels in double, one texel around.
      auto area = [&](const Aabb& box) -> std::uint64_t {
        glm::dvec2 lo(1e300), hi(-1e300);
        for (int c = 0; c < 8; ++c) {
          const glm::dvec3 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y, (c & 4) ? box.max.z : box.min.z);
          glm::dvec2 t;
          if (isRingView(view)) {
            const glm::dvec3 l = view.gridBasis * p;
            t = glm::dvec2(l.x, -l.y) / view.texelWorld;
          } else {
            const glm::dvec4 clip = view.eyeToClip * glm::dvec4(p - view.eye, 1.0);
            if (!(clip.w > 0.0)) return std::uint64_t(view.resolution) * std::uint64_t(view.resolution);
            t = (glm::dvec2(clip) / clip.w * 0.5 + 0.5) * double(view.resolution);
          }
          lo = glm::min(lo, t);
          hi = glm::max(hi, t);
        }
        const TexelRect w = windowRect(view);
        const double x0 = std::max(std::floor(lo.x) - 1, double(w.x0)), x1 = std::min(std::floor(hi.x) + 2, double(w.x1));
        const double y0 = std::max(std::floor(lo.y) - 1, double(w.y0)), y1 = std::min(std::floor(hi.y) + 2, double(w.y1));
        return x1 > x0 && y1 > y0 ? std::uint64_t((x1 - x0) * (y1 - y0)) : 0u;
      };
      EXPECT_LE(frame.stats.layers[v].texels, area(old) + area(now)) << view.name << ", step " << s;
    }
    EXPECT_LT(frame.stats.texelsTraced, frame.stats.layerTexels / 10);
  }
}

// A game that builds upward on its ground: a fill that leaves the ground's box grows it by half its largest
// side (SceneData::boxHeadroom), and a grown box re-bases every ray through the ground (the frame redoes what
// the ground covers). A tower of 16^3 blocks grows it on the first block only (a fixed step of 16 voxels grew it
// on every other block: 3 of 5); every frame still equals a new renderer's.
TEST(FrameLoop, ATowerOnTheGroundGrowsItsBoxOnce) {
  Game game("frame_loop_tower", 5);
  std::unique_ptr<Tracer> tracer = makeTracer("cpu"), fresh = makeTracer("cpu");
  FrameRenderer renderer(*tracer);
  const RenderOptions options = smallFrame();
  renderer.render(game.scene, options);
  const VoxelBox ground = game.scene.objects()[game.ground].brickmap.bounds();
  const gpu::ObjectRecord& record = game.scene.data().objects[game.ground];
  const int tableTop = (glm::ivec3(record.regionOrigin).y + glm::ivec3(record.regionDims).y) * 128;
  const glm::ivec3 at(ground.min.x + 8, ground.max.y, ground.min.z + 8);
  int grown = 0, blocks = 0;
  for (int b = 0; at.y + 16 * (b + 1) <= tableTop && b < 5; ++b) {
    const int boxTop = game.scene.data().objects[game.ground].voxelMax.y;
    game.scene.fillVoxels(game.ground, VoxelBox{at + glm::ivec3(0, 16 * b, 0), at + glm::ivec3(16, 16 * (b + 1), 16)}, 2);
    const bool grew = game.scene.data().objects[game.ground].voxelMax.y != boxTop;
    const RenderedFrame& frame = renderer.render(game.scene, options);
    grown += grew ? 1 : 0;
    ++blocks;
    // A block within the box redoes only what it shades, not the ground's every texel.
    if (!grew) {
      EXPECT_LT(frame.stats.texelsTraced, frame.stats.layerTexels / 10) << "block " << b;
    }
    const Differences d = compareWithFresh(game.scene, *fresh, renderer, frame, options);
    EXPECT_FALSE(d.any()) << "block " << b << ": " << d.layers << " layers, " << d.color << " colour differ";
  }
  ASSERT_GE(blocks, 3) << "the ground's region table leaves room for three blocks above it";
  EXPECT_EQ(grown, 1) << "of " << blocks << " blocks";
}

// A still frame does nothing; an edit's frame uploads little on Vulkan.
TEST(FrameLoop, AStillFrameDoesNothingAndADigUploadsLittle) {
  for (const std::string backend : {"cpu", "vulkan"}) {
    Game game("frame_loop_still_" + backend, 3);
    std::unique_ptr<Tracer> tracer = makeTracer(backend);
    FrameRenderer renderer(*tracer);
    const RenderOptions options = smallFrame();
    renderer.render(game.scene, options);
    for (int f = 0; f < 3; ++f) {
      const FrameStats& s = renderer.render(game.scene, options).stats;
      EXPECT_EQ(s.texelsTraced + s.primaryRays + s.visibilityRays + s.pixelsShaded, 0u) << backend;
      EXPECT_EQ(s.bytesUploaded + s.bytesReadBack, 0u) << backend;
      EXPECT_EQ(s.dispatches, 0) << backend;
    }
    const std::uint64_t before = tracer->bytesUploaded();
    game.scene.fillVoxels(game.ground, VoxelBox{{40, 4, 40}, {44, 8, 44}}, 0);
    const RenderedFrame& digFrame = renderer.render(game.scene, options);
    const FrameStats dig = digFrame.stats;  // a copy: the frames below reuse the renderer's
    EXPECT_LE(tracer->bytesUploaded() - before, 4u * 1024u) << backend << ": the scene update of a 4^3 hole";
    EXPECT_LT(dig.texelsTraced, dig.layerTexels / 20) << backend;
    // The Vulkan lighting pass keeps the layers, the G-buffer and the answers in place: the dig writes its traced
    // rows and its marked pixels' inputs, less than the store alone (4 bytes a texel) that a whole pass uploads.
    EXPECT_LT(dig.bytesUploaded, dig.layerTexels * sizeof(float)) << backend;
    EXPECT_GT(dig.pixelsShaded, 0u) << backend;
    // Both lighting passes shade again only the pixels the hole touches (Vulkan: one invocation per listed
    // pixel), not the frame.
    EXPECT_LT(dig.pixelsShaded, std::uint64_t(digFrame.width) * std::uint64_t(digFrame.height) / 2) << backend;
    // Vulkan resolves the G-buffer and spreads the answers on the device: a frame uploads its scene update, its
    // pixel lists (4 bytes a listed pixel) and its records, not the texels or answers of the pixels it redoes.
    const std::uint64_t digScene = tracer->bytesUploaded() - before;
    EXPECT_LE(dig.bytesUploaded - digScene, 4 * (dig.primaryRays + dig.visibilityRays + dig.pixelsShaded) + 8192)
        << backend;
    // Blocks placed on the ground (not the scene's last object): the first outgrows the ground's arrays, which
    // are laid out again with headroom; the next ones grow in place and upload only what they changed.
    std::uint64_t blockUploads = 0;
    for (int b = 0; b < 3; ++b) {
      const std::uint64_t at = tracer->bytesUploaded();
      game.scene.fillVoxels(game.ground, VoxelBox{{8 + 20 * b, 8, 60}, {24 + 20 * b, 24, 76}}, 2);
      const FrameStats& block = renderer.render(game.scene, options).stats;
      if (b > 0) {
        EXPECT_LE(tracer->bytesUploaded() - at, 16u * 1024u) << backend << ": the scene update of block " << b;
        blockUploads = std::max(blockUploads, block.bytesUploaded);
      }
    }
    // A camera step redoes every pixel: it uploads no texel, receiver or answer of them (64 + 32 + 4 a light
    // bytes each), less than 4 bytes a pixel in all.
    CameraDesc camera = *game.scene.desc().camera;
    camera.position += glm::vec3(0.25f, 0.0f, 0.1f);
    game.scene.setCamera(camera);
    const FrameStats step = renderer.render(game.scene, options).stats;  // a copy: later frames reuse the renderer's
    const std::uint64_t pixels = std::uint64_t(options.width) * std::uint64_t(options.height);
    EXPECT_EQ(step.primaryRays, pixels) << backend;
    EXPECT_LT(step.bytesUploaded, 4 * pixels) << backend;
    // The same step by a game that reads nothing back (it shades with vulkanShadows()): no hit, G-buffer texel,
    // colour or term crosses to the host; only the contact rays' answers (4 bytes a pixel and light with rays).
    RenderOptions game_ = options;
    game_.readColor = game_.readShadowTerms = game_.readGBuffer = false;
    camera.position += glm::vec3(0.25f, 0.0f, 0.1f);
    game.scene.setCamera(camera);
    const RenderedFrame& unread = renderer.render(game.scene, game_);
    EXPECT_EQ(unread.stats.primaryRays, pixels) << backend;
    const std::uint64_t lights = game.scene.desc().lights.size();
    if (backend == "vulkan") {
      EXPECT_TRUE(unread.gbuffer.texels.empty());
      EXPECT_LE(unread.stats.bytesReadBack, 4 * pixels * lights) << backend;
    } else {
      EXPECT_EQ(unread.gbuffer.texels.size(), pixels);
    }
    // The next two holes: the first reads the device's G-buffer back once (64 bytes a pixel) to find the pixels
    // they touch, the second no more than its own pixels' data.
    for (int h = 0; h < 2; ++h) {
      game.scene.fillVoxels(game.ground, VoxelBox{{30 + 8 * h, 4, 30}, {34 + 8 * h, 8, 34}}, 0);
      const FrameStats& hole = renderer.render(game.scene, game_).stats;
      if (backend != "vulkan") continue;
      if (h == 0) EXPECT_GE(hole.bytesReadBack, 64 * pixels) << backend << ": the G-buffer read back once";
      else EXPECT_LT(hole.bytesReadBack, 64 * pixels) << backend << ": read back again";
    }
    std::printf("%s: a 4^3 hole's frame uploaded %llu bytes (%llu of them its scene update), a 16^3 block's at most "
                "%llu, a camera step's %llu\n",
                backend.c_str(), (unsigned long long)dig.bytesUploaded, (unsigned long long)digScene,
                (unsigned long long)blockUploads, (unsigned long long)step.bytesUploaded);
  }
}

std::size_t residentKiB() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stoul(line.substr(6));
  return 0;
}

// Bytes the process has allocated and not freed (every malloc arena and mapped block).
std::size_t heapInUse() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}

// Soak: edits that dig and fill back, actors walking to and fro. The change journal fills in the first frames
// and the allocator settles a while longer, so the second quarter of the run is the baseline: the most memory
// held in it against the most held in the second half. Heap bytes in use show a leak of a few bytes a frame;
// resident memory (lavapipe's device memory included) within 1% shows nothing else grows. Both loops repeat
// every 200 frames, so each window holds every phase. 3,000 frames on the CPU and 1,000 on Vulkan fit the
// suite's time; VOXSHADOW_SOAK_FRAMES=10000 runs the long soak (a benchmark mode, BENCHMARKS.md).
TEST(FrameLoop, SoakKeepsMemoryFlat) {
  const char* env = std::getenv("VOXSHADOW_SOAK_FRAMES");
  for (const std::string backend : {"cpu", "vulkan"}) {
    const int frames = env ? std::max(800, std::atoi(env)) : backend == "cpu" ? 3000 : 1000;
    // Layers of 64^2 and a 96x54 frame: many frames in the suite's time.
    Game game("frame_loop_soak_" + backend, 4, 64);
    std::unique_ptr<Tracer> tracer = makeTracer(backend);
    FrameRenderer renderer(*tracer);
    const RenderOptions options = smallFrame(96, 54);
    const std::size_t walker = game.scene.addInstance(game.actor, glm::translate(glm::dmat4(1.0), glm::dvec3(20, 0, 40)));
    std::size_t baseResident = 0, baseHeap = 0, peakResident = 0, peakHeap = 0;
    for (int f = 0; f < frames; ++f) {
      const double phase = double(f % 200) / 200.0;
      game.scene.moveInstance(walker, glm::translate(glm::dmat4(1.0), glm::dvec3(10.0 + 20.0 * std::abs(phase - 0.5), 0, 40)));
      const glm::ivec3 at(30 + 4 * (f % 8), 4, 40);
      game.scene.fillVoxels(game.ground, VoxelBox{at, at + 4}, (f / 8) % 2 ? std::uint8_t(2) : std::uint8_t(0));
      renderer.render(game.scene, options);
      if (f < frames / 4) continue;
      const bool baseline = f < frames / 2;
      std::size_t& resident = baseline ? baseResident : peakResident;
      std::size_t& heap = baseline ? baseHeap : peakHeap;
      resident = std::max(resident, residentKiB());
      heap = std::max(heap, heapInUse());
    }
    EXPECT_LE(double(peakHeap), 1.01 * double(baseHeap))
        << backend << ": heap in use grew from at most " << baseHeap << " bytes to " << peakHeap;
    // Resident memory: 1%, but at least 2 MiB. With the heap in use flat, glibc's arenas were seen to keep
    // 1.2 MiB more pages resident in the second half under ctest -j2 (a step, once): a leak of 1.4 KiB a frame
    // or more still fails here, and the heap check above catches a smaller one.
    EXPECT_LE(double(peakResident), std::max(1.01 * double(baseResident), double(baseResident) + 2048.0))
        << backend << ": resident memory grew from at most " << baseResident << " KiB to " << peakResident << " KiB";
    std::printf("%s soak: %d frames, at most %zu KiB resident and %zu heap bytes in frames %d..%d, at most %zu KiB "
                "and %zu bytes after\n",
                backend.c_str(), frames, baseResident, baseHeap, frames / 4, frames / 2 - 1, peakResident, peakHeap);
    if (VulkanTracer* v = tracer->vulkan()) {
      EXPECT_TRUE(v->validationMessages().empty());
    }
  }
}

}  // namespace
}  // namespace vs
