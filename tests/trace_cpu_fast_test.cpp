// The CPU fast path (CpuTracePath::Interleaved: the box-table walk in 16 AVX-512 or 8 AVX2 lanes where the
// processor has them, else one scalar lane) equals the reference
// per-ray traversal bit for bit on the benchmark scene, from many directions, both depth points, partial
// rectangles, and rays aimed along voxel faces, edges and corners.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>

#include "compute/box_table.h"
#include "compute/cpu/cpu_tracer.h"
#include "compute/cpu/lane_tracer.h"
#include "support/hostile_views.h"
#include "support/test_scenes.h"
#include "voxel/error.h"

namespace vs {
namespace {

// Orthographic NDC-depth view looking along `direction` at `center`, half-width `half`, res x res texels.
// With half = res the texel centres sit 2 units apart on odd offsets from `center`: on voxel faces, edges
// and corners when `center` is an integer point and the view is axis-aligned or diagonal.
gpu::TraceView gridView(glm::vec3 center, glm::vec3 direction, float half, int res) {
  glm::vec3 d = glm::normalize(direction);
  glm::vec3 up = std::abs(d.y) > 0.99f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
  glm::mat4 view = glm::lookAtRH(center - d * 600.0f, center, up);
  glm::mat4 proj = glm::orthoRH_ZO(-half, half, -half, half, 10.0f, 1300.0f);
  return gpu::makeTraceView(glm::dmat4(proj * view), res, res, gpu::VS_ENCODING_NDC_DEPTH, gpu::VS_DEPTH_POINT_ENTRY);
}

std::vector<gpu::TraceView> cityViews(const Aabb& b) {
  const int res = 160;
  std::vector<gpu::TraceView> views;
  const glm::vec3 directions[] = {{-0.4f, -1.0f, -0.3f}, {0, -1, 0}, {1, 0, 0},    {0, 0, -1},
                                  {-1, -1, 0},           {1, -1, 1}, {-1, -1, -1}, {0.3f, -0.2f, 1}};
  for (const glm::vec3& d : directions) views.push_back(test::directionalView(b, d, res));
  glm::vec3 c = (b.min + b.max) * 0.5f;
  // Spot views from above, from inside the city and from a corner, looking along axes and diagonals.
  views.push_back(test::distanceView(c + glm::vec3(0, 400, 0), {0.2f, -1, 0.1f}, 1500.0f, res));
  views.push_back(test::distanceView({100.5f, 60.0f, 200.25f}, {1, 0, 0}, 800.0f, res));
  views.push_back(test::distanceView({256.0f, 128.0f, 256.0f}, {0, -1, 0}, 800.0f, res));
  views.push_back(test::distanceView({0.0f, 300.0f, 0.0f}, {1, -1, 1}, 1200.0f, res, 60.0f));
  views.push_back(test::distanceView({500.0f, 20.0f, 12.0f}, {-1, 0, 1}, 1200.0f, res, 120.0f));
  // Rays along voxel faces, edges and corners.
  for (glm::vec3 center : {glm::vec3(256, 128, 256), glm::vec3(256.5f, 128.5f, 256.5f)}) {
    views.push_back(gridView(center, {0, -1, 0}, 160.0f, res));
    views.push_back(gridView(center, {1, 0, 0}, 160.0f, res));
    views.push_back(gridView(center, {1, -1, 0}, 160.0f, res));
    views.push_back(gridView(center, {-1, -1, 1}, 160.0f, res));
  }
  test::appendVoxelCenterCopies(views, {7, 5, 3, 11});
  return views;
}

std::size_t differingTexels(const ShadowLayer& a, const ShadowLayer& b) {
  EXPECT_EQ(a.texels.size(), b.texels.size());
  std::size_t differing = 0;
  for (std::size_t k = 0; k < a.texels.size() && k < b.texels.size(); ++k)
    if (std::memcmp(&a.texels[k], &b.texels[k], sizeof(float)) != 0) ++differing;
  return differing;
}

TEST(TraceCpuFast, City512MatchesReferenceBitForBit) {
  auto scene = test::city512Scene();
  std::printf("the fast path runs %s lanes\n", laneWidthName(widestLaneWidth()));
  auto views = cityViews(scene.data.worldBounds);
  std::vector<ShadowLayer> reference, fast;
  traceCpu(scene.data, views, reference, CpuTracePath::Reference, 2);
  traceCpu(scene.data, views, fast, CpuTracePath::Interleaved, 2);
  ASSERT_EQ(reference.size(), views.size());
  ASSERT_EQ(fast.size(), views.size());
  std::size_t hits = 0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    EXPECT_EQ(differingTexels(reference[i], fast[i]), 0u) << "view " << i;
    float miss = views[i].info.z == gpu::VS_ENCODING_NDC_DEPTH ? 1.0f : views[i].eyeHigh.w;
    for (float t : reference[i].texels) hits += t < miss;
  }
  // The views see the city: a large share of the texels hit.
  EXPECT_GT(hits, std::size_t(views.size()) * 160 * 160 / 10);
}

// The default path is the fast one, and texels outside a view's rectangle keep their values.
TEST(TraceCpuFast, DefaultPathKeepsTexelsOutsideTheRectangle) {
  auto scene = test::city512Scene();
  gpu::TraceView view = test::directionalView(scene.data.worldBounds, {-0.4f, -1.0f, -0.3f}, 64);
  view.rect = glm::ivec4(10, 20, 37, 41);
  std::vector<ShadowLayer> fast(1), reference(1);
  for (auto* layers : {&fast, &reference}) {
    (*layers)[0].width = 64;
    (*layers)[0].height = 64;
    (*layers)[0].texels.assign(64 * 64, -7.0f);
  }
  traceCpu(scene.data, std::span<const gpu::TraceView>(&view, 1), fast);
  traceCpu(scene.data, std::span<const gpu::TraceView>(&view, 1), reference, CpuTracePath::Reference);
  EXPECT_EQ(differingTexels(reference[0], fast[0]), 0u);
  std::size_t untouched = 0;
  for (float t : fast[0].texels) untouched += t == -7.0f;
  EXPECT_EQ(untouched, 64u * 64u - 27u * 21u);
}

// Scenes with many rotated instances and long objects: the lanes switch objects within one ray.
TEST(TraceCpuFast, InstancedScenesMatchReferenceBitForBit) {
  std::vector<test::TestScene> scenes;
  scenes.push_back(test::manyInstancesScene(2000));
  scenes.push_back(test::longObjectScene());
  scenes.push_back(test::floorScene());
  for (const auto& scene : scenes) {
    const Aabb& b = scene.data.worldBounds;
    glm::vec3 c = (b.min + b.max) * 0.5f;
    float r = glm::length(b.max - b.min);
    std::vector<gpu::TraceView> views = {
        test::directionalView(b, {-0.4f, -1.0f, -0.3f}, 128), test::directionalView(b, {1, -1, 0}, 128),
        test::distanceView(c + glm::vec3(0, r * 0.4f, 0), {0.2f, -1, 0.1f}, r * 2, 128),
        test::distanceView(c, {0, 0, 1}, r, 96)};
    views.push_back(views[2]);
    views.back().info.w = gpu::VS_DEPTH_POINT_VOXEL_CENTER;
    std::vector<ShadowLayer> reference, fast;
    traceCpu(scene.data, views, reference, CpuTracePath::Reference, 2);
    traceCpu(scene.data, views, fast, CpuTracePath::Interleaved, 2);
    for (std::size_t i = 0; i < views.size(); ++i)
      EXPECT_EQ(differingTexels(reference[i], fast[i]), 0u) << scene.name << " view " << i;
  }
}

}  // namespace
}  // namespace vs

namespace vs {
namespace {

// Every lane width equals the hierarchy walk bit for bit (and so the reference's box walk, which the other
// tests compare), on one instance and on many: a width sets up the rays of a many-instance scene a lane batch
// at a time (one BVH walk per batch), and a horizontal ray across the grid of instances crosses more boxes
// than a ray keeps candidates for, so it is also handed to the reference. A width this processor does not run
// is named as not compared.
TEST(TraceCpuFast, EveryLaneWidthMatchesTheHierarchyWalk) {
  std::vector<test::TestScene> scenes;
  scenes.push_back(test::city512Scene());
  scenes.push_back(test::manyInstancesScene(400));
  std::size_t compared = 0;
  for (const test::TestScene& scene : scenes) {
    const Aabb& b = scene.data.worldBounds;
    const glm::vec3 c = (b.min + b.max) * 0.5f;
    const float r = glm::length(b.max - b.min);
    std::vector<gpu::TraceView> views = {test::directionalView(b, {-0.4f, -1.0f, -0.3f}, 128),
                                         test::directionalView(b, {1, -1, 1}, 128),
                                         test::distanceView(c + glm::vec3(0, r * 0.5f, 0), {0.1f, -1, 0.2f}, r * 2, 128),
                                         test::distanceView(glm::vec3(c.x, b.min.y + 5.0f, b.min.z - 1.0f), {0, 0, 1}, r, 96)};
    views[1].info.w = gpu::VS_DEPTH_POINT_VOXEL_CENTER;
    std::vector<ShadowLayer> hierarchy;
    traceCpu(scene.data, views, hierarchy, CpuTracePath::PortableTiles, 1);
    for (auto [path, width] : {std::pair{CpuTracePath::LanesScalar, LaneWidth::Scalar},
                               std::pair{CpuTracePath::LanesAvx2, LaneWidth::Avx2},
                               std::pair{CpuTracePath::LanesAvx512, LaneWidth::Avx512}}) {
      if (!laneWidthSupported(width)) {
        std::printf("NOT COMPARED: this processor does not run the %s lane tracer\n", laneWidthName(width));
        EXPECT_THROW(traceCpu(scene.data, views, hierarchy, path, 1), Error);
        continue;
      }
      std::vector<ShadowLayer> lanes;
      traceCpu(scene.data, views, lanes, path, 1);
      for (std::size_t i = 0; i < views.size(); ++i)
        EXPECT_EQ(differingTexels(hierarchy[i], lanes[i]), 0u) << scene.name << ", " << laneWidthName(width) << " view " << i;
      ++compared;
    }
  }
  EXPECT_GE(compared, 2u);
}

}  // namespace
}  // namespace vs

namespace vs {
namespace {

// A plain voxel-by-voxel walk in the canonical order of traverse.h, written out here: exit through the nearest
// plane (the highest axis on ties), step one voxel, test it. The hierarchical walk skips empty cells of up to
// 128 voxels and the fast path skips larger empty boxes still; both must stop where this walk stops, at the
// same t bit for bit.
bool voxelWalk(const Brickmap& bm, gpu::SceneArrays& arrays, glm::vec3 o, glm::vec3 d, float tMin, float tMax,
               float& tHit, glm::ivec3& voxel) {
  gpu::SceneArrays::ObjectWalk w;
  if (!arrays.vsObjectWalkBegin(0, o, d, tMin, tMax, w)) return false;
  for (;;) {
    if (bm.isSolid(w.v)) {
      tHit = w.tEnter;
      voxel = w.v;
      return true;
    }
    float tExit = gpu::VS_T_INFINITY;
    int exitAxis = -1;
    for (int a = 0; a < 3; ++a) {
      if (w.d[a] == 0.0f) continue;
      float ta = (float(w.d[a] > 0.0f ? w.v[a] + 1 : w.v[a]) - w.o[a]) * w.invD[a];
      if (ta <= tExit) tExit = ta, exitAxis = a;
    }
    if (exitAxis < 0 || tExit >= w.t1) return false;
    w.v[exitAxis] += w.d[exitAxis] > 0.0f ? 1 : -1;
    if (w.v[exitAxis] < w.obj.voxelMin[exitAxis] || w.v[exitAxis] >= w.obj.voxelMax[exitAxis]) return false;
    w.tEnter = std::max(tExit, w.tEnter);
  }
}

TEST(TraceCpuCanonicalOrder, HierarchicalWalkEqualsVoxelWalk) {
  std::vector<test::TestScene> scenes;
  scenes.push_back(test::floorScene());
  scenes.push_back(test::city512Scene());
  for (const test::TestScene& scene : scenes) {
    gpu::SceneArrays arrays(scene.data);
    // The same walks over the box table (vsObjectWalkBoxes), which vsTraceObject takes when one is bound.
    const std::vector<std::int32_t> boxTable = buildBoxTable(scene.data);
    ASSERT_FALSE(boxTable.empty());
    gpu::SceneArrays boxArrays(scene.data);
    boxArrays.boxTable = boxTable.data();
    const Brickmap& bm = *scene.brickmaps[0];
    std::vector<gpu::TraceView> views = {test::directionalView(scene.data.worldBounds, {-0.4f, -1.0f, -0.3f}, 96),
                                         gridView(glm::vec3(48, 8, 48), {1, -1, 0}, 96.0f, 96),
                                         gridView(glm::vec3(256, 128, 256), {-1, -1, 1}, 96.0f, 96),
                                         test::distanceView({40.0f, 20.0f, 40.0f}, {0.3f, -1, 0.2f}, 600.0f, 96)};
    std::size_t hits = 0;
    for (const gpu::TraceView& view : views)
      for (int y = 0; y < view.info.y; ++y)
        for (int x = 0; x < view.info.x; ++x) {
          gpu::SceneArrays::WorldRay ray;
          arrays.vsViewRay(view, {x, y}, ray);
          float tBase = arrays.vsInstanceBaseT(ray, 0u);
          glm::vec3 lo, ld;
          arrays.vsInstanceRay(ray, 0u, tBase, lo, ld);
          const float tMax = arrays.vsLocalT(ray.tMax, tBase);
          float t = 0, tv = 0;
          glm::ivec3 v(0), vv(0);
          const float tMin = arrays.vsLocalT(0.0f, tBase);
          bool hit = arrays.vsTraceObject(0, lo, ld, tMin, tMax, t, v);
          bool hitv = voxelWalk(bm, arrays, lo, ld, tMin, tMax, tv, vv);
          float tb = 0;
          glm::ivec3 vb(0);
          bool hitb = boxArrays.vsTraceObject(0, lo, ld, tMin, tMax, tb, vb);
          ASSERT_EQ(hit, hitv) << scene.name << " texel " << x << "," << y;
          ASSERT_EQ(hitb, hitv) << scene.name << " texel " << x << "," << y << " (box table)";
          if (!hit) continue;
          ++hits;
          ASSERT_EQ(v, vv) << scene.name << " texel " << x << "," << y;
          ASSERT_EQ(std::memcmp(&t, &tv, sizeof t), 0) << scene.name << " texel " << x << "," << y;
          ASSERT_EQ(vb, vv) << scene.name << " texel " << x << "," << y << " (box table)";
          ASSERT_EQ(std::memcmp(&tb, &tv, sizeof t), 0) << scene.name << " texel " << x << "," << y << " (box table)";
        }
    EXPECT_GT(hits, 1000u) << scene.name;
  }
}

// Every empty brick's box (compute/box_table.cpp) holds no solid voxel, and each of its faces below the extent cap
// is blocked: the slab of bricks beyond it holds one.
TEST(TraceCpuFast, EmptyBrickBoxesAreEmptyAndBlocked) {
  auto scene = test::floorScene();
  const std::vector<std::int32_t> table = buildBoxTable(scene.data);
  ASSERT_FALSE(table.empty());
  const Brickmap& bm = *scene.brickmaps[0];
  const gpu::ObjectRecord& obj = scene.data.objects[0];
  const glm::ivec3 dims = 16 * glm::ivec3(obj.regionDims), origin = 16 * glm::ivec3(obj.regionOrigin);
  auto brickSolid = [&](glm::ivec3 b) {
    for (int z = 0; z < 8; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x)
          if (bm.isSolid(b * 8 + glm::ivec3(x, y, z))) return true;
    return false;
  };
  std::vector<char> solid(std::size_t(dims.x) * dims.y * dims.z);
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x)
        solid[(std::size_t(z) * dims.y + y) * dims.x + x] = brickSolid(origin + glm::ivec3(x, y, z));
  auto anySolid = [&](glm::ivec3 lo, glm::ivec3 hi) {  // inclusive brick box, clipped to the grid
    lo = glm::max(lo, glm::ivec3(0));
    hi = glm::min(hi, dims - 1);
    for (int z = lo.z; z <= hi.z; ++z)
      for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x)
          if (solid[(std::size_t(z) * dims.y + y) * dims.x + x]) return true;
    return false;
  };
  std::size_t boxes = 0, aligned = 0, elongated = 0;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        std::int32_t code = table[std::size_t(table[0]) + (std::size_t(z) * dims.y + y) * dims.x + x];
        bool isSolid = solid[(std::size_t(z) * dims.y + y) * dims.x + x];
        ASSERT_EQ(isSolid, code >= 0 || code == gpu::VS_BOX_FULL) << x << "," << y << "," << z;
        if (isSolid) continue;
        int box = -1 - code, log2 = box >> 24;
        glm::ivec3 b(x, y, z);
        if (log2 != gpu::VS_BRICK_LOG2) {
          ASSERT_EQ(box & 0xffffff, 0);
          int n = 1 << (log2 - gpu::VS_BRICK_LOG2);
          glm::ivec3 lo = ((origin + b) >> (log2 - gpu::VS_BRICK_LOG2)) * n - origin;
          ASSERT_FALSE(anySolid(lo, lo + n - 1)) << x << "," << y << "," << z;
          ++aligned;
          continue;
        }
        int ext[6];
        for (int f = 0; f < 6; ++f) ext[f] = (box >> (4 * f)) & 15;
        glm::ivec3 lo = b - glm::ivec3(ext[0], ext[2], ext[4]), hi = b + glm::ivec3(ext[1], ext[3], ext[5]);
        ASSERT_FALSE(anySolid(lo, hi)) << x << "," << y << "," << z;
        for (int f = 0; f < 6; ++f) {
          if (ext[f] == kMaxBoxExtent) continue;
          glm::ivec3 slo = lo, shi = hi;
          int a = f / 2;
          if (f % 2 == 0) slo[a] = shi[a] = lo[a] - 1;
          else slo[a] = shi[a] = hi[a] + 1;
          ASSERT_TRUE(anySolid(slo, shi)) << x << "," << y << "," << z << " face " << f;
        }
        ++boxes;
        elongated += *std::max_element(ext, ext + 6) != *std::min_element(ext, ext + 6);
      }
  EXPECT_GT(boxes, 100u);
  EXPECT_GT(elongated, 100u);
  std::printf("%zu grown boxes (%zu not cubes), %zu empty sectors or regions kept\n", boxes, elongated, aligned);
}

// A CpuTracer keeps its tables between traces and rebuilds them after voxelsChanged(): every trace equals the
// reference of the scene as it is then.
TEST(CpuTracer, KeepsTablesUntilVoxelsChange) {
  auto scene = test::floorScene();
  std::vector<gpu::TraceView> views = {test::directionalView(scene.data.worldBounds, {-0.4f, -1.0f, -0.3f}, 96),
                                       test::distanceView({40.0f, 60.0f, 40.0f}, {0.1f, -1, 0.2f}, 300.0f, 64)};
  CpuTracer tracer(scene.data);
  std::vector<ShadowLayer> first, second, reference;
  tracer.trace(views, first, CpuTracePath::Interleaved, 2);
  tracer.trace(views, second, CpuTracePath::Interleaved, 2);
  traceCpu(scene.data, views, reference, CpuTracePath::Reference, 2);
  for (std::size_t i = 0; i < views.size(); ++i) {
    EXPECT_EQ(differingTexels(reference[i], first[i]), 0u);
    EXPECT_EQ(differingTexels(reference[i], second[i]), 0u);
  }
  // A new block on the floor, the scene's arrays rebuilt in place.
  scene.brickmaps[0]->fillBox(VoxelBox{{20, 8, 60}, {36, 30, 76}}, 1);
  scene.finish();
  tracer.voxelsChanged();
  std::vector<ShadowLayer> edited, editedReference;
  tracer.trace(views, edited, CpuTracePath::Interleaved, 2);
  traceCpu(scene.data, views, editedReference, CpuTracePath::Reference, 2);
  std::size_t changed = 0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    EXPECT_EQ(differingTexels(editedReference[i], edited[i]), 0u);
    changed += differingTexels(reference[i], edited[i]);
  }
  EXPECT_GT(changed, 100u);
}

}  // namespace
}  // namespace vs

namespace vs {

// A ray with a NaN or infinite component is a miss on every CPU path, never a voxel index out of range.
TEST(TraceCpuFast, NonFiniteRaysAreMisses) {
  for (const test::TestScene& scene : test::hostileViewScenes()) {
    SCOPED_TRACE(scene.name);
    std::vector<test::HostileView> hostile = test::hostileViews(scene.data.worldBounds);
    for (CpuTracePath path : {CpuTracePath::Reference, CpuTracePath::Interleaved}) {
      std::vector<ShadowLayer> layers;
      traceCpu(scene.data, test::traceViewsOf(hostile), layers, path, 2);
      test::expectAllMisses(hostile, layers);
    }
  }
}

}  // namespace vs
