// The Embree peer of the benchmark (tools/peer/embree_peer.h) against the reference tracer on the kinds of rays
// the benchmark gives it (shadow texels of a sun and of a spot light, camera rays, visibility rays toward a
// light): hit or miss agree on at least 99.99% of rays (the rest graze voxel edges, where a triangle mesh and a
// voxel walk may decide a tie differently), and where both hit, the entry depth within 1e-3 voxel and the same
// voxel and face, on instanced, rotated, non-uniformly scaled objects and on real third-party assets; and the
// mesh is watertight (no edge met by an odd number of triangles).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "compute/tracer.h"
#include "support/test_scenes.h"
#include "tools/peer/embree_peer.h"

namespace vs {
namespace {

using test::TestScene;

// The world size of a voxel of instance i (the cube root of its map's determinant).
double voxelWorldSize(const SceneData& data, std::uint32_t i) {
  const gpu::Affine& m = data.instances[i].brickToWorld;
  const glm::dmat3 linear(glm::dvec3(m.row0.x, m.row1.x, m.row2.x), glm::dvec3(m.row0.y, m.row1.y, m.row2.y),
                          glm::dvec3(m.row0.z, m.row1.z, m.row2.z));
  return std::cbrt(std::abs(glm::determinant(linear)));
}

// The benchmark's kinds of rays over a scene's world box, `count` of each: parallel rays of a sun, rays fanning
// out of a spot light, rays from a camera through the box, and segments from surface points toward a light
// (from where the reference's camera rays hit, moved back off the surface by 1e-3 of the ray's length).
std::vector<gpu::TraceRay> benchmarkRays(const TestScene& scene, std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const glm::dvec3 lo(scene.data.worldBounds.min), hi(scene.data.worldBounds.max);
  const glm::dvec3 centre = (lo + hi) * 0.5, extent = hi - lo;
  const double reach = glm::length(extent);
  auto inBox = [&] { return lo + extent * glm::dvec3(unit(rng), unit(rng), unit(rng)); };
  std::vector<gpu::TraceRay> rays;
  const glm::dvec3 sun = glm::normalize(glm::dvec3(-0.35, -1.0, -0.55));
  for (std::size_t i = 0; i < count; ++i) {  // the sun: origins on a plane before the box
    const glm::dvec3 target = inBox();
    rays.push_back(gpu::makeTraceRay(target - sun * reach, sun, 0.0f, float(2.0 * reach)));
  }
  const glm::dvec3 spot = centre + glm::dvec3(0.3, 0.8, 0.2) * reach;
  for (std::size_t i = 0; i < count; ++i)
    rays.push_back(gpu::makeTraceRay(spot, glm::normalize(inBox() - spot), 0.0f, float(2.0 * reach)));
  const glm::dvec3 eye = centre + glm::dvec3(0.6, 0.4, 0.7) * reach;
  std::vector<gpu::TraceRay> camera;
  for (std::size_t i = 0; i < count; ++i)
    camera.push_back(gpu::makeTraceRay(eye, glm::normalize(inBox() - eye), 0.0f, float(3.0 * reach)));
  rays.insert(rays.end(), camera.begin(), camera.end());
  auto reference = makeCpuTracer({CpuTracePath::Reference, 0});
  reference->setScene(scene.data);
  std::vector<gpu::RayHit> hits(camera.size());
  reference->traceClosest(camera, hits);
  const glm::dvec3 light = centre + glm::dvec3(-0.5, 0.9, 0.1) * reach;
  for (std::size_t i = 0; i < camera.size(); ++i) {
    if (!hits[i].hit) continue;
    const glm::dvec3 o = glm::dvec3(glm::vec3(camera[i].originHigh)) + glm::dvec3(glm::vec3(camera[i].originLow));
    const glm::dvec3 d(glm::vec3(camera[i].direction));
    const glm::dvec3 p = o + d * (double(hits[i].t) * (1.0 - 1e-3));
    rays.push_back(gpu::makeTraceRay(p, glm::normalize(light - p), 0.0f, float(glm::length(light - p))));
  }
  return rays;
}

struct Agreement {
  std::size_t rays = 0, hitMissDiffer = 0, bothHit = 0, depthDiffer = 0, voxelDiffer = 0, insideStarts = 0;
  double worstDepthVoxels = 0.0;
};

Agreement compare(const SceneData& data, const std::vector<gpu::RayHit>& peer, const std::vector<gpu::RayHit>& ref) {
  Agreement a;
  a.rays = ref.size();
  for (std::size_t i = 0; i < ref.size(); ++i) {
    if ((peer[i].hit != 0u) != (ref[i].hit != 0u)) {
      ++a.hitMissDiffer;
      continue;
    }
    if (!ref[i].hit) continue;
    if (std::uint32_t(ref[i].voxel.w) == gpu::VS_FACE_NONE) {  // started inside a solid: no entry to compare
      ++a.insideStarts;
      continue;
    }
    ++a.bothHit;
    const double voxels = std::abs(double(peer[i].t) - double(ref[i].t)) / voxelWorldSize(data, ref[i].instance);
    a.worstDepthVoxels = std::max(a.worstDepthVoxels, voxels);
    if (voxels > 1e-3) ++a.depthDiffer;
    if (peer[i].instance != ref[i].instance || peer[i].voxel != ref[i].voxel) ++a.voxelDiffer;
  }
  return a;
}

void expectAgreement(const char* what, const SceneData& data, const std::vector<gpu::RayHit>& peer,
                     const std::vector<gpu::RayHit>& ref) {
  const Agreement a = compare(data, peer, ref);
  std::printf("%-12s %zu rays: hit/miss differ on %zu; of %zu both hit, depth beyond 1e-3 voxel %zu (worst %.3g "
              "voxel), another voxel or face %zu; %zu start inside a solid\n",
              what, a.rays, a.hitMissDiffer, a.bothHit, a.depthDiffer, a.worstDepthVoxels, a.voxelDiffer,
              a.insideStarts);
  EXPECT_LE(double(a.hitMissDiffer), 1e-4 * double(a.rays)) << what;
  EXPECT_LE(double(a.depthDiffer), 1e-4 * double(a.rays)) << what;
  EXPECT_LE(double(a.voxelDiffer), 1e-4 * double(a.rays)) << what;
  EXPECT_GT(a.bothHit, a.rays / 10) << what << ": the rays meet the scene";
}

void checkScene(const TestScene& scene, std::size_t perKind) {
  SCOPED_TRACE(scene.name);
  const std::vector<const Brickmap*> brickmaps = scene.brickmapPointers();
  EmbreePeer peer(brickmaps, scene.data);
  std::printf("%s: %llu rectangles, %llu triangles\n", scene.name.c_str(),
              static_cast<unsigned long long>(peer.rectangleCount()),
              static_cast<unsigned long long>(peer.triangleCount()));
  EXPECT_EQ(peer.unpairedEdges(), 0u) << "the mesh is watertight: every edge is met by an even number of triangles";
  const std::vector<gpu::TraceRay> rays = benchmarkRays(scene, perKind, 41);
  auto reference = makeCpuTracer({CpuTracePath::Reference, 0});
  reference->setScene(scene.data);
  std::vector<gpu::RayHit> expected(rays.size());
  reference->traceClosest(rays, expected);
  std::vector<std::uint32_t> expectedAny(rays.size());
  reference->traceAny(rays, expectedAny);

  std::vector<gpu::RayHit> one(rays.size()), eight(rays.size());
  peer.intersect(rays, one, false);
  peer.intersect(rays, eight, true);
  expectAgreement("intersect1", scene.data, one, expected);
  expectAgreement("intersect8", scene.data, eight, expected);
  std::vector<std::uint32_t> occluded(rays.size());
  peer.occluded8(rays, occluded);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) differ += occluded[i] != expectedAny[i];
  std::printf("%-12s %zu rays: answers differ on %zu\n", "occluded8", rays.size(), differ);
  EXPECT_LE(double(differ), 1e-4 * double(rays.size()));
}

TEST(EmbreePeer, AgreesWithTheReferenceOnInstancedObjects) { checkScene(test::manyInstancesScene(24), 40000); }

TEST(EmbreePeer, AgreesWithTheReferenceOnThirdPartyAssets) { checkScene(test::thirdPartyAssetsScene(), 40000); }

TEST(EmbreePeer, AgreesWithTheReferenceOnAxisAlignedWalls) { checkScene(test::floorScene(), 40000); }

TEST(EmbreePeer, MeshesNothingOfAnEmptyObject) {
  TestScene scene = test::emptyObjectScene();
  const std::vector<const Brickmap*> brickmaps = scene.brickmapPointers();
  EmbreePeer peer(brickmaps, scene.data);
  EXPECT_EQ(peer.triangleCount(), 0u);
  const std::vector<gpu::TraceRay> rays = {
      gpu::makeTraceRay(glm::dvec3(-5.0), glm::normalize(glm::dvec3(1.0)), 0.0f, 100.0f)};
  std::vector<gpu::RayHit> hits(1);
  peer.intersect(rays, hits, false);
  EXPECT_EQ(hits[0].hit, 0u);
}

}  // namespace
}  // namespace vs
