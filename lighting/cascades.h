// cascades.h: cascaded shadow views of a directional light (DESIGN.md §7): the practical split scheme, one
// bounding sphere per frustum slice, a light-space origin snapped to whole texels and a depth range taken from
// the scene bounds. Each step is chosen so that a moving camera changes a cascade's matrices only by whole
// texels: the sphere's size depends on the camera's intrinsics alone (rotation-invariant), the snap removes
// sub-texel motion, and the depth range does not follow the camera at all.
#ifndef VOXSHADOW_CASCADES_H
#define VOXSHADOW_CASCADES_H

#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/type_precision.hpp>

#include "bvh/bvh.h"
#include "lighting/camera.h"

namespace vs {

// The view depths (distance along the camera's forward axis) that bound the cascades: count + 1 values from
// nearPlane to farPlane, each split lambda * logarithmic + (1 - lambda) * uniform.
// Preconditions: 0 < nearPlane < farPlane, 1 <= count <= 4, 0 <= lambda <= 1.
std::vector<double> cascadeSplits(double nearPlane, double farPlane, int count, double lambda);

struct CascadeFit {
  glm::dmat4 worldToClip{1.0};  // the orthographic view-projection (Vulkan clip, y flipped as every view)
  glm::dvec3 eye{0.0};          // the centre of its near plane: where its rays' eye-relative origins start
  double texelWorld = 0.0;      // world size of one texel
  double diameter = 0.0;        // of the bounding sphere, rounded up
  glm::dvec2 snappedCentre{0.0};  // the sphere's centre in light space, on whole texels
  // The light-space texel grid the cascade is a window of (DESIGN.md §11): global texel (gx, gy) covers
  // light-space x in [gx, gx + 1) * texelWorld and y in (-(gy + 1), -gy] * texelWorld (rows grow downwards, as
  // layer rows do). The grid depends on the light, the camera's intrinsics, the splits and the depth range,
  // never on where the camera is; windowOrigin, the global texel of the window's texel (0, 0), does.
  glm::dmat3 basis{1.0};        // lightBasis(lightDirection)
  double nearDist = 0.0, farDist = 0.0;  // the depth range, distances along the light from the light-space origin
  glm::i64vec2 windowOrigin{0};
};

// Fits one cascade: the slice [sliceNear, sliceFar] of the camera's frustum, as seen along `lightDirection`
// (unit, where the light travels), at `resolution` texels a side, with a depth range that covers worldBounds
// (empty bounds: a unit box at the origin) rounded outward by depthRangeBounds. Preconditions:
// 0 < sliceNear < sliceFar; resolution > 0.
CascadeFit fitCascade(const CameraFrame& camera, double sliceNear, double sliceFar, const glm::dvec3& lightDirection,
                      int resolution, const Aabb& worldBounds);

// The box a directional view's depth range is fitted to: the bounds rounded outward to a grid of a quarter of
// their largest side (a power of two), plus one step. It is a function of the bounds alone, so a renderer kept
// across frames and a new one agree on it, and it stays put while edits and moves change the bounds by less
// than a step: the depth range, and with it every texel, does not follow each voxel an edit adds.
Aabb depthRangeBounds(const Aabb& worldBounds);

// The light-space basis of a directional light: rows right, up, -forward (a lookAt rotation); the same one
// for every cascade and every frame, so that snapping in it is stable.
glm::dmat3 lightBasis(const glm::dvec3& lightDirection);

}  // namespace vs

#endif
