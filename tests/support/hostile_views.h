// hostile_views.h: trace views whose rays are not finite (NaN or infinite matrix entries or origins) or are
// absurdly far, as a library user could hand them over; every tracer must treat their texels as misses.
#ifndef VOXSHADOW_HOSTILE_VIEWS_H
#define VOXSHADOW_HOSTILE_VIEWS_H

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "compute/cpu/cpu_tracer.h"
#include "support/test_scenes.h"

namespace vs::test {

// Views over `bounds`, each with the value every one of its texels must hold: the view's miss value, or
// NaN where the miss value itself is not finite (compare those with isnan).
struct HostileView {
  gpu::TraceView view;
  float miss;
};

inline std::vector<HostileView> hostileViews(const Aabb& bounds) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  glm::vec3 c = (bounds.min + bounds.max) * 0.5f;
  std::vector<HostileView> out;
  gpu::TraceView v = directionalView(bounds, {-0.4f, -1.0f, -0.3f}, 24);
  v.clipToEye[0][0] = nan;
  out.push_back({v, 1.0f});
  v = directionalView(bounds, {0.0f, -1.0f, 0.0f}, 24);
  v.clipToEye[3][1] = inf;
  out.push_back({v, 1.0f});
  v = distanceView(c + glm::vec3(0, 30, 0), {0, -1, 0}, 100.0f, 16);
  v.eyeHigh.x = inf;
  out.push_back({v, 100.0f});
  v = distanceView(c + glm::vec3(0, 30, 0), {0, -1, 0}, 100.0f, 16);
  v.eyeHigh = glm::vec4(1e30f, -1e30f, 1e30f, 100.0f);
  out.push_back({v, 100.0f});
  v = distanceView(c + glm::vec3(0, 30, 0), {0, -1, 0}, 100.0f, 16);
  v.eyeHigh.w = nan;
  out.push_back({v, nan});
  return out;
}

// The trace records of hostile views.
inline std::vector<gpu::TraceView> traceViewsOf(const std::vector<HostileView>& hostile) {
  std::vector<gpu::TraceView> views;
  for (const auto& h : hostile) views.push_back(h.view);
  return views;
}

// The scenes the hostile views are traced over: one instance (the single-instance lane driver) and many.
inline std::vector<TestScene> hostileViewScenes() {
  std::vector<TestScene> scenes;
  scenes.push_back(floorScene());
  scenes.push_back(manyInstancesScene(40));
  return scenes;
}

// Every texel of each layer holds its view's miss value (NaN where that is NaN).
inline void expectAllMisses(const std::vector<HostileView>& hostile, const std::vector<ShadowLayer>& layers) {
  ASSERT_EQ(layers.size(), hostile.size());
  for (std::size_t i = 0; i < hostile.size(); ++i)
    for (float t : layers[i].texels) {
      if (std::isnan(hostile[i].miss)) ASSERT_TRUE(std::isnan(t)) << "view " << i;
      else ASSERT_EQ(t, hostile[i].miss) << "view " << i;
    }
}

}  // namespace vs::test

#endif
