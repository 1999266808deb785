// bvh.h: binned-SAH bounding volume hierarchy over instance world boxes, flattened for the GPU.
#ifndef VOXSHADOW_BVH_H
#define VOXSHADOW_BVH_H

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "bvh/bvh_layout.h"

namespace vs {

struct Aabb {
  glm::vec3 min{std::numeric_limits<float>::infinity()};
  glm::vec3 max{-std::numeric_limits<float>::infinity()};
  bool empty() const { return max.x < min.x || max.y < min.y || max.z < min.z; }
  void extend(const glm::vec3& p) { min = glm::min(min, p); max = glm::max(max, p); }
  void extend(const Aabb& b) { min = glm::min(min, b.min); max = glm::max(max, b.max); }
  float surfaceArea() const;
};

class Bvh {
 public:
  // Cost of traversing a node relative to intersecting one instance, for the SAH.
  static constexpr float kTraversalCost = 1.0f;
  static constexpr float kIntersectionCost = 1.0f;
  static constexpr int kBins = 16;
  static constexpr int kMaxLeafSize = 4;

  // Builds over the boxes (one per instance, index = instance index). Empty boxes are skipped (never hit).
  // Preconditions: boxes finite. Zero boxes gives a BVH with no nodes.
  static Bvh build(std::span<const Aabb> boxes);

  // Recomputes node bounds bottom-up for moved instances, keeping the topology. Precondition: same count.
  void refit(std::span<const Aabb> boxes);

  // SAH cost of the current tree (relative units); compare with the cost at build time to decide a rebuild.
  float sahCost() const;
  float builtSahCost() const { return builtSahCost_; }

  std::span<const gpu::BvhNode> nodes() const { return nodes_; }
  // Leaf entries index this list, which holds instance indices.
  std::span<const std::uint32_t> instanceIndices() const { return indices_; }

 private:
  std::vector<gpu::BvhNode> nodes_;
  std::vector<std::uint32_t> indices_;
  float builtSahCost_ = 0.0f;
};

}  // namespace vs

#endif
