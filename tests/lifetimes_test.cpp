// Lifetimes in a frame loop (DESIGN.md §11), on both backends: a tracer keeps the arrays of a scene destroyed
// after it was bound; a renderer given another scene renders that scene whole, never a mix of the two; a
// tracer destroyed before its renderer makes render() a vs::Error, and the renderer still goes away cleanly; a
// copied Scene is a scene of its own.
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/renderer.h"
#include "lighting/scene.h"
#include "lighting/scene_file.h"
#include "support/demo_frames.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace vs {
namespace {

const char* const kBackends[] = {"cpu", "vulkan"};

using test::demoScene;
using test::expectNoValidationMessages;
using test::sameBytes;

RenderOptions smallFrame() {
  RenderOptions o;
  o.width = 120;
  o.height = 68;
  return o;
}

std::unique_ptr<Tracer> tracerFor(const std::string& backend) {
  if (backend == "cpu") return makeCpuTracer({CpuTracePath::Interleaved, 2});
  VulkanOptions o;
  o.validation = true;
  return makeVulkanTracer(o);  // no device: fails here, loudly
}

// The frame and layers `kept` rendered are what a new renderer on a tracer of its own gives for `scene`.
void expectSameAsNewRenderer(const Scene& scene, const FrameRenderer& kept, const RenderedFrame& frame,
                             const std::string& backend, const std::string& what) {
  std::unique_ptr<Tracer> tracer = tracerFor(backend);
  FrameRenderer fresh(*tracer);
  const RenderedFrame& truth = fresh.render(scene, smallFrame());
  EXPECT_TRUE(sameBytes(frame.color, truth.color)) << backend << ", " << what << ": colour";
  EXPECT_TRUE(sameBytes(frame.gbuffer.texels, truth.gbuffer.texels)) << backend << ", " << what << ": G-buffer";
  EXPECT_TRUE(sameBytes(frame.shadowTerms, truth.shadowTerms)) << backend << ", " << what << ": shadow terms";
  const std::vector<ShadowLayer> a = kept.layers(), b = fresh.layers();
  ASSERT_EQ(a.size(), b.size()) << backend << ", " << what;
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_TRUE(sameBytes(a[i].texels, b[i].texels)) << backend << ", " << what << ": layer " << i;
}

// Tracing the views of a frame whose scene is gone reads the arrays the tracer keeps: the texels equal those
// traced while the scene lived. Before the tracer shared the arrays, the CPU tracer read freed memory here.
TEST(Lifetimes, ATracerKeepsTheArraysOfASceneDestroyedAfterItWasBound) {
  for (const std::string backend : kBackends) {
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    std::vector<gpu::TraceView> views;
    std::vector<ShadowLayer> before, after;
    {
      Scene scene = demoScene("lifetimes_destroyed_" + backend, 64, 0.0f);
      tracer->setScene(scene.sharedData());
      FrameRenderer renderer(*tracer);
      for (const LightView& v : renderer.render(scene, smallFrame()).views) views.push_back(v.trace);
      tracer->traceShadow(views, before);
    }
    tracer->traceShadow(views, after);
    ASSERT_EQ(before.size(), after.size());
    for (std::size_t i = 0; i < before.size(); ++i)
      EXPECT_TRUE(sameBytes(before[i].texels, after[i].texels)) << backend << ": view " << i;
    expectNoValidationMessages(*tracer);
  }
}

// One renderer, two scenes, taken in turns, and one of them destroyed between frames: every frame is that of
// the scene given, whole, as a new renderer draws it (before, the second scene's camera came over the first
// scene's geometry).
TEST(Lifetimes, ARendererGivenAnotherSceneRendersItWholeNeverAMix) {
  for (const std::string backend : kBackends) {
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    FrameRenderer renderer(*tracer);
    const Scene second = demoScene("lifetimes_second_" + backend, 32, 6.0f);
    {
      const Scene first = demoScene("lifetimes_first_" + backend, 64, 0.0f);
      for (int turn = 0; turn < 2; ++turn) {
        expectSameAsNewRenderer(first, renderer, renderer.render(first, smallFrame()), backend,
                                "the first scene, turn " + std::to_string(turn));
        const RenderedFrame& frame = renderer.render(second, smallFrame());
        EXPECT_TRUE(frame.stats.full) << backend << ": another scene is rendered whole";
        expectSameAsNewRenderer(second, renderer, frame, backend, "the second scene, turn " + std::to_string(turn));
      }
      renderer.render(first, smallFrame());
    }
    // The first scene is gone; the renderer last drew it.
    expectSameAsNewRenderer(second, renderer, renderer.render(second, smallFrame()), backend,
                            "the second scene after the first was destroyed");
    expectNoValidationMessages(*tracer);
  }
}

// A tracer destroyed before its renderer: render() refuses with vs::Error(Runtime) (before, Vulkan aborted),
// again on a second call, and the renderer is destroyed without harm afterwards.
TEST(Lifetimes, ATracerDestroyedBeforeItsRendererMakesRenderAnError) {
  for (const std::string backend : kBackends) {
    const Scene scene = demoScene("lifetimes_tracer_" + backend, 32, 0.0f);
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    std::optional<FrameRenderer> renderer(std::in_place, *tracer);
    renderer->render(scene, smallFrame());
    tracer.reset();
    for (int call = 0; call < 2; ++call) {
      try {
        renderer->render(scene, smallFrame());
        ADD_FAILURE() << backend << ": render() on a destroyed tracer returned";
      } catch (const Error& e) {
        EXPECT_EQ(e.kind(), ErrorKind::Runtime) << backend;
        EXPECT_NE(std::string(e.what()).find("tracer was destroyed"), std::string::npos) << e.what();
      }
    }
    renderer.reset();
  }
}

// A copy of a Scene has its own arrays and id: changing the copy changes nothing of the original, and one
// renderer given both in turns draws each as a new renderer does.
TEST(Lifetimes, ACopiedSceneIsASceneOfItsOwn) {
  for (const std::string backend : kBackends) {
    const Scene original = demoScene("lifetimes_copy_" + backend, 64, 0.0f);
    Scene copy = original;
    EXPECT_NE(copy.id(), original.id());
    EXPECT_NE(copy.sharedData(), original.sharedData());
    const SceneData before = original.data();
    const std::uint64_t solid = original.objects()[0].brickmap.solidCount();
    // Digs out a corner of the first object (the demo's ground, solid there).
    const VoxelBox bounds = copy.objects()[0].brickmap.bounds();
    copy.fillVoxels(0, VoxelBox{bounds.min, glm::min(bounds.max, bounds.min + 8)}, 0);
    EXPECT_LT(copy.objects()[0].brickmap.solidCount(), solid) << "the edit changed nothing: the test shows nothing";
    EXPECT_EQ(original.objects()[0].brickmap.solidCount(), solid) << "an edit of the copy changed the original";
    const SceneData& after = original.data();
    EXPECT_TRUE(sameBytes(before.bricks, after.bricks) && sameBytes(before.sectors, after.sectors) &&
                sameBytes(before.occupancy, after.occupancy) && sameBytes(before.regions, after.regions))
        << "an edit of the copy changed the original's arrays";
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    FrameRenderer renderer(*tracer);
    for (int turn = 0; turn < 2; ++turn) {
      expectSameAsNewRenderer(original, renderer, renderer.render(original, smallFrame()), backend, "the original");
      expectSameAsNewRenderer(copy, renderer, renderer.render(copy, smallFrame()), backend, "the edited copy");
    }
    expectNoValidationMessages(*tracer);
  }
}

}  // namespace
}  // namespace vs
