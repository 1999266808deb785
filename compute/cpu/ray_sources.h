// ray_sources.h: what the CPU drivers (compute/cpu/tile_tracer.h, compute/cpu/lane_tracer.h) trace and where the
// results go, one type per ray kind. A driver decides how rays walk (interleaved, in SIMD lanes); a source
// decides what a ray is and what its result is, through the shared functions of compute/shared/traverse.h, so
// that each ray kind is written once for every driver. A source provides:
//   bool next(SceneArrays&, WorldRay& ray, Target& target)  the next ray and where its result goes; false at the end
//   void finish(SceneArrays&, const Target&, const WorldRay&, bool hit, float t, uint32_t instance, ivec3 voxel)
//        a finished ray: whether it hit, and the closest hit's world t, instance and voxel
//   void traceAlone(SceneArrays&, const Target&, const WorldRay&)  a ray the driver does not take (too many
//        candidate instances): the reference traversal gives its result
//   kAnyHit  true when the first hit found ends the ray (any-hit rays)
#ifndef VOXSHADOW_RAY_SOURCES_H
#define VOXSHADOW_RAY_SOURCES_H

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "compute/cpu/scene_arrays.h"

namespace vs {

// A texel rectangle [x0, x1) x [y0, y1) of view `view`.
struct TexelTile {
  int view, x0, y0, x1, y1;
};

namespace rays {

using WorldRay = gpu::SceneArrays::WorldRay;

// Shadow texels of a run of tiles, in order, into layers[tile.view] (row stride: the layer's width).
struct TexelSource {
  struct Target {
    const gpu::TraceView* view;
    float* texel;
  };
  static constexpr bool kAnyHit = false;

  std::span<const gpu::TraceView> views;
  std::span<const TexelTile> tiles;
  std::vector<ShadowLayer>* layers;
  std::size_t tile = 0;
  int x = 0, y = 0;
  bool started = false;

  TexelSource(std::span<const gpu::TraceView> v, std::span<const TexelTile> t, std::vector<ShadowLayer>& l)
      : views(v), tiles(t), layers(&l) {}

  bool next(gpu::SceneArrays& arrays, WorldRay& ray, Target& target) {
    while (tile < tiles.size()) {
      const TexelTile& t = tiles[tile];
      if (!started) {
        x = t.x0;
        y = t.y0;
        started = true;
      }
      if (y < t.y1 && x < t.x1) {
        const gpu::TraceView& view = views[std::size_t(t.view)];
        ShadowLayer& layer = (*layers)[std::size_t(t.view)];
        target.view = &view;
        target.texel = &layer.texels[std::size_t(y) * std::size_t(layer.width) + std::size_t(x)];
        arrays.vsViewRay(view, glm::ivec2(x, y), ray);
        if (++x == t.x1) {
          x = t.x0;
          ++y;
        }
        return true;
      }
      ++tile;
      started = false;
    }
    return false;
  }
  void finish(gpu::SceneArrays& arrays, const Target& target, const WorldRay& ray, bool hit, float t,
              std::uint32_t instance, glm::ivec3 voxel) const {
    *target.texel = arrays.vsTexelValue(*target.view, ray, hit, t, instance, voxel);
  }
  void traceAlone(gpu::SceneArrays& arrays, const Target& target, const WorldRay& ray) const {
    float tHit = ray.tMax;
    std::uint32_t instance = 0u;
    glm::ivec3 voxel(0);
    bool hit = arrays.vsRayIsFinite(ray) && arrays.vsTraceClosest(ray, tHit, instance, voxel);
    finish(arrays, target, ray, hit, tHit, instance, voxel);
  }
};

// Caller-given rays [begin, end) of `rays`, and where each one's result goes (the same index of the output).
struct RayRange {
  struct Target {
    std::size_t index;
  };
  std::span<const gpu::TraceRay> rays;
  std::size_t cursor = 0, end = 0;

  bool next(gpu::SceneArrays& arrays, WorldRay& ray, Target& target) {
    if (cursor >= end) return false;
    target.index = cursor;
    ray = arrays.vsTraceRayToWorld(rays[cursor++]);
    return true;
  }
};

// Closest-hit rays into their hit records.
struct ClosestSource : RayRange {
  static constexpr bool kAnyHit = false;
  gpu::RayHit* hits = nullptr;

  void finish(gpu::SceneArrays& arrays, const Target& target, const WorldRay& ray, bool hit, float t,
              std::uint32_t instance, glm::ivec3 voxel) const {
    hits[target.index] = arrays.vsHitRecord(ray, hit, t, instance, voxel);
  }
  void traceAlone(gpu::SceneArrays& arrays, const Target& target, const WorldRay& ray) const {
    hits[target.index] = arrays.vsClosestHit(ray);
  }
};

// Any-hit rays into one word each: 1 where the segment holds a solid voxel.
struct AnySource : RayRange {
  static constexpr bool kAnyHit = true;
  std::uint32_t* occluded = nullptr;

  void finish(gpu::SceneArrays&, const Target& target, const WorldRay&, bool hit, float, std::uint32_t,
              glm::ivec3) const {
    occluded[target.index] = hit ? 1u : 0u;
  }
  void traceAlone(gpu::SceneArrays& arrays, const Target& target, const WorldRay& ray) const {
    occluded[target.index] = arrays.vsAnyHit(ray) ? 1u : 0u;
  }
};

}  // namespace rays
}  // namespace vs

#endif
