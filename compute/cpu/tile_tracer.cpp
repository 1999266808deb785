#include "compute/cpu/tile_tracer.h"

#include <array>

#include "compute/cpu/tile_rays.h"

namespace vs {

template <class Source>
void traceInterleaved(gpu::SceneArrays& arrays, Source& source) {
  using Target = typename Source::Target;
  std::array<tile::RayState, kMaxTileRays> rays;
  std::array<Target, kMaxTileRays> targets;
  std::array<int, kMaxTileRays> active;
  auto finish = [&](int i) {
    const tile::RayState& r = rays[i];
    source.finish(arrays, targets[i], r.ray, r.hit, r.tBest, r.instanceHit, r.voxel);
  };
  for (bool more = true; more;) {
    int activeCount = 0;
    for (int i = 0; i < kMaxTileRays; ++i) {
      tile::RayState& r = rays[i];
      tile::WorldRay ray;
      if (!source.next(arrays, ray, targets[i])) {
        more = false;
        break;
      }
      tile::beginRay(arrays, r, ray);
      if (!tile::collectCandidates(arrays, r)) {
        source.traceAlone(arrays, targets[i], ray);
        continue;
      }
      if (tile::beginNextWalk(arrays, r)) {
        active[activeCount++] = i;
      } else {
        finish(i);
      }
    }
    while (activeCount > 0) {
      int kept = 0;
      for (int k = 0; k < activeCount; ++k) {
        int i = active[k];
        tile::RayState& r = rays[i];
        int status = arrays.vsObjectWalkStep(r.walk);
        if (status == gpu::VS_WALK_CONTINUE) {
          active[kept++] = i;
          continue;
        }
        if (status == gpu::VS_WALK_HIT) tile::recordHit(arrays, r, r.walk.tEnter, r.walk.v);
        if (!(Source::kAnyHit && r.hit) && tile::beginNextWalk(arrays, r)) {
          active[kept++] = i;
        } else {
          finish(i);
        }
      }
      activeCount = kept;
    }
  }
}

template void traceInterleaved<rays::TexelSource>(gpu::SceneArrays&, rays::TexelSource&);
template void traceInterleaved<rays::ClosestSource>(gpu::SceneArrays&, rays::ClosestSource&);
template void traceInterleaved<rays::AnySource>(gpu::SceneArrays&, rays::AnySource&);

}  // namespace vs
