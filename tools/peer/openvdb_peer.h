// openvdb_peer.h: the independent reference and benchmark peer (DESIGN.md §6, §10): OpenVDB's
// VolumeRayIntersector<BoolGrid, 0> + math::DDA over BoolGrids holding the same voxels as the brickmaps.
#ifndef VOXSHADOW_OPENVDB_PEER_H
#define VOXSHADOW_OPENVDB_PEER_H

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>
#include <openvdb/openvdb.h>

#include "compute/cpu/scene_arrays.h"
#include "compute/scene_data.h"

namespace vs {

class OpenVdbPeer {
 public:
  // One BoolGrid per object, filled from the brickmap's solid voxels (brick-space voxel v is index ijk = v:
  // the intersector treats index voxel ijk as the cube [ijk, ijk+1), as brick space does). Rays enter each
  // instance through the scene's own float world-to-brick maps, evaluated as the traversal does, so that both
  // tracers walk identical brick-space rays and differ only in how they walk them.
  // Preconditions: scene was built from these brickmaps; the grids are copies (nothing needs to outlive).
  OpenVdbPeer(std::span<const Brickmap* const> brickmaps, const SceneData& scene);
  ~OpenVdbPeer();

  // Wraps a ready BoolGrid as object 0 with one identity instance (benchmarks build it once).
  explicit OpenVdbPeer(openvdb::BoolGrid::Ptr grid);

  // Closest hit of the world ray over every instance (brute force); each instance is entered through the
  // traversal's own re-based brick-space ray (vsInstanceBaseT, vsInstanceRay), and t is the world t.
  // tHit is the entry time of the hit voxel. Thread-safe.
  bool trace(const gpu::SceneArrays::WorldRay& ray, double& tHit, std::uint32_t& instance, glm::ivec3& voxel) const;
  // With anyHit, the first instance that holds a hit ends the search (visibility rays: whether, not where).
  bool trace(const gpu::SceneArrays::WorldRay& ray, double& tHit, std::uint32_t& instance, glm::ivec3& voxel,
             bool anyHit) const;
  // Whether each ray hits (closest-hit rays, or any-hit rays with anyHit), 1 or 0 per ray. threads <= 0: all.
  std::vector<std::uint8_t> traceRays(std::span<const gpu::TraceRay> rays, bool anyHit, int threads = 0) const;
  // The same for the ray o + t*d, t in [tMin, tMax].
  bool trace(const glm::vec3& o, const glm::vec3& d, double tMin, double tMax, double& tHit,
             std::uint32_t& instance, glm::ivec3& voxel) const;

  // Traces every texel of each view's rectangle with the same float ray the portable traversal builds
  // (vsViewRay) and returns the texel values (entry depth point; miss = t range end). threads <= 0: all.
  std::vector<std::vector<float>> traceViews(const SceneData& scene, std::span<const gpu::TraceView> views,
                                             int threads = 0) const;

  struct Object;  // a BoolGrid and its master intersector (defined in the .cpp)

 private:
  std::vector<std::unique_ptr<Object>> objects_;
  std::vector<gpu::InstanceRecord> instances_;
  struct ThreadStates;
  std::unique_ptr<ThreadStates> threads_;  // per-thread intersector copies (accessors are not shareable)
};

}  // namespace vs

#endif
