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
  // Deepest leaf (root at depth 0): bounds the builder's recursion on degenerate input (every traversal is
  // stackless, through nodeEscapes, and needs no bound of its own).
  static constexpr int kMaxDepth = 62;
  // shouldRebuild() threshold: refit SAH cost over the cost at build time.
  static constexpr float kRebuildCostRatio = 1.5f;

  // Builds over the boxes (one per instance, index = instance index). Empty boxes are skipped (never hit).
  // Preconditions: boxes finite. Zero boxes gives a BVH with no nodes.
  static Bvh build(std::span<const Aabb> boxes);

  // Recomputes node bounds bottom-up for moved instances, keeping the topology. Precondition: the same
  // number of boxes as at build (throws vs::Error(BadInput) otherwise). A box that was empty at build is not
  // in the tree: if it becomes non-empty, shouldRebuild() turns true; so it does when a box in the tree
  // becomes empty (a removed instance), so that the tree never lists an instance that has no box.
  void refit(std::span<const Aabb> boxes);

  // True when the refitted tree has degraded enough (sahCost() > builtSahCost() * kRebuildCostRatio), or the
  // boxes that are empty are no longer those that were at build, that build() should be called again.
  bool shouldRebuild() const;

  // The rule by which a scene keeps its tree over changed boxes, in one place: refit when the boxes are as
  // many as at build and the refitted tree does not need a rebuild (shouldRebuild), else build anew.
  // Returns true when it rebuilt. Precondition: boxes finite.
  bool update(std::span<const Aabb> boxes);

  // SAH cost of the current tree (relative units); compare with the cost at build time to decide a rebuild.
  float sahCost() const;
  float builtSahCost() const { return builtSahCost_; }

  std::span<const gpu::BvhNode> nodes() const { return nodes_; }
  // Leaf entries index this list, which holds instance indices.
  std::span<const std::uint32_t> instanceIndices() const { return indices_; }
  // Per node, the first node after its subtree (the node count after the last): where a depth-first walk
  // goes when it skips or finishes the node, so a traversal needs no stack. Fixed by build(); refit() keeps it.
  std::span<const std::uint32_t> nodeEscapes() const { return escapes_; }

 private:
  std::vector<gpu::BvhNode> nodes_;
  std::vector<std::uint32_t> indices_;
  std::vector<std::uint32_t> escapes_;
  float builtSahCost_ = 0.0f;
  std::size_t boxCount_ = 0;
  std::vector<std::uint8_t> inTree_;  // per box: non-empty at build
  bool missingInstance_ = false;  // a box's emptiness differs from what it was at build
};

}  // namespace vs

#endif
