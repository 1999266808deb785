#include "support/exact_reference.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vs::test {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::uint64_t key(glm::ivec3 c) {
  auto part = [](int v) { return std::uint64_t(std::uint32_t(v + (1 << 20))) & 0x1fffffu; };
  return part(c.x) | (part(c.y) << 21) | (part(c.z) << 42);
}

// [t0, t1] of the ray inside the box [lo, hi]; false when it misses.
bool clip(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi, double& t0,
          double& t1) {
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  return t0 <= t1;
}

// The cell of size `size` the ray is in just after t (moving along d).
glm::ivec3 cellAt(const glm::dvec3& o, const glm::dvec3& d, double t, int size) {
  glm::ivec3 c;
  for (int a = 0; a < 3; ++a) {
    double p = (o[a] + d[a] * t) / size;
    c[a] = d[a] >= 0.0 ? int(std::floor(p)) : int(std::ceil(p)) - 1;
  }
  return c;
}

// Walks the cells of size `size` inside [lo, hi) (cell units) along the ray for t in [t0, t1], calling
// visit(cell, tEnter, tExit) until it returns true; returns whether one did.
template <class Visit>
bool walkCells(const glm::dvec3& o, const glm::dvec3& d, double t0, double t1, int size, glm::ivec3 lo,
               glm::ivec3 hi, Visit visit) {
  glm::ivec3 c = glm::clamp(cellAt(o, d, t0, size), lo, hi - 1);
  double t = t0;
  for (int guard = 0; guard < 1 << 24; ++guard) {
    double tExit = kInf;
    int axis = -1;
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0.0) continue;
      double plane = double(d[a] > 0.0 ? c[a] + 1 : c[a]) * size;
      double ta = (plane - o[a]) / d[a];
      if (ta < tExit) tExit = ta, axis = a;
    }
    if (visit(c, t, std::min(std::max(tExit, t), t1))) return true;
    if (axis < 0 || tExit >= t1) return false;
    c[axis] += d[axis] > 0.0 ? 1 : -1;
    if (c[axis] < lo[axis] || c[axis] >= hi[axis]) return false;
    t = std::max(t, tExit);
  }
  return false;
}

// Length in t of the ray's segment [tMin, tMax] inside voxel v grown by `grow` on every side (negative: no
// intersection).
double spanInVoxel(const glm::dvec3& o, const glm::dvec3& d, double tMin, double tMax, glm::ivec3 v, double grow) {
  double t0 = tMin, t1 = tMax;
  if (!clip(o, d, glm::dvec3(v) - grow, glm::dvec3(v) + 1.0 + grow, t0, t1)) return -1.0;
  return t1 - t0;
}

}  // namespace

ExactRay exactTexelRay(const glm::dvec3& eye, const glm::dmat4& eyeToClip, bool ndcDepth, double range, int width,
                       int height, int x, int y) {
  glm::dmat4 clipToEye = glm::inverse(eyeToClip);
  double nx = (x + 0.5) / width * 2.0 - 1.0, ny = (y + 0.5) / height * 2.0 - 1.0;
  glm::dvec4 f = clipToEye * glm::dvec4(nx, ny, 1.0, 1.0);
  glm::dvec3 farP = glm::dvec3(f) / f.w;
  ExactRay r;
  if (ndcDepth) {
    glm::dvec4 n = clipToEye * glm::dvec4(nx, ny, 0.0, 1.0);
    glm::dvec3 nearP = glm::dvec3(n) / n.w;
    r.o = eye + nearP;
    r.d = farP - nearP;
    r.tMax = 1.0;
  } else {
    r.o = eye;
    r.d = glm::normalize(farP);
    r.tMax = range;
  }
  return r;
}

ExactReference::ExactReference(std::span<const Brickmap* const> objects, std::span<const SceneInstance> instances) {
  std::vector<std::unordered_set<std::uint64_t>> bricks(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i)
    objects[i]->forEachSolid([&](glm::ivec3 v, std::uint8_t) { bricks[i].insert(key(v >> 3)); });
  for (const SceneInstance& inst : instances) {
    const Brickmap* bm = objects[inst.object];
    VoxelBox box = bm->bounds();
    placed_.push_back({bm, glm::inverse(inst.brickToWorld), box.min, box.max, bricks[inst.object]});
  }
}

ExactHit ExactReference::trace(const ExactRay& ray) const {
  ExactHit best;
  best.t = ray.tMax;
  for (std::size_t i = 0; i < placed_.size(); ++i) {
    const Placed& p = placed_[i];
    if (glm::any(glm::greaterThanEqual(p.vmin, p.vmax))) continue;
    glm::dvec3 o(p.worldToBrick * glm::dvec4(ray.o, 1.0)), d(p.worldToBrick * glm::dvec4(ray.d, 0.0));
    double t0 = ray.tMin, t1 = best.hit ? best.t : ray.tMax;
    if (!clip(o, d, glm::dvec3(p.vmin), glm::dvec3(p.vmax), t0, t1)) continue;
    glm::ivec3 blo = p.vmin >> 3, bhi = ((p.vmax - 1) >> 3) + 1;
    double tHit = 0.0;
    glm::ivec3 voxel(0);
    bool hit = walkCells(o, d, t0, t1, 8, blo, bhi, [&](glm::ivec3 b, double bt0, double bt1) {
      if (!p.bricks.count(key(b))) return false;
      glm::ivec3 lo = glm::max(b * 8, p.vmin), hi = glm::min(b * 8 + 8, p.vmax);
      return walkCells(o, d, bt0, bt1, 1, lo, hi, [&](glm::ivec3 v, double vt0, double) {
        if (!p.brickmap->isSolid(v)) return false;
        tHit = vt0;
        voxel = v;
        return true;
      });
    });
    if (hit && (!best.hit || tHit < best.t)) {
      best.hit = true;
      best.t = tHit;
      best.instance = i;
      best.voxel = voxel;
      best.voxelsPerT = glm::length(d);
      // Near-plane t per axis; the start counts as one more "plane" (a ray that begins inside the voxel).
      double planes[4];
      for (int a = 0; a < 3; ++a)
        planes[a] = d[a] == 0.0 ? -1e300 : (double(d[a] > 0.0 ? voxel[a] : voxel[a] + 1) - o[a]) / d[a];
      planes[3] = ray.tMin;
      int last = 3;
      for (int a = 0; a < 3; ++a)
        if (planes[a] >= planes[last]) last = a;
      double runnerUp = -1e300;
      for (int a = 0; a < 4; ++a)
        if (a != last) runnerUp = std::max(runnerUp, planes[a]);
      best.face = last == 3 ? 6u : unsigned(2 * last + (d[last] > 0.0 ? 0 : 1));
      best.faceMargin = (planes[last] - runnerUp) * best.voxelsPerT;
    }
  }
  if (!best.hit) best.t = ray.tMax;
  return best;
}

bool ExactReference::grazesNear(const ExactRay& ray, double t, double slackVoxels, double tolerance) const {
  for (const Placed& p : placed_) {
    glm::dvec3 o(p.worldToBrick * glm::dvec4(ray.o, 1.0)), d(p.worldToBrick * glm::dvec4(ray.d, 0.0));
    double len = glm::length(d);
    if (len == 0.0) continue;
    double slack = (slackVoxels + tolerance) / len;
    // Every solid voxel the ray passes within `tolerance` of, for t within `slack` of t.
    double ta = t - slack, tb = t + slack;
    glm::dvec3 a = o + d * ta, b = o + d * tb;
    glm::ivec3 lo = glm::ivec3(glm::floor(glm::min(a, b))) - 1, hi = glm::ivec3(glm::floor(glm::max(a, b))) + 1;
    if (glm::any(glm::greaterThan(hi - lo, glm::ivec3(64)))) continue;  // slack too large to search
    for (int z = lo.z; z <= hi.z; ++z)
      for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x) {
          glm::ivec3 v(x, y, z);
          if (!p.brickmap->isSolid(v)) continue;
          if (spanInVoxel(o, d, ray.tMin, ray.tMax, v, tolerance) < 0.0) continue;  // passes farther away
          if (spanInVoxel(o, d, ray.tMin, ray.tMax, v, 0.0) * len <= tolerance) return true;
        }
  }
  return false;
}

double ExactReference::entryT(const ExactRay& ray, std::size_t instance, glm::ivec3 voxel) const {
  if (instance >= placed_.size()) return -1.0;
  const Placed& p = placed_[instance];
  glm::dvec3 o(p.worldToBrick * glm::dvec4(ray.o, 1.0)), d(p.worldToBrick * glm::dvec4(ray.d, 0.0));
  double t0 = ray.tMin, t1 = ray.tMax;
  if (!clip(o, d, glm::dvec3(voxel), glm::dvec3(voxel) + 1.0, t0, t1)) return -1.0;
  return t0;
}

}  // namespace vs::test
