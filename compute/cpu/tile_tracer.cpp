#include "compute/cpu/tile_tracer.h"

#include <algorithm>
#include <array>

#include "compute/cpu/tile_rays.h"

namespace vs {

using tile::RayState;
using tile::beginNextWalk;
using tile::collectCandidates;

void traceTileInterleaved(gpu::SceneArrays& arrays, const gpu::TraceView& view, int x0, int y0, int x1, int y1,
                          float* texels, int stride) {
  std::array<RayState, kMaxTileRays> rays;
  std::array<int, kMaxTileRays> texelIndex;
  std::array<int, kMaxTileRays> active;
  int activeCount = 0;
  int count = 0;
  auto finish = [&](int i) {
    const RayState& r = rays[i];
    texels[texelIndex[i]] = tile::texelValue(arrays, view, r);
  };
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      int i = count++;
      RayState& r = rays[i];
      texelIndex[i] = y * stride + x;
      tile::WorldRay ray;
      arrays.vsViewRay(view, glm::ivec2(x, y), ray);
      tile::beginRay(arrays, r, ray);
      if (!collectCandidates(arrays, r)) {
        texels[texelIndex[i]] = arrays.vsShadowTexel(view, glm::ivec2(x, y));
        continue;
      }
      if (beginNextWalk(arrays, r)) {
        active[activeCount++] = i;
      } else {
        finish(i);
      }
    }
  }
  while (activeCount > 0) {
    int kept = 0;
    for (int k = 0; k < activeCount; ++k) {
      int i = active[k];
      RayState& r = rays[i];
      int status = arrays.vsObjectWalkStep(r.walk);
      if (status == gpu::VS_WALK_CONTINUE) {
        active[kept++] = i;
        continue;
      }
      if (status == gpu::VS_WALK_HIT) tile::recordHit(arrays, r, r.walk.tEnter, r.walk.v);
      if (beginNextWalk(arrays, r)) {
        active[kept++] = i;
      } else {
        finish(i);
      }
    }
    activeCount = kept;
  }
}

}  // namespace vs
