// exact_reference.h: an independent double-precision ray tracer for the exactness tests.
//
// Nothing here uses compute/shared: the rays come from a view's stored eye and eyeToClip (DESIGN.md §9), the
// instances enter brick space through the inverse of their double transforms (SceneInstance), and a plain
// two-level voxel walk in double (8^3 bricks, then voxels) finds the first solid voxel. Its rounding errors are
// some 10^-9 of the tracers', so a disagreement beyond the tolerances is the tracer's.
#ifndef VOXSHADOW_EXACT_REFERENCE_H
#define VOXSHADOW_EXACT_REFERENCE_H

#include <cstdint>
#include <span>
#include <unordered_set>
#include <vector>

#include <glm/glm.hpp>

#include "compute/scene_data.h"
#include "voxel/brickmap.h"

namespace vs::test {

// The points o + t*d, t in [tMin, tMax].
struct ExactRay {
  glm::dvec3 o{0.0}, d{0.0};
  double tMin = 0.0, tMax = 0.0;
};

// Texel (x, y)'s ray of a view of size width x height, from the eye and the view-projection about it:
// NDC-depth views run from the near plane (t = 0) to the far plane (t = 1); linear-distance views start at the
// eye with |d| = 1 and t in [0, range].
ExactRay exactTexelRay(const glm::dvec3& eye, const glm::dmat4& eyeToClip, bool ndcDepth, double range, int width,
                       int height, int x, int y);

struct ExactHit {
  bool hit = false;
  double t = 0.0;             // where the ray enters the hit voxel
  std::size_t instance = 0;
  glm::ivec3 voxel{0};
  double voxelsPerT = 0.0;    // voxels of the hit instance per unit of t
  // The face of the hit voxel the ray entered through (the near plane crossed last; VS_FACE_* numbering of
  // compute/shared/trace_rays.h: 2 * axis, + 1 when the ray moves toward -axis; 6 when the ray starts inside
  // the voxel), and how far, in voxels along the ray, the runner-up plane or the ray's start lies from that
  // plane: below a tracer's rounding the face is a tie either tracer may break its own way.
  unsigned face = 6;
  double faceMargin = 0.0;
};

class ExactReference {
 public:
  // Preconditions: instances[i].object < objects.size(); the objects outlive the reference.
  ExactReference(std::span<const Brickmap* const> objects, std::span<const SceneInstance> instances);

  // The nearest solid voxel over every instance.
  ExactHit trace(const ExactRay& ray) const;

  // Whether the ray passes a solid voxel of some instance at about t (within `slackVoxels` of it along the
  // ray) over at most `tolerance` voxels of its length, touching it or missing it by at most `tolerance`
  // voxels: an edge or corner contact, where two tracers within `tolerance` of each other may decide
  // differently.
  bool grazesNear(const ExactRay& ray, double t, double slackVoxels, double tolerance) const;

  // Where the ray's segment enters voxel `voxel` of instance `instance`, in t; negative when it does not
  // (whether or not the voxel is solid).
  double entryT(const ExactRay& ray, std::size_t instance, glm::ivec3 voxel) const;

 private:
  struct Placed {
    const Brickmap* brickmap;
    glm::dmat4 worldToBrick;
    glm::ivec3 vmin, vmax;  // the object's voxel box, max exclusive
    std::unordered_set<std::uint64_t> bricks;  // 8^3 bricks holding a solid voxel
  };
  std::vector<Placed> placed_;
};

}  // namespace vs::test

#endif
