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
  float entry;  // t where the ray enters the instance's world box
  std::uint32_t instance;
};

struct RayState {
  glm::vec3 o, d;
  float tMax;
  float tBest;
  bool hit;
  std::uint32_t instanceHit;
  glm::ivec3 voxel;
  std::uint32_t walkingInstance;
  int candidateCount;
  int nextCandidate;
  std::array<Candidate, kMaxCandidates> candidates;
  gpu::SceneArrays::ObjectWalk walk;
};

// Instances whose world boxes the ray enters within [0, tMax], in order of entry; false when there are
// more than kMaxCandidates.
inline bool collectCandidates(gpu::SceneArrays& arrays, RayState& ray) {
  ray.candidateCount = 0;
  // A non-finite ray is a miss (vsShadowTexel gives its texel); it must never reach the walk's integer cells.
  if (!arrays.vsRayIsFinite(ray.o, ray.d, ray.tMax)) return false;
  if (arrays.nodeCount == 0u) return true;
  std::uint32_t stack[gpu::VS_BVH_STACK_SIZE];
  int top = 0;
  stack[top++] = 0u;
  while (top > 0) {
    const gpu::BvhNode& node = arrays.nodes[stack[--top]];
    std::uint32_t nodeIndex = static_cast<std::uint32_t>(&node - arrays.nodes);
    if (arrays.vsBoxEntry(node.boundsMin, node.boundsMax, ray.o, ray.d, 0.0f, ray.tMax) == gpu::VS_T_INFINITY) continue;
    if (node.count == 0u) {
      stack[top++] = node.rightOrFirst;
      stack[top++] = nodeIndex + 1u;
      continue;
    }
    for (std::uint32_t i = 0; i < node.count; ++i) {
      std::uint32_t instance = arrays.instanceIndices[node.rightOrFirst + i];
      const gpu::InstanceRecord& rec = arrays.instances[instance];
      float entry = arrays.vsBoxEntry(glm::vec3(rec.boundsMin), glm::vec3(rec.boundsMax), ray.o, ray.d, 0.0f, ray.tMax);
      if (entry == gpu::VS_T_INFINITY) continue;
      if (ray.candidateCount == kMaxCandidates) return false;
      ray.candidates[ray.candidateCount++] = {entry, instance};
    }
  }
  std::sort(ray.candidates.begin(), ray.candidates.begin() + ray.candidateCount,
            [](const Candidate& a, const Candidate& b) {
              return a.entry < b.entry || (a.entry == b.entry && a.instance < b.instance);
            });
  return true;
}

// Starts the walk through the next instance that could still hold a closer hit; false when none is left.
inline bool beginNextWalk(gpu::SceneArrays& arrays, RayState& ray) {
  while (ray.nextCandidate < ray.candidateCount) {
    const Candidate& c = ray.candidates[ray.nextCandidate++];
    if (c.entry > ray.tBest) return false;  // sorted by entry: no later box starts before the best hit
    const gpu::InstanceRecord& rec = arrays.instances[c.instance];
    glm::vec3 lo = arrays.vsApplyAffine(rec.worldToBrick, ray.o);
    glm::vec3 ld = arrays.vsApplyLinear(rec.worldToBrick, ray.d);
    if (arrays.vsObjectWalkBegin(rec.info.x, lo, ld, 0.0f, ray.tBest, ray.walk)) {
      ray.walkingInstance = c.instance;
      return true;
    }
  }
  return false;
}

// The reference's rule for a walk's hit: the smallest t wins; among equal t, the lowest instance index.
inline void recordHit(RayState& ray, float t, glm::ivec3 voxel) {
  if (!ray.hit || t < ray.tBest || (t == ray.tBest && ray.walkingInstance < ray.instanceHit)) {
    ray.tBest = t;
    ray.instanceHit = ray.walkingInstance;
    ray.voxel = voxel;
  }
  ray.hit = true;
}

}  // namespace vs::tile

#endif
