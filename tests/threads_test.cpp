// Threads (README "Threads"), on both backends: renderers on several threads sharing one tracer render their
// own scenes exactly as alone; calls to one Tracer from several threads give what they give one at a time;
// what is not allowed (one renderer, one VulkanTracer or one scene used by two threads at once) is refused
// with vs::Error and never crashes; a frame's host work runs on the tracer's host threads.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <tbb/task_arena.h>

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

const char* const kBackends[] = {"cpu", "vulkan"};

// The demo scene with small layers, its camera stepped by `cameraStep` along x: scenes with other steps give
// other frames.
Scene demoScene(const std::string& dir, float cameraStep) { return test::demoScene(dir, 128, cameraStep); }

using test::expectNoValidationMessages;

RenderOptions smallFrame() {
  RenderOptions o;
  o.width = 96;
  o.height = 54;
  return o;
}

std::unique_ptr<Tracer> tracerFor(const std::string& backend, int hostThreads = 2) {
  if (backend == "cpu") return makeCpuTracer({CpuTracePath::Interleaved, hostThreads});
  VulkanOptions o;
  o.validation = true;
  o.hostThreads = hostThreads;
  return makeVulkanTracer(o);  // no device: fails here, loudly
}

bool sameColor(const RenderedFrame& a, const RenderedFrame& b) {
  return a.color.size() == b.color.size() &&
         std::memcmp(a.color.data(), b.color.data(), a.color.size() * sizeof(glm::vec4)) == 0;
}

// Moves the camera of `scene` by `step` along x (a frame loop's change between frames).
void stepCamera(Scene& scene, float step) {
  CameraDesc camera = *scene.desc().camera;
  camera.position.x += step;
  camera.target.x += step;
  scene.setCamera(camera);
}

bool refusedAsBusy(const Error& e) {
  return e.kind() == ErrorKind::Runtime && std::string(e.what()).find("another thread") != std::string::npos;
}

// Two threads, each with its own scene and renderer, both renderers on one tracer; each steps its camera and
// renders kFrames frames, and every frame equals the frame a renderer alone (its own tracer, one thread) gives
// for the same scene. Unguarded, one renderer's traces would run on the other's scene binding.
TEST(Threads, RenderersOnTwoThreadsShareOneTracer) {
  constexpr int kFrames = 4;
  constexpr float kSteps[2] = {0.0f, 9.0f};
  for (const char* backend : kBackends) {
    SCOPED_TRACE(backend);
    // What each thread must get, frame by frame, rendered alone.
    std::vector<RenderedFrame> expected[2];
    for (int t = 0; t < 2; ++t) {
      Scene scene = demoScene(std::string("threads_share_ref_") + backend, kSteps[t]);
      std::unique_ptr<Tracer> tracer = tracerFor(backend);
      FrameRenderer alone(*tracer);
      for (int f = 0; f < kFrames; ++f) {
        expected[t].push_back(alone.render(scene, smallFrame()));
        stepCamera(scene, 0.75f);
      }
    }

    std::unique_ptr<Tracer> shared = tracerFor(backend);
    Scene scenes[2] = {demoScene(std::string("threads_share_a_") + backend, kSteps[0]),
                       demoScene(std::string("threads_share_b_") + backend, kSteps[1])};
    std::atomic<int> different{0}, failed{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 2; ++t)
      threads.emplace_back([&, t] {
        try {
          FrameRenderer renderer(*shared);
          for (int f = 0; f < kFrames; ++f) {
            if (!sameColor(renderer.render(scenes[t], smallFrame()), expected[t][std::size_t(f)])) ++different;
            stepCamera(scenes[t], 0.75f);
          }
        } catch (const std::exception& e) {
          ADD_FAILURE() << "thread " << t << ": " << e.what();
          ++failed;
        }
      });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(failed.load(), 0);
    EXPECT_EQ(different.load(), 0) << "frames that differ from a renderer alone";
    expectNoValidationMessages(*shared);
  }
}

// Four threads trace their own batches of closest-hit and any-hit rays through one Tracer at once, many
// times; every answer equals the one-thread answer.
TEST(Threads, TracerCallsFromSeveralThreadsRunOneAfterAnother) {
  const Scene scene = demoScene("threads_calls", 0.0f);
  const Aabb bounds = scene.data().worldBounds;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<gpu::TraceRay> rays;
  for (int k = 0; k < 4096; ++k) {
    const glm::dvec3 from(bounds.min.x + u(rng) * (bounds.max.x - bounds.min.x), bounds.max.y + 2.0,
                          bounds.min.z + u(rng) * (bounds.max.z - bounds.min.z));
    const glm::dvec3 dir = glm::normalize(glm::dvec3(u(rng) - 0.5, -1.0, u(rng) - 0.5));
    rays.push_back(gpu::makeTraceRay(from, dir, 0.0f, 1.0e4f));
  }
  for (const char* backend : kBackends) {
    SCOPED_TRACE(backend);
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    tracer->setScene(scene.sharedData());
    std::vector<gpu::RayHit> hits(rays.size());
    std::vector<std::uint32_t> occluded(rays.size());
    tracer->traceClosest(rays, hits);
    tracer->traceAny(rays, occluded);
    std::size_t hitCount = 0;
    for (const gpu::RayHit& h : hits) hitCount += h.hit != 0;
    ASSERT_GT(hitCount, 0u);

    std::atomic<int> different{0}, failed{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
      threads.emplace_back([&, t] {
        try {
          std::vector<gpu::RayHit> mine(rays.size());
          std::vector<std::uint32_t> mineAny(rays.size());
          for (int round = 0; round < 6; ++round) {
            if ((round + t) % 2 == 0) {
              tracer->traceClosest(rays, mine);
              if (std::memcmp(mine.data(), hits.data(), hits.size() * sizeof(gpu::RayHit)) != 0) ++different;
            } else {
              tracer->traceAny(rays, mineAny);
              if (mineAny != occluded) ++different;
            }
          }
        } catch (const std::exception& e) {
          ADD_FAILURE() << "thread " << t << ": " << e.what();
          ++failed;
        }
      });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(failed.load(), 0);
    EXPECT_EQ(different.load(), 0);
    expectNoValidationMessages(*tracer);
  }
}

// Runs `first` on a thread of its own while this thread calls `second` again and again until `first` returns;
// returns how many of `second`'s calls were refused as busy. Every other outcome of either is a failure.
template <class First, class Second>
int refusalsWhileRunning(First&& first, Second&& second) {
  std::atomic<bool> done{false};
  std::atomic<int> refusedFirst{0};
  std::thread runner([&] {
    try {
      first();
    } catch (const Error& e) {
      if (refusedAsBusy(e)) ++refusedFirst;
      else ADD_FAILURE() << "first: " << e.what();
    }
    done = true;
  });
  int refused = 0;
  while (!done) {
    try {
      second();
    } catch (const Error& e) {
      if (refusedAsBusy(e)) ++refused;
      else ADD_FAILURE() << "second: " << e.what();
    }
  }
  runner.join();
  return refused + refusedFirst;
}

// One renderer used by two threads at once: the second call is refused (vs::Error naming the other thread),
// nothing crashes, and the renderer's frames stay right.
TEST(Threads, OneRendererUsedByTwoThreadsRefusesTheSecondCall) {
  for (const char* backend : kBackends) {
    SCOPED_TRACE(backend);
    Scene scene = demoScene(std::string("threads_one_renderer_") + backend, 0.0f);
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    FrameRenderer renderer(*tracer);
    std::unique_ptr<Tracer> aloneTracer = tracerFor(backend);
    FrameRenderer alone(*aloneTracer);
    const RenderedFrame expected = alone.render(scene, smallFrame());

    std::atomic<int> wrong{0};
    const int refused = refusalsWhileRunning(
        [&] {
          for (int f = 0; f < 6; ++f) {
            renderer.invalidateLayers();
            if (!sameColor(renderer.render(scene, smallFrame()), expected)) ++wrong;
          }
        },
        [&] { (void)renderer.layers(); });
    EXPECT_GT(refused, 0) << "no call was refused while another ran";
    EXPECT_EQ(wrong.load(), 0);
    // Still usable, and right, afterwards.
    renderer.invalidateLayers();
    EXPECT_TRUE(sameColor(renderer.render(scene, smallFrame()), expected));
    expectNoValidationMessages(*tracer);
  }
}

// A VulkanTracer used directly by two threads at once: the second call is refused before it touches anything.
TEST(Threads, OneVulkanTracerUsedDirectlyByTwoThreadsRefusesTheSecondCall) {
  const Scene scene = demoScene("threads_direct_vulkan", 0.0f);
  std::unique_ptr<Tracer> tracer = tracerFor("vulkan");
  tracer->setScene(scene.sharedData());
  VulkanTracer& direct = *tracer->vulkan();
  std::vector<ShadowLayer> expected;
  std::vector<gpu::TraceView> views;
  for (const LightView& v : scene.lightViews()) views.push_back(v.trace);
  direct.trace(views, expected);

  std::atomic<int> wrong{0};
  std::vector<ShadowLayer> mine, theirs;
  const int refused = refusalsWhileRunning(
      [&] {
        for (int r = 0; r < 8; ++r) {
          direct.trace(views, mine);
          for (std::size_t i = 0; i < views.size(); ++i)
            if (mine[i].texels != expected[i].texels) ++wrong;
        }
      },
      [&] { direct.trace(views, theirs); });
  EXPECT_GT(refused, 0) << "no call was refused while another ran";
  EXPECT_EQ(wrong.load(), 0);
  expectNoValidationMessages(*tracer);
}

// A scene changed while another thread renders it: the change is refused (nothing changed) or, when the change
// runs first, the render is; never a crash or a frame of a half-changed scene. Afterwards the renderer's frame
// equals a new renderer's.
TEST(Threads, ASceneChangedWhileRenderedIsRefused) {
  for (const char* backend : kBackends) {
    SCOPED_TRACE(backend);
    Scene scene = demoScene(std::string("threads_scene_") + backend, 0.0f);
    std::unique_ptr<Tracer> tracer = tracerFor(backend);
    FrameRenderer renderer(*tracer);
    const CameraDesc camera = *scene.desc().camera;
    std::atomic<int> refusedChanges{0}, refusedRenders{0};
    const int refused = refusalsWhileRunning(
        [&] {
          // Six whole frames; a render that finds a change running is refused and tried again.
          for (int frames = 0; frames < 6;) {
            try {
              renderer.invalidateLayers();
              (void)renderer.render(scene, smallFrame());
              ++frames;
            } catch (const Error& e) {
              if (!refusedAsBusy(e)) throw;
              ++refusedRenders;
            }
          }
        },
        [&] {
          // Leave the renders room to start.
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
          const std::uint64_t before = scene.revision();
          try {
            scene.setCamera(camera);
          } catch (const Error& e) {
            EXPECT_EQ(scene.revision(), before) << "a refused change changed the scene";
            if (refusedAsBusy(e)) ++refusedChanges;
            throw;
          }
        });
    std::printf("%s: %d changes and %d renders refused\n", backend, refusedChanges.load(), refusedRenders.load());
    EXPECT_GT(refused, 0);
    EXPECT_GT(refusedChanges.load(), 0) << "no change was refused while the scene was rendered";
    const RenderedFrame& kept = renderer.render(scene, smallFrame());
    std::unique_ptr<Tracer> freshTracer = tracerFor(backend);
    FrameRenderer fresh(*freshTracer);
    EXPECT_TRUE(sameColor(kept, fresh.render(scene, smallFrame())));
    expectNoValidationMessages(*tracer);
  }
}

// A frame's host work runs on the tracer's host threads, else in the caller's arena.
TEST(Threads, HostWorkRunsOnTheTracersThreads) {
  for (const char* backend : kBackends) {
    SCOPED_TRACE(backend);
    Scene scene = demoScene(std::string("threads_host_") + backend, 0.0f);
    {
      std::unique_ptr<Tracer> tracer = tracerFor(backend, 1);
      FrameRenderer renderer(*tracer);
      EXPECT_EQ(renderer.render(scene, smallFrame()).stats.hostThreads, 1);
    }
    {
      std::unique_ptr<Tracer> tracer = tracerFor(backend, 0);
      FrameRenderer renderer(*tracer);
      tbb::task_arena callers(1);
      int threads = 0;
      callers.execute([&] { threads = renderer.render(scene, smallFrame()).stats.hostThreads; });
      EXPECT_EQ(threads, 1) << "the caller's one-thread arena";
      renderer.invalidateLayers();
      EXPECT_EQ(renderer.render(scene, smallFrame()).stats.hostThreads, tbb::this_task_arena::max_concurrency());
    }
  }
}

}  // namespace
}  // namespace vs
