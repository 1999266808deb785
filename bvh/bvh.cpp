// bvh.cpp: binned-SAH build, bottom-up refit and SAH cost of the instance BVH (DESIGN.md §5).
#include "bvh/bvh.h"

#include <algorithm>
#include <array>
#include <bit>

#include "voxel/error.h"

namespace vs {

float Aabb::surfaceArea() const {
  if (empty()) return 0.0f;
  glm::vec3 e = max - min;
  return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
}

namespace {

constexpr int kMaxDepth = Bvh::kMaxDepth;

// A leaf bigger than kMaxLeafSize is only accepted from the SAH up to this count: beyond it a leaf's linear
// scan in the shader costs more than any plausible split, even one the SAH prices badly (identical boxes).
constexpr std::uint32_t kMaxSahLeafSize = 4 * Bvh::kMaxLeafSize;

// Levels a balanced (median) split needs to bring `count` entries down to leaves of kMaxLeafSize.
int balancedLevels(std::uint32_t count) {
  std::uint32_t leaves = (count + Bvh::kMaxLeafSize - 1) / Bvh::kMaxLeafSize;
  return leaves <= 1 ? 0 : int(std::bit_width(leaves - 1));
}

glm::vec3 toVec3(const glm::vec3& v) { return v; }

struct Builder {
  std::span<const Aabb> boxes;
  std::vector<glm::vec3> centroids;  // per original box index
  std::vector<std::uint32_t>& refs;  // becomes the leaf entry list
  std::vector<gpu::BvhNode>& nodes;

  std::uint32_t makeLeaf(const Aabb& bounds, std::uint32_t begin, std::uint32_t count) {
    gpu::BvhNode node{};
    node.boundsMin = bounds.min;
    node.boundsMax = bounds.max;
    node.rightOrFirst = begin;
    node.count = count;
    nodes.push_back(node);
    return std::uint32_t(nodes.size() - 1);
  }

  // Returns the split position (begin < mid < end), reordering refs[begin, end).
  std::uint32_t medianSplit(std::uint32_t begin, std::uint32_t end, int axis) {
    std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(refs.begin() + begin, refs.begin() + mid, refs.begin() + end,
                     [&](std::uint32_t a, std::uint32_t b) {
                       float ca = centroids[a][axis], cb = centroids[b][axis];
                       return ca < cb || (ca == cb && a < b);
                     });
    return mid;
  }

  std::uint32_t build(std::uint32_t begin, std::uint32_t end, int depth) {
    Aabb bounds, centroidBounds;
    for (std::uint32_t i = begin; i < end; ++i) {
      bounds.extend(boxes[refs[i]]);
      centroidBounds.extend(centroids[refs[i]]);
    }
    const std::uint32_t count = end - begin;
    if (count <= std::uint32_t(Bvh::kMaxLeafSize)) return makeLeaf(bounds, begin, count);

    glm::vec3 extent = centroidBounds.max - centroidBounds.min;
    int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);

    std::uint32_t mid = 0;
    // Median splits keep the tree within kMaxDepth: once the remaining depth only just suffices for a
    // balanced subtree, or when the centroids coincide and no plane separates them.
    bool useMedian = extent[axis] <= 0.0f || depth + balancedLevels(count) >= kMaxDepth - 1;
    if (!useMedian) {
      struct Bin {
        Aabb box;
        std::uint32_t count = 0;
      };
      std::array<Bin, Bvh::kBins> bins{};
      const float scale = float(Bvh::kBins) / extent[axis];
      auto binOf = [&](std::uint32_t ref) {
        int b = int((centroids[ref][axis] - centroidBounds.min[axis]) * scale);
        return std::clamp(b, 0, Bvh::kBins - 1);
      };
      for (std::uint32_t i = begin; i < end; ++i) {
        Bin& bin = bins[binOf(refs[i])];
        bin.box.extend(boxes[refs[i]]);
        ++bin.count;
      }
      // Sweep from the right to get the cost of every plane between bins.
      std::array<float, Bvh::kBins> rightCost{};
      Aabb acc;
      std::uint32_t accCount = 0;
      for (int b = Bvh::kBins - 1; b > 0; --b) {
        acc.extend(bins[b].box);
        accCount += bins[b].count;
        rightCost[b] = accCount == 0 ? 0.0f : acc.surfaceArea() * float(accCount);
      }
      acc = Aabb{};
      accCount = 0;
      float bestCost = std::numeric_limits<float>::infinity();
      int bestPlane = -1;
      for (int b = 0; b + 1 < Bvh::kBins; ++b) {
        acc.extend(bins[b].box);
        accCount += bins[b].count;
        if (accCount == 0 || accCount == count) continue;
        float cost = acc.surfaceArea() * float(accCount) + rightCost[b + 1];
        if (cost < bestCost) {
          bestCost = cost;
          bestPlane = b;
        }
      }
      const float area = bounds.surfaceArea();
      if (bestPlane < 0) {
        useMedian = true;
      } else {
        float splitCost = Bvh::kTraversalCost + Bvh::kIntersectionCost * (area > 0.0f ? bestCost / area : 0.0f);
        float leafCost = Bvh::kIntersectionCost * float(count);
        if (area > 0.0f && splitCost >= leafCost && count <= kMaxSahLeafSize) return makeLeaf(bounds, begin, count);
        auto it = std::partition(refs.begin() + begin, refs.begin() + end,
                                 [&](std::uint32_t ref) { return binOf(ref) <= bestPlane; });
        mid = std::uint32_t(it - refs.begin());
      }
    }
    if (useMedian) mid = medianSplit(begin, end, axis);

    std::uint32_t self = makeLeaf(bounds, 0, 0);  // becomes interior below
    build(begin, mid, depth + 1);                 // lands at self + 1
    std::uint32_t right = build(mid, end, depth + 1);
    nodes[self].rightOrFirst = right;
    nodes[self].count = 0;
    return self;
  }
};

}  // namespace

Bvh Bvh::build(std::span<const Aabb> boxes) {
  Bvh bvh;
  bvh.boxCount_ = boxes.size();
  bvh.inTree_.assign(boxes.size(), 0);
  std::vector<glm::vec3> centroids(boxes.size());
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    if (boxes[i].empty()) continue;
    bvh.indices_.push_back(std::uint32_t(i));
    bvh.inTree_[i] = 1;
    centroids[i] = toVec3((boxes[i].min + boxes[i].max) * 0.5f);
  }
  if (bvh.indices_.empty()) return bvh;
  bvh.nodes_.reserve(2 * bvh.indices_.size());
  Builder builder{boxes, std::move(centroids), bvh.indices_, bvh.nodes_};
  builder.build(0, std::uint32_t(bvh.indices_.size()), 0);
  // A left child (the next node) escapes to its right sibling; a right child where its parent does.
  bvh.escapes_.assign(bvh.nodes_.size(), std::uint32_t(bvh.nodes_.size()));
  for (std::size_t n = 0; n < bvh.nodes_.size(); ++n) {
    const gpu::BvhNode& node = bvh.nodes_[n];
    if (node.count > 0) continue;
    bvh.escapes_[n + 1] = node.rightOrFirst;
    bvh.escapes_[node.rightOrFirst] = bvh.escapes_[n];
  }
  bvh.builtSahCost_ = bvh.sahCost();
  return bvh;
}

void Bvh::refit(std::span<const Aabb> boxes) {
  if (boxes.size() != boxCount_) throwBadInput("Bvh::refit: box count changed; rebuild instead");
  for (std::size_t i = 0; i < boxes.size(); ++i)
    if (!inTree_[i] != boxes[i].empty()) missingInstance_ = true;
  // Children always follow their parent, so a reverse sweep sees both children before the parent.
  for (std::size_t n = nodes_.size(); n-- > 0;) {
    gpu::BvhNode& node = nodes_[n];
    Aabb b;
    if (node.count > 0) {
      for (std::uint32_t k = 0; k < node.count; ++k) b.extend(boxes[indices_[node.rightOrFirst + k]]);
    } else {
      const gpu::BvhNode& l = nodes_[n + 1];
      const gpu::BvhNode& r = nodes_[node.rightOrFirst];
      b.extend(Aabb{l.boundsMin, l.boundsMax});
      b.extend(Aabb{r.boundsMin, r.boundsMax});
    }
    node.boundsMin = b.min;
    node.boundsMax = b.max;
  }
}

float Bvh::sahCost() const {
  if (nodes_.empty()) return 0.0f;
  double total = 0.0;
  for (const gpu::BvhNode& node : nodes_) {
    double area = Aabb{node.boundsMin, node.boundsMax}.surfaceArea();
    total += area * (node.count > 0 ? kIntersectionCost * double(node.count) : kTraversalCost);
  }
  double rootArea = Aabb{nodes_[0].boundsMin, nodes_[0].boundsMax}.surfaceArea();
  // A tree over flat or point-like boxes has no area: every ray that reaches the root visits every node.
  if (rootArea <= 0.0) return float(nodes_.size() - indices_.size()) * kTraversalCost +
                                float(indices_.size()) * kIntersectionCost;
  return float(total / rootArea);
}

bool Bvh::shouldRebuild() const {
  // Refit keeps the topology, so its cost only grows as instances drift from where they were grouped; a
  // rebuild (linear-ish in the instance count) pays off once the expected cost per ray is well above the
  // fresh tree's. kRebuildCostRatio tolerates ordinary animation jitter while catching trees that degrade badly.
  return missingInstance_ || sahCost() > builtSahCost_ * kRebuildCostRatio;
}

bool Bvh::update(std::span<const Aabb> boxes) {
  if (boxes.size() == boxCount_) {
    refit(boxes);
    if (!shouldRebuild()) return false;
  }
  *this = build(boxes);
  return true;
}

}  // namespace vs
