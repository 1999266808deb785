#include "compute/cpu/tile_tracer.h"

#include <algorithm>
#include <array>

namespace vs {
namespace {

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
bool collectCandidates(gpu::SceneArrays& arrays, RayState& ray) {
  ray.candidateCount = 0;
  if (arrays.nodeCount == 0u) return true;
  std::uint32_t stack[gpu::VS_BVH_STACK_SIZE];
  int top = 0;
  stack[top++] = 0u;
  while (top > 0) {
    const gpu::BvhNode& node = arrays.nodes[stack[--top]];
    std::uint32_t nodeIndex = static_cast<std::uint32_t>(&node - arrays.nodes);
    if (arrays.vsBoxEntry(node.boundsMin, node.boundsMax, ray.o, ray.d, 0.0f, ray.tMax) == gpu::VS_T_INFINITY)
      continue;
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
            [](const Candidate& a, const Candidate& b) { return a.entry < b.entry || (a.entry == b.entry && a.instance < b.instance); });
  return true;
}

// Starts the walk through the next instance that could still hold a closer hit; false when none is left.
bool beginNextWalk(gpu::SceneArrays& arrays, RayState& ray) {
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

}  // namespace

void traceTileInterleaved(gpu::SceneArrays& arrays, const gpu::TraceView& view, int x0, int y0, int x1, int y1,
                          float* texels, int stride) {
  std::array<RayState, kMaxTileRays> rays;
  std::array<int, kMaxTileRays> texelIndex;
  std::array<int, kMaxTileRays> active;
  int activeCount = 0;
  int count = 0;
  auto finish = [&](int i) {
    const RayState& r = rays[i];
    texels[texelIndex[i]] = arrays.vsTexelValue(view, r.o, r.d, r.tMax, r.hit, r.tBest, r.instanceHit, r.voxel);
  };
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      int i = count++;
      RayState& r = rays[i];
      texelIndex[i] = y * stride + x;
      arrays.vsViewRay(view, glm::ivec2(x, y), r.o, r.d, r.tMax);
      r.tBest = r.tMax;
      r.hit = false;
      r.instanceHit = 0u;
      r.voxel = glm::ivec3(0);
      r.nextCandidate = 0;
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
      if (status == gpu::VS_WALK_HIT) {
        float t = r.walk.tEnter;
        // The reference's rule: the smallest t wins; among equal t, the lowest instance index.
        if (!r.hit || t < r.tBest || (t == r.tBest && r.walkingInstance < r.instanceHit)) {
          r.tBest = t;
          r.instanceHit = r.walkingInstance;
          r.voxel = r.walk.v;
        }
        r.hit = true;
      }
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
