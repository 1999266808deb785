// Instance BVH: structure invariants, closest-hit agreement with brute force, refit and rebuild decisions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "bvh/bvh.h"
#include "compute/shared/trace_view.h"

namespace {

using vs::Aabb;
using vs::Bvh;


std::vector<Aabb> randomBoxes(std::mt19937& rng, int n, float world, float maxSize) {
  std::uniform_real_distribution<float> pos(0.0f, world), size(0.0f, maxSize);
  std::vector<Aabb> boxes(n);
  for (Aabb& b : boxes) {
    b.min = glm::vec3(pos(rng), pos(rng), pos(rng));
    b.max = b.min + glm::vec3(size(rng), size(rng), size(rng));
  }
  return boxes;
}

bool contains(const vs::gpu::BvhNode& outer, const Aabb& inner) {
  return glm::all(glm::lessThanEqual(outer.boundsMin, inner.min)) &&
         glm::all(glm::greaterThanEqual(outer.boundsMax, inner.max));
}

// Checks every structural invariant; `tight` also demands each node box equal the union of its contents.
void checkTree(const Bvh& bvh, const std::vector<Aabb>& boxes, bool tight) {
  auto nodes = bvh.nodes();
  auto indices = bvh.instanceIndices();
  std::size_t nonEmpty = std::count_if(boxes.begin(), boxes.end(), [](const Aabb& b) { return !b.empty(); });
  if (nonEmpty == 0) {
    EXPECT_TRUE(nodes.empty());
    return;
  }
  ASSERT_FALSE(nodes.empty());
  // Each node's subtree is the node range [n, escape): a leaf's is itself, an interior node's ends with its right
  // child's. The stackless traversal (compute/shared/traverse.h) jumps there when it skips or finishes a node.
  auto escapes = bvh.nodeEscapes();
  ASSERT_EQ(escapes.size(), nodes.size());
  for (std::uint32_t n = 0; n < nodes.size(); ++n) {
    std::uint32_t end = n;
    while (nodes[end].count == 0) {
      ASSERT_GT(nodes[end].rightOrFirst, end);
      ASSERT_LT(nodes[end].rightOrFirst, nodes.size());
      end = nodes[end].rightOrFirst;
    }
    ASSERT_EQ(escapes[n], end + 1) << "node " << n;
  }
  std::vector<int> seen(boxes.size(), 0);
  std::vector<int> visited(nodes.size(), 0);
  std::vector<std::pair<std::uint32_t, int>> stack{{0u, 0}};
  int maxDepth = 0;
  while (!stack.empty()) {
    auto [n, depth] = stack.back();
    stack.pop_back();
    ASSERT_LT(n, nodes.size());
    ASSERT_EQ(visited[n]++, 0) << "node " << n << " reached twice";
    maxDepth = std::max(maxDepth, depth);
    const auto& node = nodes[n];
    Aabb content;
    if (node.count > 0) {
      ASSERT_LE(std::size_t(node.rightOrFirst) + node.count, indices.size());
      for (std::uint32_t k = 0; k < node.count; ++k) {
        std::uint32_t inst = indices[node.rightOrFirst + k];
        ASSERT_LT(inst, boxes.size());
        EXPECT_FALSE(boxes[inst].empty()) << "empty box " << inst << " in a leaf";
        ++seen[inst];
        EXPECT_TRUE(contains(node, boxes[inst])) << "leaf " << n << " does not contain instance " << inst;
        content.extend(boxes[inst]);
      }
    } else {
      ASSERT_LT(n + 1, nodes.size());
      ASSERT_GT(node.rightOrFirst, n + 1) << "right child must follow the left subtree";
      ASSERT_LT(node.rightOrFirst, nodes.size());
      for (std::uint32_t c : {n + 1, node.rightOrFirst}) {
        Aabb child{nodes[c].boundsMin, nodes[c].boundsMax};
        EXPECT_TRUE(contains(node, child)) << "node " << n << " does not contain child " << c;
        content.extend(child);
        stack.push_back({c, depth + 1});
      }
    }
    if (tight) {
      EXPECT_EQ(content.min, node.boundsMin) << "node " << n;
      EXPECT_EQ(content.max, node.boundsMax) << "node " << n;
    }
  }
  EXPECT_LE(maxDepth, Bvh::kMaxDepth);
  EXPECT_EQ(std::count(visited.begin(), visited.end(), 1), std::ptrdiff_t(nodes.size())) << "unreachable nodes";
  for (std::size_t i = 0; i < boxes.size(); ++i)
    EXPECT_EQ(seen[i], boxes[i].empty() ? 0 : 1) << "instance " << i;
}

int treeDepth(const Bvh& bvh) {
  auto nodes = bvh.nodes();
  if (nodes.empty()) return -1;
  int maxDepth = 0;
  std::vector<std::pair<std::uint32_t, int>> stack{{0u, 0}};
  while (!stack.empty()) {
    auto [n, d] = stack.back();
    stack.pop_back();
    maxDepth = std::max(maxDepth, d);
    if (nodes[n].count == 0) {
      stack.push_back({n + 1, d + 1});
      stack.push_back({nodes[n].rightOrFirst, d + 1});
    }
  }
  return maxDepth;
}

float slabEntry(const glm::vec3& bmin, const glm::vec3& bmax, const glm::vec3& o, const glm::vec3& invD) {
  float t0 = 0.0f, t1 = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    float lo = (bmin[a] - o[a]) * invD[a], hi = (bmax[a] - o[a]) * invD[a];
    t0 = std::max(t0, std::min(lo, hi));
    t1 = std::min(t1, std::max(lo, hi));
  }
  return t0 <= t1 ? t0 : std::numeric_limits<float>::infinity();
}

// Closest entry t over all boxes through the BVH, front-to-back with pruning by the best hit so far.
float bvhClosest(const Bvh& bvh, const std::vector<Aabb>& boxes, const glm::vec3& o, const glm::vec3& invD) {
  float best = std::numeric_limits<float>::infinity();
  auto nodes = bvh.nodes();
  if (nodes.empty()) return best;
  std::vector<std::uint32_t> stack{0u};
  while (!stack.empty()) {
    const auto& node = nodes[stack.back()];
    std::uint32_t n = stack.back();
    stack.pop_back();
    if (slabEntry(node.boundsMin, node.boundsMax, o, invD) > best) continue;
    if (node.count > 0) {
      for (std::uint32_t k = 0; k < node.count; ++k) {
        const Aabb& b = boxes[bvh.instanceIndices()[node.rightOrFirst + k]];
        best = std::min(best, slabEntry(b.min, b.max, o, invD));
      }
    } else {
      stack.push_back(node.rightOrFirst);
      stack.push_back(n + 1);
    }
  }
  return best;
}

float bruteClosest(const std::vector<Aabb>& boxes, const glm::vec3& o, const glm::vec3& invD) {
  float best = std::numeric_limits<float>::infinity();
  for (const Aabb& b : boxes)
    if (!b.empty()) best = std::min(best, slabEntry(b.min, b.max, o, invD));
  return best;
}

void checkRays(const Bvh& bvh, const std::vector<Aabb>& boxes, std::mt19937& rng, float world, int rays) {
  std::uniform_real_distribution<float> pos(-0.2f * world, 1.2f * world), dir(-1.0f, 1.0f);
  int hits = 0;
  for (int r = 0; r < rays; ++r) {
    glm::vec3 o(pos(rng), pos(rng), pos(rng));
    glm::vec3 d(dir(rng), dir(rng), dir(rng));
    if (glm::length(d) < 1e-3f) continue;
    glm::vec3 invD = 1.0f / d;
    float expected = bruteClosest(boxes, o, invD);
    ASSERT_EQ(bvhClosest(bvh, boxes, o, invD), expected) << "ray " << r;
    hits += std::isfinite(expected) ? 1 : 0;
  }
  EXPECT_GT(hits, 0) << "the ray test should hit something";
}

TEST(Bvh, SurfaceArea) {
  EXPECT_FLOAT_EQ((Aabb{glm::vec3(0), glm::vec3(1, 2, 3)}.surfaceArea()), 2.0f * (2 + 6 + 3));
  EXPECT_EQ(Aabb{}.surfaceArea(), 0.0f);
}

TEST(Bvh, EmptyInputGivesNoNodes) {
  std::vector<Aabb> none;
  EXPECT_TRUE(Bvh::build(none).nodes().empty());
  std::vector<Aabb> allEmpty(5);
  Bvh bvh = Bvh::build(allEmpty);
  EXPECT_TRUE(bvh.nodes().empty());
  EXPECT_TRUE(bvh.instanceIndices().empty());
}

TEST(Bvh, SingleBox) {
  std::vector<Aabb> boxes{Aabb{glm::vec3(1), glm::vec3(2)}};
  Bvh bvh = Bvh::build(boxes);
  ASSERT_EQ(bvh.nodes().size(), 1u);
  EXPECT_EQ(bvh.nodes()[0].count, 1u);
  checkTree(bvh, boxes, true);
}

TEST(Bvh, RandomBoxesInvariantsAndClosestHit) {
  std::mt19937 rng(7);
  for (int n : {2, 5, 17, 100, 1000}) {
    auto boxes = randomBoxes(rng, n, 100.0f, 10.0f);
    Bvh bvh = Bvh::build(boxes);
    SCOPED_TRACE(n);
    checkTree(bvh, boxes, true);
    checkRays(bvh, boxes, rng, 100.0f, 300);
  }
}

TEST(Bvh, TenThousandBoxes) {
  std::mt19937 rng(11);
  auto boxes = randomBoxes(rng, 10000, 1000.0f, 5.0f);
  Bvh bvh = Bvh::build(boxes);
  checkTree(bvh, boxes, true);
  checkRays(bvh, boxes, rng, 1000.0f, 300);
  EXPECT_GT(bvh.builtSahCost(), 0.0f);
  EXPECT_EQ(bvh.sahCost(), bvh.builtSahCost());
}

TEST(Bvh, DegenerateIdenticalFlatAndEmptyBoxes) {
  std::mt19937 rng(3);
  std::vector<Aabb> boxes;
  for (int i = 0; i < 500; ++i) boxes.push_back(Aabb{glm::vec3(5), glm::vec3(6)});           // identical
  for (int i = 0; i < 300; ++i) boxes.push_back(Aabb{glm::vec3(2, 2, 2), glm::vec3(2, 2, 2)});  // identical points
  for (int i = 0; i < 200; ++i) boxes.push_back(Aabb{});                                     // empty
  auto flat = randomBoxes(rng, 300, 50.0f, 4.0f);
  for (Aabb& b : flat) b.max.y = b.min.y = 1.0f;  // flat, coplanar
  boxes.insert(boxes.end(), flat.begin(), flat.end());
  std::shuffle(boxes.begin(), boxes.end(), rng);
  Bvh bvh = Bvh::build(boxes);
  checkTree(bvh, boxes, true);
  checkRays(bvh, boxes, rng, 50.0f, 300);
  // All-identical boxes are still split down to small leaves.
  std::vector<Aabb> same(1000, Aabb{glm::vec3(0), glm::vec3(1)});
  Bvh sameBvh = Bvh::build(same);
  checkTree(sameBvh, same, true);
  for (const auto& node : sameBvh.nodes()) EXPECT_LE(node.count, 4u * Bvh::kMaxLeafSize);
}

TEST(Bvh, DepthStaysWithinTheTraversalStack) {
  // Exponentially spaced boxes make every SAH split peel off one box: without a depth guard the tree would be
  // about as deep as there are boxes.
  std::vector<Aabb> boxes;
  for (int i = 0; i < 400; ++i) {
    float x = std::pow(1.2f, float(i % 200)) * (i < 200 ? 1.0f : -1.0f);
    boxes.push_back(Aabb{glm::vec3(x, 0, 0), glm::vec3(x + 0.5f, 1, 1)});
  }
  Bvh bvh = Bvh::build(boxes);
  checkTree(bvh, boxes, true);
  EXPECT_LE(treeDepth(bvh), Bvh::kMaxDepth);
  EXPECT_GT(treeDepth(bvh), 10) << "the stress case should be deep enough to need the guard";
}

TEST(Bvh, RefitKeepsInvariantsAndTightBoxes) {
  std::mt19937 rng(5);
  auto boxes = randomBoxes(rng, 2000, 200.0f, 8.0f);
  boxes[17] = Aabb{};
  Bvh bvh = Bvh::build(boxes);
  std::size_t nodeCount = bvh.nodes().size();
  std::vector<std::uint32_t> counts;
  for (const auto& n : bvh.nodes()) counts.push_back(n.count);

  std::uniform_real_distribution<float> jitter(-0.05f, 0.05f);
  for (Aabb& b : boxes) {
    if (b.empty()) continue;
    glm::vec3 shift(jitter(rng), jitter(rng), jitter(rng));
    b.min += shift;
    b.max += shift;
  }
  bvh.refit(boxes);
  ASSERT_EQ(bvh.nodes().size(), nodeCount);
  for (std::size_t i = 0; i < nodeCount; ++i) EXPECT_EQ(bvh.nodes()[i].count, counts[i]) << "topology changed";
  checkTree(bvh, boxes, true);
  checkRays(bvh, boxes, rng, 200.0f, 300);
  EXPECT_FALSE(bvh.shouldRebuild()) << "a small jitter must not ask for a rebuild";

  // A box that was empty at build is not in the tree: refit cannot place it, so a rebuild is due.
  boxes[17] = Aabb{glm::vec3(1), glm::vec3(2)};
  bvh.refit(boxes);
  EXPECT_TRUE(bvh.shouldRebuild());
}

TEST(Bvh, BigMoveRaisesCostAndAsksForRebuild) {
  std::mt19937 rng(9);
  auto boxes = randomBoxes(rng, 3000, 500.0f, 5.0f);
  Bvh bvh = Bvh::build(boxes);
  const float built = bvh.builtSahCost();
  // Every instance jumps to a random place: the old grouping no longer matches the positions.
  std::uniform_real_distribution<float> pos(0.0f, 500.0f);
  for (Aabb& b : boxes) {
    glm::vec3 size = b.max - b.min;
    b.min = glm::vec3(pos(rng), pos(rng), pos(rng));
    b.max = b.min + size;
  }
  bvh.refit(boxes);
  checkTree(bvh, boxes, true);
  EXPECT_GT(bvh.sahCost(), built * Bvh::kRebuildCostRatio);
  EXPECT_TRUE(bvh.shouldRebuild());
  Bvh rebuilt = Bvh::build(boxes);
  EXPECT_LT(rebuilt.sahCost(), bvh.sahCost());
  EXPECT_FALSE(rebuilt.shouldRebuild());
}

TEST(Bvh, RefitRejectsAnotherBoxCount) {
  std::mt19937 rng(1);
  auto boxes = randomBoxes(rng, 10, 10.0f, 1.0f);
  Bvh bvh = Bvh::build(boxes);
  boxes.pop_back();
  EXPECT_THROW(bvh.refit(boxes), std::exception);
}

}  // namespace
