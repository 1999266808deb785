// embree_peer.h: the triangle-tracer peer of the benchmark (DESIGN.md §10): Intel Embree 3 over a watertight
// triangle mesh of each object's voxels, one Embree instance per scene instance, BVH quality HIGH, robust
// (watertight) intersection. What a user would compare a voxel tracer with.
//
// The mesh: for each face direction and each slice, the exposed voxel faces merged into maximal rectangles
// (greedy, row by row), then every rectangle's boundary split at each rectangle corner that lies on it (of any
// rectangle, in any plane), and triangulated as a fan around its centre (two triangles where no corner lies on
// its edges). Every edge then meets its neighbour's edge at identical vertices, with no T-junction, so the mesh
// is watertight; all vertices lie on the half-integer grid of brick space, exact in float.
#ifndef VOXSHADOW_EMBREE_PEER_H
#define VOXSHADOW_EMBREE_PEER_H

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "compute/scene_data.h"
#include "compute/shared/trace_rays.h"

namespace vs {

class Brickmap;

class EmbreePeer {
 public:
  // Meshes each object's solid voxels (brick-space voxel v is the cube [v, v + 1)) and instances them with the
  // scene's brick-to-world maps. Preconditions: `scene` was built from these brickmaps, in order. Throws
  // vs::Error(Runtime) when Embree fails (its message named) or an object's box is too large to mesh (more
  // than 2^34 voxels).
  EmbreePeer(std::span<const Brickmap* const> brickmaps, const SceneData& scene);
  ~EmbreePeer();
  EmbreePeer(const EmbreePeer&) = delete;
  EmbreePeer& operator=(const EmbreePeer&) = delete;

  // Closest hits, as RayHit records: hit, world t of the entry, instance, the hit voxel in brick space and its
  // entry face (xyz, w: VS_FACE_*; a ray starting inside a solid meets its exit face, which the voxel tracers
  // report as VS_FACE_NONE at tMin), material 0. On a miss: hit 0, t the ray's tMax.
  // packets8: rtcIntersect8 over consecutive groups of 8 rays (the caller orders them, e.g. 4x2 texel blocks),
  // with the coherent context flag; else rtcIntersect1 per ray. threads <= 0: every hardware thread.
  // Preconditions: hits as long as rays.
  void intersect(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits, bool packets8,
                 int threads = 0) const;
  // Any hit in [tMin, tMax] (1 or 0 per ray), rtcOccluded8 over consecutive groups of 8 rays.
  void occluded8(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded, int threads = 0) const;

  // Mesh edges (vertex pairs) used by an odd number of triangles, over every object: 0 for a watertight mesh
  // (each edge of a closed surface is met by two triangles, or four where two voxels touch only along it).
  std::uint64_t unpairedEdges() const;

  std::uint64_t triangleCount() const { return triangles_; }
  // The Embree release this peer was built with, e.g. "3.13.5".
  static const char* version();
  std::uint64_t rectangleCount() const { return rectangles_; }

  struct State;  // the Embree device, scenes and per-triangle faces (defined in the .cpp)

 private:
  std::unique_ptr<State> state_;
  std::uint64_t triangles_ = 0, rectangles_ = 0;
};

}  // namespace vs

#endif
