// hostile_views.h: trace views whose rays are not finite (NaN or infinite matrix entries or origins) or are
// absurdly far, as a library user could hand them over; every tracer must treat their texels as misses.
#ifndef VOXSHADOW_HOSTILE_VIEWS_H
#define VOXSHADOW_HOSTILE_VIEWS_H

#include <cmath>
#include <limits>
#include <vector>

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
  v.invViewProj[0][0] = nan;
  out.push_back({v, 1.0f});
  v = directionalView(bounds, {0.0f, -1.0f, 0.0f}, 24);
  v.invViewProj[3][1] = inf;
  out.push_back({v, 1.0f});
  v = distanceView(c + glm::vec3(0, 30, 0), {0, -1, 0}, 100.0f, 16);
  v.origin.x = inf;
  out.push_back({v, 100.0f});
  v = distanceView(c + glm::vec3(0, 30, 0), {0, -1, 0}, 100.0f, 16);
  v.origin = glm::vec4(1e30f, -1e30f, 1e30f, 100.0f);
  out.push_back({v, 100.0f});
  v = distanceView(c + glm::vec3(0, 30, 0), {0, -1, 0}, 100.0f, 16);
  v.origin.w = nan;
  out.push_back({v, nan});
  return out;
}

}  // namespace vs::test

#endif
