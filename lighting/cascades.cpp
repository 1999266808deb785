// cascades.cpp: split, fit, snap.
#include "lighting/cascades.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/gtc/matrix_transform.hpp>

namespace vs {

std::vector<double> cascadeSplits(double nearPlane, double farPlane, int count, double lambda) {
  std::vector<double> splits(std::size_t(count) + 1);
  for (int i = 0; i <= count; ++i) {
    const double f = double(i) / double(count);
    const double logarithmic = nearPlane * std::pow(farPlane / nearPlane, f);
    const double uniform = nearPlane + (farPlane - nearPlane) * f;
    splits[std::size_t(i)] = lambda * logarithmic + (1.0 - lambda) * uniform;
  }
  // Exact ends: a pixel at the far plane still falls in the last cascade.
  splits.front() = nearPlane;
  splits.back() = farPlane;
  return splits;
}

glm::dmat3 lightBasis(const glm::dvec3& lightDirection) {
  const glm::dvec3 forward = glm::normalize(lightDirection);
  const glm::dvec3 worldUp = std::abs(forward.y) < 0.99 ? glm::dvec3(0.0, 1.0, 0.0) : glm::dvec3(0.0, 0.0, 1.0);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, worldUp));
  const glm::dvec3 up = glm::cross(right, forward);
  // Rows: glm is column-major, so the transpose of the columns (right, up, -forward).
  return glm::transpose(glm::dmat3(right, up, -forward));
}

namespace {

// The sphere's diameter is rounded up to 1/64 of its power of two: it depends only on the camera's
// intrinsics and the splits, but is computed from floating-point corners, and a last-bit change would change
// the texel size and with it every texel.
double roundUpDiameter(double d) {
  const double quantum = std::exp2(std::floor(std::log2(d)) - 6.0);
  return std::ceil(d / quantum) * quantum;
}

}  // namespace

Aabb depthRangeBounds(const Aabb& worldBounds) {
  if (worldBounds.empty()) return worldBounds;
  const glm::dvec3 lo(worldBounds.min), hi(worldBounds.max);
  const glm::dvec3 size = hi - lo;
  const double side = std::max({size.x, size.y, size.z, 1.0});
  const double step = std::exp2(std::ceil(std::log2(side / 4.0)));
  Aabb out;
  out.min = glm::vec3((glm::floor(lo / step) - 1.0) * step);
  out.max = glm::vec3((glm::ceil(hi / step) + 1.0) * step);
  return out;
}

CascadeFit fitCascade(const CameraFrame& camera, double sliceNear, double sliceFar, const glm::dvec3& lightDirection,
                      int resolution, const Aabb& worldBounds) {
  // The slice's corners lie at distance z * k from the view axis (k: the half-diagonal slope of the frustum).
  // The smallest sphere through both end rectangles has its centre on the axis where they are equidistant,
  // or at the far rectangle's centre when that one alone encloses both.
  const double k2 = camera.tanHalfFovY * camera.tanHalfFovY * (1.0 + camera.aspect * camera.aspect);
  const double n = sliceNear, f = sliceFar;
  const double c = std::min(f, 0.5 * (n + f) * (1.0 + k2));
  const double radius = std::sqrt((f - c) * (f - c) + f * f * k2);
  CascadeFit fit;
  fit.diameter = roundUpDiameter(2.0 * radius);
  fit.texelWorld = fit.diameter / double(resolution);

  const glm::dmat3 basis = lightBasis(lightDirection);
  const glm::dvec3 centre = camera.position + camera.forward * c;
  const glm::dvec3 lightCentre = basis * centre;
  // Whole texels: a camera that moves by less than a texel leaves the matrices bit-identical, and one that
  // moves further scrolls the layer by whole texels.
  const double cellX = std::floor(lightCentre.x / fit.texelWorld), cellY = std::floor(lightCentre.y / fit.texelWorld);
  fit.snappedCentre = glm::dvec2(cellX * fit.texelWorld, cellY * fit.texelWorld);
  // The window spans cellX -+ resolution / 2 texels; its top row is the highest light-space y.
  fit.windowOrigin = glm::i64vec2(std::int64_t(cellX) - resolution / 2, -(std::int64_t(cellY) + resolution / 2));
  fit.basis = basis;

  // Depth along the light from the scene bounds (not the slice): every caster is in front of the near plane,
  // whichever part of the scene the camera sees, and the range never changes with the camera.
  glm::dvec3 lo(-0.5), hi(0.5);
  const Aabb depthBox = depthRangeBounds(worldBounds);
  if (!depthBox.empty()) {
    lo = glm::dvec3(depthBox.min);
    hi = glm::dvec3(depthBox.max);
  }
  double zMin = std::numeric_limits<double>::infinity(), zMax = -zMin;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::dvec3 p((corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y, (corner & 4) ? hi.z : lo.z);
    const double z = (basis * p).z;  // -distance along the light
    zMin = std::min(zMin, z);
    zMax = std::max(zMax, z);
  }
  const double size = std::max(glm::length(hi - lo), 1.0);
  const double pad = 1e-3 * size;
  const double nearDist = -zMax - pad, farDist = -zMin + pad;
  fit.nearDist = nearDist;
  fit.farDist = farDist;

  const double r = 0.5 * fit.diameter;
  const glm::dvec2 s = fit.snappedCentre;
  const glm::dmat4 view(basis);  // world -> light space, rotation only
  const glm::dmat4 proj = glm::orthoRH_ZO(s.x - r, s.x + r, s.y - r, s.y + r, nearDist, farDist);
  const glm::dmat4 flipY = glm::scale(glm::dmat4(1.0), glm::dvec3(1.0, -1.0, 1.0));
  fit.worldToClip = flipY * proj * view;
  // The near plane's centre, back in world space (the basis is orthonormal: its inverse is its transpose).
  fit.eye = glm::transpose(basis) * glm::dvec3(s.x, s.y, -nearDist);
  return fit;
}

}  // namespace vs
