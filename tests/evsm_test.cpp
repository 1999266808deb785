// evsm_test.cpp: exponential variance shadow maps: the portable exponential, the moments on both backends bit
// for bit, the cube faces' blur across their edges against an independent construction, agreement with the
// ray-traced truth on the demo and the city, light bleeding under stacked occluders, and the scene keys.
#include <algorithm>
#include <cmath>
#include <cfloat>
#include <cstring>
#include <fstream>
#include <map>
#include <random>

#include <gtest/gtest.h>
#include <OpenImageIO/imageio.h>

#include "compute/cpu/cpu_tracer.h"
#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/evsm.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "lighting/shared/evsm.h"
#include "support/lighting_scenes.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace fs = std::filesystem;
using namespace vs;

namespace {

// The demo scene with every shadowed light on EVSM (and the given layer size, 0: its own).
Scene evsmDemo(const std::string& dirName, int resolution, const nlohmann::json& keys = nlohmann::json::object()) {
  const std::vector<std::string> written = writeDemoWorld(test::scratchDir(dirName));
  nlohmann::json doc = nlohmann::json::parse(std::ifstream(written.back()));
  for (auto& l : doc["lights"])
    if (l.contains("shadow")) {
      l["shadow"]["filter"] = "evsm";
      if (resolution > 0) l["shadow"]["resolution"] = resolution;
      for (auto it = keys.begin(); it != keys.end(); ++it) l["shadow"][it.key()] = it.value();
    }
  return Scene::load(parseSceneJson(doc.dump(), fs::path(written.back()).parent_path() / "evsm.json"));
}

std::unique_ptr<Tracer> cpuTracer() { return makeCpuTracer({CpuTracePath::Interleaved, 0}); }

// How the EVSM terms of a frame differ from the ray-traced truth's, over receivers (a hit that faces the light
// and lies in its reach): the share differing by more than 0.5, and a histogram of |difference|.
struct TermDifferences {
  std::size_t receivers = 0, overHalf = 0;
  std::map<double, std::size_t> upTo;  // bin upper bound -> count of differences in (previous bound, bound]
  double share() const { return receivers ? double(overHalf) / double(receivers) : 0.0; }
  std::string histogram() const {
    std::string out;
    double below = 0.0;
    for (const auto& [bound, n] : upTo) {
      char text[64];
      const double percent = 100.0 * double(n) / double(std::max<std::size_t>(1, receivers));
      if (bound == 0.0) std::snprintf(text, sizeof text, " equal: %.3f%%", percent);
      else std::snprintf(text, sizeof text, " (%.2f, %.2f]: %.3f%%", below, bound, percent);
      out += text;
      below = bound;
    }
    return out;
  }
};

TermDifferences compareTerms(const Scene& scene, const RenderedFrame& maps, const RenderedFrame& truth, std::size_t light) {
  TermDifferences d;
  for (double b : {0.0, 0.05, 0.1, 0.25, 0.5, 1.0}) d.upTo[b] = 0;
  const LightDesc& l = scene.desc().lights[light];
  const std::size_t lights = maps.lightNames.size();
  for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
    glm::dvec3 toLight;
    if (!test::receivesLight(l, maps.gbuffer.texels[i], toLight)) continue;
    ++d.receivers;
    const double diff = std::abs(double(maps.shadowTerms[i * lights + light]) - double(truth.shadowTerms[i * lights + light]));
    if (diff > 0.5) ++d.overHalf;
    for (auto& [bound, n] : d.upTo)
      if (diff <= bound) {
        ++n;
        break;
      }
  }
  return d;
}

RenderedFrame renderFrame(const Scene& scene, Tracer& tracer, ShadowSource source, int width, int height) {
  FrameRenderer renderer(tracer);
  RenderOptions options;
  options.shadows = source;
  options.width = width;
  options.height = height;
  return renderer.render(scene, options);
}

}  // namespace

// The exponential the moments use, against the library's in double, over the whole range the warps reach.
TEST(Evsm, ExactExponentialIsAccurate) {
  double worst = 0.0;
  for (int i = -840000; i <= 840000; ++i) {
    const float x = float(i) * 1e-4f;
    const double truth = std::exp(double(x));
    worst = std::max(worst, std::abs(double(gpu::vsExpExact(x)) - truth) / truth);
  }
  EXPECT_LT(worst, 2.5e-7);
  std::printf("vsExpExact over [-84, 84]: largest relative error %.3g\n", worst);
  // The moments' extremes stay finite and normal.
  const glm::vec4 far = gpu::vsEvsmWarp(1.0f, 1.0f, glm::vec2(kMaxEvsmExponent));
  const glm::vec4 near = gpu::vsEvsmWarp(0.0f, 1.0f, glm::vec2(kMaxEvsmExponent));
  EXPECT_TRUE(std::isfinite(far.y * float(2 * kMaxEvsmBlur + 1)));
  EXPECT_GE(near.y, FLT_MIN);
  EXPECT_GE(far.w, FLT_MIN);
}

// EVSM against one exact visibility ray per pixel and light, on the demo (its own layers: sun cascades 2048^2,
// lamp 1024^2, torch 6 x 512^2) and the city: at most 1% of receivers differ by more than 0.5 (soft edges differ
// by less; the histogram says how the rest spread).
TEST(Evsm, DemoAndCityAgreeWithRayTracedShadows) {
  auto tracer = cpuTracer();
  const int width = 640, height = 360;
  const Scene demo = evsmDemo("evsm_truth_demo", 0);
  tracer->setScene(demo.data());
  const RenderedFrame truth = renderFrame(demo, *tracer, ShadowSource::Raytraced, width, height);
  const RenderedFrame maps = renderFrame(demo, *tracer, ShadowSource::Maps, width, height);
  for (std::size_t l = 0; l < demo.desc().lights.size(); ++l) {
    const TermDifferences d = compareTerms(demo, maps, truth, l);
    EXPECT_GT(d.receivers, 1000u) << demo.desc().lights[l].name;
    EXPECT_LE(d.share(), 0.01) << demo.desc().lights[l].name << ":" << d.histogram();
    std::printf("demo, %s: %zu of %zu receivers differ by more than 0.5 (%.3f%%); |difference|%s\n",
                demo.desc().lights[l].name.c_str(), d.overHalf, d.receivers, 100.0 * d.share(), d.histogram().c_str());
  }
  const fs::path dir = test::scratchDir("evsm_truth_city");
  const fs::path vdb = dir / "city.vdb";
  if (!fs::exists(vdb)) test::writeBoxesVdb(vdb, test::cityBoxes());
  for (double elevation : {20.0, 45.0, 70.0}) {
    const Scene city = Scene::load(test::writeLightingScene(dir, "e" + std::to_string(int(elevation)), vdb,
                                                            test::sunDirection(elevation),
                                                            {{"resolution", 2048}, {"filter", "evsm"}}));
    tracer->setScene(city.data());
    const RenderedFrame cityTruth = renderFrame(city, *tracer, ShadowSource::Raytraced, 0, 0);
    const RenderedFrame cityMaps = renderFrame(city, *tracer, ShadowSource::Maps, 0, 0);
    const TermDifferences d = compareTerms(city, cityMaps, cityTruth, 0);
    EXPECT_GT(d.receivers, 30000u);
    EXPECT_LE(d.share(), 0.01) << "elevation " << elevation << ":" << d.histogram();
    std::printf("city, sun at %.0f deg: %zu of %zu receivers differ by more than 0.5 (%.3f%%); |difference|%s\n",
                elevation, d.overHalf, d.receivers, 100.0 * d.share(), d.histogram().c_str());
  }
}

namespace {

// The demo with every layer at `resolution`, EVSM with a blur of 2, in a small frame.
RenderOptions smallFrame() {
  RenderOptions o;
  o.width = 200;
  o.height = 120;
  return o;
}

}  // namespace

// GPU = CPU: the moment layers bit for bit (the pass runs the same sums in the same order on both), the image
// within the lighting tests' rule; and a still frame computes no moment.
TEST(Evsm, VulkanMomentsEqualTheCpusBitForBit) {
  VulkanOptions options;
  options.validation = true;
  std::unique_ptr<Tracer> vulkan = makeVulkanTracer(options);  // no device: fails here, loudly
  std::unique_ptr<Tracer> cpu = cpuTracer();
  const Scene scene = evsmDemo("evsm_backends", 256, {{"evsm_blur", 2}, {"evsm_exponent", {42, 12}}});
  FrameRenderer onGpu(*vulkan), onCpu(*cpu);
  const RenderedFrame gpu = onGpu.render(scene, smallFrame());
  const RenderedFrame host = onCpu.render(scene, smallFrame());
  const std::vector<std::vector<glm::vec4>> gm = onGpu.moments(), cm = onCpu.moments();
  ASSERT_EQ(gm.size(), cm.size());
  ASSERT_EQ(gm.size(), 10u);
  std::size_t texels = 0;
  for (std::size_t i = 0; i < cm.size(); ++i) {
    ASSERT_EQ(gm[i].size(), cm[i].size()) << host.views[i].name;
    ASSERT_EQ(cm[i].size(), 256u * 256u) << host.views[i].name;
    std::size_t differ = 0;
    for (std::size_t k = 0; k < cm[i].size(); ++k) differ += std::memcmp(&gm[i][k], &cm[i][k], sizeof(glm::vec4)) != 0;
    EXPECT_EQ(differ, 0u) << host.views[i].name;
    texels += cm[i].size();
  }
  EXPECT_EQ(host.stats.momentTexels, texels);
  double worst = 0.0;
  std::size_t termsDiffer = 0;
  for (std::size_t i = 0; i < host.color.size(); ++i)
    for (int c = 0; c < 4; ++c)
      worst = std::max(worst, double(std::abs(gpu.color[i][c] - host.color[i][c])) / std::max(1.0f, std::abs(host.color[i][c])));
  for (std::size_t i = 0; i < host.shadowTerms.size(); ++i) termsDiffer += std::abs(gpu.shadowTerms[i] - host.shadowTerms[i]) > 1e-4f;
  EXPECT_LE(worst, 1.0 / 255.0);
  EXPECT_LE(termsDiffer, host.shadowTerms.size() / 1000);
  std::printf("EVSM on both backends: %zu moment texels equal; largest colour difference %.2e, %zu of %zu terms "
              "differ by more than 1e-4\n", texels, worst, termsDiffer, host.shadowTerms.size());
  // The moments debug view of the torch's first face: the same image from both backends' moments, and not flat.
  RenderOptions debug = smallFrame();
  debug.debug = DebugView::Moments;
  debug.debugLayer = 4;
  const std::vector<glm::vec4> gpuDebug = onGpu.render(scene, debug).color, cpuDebug = onCpu.render(scene, debug).color;
  ASSERT_EQ(gpuDebug.size(), cpuDebug.size());
  EXPECT_EQ(0, std::memcmp(gpuDebug.data(), cpuDebug.data(), cpuDebug.size() * sizeof(glm::vec4)));
  const auto [darkest, brightest] = std::minmax_element(cpuDebug.begin(), cpuDebug.end(),
                                                        [](const glm::vec4& a, const glm::vec4& b) { return a.x < b.x; });
  EXPECT_LT(darkest->x + 0.05f, brightest->x);
  onGpu.render(scene, smallFrame());
  onCpu.render(scene, smallFrame());
  // A still frame: no texel traced, no moment computed.
  for (FrameRenderer* r : {&onGpu, &onCpu}) {
    const RenderedFrame& still = r->render(scene, smallFrame());
    EXPECT_EQ(still.stats.texelsTraced, 0u);
    EXPECT_EQ(still.stats.momentTexels, 0u);
    EXPECT_EQ(still.stats.dispatches, 0);
  }
  EXPECT_TRUE(vulkan->vulkan()->validationMessages().empty());
}

// A point light's faces blur across their edges as one surface: every moment within r texels of a face's edge
// equals a 2D box over the face's plane extended past its edges, each sample read from the face that the major
// axis of its direction names, built here apart from the pass (double, the views' own matrices, no border map).
TEST(Evsm, CubeFacesBlurAcrossTheirEdges) {
  const fs::path dir = test::scratchDir("evsm_cube");
  const fs::path vdb = dir / "world.vdb";
  if (!fs::exists(vdb)) test::writeBoxesVdb(vdb, test::floorWithBoxBoxes());
  const fs::path sceneFile = test::writeLightingScene(dir, "cube", vdb, test::sunDirection(60.0));
  nlohmann::json doc = nlohmann::json::parse(std::ifstream(sceneFile));
  const int n = 64, r = 3;
  doc["lights"] = {{{"name", "bulb"}, {"type", "point"}, {"position", {40.0, 20.0, 44.0}}, {"range", 60.0},
                    {"intensity", 400.0},
                    {"shadow", {{"resolution", n}, {"filter", "evsm"}, {"evsm_blur", r}, {"evsm_exponent", {30, 10}}}}}};
  const Scene scene = Scene::load(parseSceneJson(doc.dump(), sceneFile));
  auto tracer = cpuTracer();
  FrameRenderer renderer(*tracer);
  RenderOptions o;
  o.width = 64;
  o.height = 48;
  const RenderedFrame& frame = renderer.render(scene, o);
  const std::vector<ShadowLayer> layers = renderer.layers();
  const std::vector<std::vector<glm::vec4>> moments = renderer.moments();
  ASSERT_EQ(frame.views.size(), 6u);
  const std::vector<LightView>& views = frame.views;
  const float scale = float(1.0 / double(views[0].range));
  auto depthToward = [&](const glm::dvec3& d) {
    const glm::dvec3 a = glm::abs(d);
    const int face = a.x >= a.y && a.x >= a.z ? (d.x >= 0 ? 0 : 1) : a.y >= a.z ? (d.y >= 0 ? 2 : 3) : (d.z >= 0 ? 4 : 5);
    const LightView& v = views[std::size_t(face)];
    const glm::dvec4 clip = v.eyeToClip * glm::dvec4(d, 1.0);
    const glm::dvec2 q = glm::dvec2(clip) / clip.w;
    const int tx = std::clamp(int(std::floor((q.x * 0.5 + 0.5) * n)), 0, n - 1);
    const int ty = std::clamp(int(std::floor((q.y * 0.5 + 0.5) * n)), 0, n - 1);
    return layers[std::size_t(face)].texels[std::size_t(ty) * n + std::size_t(tx)];
  };
  double worst = 0.0, worstClamped = 0.0;
  std::size_t compared = 0;
  for (std::size_t f = 0; f < 6; ++f) {
    const glm::dmat4 clipToEye = glm::inverse(views[f].eyeToClip);
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        if (x >= r && y >= r && x < n - r && y < n - r) continue;
        glm::dvec4 sum(0.0), clamped(0.0);
        for (int dy = -r; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            const glm::dvec2 ndc((x + dx + 0.5) / n * 2.0 - 1.0, (y + dy + 0.5) / n * 2.0 - 1.0);
            const glm::dvec4 far = clipToEye * glm::dvec4(ndc, 1.0, 1.0);
            sum += glm::dvec4(gpu::vsEvsmWarp(depthToward(glm::dvec3(far) / far.w), scale, glm::vec2(30.0f, 10.0f)));
            const int cx = std::clamp(x + dx, 0, n - 1), cy = std::clamp(y + dy, 0, n - 1);
            clamped += glm::dvec4(gpu::vsEvsmWarp(layers[f].texels[std::size_t(cy) * n + std::size_t(cx)], scale,
                                                  glm::vec2(30.0f, 10.0f)));
          }
        const double count = double((2 * r + 1) * (2 * r + 1));
        const glm::vec4 got = moments[f][std::size_t(y) * n + std::size_t(x)];
        for (int c = 0; c < 4; ++c) {
          const double want = sum[c] / count;
          worst = std::max(worst, std::abs(double(got[c]) - want) / std::max(std::abs(want), 1e-30));
          worstClamped = std::max(worstClamped, std::abs(clamped[c] / count - want) / std::max(std::abs(want), 1e-30));
        }
        ++compared;
      }
  }
  EXPECT_LT(worst, 1e-5);
  // Clamping at each face's edge instead would be visibly off: the comparison can tell them apart.
  EXPECT_GT(worstClamped, 1e-2);
  std::printf("cube faces: %zu edge texels, largest relative difference %.2e from the independent blur (%.2e had "
              "each face clamped at its edges)\n", compared, worst, worstClamped);
}

// Light bleeding: a plate over the floor and a smaller plate above it; the floor that both shadow stays below 0.1
// (a single variance bound over the two occluders' depths would let light through near the upper plate's edge).
TEST(Evsm, StackedOccludersBleedLittle) {
  const fs::path dir = test::scratchDir("evsm_stacked");
  const fs::path vdb = dir / "world.vdb";
  test::VoxelBoxSet boxes = test::floorBoxes();
  const glm::ivec3 lowMin(28, 10, 28), lowMax(67, 11, 67), highMin(38, 40, 38), highMax(57, 41, 57);
  boxes.boxes.push_back({lowMin, lowMax});
  boxes.boxes.push_back({highMin, highMax});
  if (!fs::exists(vdb)) test::writeBoxesVdb(vdb, boxes);
  const glm::dvec3 sun = test::sunDirection(70.0);
  auto tracer = cpuTracer();
  auto blocks = [&](const glm::ivec3& lo, const glm::ivec3& hi, const glm::dvec3& p) {
    // The ray from p toward the light against the box [lo - 0.5, hi + 0.5] (slabs, double).
    const glm::dvec3 d = -sun;
    double t0 = 0.0, t1 = 1e9;
    for (int a = 0; a < 3; ++a) {
      const double l = (lo[a] - 0.5 - p[a]) / d[a], h = (hi[a] + 0.5 - p[a]) / d[a];
      t0 = std::max(t0, std::min(l, h));
      t1 = std::min(t1, std::max(l, h));
    }
    return t0 <= t1;
  };
  // The largest term over the floor both plates shadow, for the given shadow keys.
  auto worstUnderBoth = [&](const std::string& name, const nlohmann::json& keys, std::size_t& both) {
    // A camera low beside the plates, looking at the floor beneath them.
    const Scene scene = Scene::load(test::writeLightingScene(dir, name, vdb, sun, keys,
                                                             {{"position", {100, 8.5, 56}}, {"target", {40, 3, 48}}}));
    tracer->setScene(scene.data());
    const RenderedFrame maps = renderFrame(scene, *tracer, ShadowSource::Maps, 0, 0);
    both = 0;
    float worst = 0.0f;
    for (std::size_t i = 0; i < maps.gbuffer.texels.size(); ++i) {
      const gpu::GBufferTexel& g = maps.gbuffer.texels[i];
      if (g.info.w == 0u || g.normal.y < 0.5f || g.position.y > 4.0f) continue;  // the floor's top
      const glm::dvec3 p(glm::vec3(g.position));
      if (!blocks(lowMin, lowMax, p) || !blocks(highMin, highMax, p)) continue;
      ++both;
      worst = std::max(worst, maps.shadowTerms[i]);
    }
    return worst;
  };
  std::size_t both = 0, weakBoth = 0;
  const float worst = worstUnderBoth("stacked", {{"filter", "evsm"}, {"resolution", 1024}, {"evsm_blur", 4}}, both);
  EXPECT_GT(both, 500u);
  EXPECT_LT(worst, 0.1f);
  // Warps too weak to separate the depths, and no reduction, let the light through: the measure can tell.
  const float weak = worstUnderBoth("stacked_weak", {{"filter", "evsm"}, {"resolution", 1024}, {"evsm_blur", 4},
                                                      {"evsm_exponent", 1}, {"light_bleed_reduction", 0}}, weakBoth);
  EXPECT_GT(weak, 0.1f);
  std::printf("stacked occluders: %zu floor pixels shadowed by both plates, largest EVSM term %.4f (%.4f with both "
              "exponents 1 and no bleeding reduction)\n", both, worst, weak);
}

// Each EVSM key's bad values are refused naming the field; the CLI exits 2 and writes nothing.
TEST(Evsm, BadKeysAreRefusedNamingTheField) {
  const fs::path dir = test::scratchDir("evsm_keys");
  auto error = [&](const nlohmann::json& shadow) {
    const nlohmann::json light = {{"name", "l"}, {"type", "directional"}, {"direction", {0, -1, 0}}, {"shadow", shadow}};
    const nlohmann::json scene = {{"version", 1}, {"assets", nlohmann::json::object()}, {"lights", {light}}};
    try {
      parseSceneJson(scene.dump(), dir / "keys.json");
    } catch (const vs::Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_TRUE(test::contains(error({{"filter", "evsm2"}}), "lights[0].shadow.filter: unknown filter \"evsm2\""));
  EXPECT_TRUE(test::contains(error({{"evsm_exponent", 43}}), "lights[0].shadow.evsm_exponent: an EVSM exponent must be between 1 and 42"));
  EXPECT_TRUE(test::contains(error({{"evsm_exponent", 0.5}}), "lights[0].shadow.evsm_exponent"));
  EXPECT_TRUE(test::contains(error({{"evsm_exponent", {40, 50}}}), "lights[0].shadow.evsm_exponent[1]"));
  EXPECT_TRUE(test::contains(error({{"evsm_exponent", {40}}}), "lights[0].shadow.evsm_exponent: must be a number or an array of 2"));
  EXPECT_TRUE(test::contains(error({{"evsm_exponent", "high"}}), "lights[0].shadow.evsm_exponent: must be a number"));
  EXPECT_TRUE(test::contains(error({{"evsm_blur", 17}}), "lights[0].shadow.evsm_blur: the blur radius (texels) must be between 0 and 16"));
  EXPECT_TRUE(test::contains(error({{"evsm_blur", 1.5}}), "lights[0].shadow.evsm_blur: must be an integer"));
  EXPECT_TRUE(test::contains(error({{"evsm_blur", -1}}), "lights[0].shadow.evsm_blur"));
  EXPECT_TRUE(test::contains(error({{"light_bleed_reduction", 1.0}}), "lights[0].shadow.light_bleed_reduction: the light-bleeding reduction must be between 0 and 0.99"));
  EXPECT_TRUE(test::contains(error({{"light_bleed_reduction", -0.1}}), "lights[0].shadow.light_bleed_reduction"));
  EXPECT_TRUE(test::contains(error({{"light_bleed_reduction", nullptr}}), "lights[0].shadow.light_bleed_reduction: must be a number"));
  EXPECT_EQ(error({{"filter", "evsm"}, {"evsm_exponent", {42, 1}}, {"evsm_blur", 0}, {"light_bleed_reduction", 0}}), "");
  EXPECT_EQ(error({{"filter", "evsm"}, {"evsm_exponent", 1}, {"evsm_blur", 16}, {"light_bleed_reduction", 0.99}}), "");

  // The CLI: exit 2, the file and the field named, no output file.
  const std::vector<std::string> written = writeDemoWorld(dir);
  nlohmann::json doc = nlohmann::json::parse(std::ifstream(written.back()));
  doc["lights"][0]["shadow"]["filter"] = "evsm";
  doc["lights"][0]["shadow"]["evsm_blur"] = 99;
  const fs::path bad = dir / "bad_evsm.json";
  std::ofstream(bad) << doc.dump(1);
  std::string out;
  EXPECT_EQ(test::runCli("render " + test::quote(bad) + " -o " + test::quote(dir / "bad.png") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(test::contains(out, "bad_evsm.json")) << out;
  EXPECT_TRUE(test::contains(out, "lights[0].shadow.evsm_blur")) << out;
  EXPECT_FALSE(fs::exists(dir / "bad.png"));
  // A moments debug view of a layer without moments, and a layer past the last.
  EXPECT_EQ(test::runCli("render " + test::quote(written.back()) + " -o " + test::quote(dir / "m.png") +
                             " --backend cpu --width 64 --height 36 --debug moments=0", out), 2) << out;
  EXPECT_TRUE(test::contains(out, "--debug moments=0: layer sun.cascade0 has no EVSM moments")) << out;
  EXPECT_FALSE(fs::exists(dir / "m.png"));
}

// bake --evsm-moments: each EVSM layer's subimage carries the four moment channels, which equal a 2D box over
// the EXR's own depths (clamped at the layer's edges), warped here in double; refused without an EVSM light and
// for a shard.
TEST(Evsm, BakeWritesTheMomentsAsChannels) {
  const fs::path dir = test::scratchDir("evsm_bake");
  const std::vector<std::string> written = writeDemoWorld(dir);
  nlohmann::json doc = nlohmann::json::parse(std::ifstream(written.back()));
  for (auto& l : doc["lights"])
    if (l.contains("shadow")) l["shadow"]["resolution"] = 64;
  doc["lights"][1]["shadow"]["filter"] = "evsm";  // the lamp (spot)
  doc["lights"][1]["shadow"]["evsm_blur"] = 2;
  const fs::path scene = dir / "evsm_bake.json";
  std::ofstream(scene) << doc.dump(1);
  const fs::path exr = dir / "out.exr";
  std::string out;
  ASSERT_EQ(test::runCli("bake " + test::quote(scene) + " -o " + test::quote(exr) + " --backend cpu --evsm-moments", out), 0) << out;
  auto input = OIIO::ImageInput::open(exr.string());
  ASSERT_TRUE(input);
  int withMoments = 0;
  for (int sub = 0; input->seek_subimage(sub, 0); ++sub) {
    const OIIO::ImageSpec& spec = input->spec();
    const std::string name = spec.get_string_attribute("voxshadow:view");
    if (name != "lamp") {
      EXPECT_EQ(spec.nchannels, 1) << name;
      continue;
    }
    ++withMoments;
    ASSERT_EQ(spec.nchannels, 5);
    // OpenEXR keeps channels sorted by name: find each by its name.
    auto channel = [&](const std::string& c) {
      const auto it = std::find(spec.channelnames.begin(), spec.channelnames.end(), c);
      return it == spec.channelnames.end() ? -1 : int(it - spec.channelnames.begin());
    };
    const int z = channel("Z");
    const int m[4] = {channel("evsm.p"), channel("evsm.p2"), channel("evsm.n"), channel("evsm.n2")};
    ASSERT_GE(z, 0);
    for (int c : m) ASSERT_GE(c, 0);
    EXPECT_EQ(spec.get_int_attribute("voxshadow:evsmBlur"), 2);
    const int n = spec.width, r = 2;
    std::vector<float> px(std::size_t(n) * std::size_t(n) * 5);
    ASSERT_TRUE(input->read_image(sub, 0, 0, 5, OIIO::TypeDesc::FLOAT, px.data()));
    const double range = spec.get_float_attribute("voxshadow:range");
    double worst = 0.0;
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        glm::dvec4 sum(0.0);
        for (int dy = -r; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            const int cx = std::clamp(x + dx, 0, n - 1), cy = std::clamp(y + dy, 0, n - 1);
            const double t =
                std::clamp(double(px[(std::size_t(cy) * n + std::size_t(cx)) * 5 + std::size_t(z)]) / range, 0.0, 1.0) * 2.0 - 1.0;
            const double p = std::exp(40.0 * t), m = -std::exp(-8.0 * t);
            sum += glm::dvec4(p, p * p, m, m * m);
          }
        sum /= double((2 * r + 1) * (2 * r + 1));
        for (int c = 0; c < 4; ++c)
          worst = std::max(worst, std::abs(double(px[(std::size_t(y) * n + std::size_t(x)) * 5 + std::size_t(m[c])]) - sum[c]) /
                                      std::abs(sum[c]));
      }
    // The float warp rounds t to 6e-8, which the exponent (40, doubled in p^2) turns into ~5e-6 relative.
    EXPECT_LT(worst, 5e-5) << "moments against a box over the EXR's depths";
    std::printf("baked moments of %s against a box over its depths in double: largest relative difference %.2e\n",
                name.c_str(), worst);
  }
  EXPECT_EQ(withMoments, 1);
  const nlohmann::json sidecar = nlohmann::json::parse(std::ifstream(dir / "out.exr.json"));
  int sidecarMoments = 0;
  for (const auto& v : sidecar["views"])
    if (v.contains("evsm")) {
      ++sidecarMoments;
      EXPECT_EQ(v["evsm"]["blur"], 2);
      EXPECT_EQ(v["evsm"]["channels"][0], "evsm.p");
    }
  EXPECT_EQ(sidecarMoments, 1);
  // Two shards merged with the moments: the very files of the single bake.
  ASSERT_EQ(test::runCli("bake " + test::quote(scene) + " --shards 2 --parts " + test::quote(dir / "parts") + " -o " +
                             test::quote(dir / "sharded.exr") + " --backend cpu --evsm-moments", out), 0) << out;
  auto bytes = [](const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(bytes(dir / "sharded.exr"), bytes(exr));
  EXPECT_EQ(bytes(dir / "sharded.exr.json"), bytes(dir / "out.exr.json"));
  // Refusals: exit 2, nothing written.
  EXPECT_EQ(test::runCli("bake " + test::quote(written.back()) + " -o " + test::quote(dir / "no.exr") +
                             " --backend cpu --evsm-moments", out), 2) << out;
  EXPECT_TRUE(test::contains(out, "no light's shadow.filter is \"evsm\"")) << out;
  EXPECT_EQ(test::runCli("bake " + test::quote(scene) + " --shard 0/2 -o " + test::quote(dir / "p.vspart") +
                             " --backend cpu --evsm-moments", out), 2) << out;
  EXPECT_TRUE(test::contains(out, "--evsm-moments: a shard holds part of a layer")) << out;
  EXPECT_FALSE(fs::exists(dir / "no.exr"));
  EXPECT_FALSE(fs::exists(dir / "p.vspart"));
}
