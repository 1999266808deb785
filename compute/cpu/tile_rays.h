// tile_rays.h: one texel ray of a CPU tile path and its instance candidates (compute/cpu/tile_tracer.cpp,
// compute/cpu/lane_tracer.cpp). A ray visits the instances whose world boxes it enters, nearest entry first,
// each with the portable object walk (compute/shared/traverse.h), keeping the reference's closest-hit rule.
#ifndef VOXSHADOW_TILE_RAYS_H
#define VOXSHADOW_TILE_RAYS_H

#include <algorithm>
#include <array>
#include <cstdint>

#include "compute/cpu/scene_arrays.h"

namespace vs::tile {

// Instances one ray of a tile may visit; a ray whose path crosses more boxes than this is traced by the
// reference traversal instead (same result, no interleaving).
constexpr int kMaxCandidates = 8;

struct Candidate {
  float entry;  // t where the ray enters the instance's world box (grown by vsCullPad)
  std::uint32_t instance;
};

using WorldRay = gpu::SceneArrays::WorldRay;

struct RayState {
  WorldRay ray;
  glm::vec3 cullOrigin;  // vsCullOrigin(ray)
  float cullPad;         // vsCullPad(ray)
  float tBest;
  bool hit;
  std::uint32_t instanceHit;
  glm::ivec3 voxel;
  std::uint32_t walkingInstance;
  float walkBase;  // the walking instance's vsInstanceBaseT: its walk's t is relative to it
  int candidateCount;
  int nextCandidate;
  std::array<Candidate, kMaxCandidates> candidates;
  gpu::SceneArrays::ObjectWalk walk;
};

// A ray's search state for r.ray: no hit yet, no candidates.
inline void resetRay(RayState& r) {
  r.tBest = r.ray.tMax;
  r.hit = false;
  r.instanceHit = 0u;
  r.voxel = glm::ivec3(0);
  r.candidateCount = 0;
  r.nextCandidate = 0;
}

// Starts a ray's state: its culling origin and pad, no hit yet, no candidates.
inline void beginRay(gpu::SceneArrays& arrays, RayState& r, const WorldRay& ray) {
  r.ray = ray;
  r.cullOrigin = arrays.vsCullOrigin(ray);
  r.cullPad = arrays.vsCullPad(ray);
  resetRay(r);
}

// The order in which a ray visits its candidates: nearest entry first, ties by instance index.
inline void sortCandidates(RayState& r) {
  std::sort(r.candidates.begin(), r.candidates.begin() + r.candidateCount, [](const Candidate& a, const Candidate& b) {
    return a.entry < b.entry || (a.entry == b.entry && a.instance < b.instance);
  });
}

// Instances whose world boxes the ray enters within [tMin, tMax], in order of entry, found by the portable
// stackless BVH walk; false when there are more than kMaxCandidates.
inline bool collectCandidates(gpu::SceneArrays& arrays, RayState& r) {
  r.candidateCount = 0;
  // A non-finite ray is a miss (vsShadowTexel gives its texel); it must never reach the walk's integer cells.
  if (!arrays.vsRayIsFinite(r.ray)) return false;
  const WorldRay& ray = r.ray;
  std::uint32_t node = 0u, entry = 0u, entryEnd = 0u;
  while (arrays.vsNextLeafEntry(r.cullOrigin, ray.d, r.cullPad, ray.tMin, ray.tMax, node, entry, entryEnd)) {
    std::uint32_t instance = arrays.instanceIndices[entry++];
    float t = arrays.vsInstanceEntry(ray, instance);
    if (t == gpu::VS_T_INFINITY) continue;
    if (r.candidateCount == kMaxCandidates) return false;
    r.candidates[r.candidateCount++] = {t, instance};
  }
  sortCandidates(r);
  return true;
}

// Starts the walk through the next instance that could still hold a closer hit; false when none is left.
inline bool beginNextWalk(gpu::SceneArrays& arrays, RayState& r) {
  while (r.nextCandidate < r.candidateCount) {
    const Candidate& c = r.candidates[r.nextCandidate++];
    if (c.entry > r.tBest) return false;  // sorted by entry: no later box starts before the best hit
    const gpu::InstanceRecord& rec = arrays.instances[c.instance];
    float tBase = arrays.vsBaseT(r.ray, c.entry);  // c.entry is vsInstanceEntry
    glm::vec3 lo, ld;
    arrays.vsInstanceRay(r.ray, c.instance, tBase, lo, ld);
    if (arrays.vsObjectWalkBegin(rec.info.x, lo, ld, arrays.vsLocalT(r.ray.tMin, tBase),
                                 arrays.vsWalkEnd(r.hit, r.tBest, r.ray.tMax, tBase), r.walk)) {
      r.walkingInstance = c.instance;
      r.walkBase = tBase;
      return true;
    }
  }
  return false;
}

// A walk's hit (t relative to the walk's base), kept when vsCloserHit says so.
inline void recordHit(gpu::SceneArrays& arrays, RayState& r, float tLocal, glm::ivec3 voxel) {
  float t = arrays.vsWorldT(tLocal, r.walkBase);
  if (arrays.vsCloserHit(r.hit, t, r.walkingInstance, r.tBest, r.instanceHit)) {
    r.tBest = t;
    r.instanceHit = r.walkingInstance;
    r.voxel = voxel;
  }
  r.hit = true;
}

}  // namespace vs::tile

#endif
