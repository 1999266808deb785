// embree_peer.cpp: the voxels of each object as a watertight triangle mesh, traced by Embree 3.
#include "tools/peer/embree_peer.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "voxel/brickmap.h"
#include "voxel/error.h"

namespace vs {
namespace {

// A rectangle of exposed faces in the plane `plane` (brick space) across `axis`, facing `sign` (+1: the solid
// lies below the plane, its faces look toward +axis), covering [u0, u1) x [v0, v1) of the two other axes
// ((axis + 1) % 3, (axis + 2) % 3).
struct Rect {
  int axis = 0, sign = 1, plane = 0;
  int u0 = 0, v0 = 0, u1 = 0, v1 = 0;
};

struct ObjectMesh {
  std::vector<float> vertices;          // xyz per vertex
  std::vector<std::uint32_t> indices;   // three per triangle
  std::vector<std::uint32_t> triangleRect;  // per triangle, its rectangle
  std::vector<Rect> rects;
};

// The exposed faces of the solid voxels as maximal rectangles, slice by slice (greedy, row by row).
std::vector<Rect> greedyRectangles(const Brickmap& brickmap) {
  glm::ivec3 lo(std::numeric_limits<int>::max()), hi(std::numeric_limits<int>::min());
  std::uint64_t solid = 0;
  brickmap.forEachSolid([&](glm::ivec3 v, std::uint8_t) {
    lo = glm::min(lo, v);
    hi = glm::max(hi, v);
    ++solid;
  });
  if (solid == 0) return {};
  // A dense occupancy grid with an empty border of one voxel, so that every neighbour lookup is in range.
  const glm::ivec3 origin = lo - glm::ivec3(1);
  const glm::i64vec3 dims = glm::i64vec3(hi - lo) + glm::i64vec3(3);
  const std::uint64_t cells = std::uint64_t(dims.x) * std::uint64_t(dims.y) * std::uint64_t(dims.z);
  if (cells > (std::uint64_t(1) << 34))
    throwRuntime("Embree peer: an object's box of " + std::to_string(dims.x) + " x " + std::to_string(dims.y) +
                 " x " + std::to_string(dims.z) + " voxels is too large to mesh");
  std::vector<std::uint64_t> bits((cells + 63) / 64, 0);
  auto cellOf = [&](glm::i64vec3 c) { return std::uint64_t((c.z * dims.y + c.y) * dims.x + c.x); };
  brickmap.forEachSolid([&](glm::ivec3 v, std::uint8_t) {
    const std::uint64_t i = cellOf(glm::i64vec3(v - origin));
    bits[i >> 6] |= std::uint64_t(1) << (i & 63);
  });
  auto isSolid = [&](glm::i64vec3 c) {
    const std::uint64_t i = cellOf(c);
    return ((bits[i >> 6] >> (i & 63)) & 1u) != 0;
  };

  // One list per (axis, sign, layer), filled in parallel and joined in that order: the mesh is deterministic.
  struct Slice {
    int axis, sign;
    std::int64_t layer;
  };
  std::vector<Slice> slices;
  for (int axis = 0; axis < 3; ++axis)
    for (int sign : {-1, 1})
      for (std::int64_t k = 1; k + 1 < dims[axis]; ++k) slices.push_back({axis, sign, k});
  std::vector<std::vector<Rect>> found(slices.size());
  tbb::parallel_for(std::size_t(0), slices.size(), [&](std::size_t s) {
    const Slice& slice = slices[s];
    const int a = slice.axis, u = (a + 1) % 3, v = (a + 2) % 3;
    const std::int64_t du = dims[u], dv = dims[v];
    std::vector<std::uint8_t> mask(std::size_t(du * dv), 0);
    bool any = false;
    for (std::int64_t j = 0; j < dv; ++j)
      for (std::int64_t i = 0; i < du; ++i) {
        glm::i64vec3 c(0), n(0);
        c[a] = slice.layer;
        c[u] = i;
        c[v] = j;
        n = c;
        n[a] += slice.sign;
        if (isSolid(c) && !isSolid(n)) mask[std::size_t(j * du + i)] = any = true;
      }
    if (!any) return;
    const int plane = origin[a] + int(slice.layer) + (slice.sign > 0 ? 1 : 0);
    for (std::int64_t j = 0; j < dv; ++j)
      for (std::int64_t i = 0; i < du; ++i) {
        if (!mask[std::size_t(j * du + i)]) continue;
        std::int64_t w = 1, h = 1;
        while (i + w < du && mask[std::size_t(j * du + i + w)]) ++w;
        for (; j + h < dv; ++h) {
          const std::uint8_t* row = &mask[std::size_t((j + h) * du + i)];
          if (!std::all_of(row, row + w, [](std::uint8_t m) { return m != 0; })) break;
        }
        for (std::int64_t y = j; y < j + h; ++y) std::fill_n(&mask[std::size_t(y * du + i)], w, std::uint8_t(0));
        Rect r;
        r.axis = a;
        r.sign = slice.sign;
        r.plane = plane;
        r.u0 = origin[u] + int(i);
        r.v0 = origin[v] + int(j);
        r.u1 = r.u0 + int(w);
        r.v1 = r.v0 + int(h);
        found[s].push_back(r);
      }
  });
  std::vector<Rect> rects;
  for (const std::vector<Rect>& f : found) rects.insert(rects.end(), f.begin(), f.end());
  return rects;
}

// A point of the doubled grid (brick space * 2: rectangle centres are half-integers) as one key.
std::uint64_t pointKey(glm::i64vec3 p) {
  constexpr std::int64_t kBias = std::int64_t(1) << 20;
  for (int c = 0; c < 3; ++c)
    if (p[c] + kBias < 0 || p[c] + kBias >= 2 * kBias)
      throwRuntime("Embree peer: a voxel at brick coordinate " + std::to_string(p[c] / 2) +
                   " lies outside the meshable range of +-2^19");
  return (std::uint64_t(p.x + kBias) << 42) | (std::uint64_t(p.y + kBias) << 21) | std::uint64_t(p.z + kBias);
}

// The positions, along axis `e`, of every rectangle corner on one axis-parallel line (keyed by e and the two
// other coordinates).
std::uint64_t lineKey(int e, std::int64_t c1, std::int64_t c2) {
  constexpr std::int64_t kBias = std::int64_t(1) << 20;  // pointKey has checked the range
  return (std::uint64_t(c1 + kBias) << 23) | (std::uint64_t(c2 + kBias) << 2) | std::uint64_t(e);
}

ObjectMesh meshObject(const Brickmap& brickmap) {
  ObjectMesh mesh;
  mesh.rects = greedyRectangles(brickmap);
  auto corner = [](const Rect& r, int cu, int cv) {
    glm::i64vec3 p(0);
    p[r.axis] = r.plane;
    p[(r.axis + 1) % 3] = cu;
    p[(r.axis + 2) % 3] = cv;
    return p;
  };
  // Every corner on the three lines through it.
  std::unordered_map<std::uint64_t, std::vector<int>> lines;
  for (const Rect& r : mesh.rects)
    for (glm::i64vec3 p : {corner(r, r.u0, r.v0), corner(r, r.u1, r.v0), corner(r, r.u1, r.v1), corner(r, r.u0, r.v1)})
      for (int e = 0; e < 3; ++e) lines[lineKey(e, p[(e + 1) % 3], p[(e + 2) % 3])].push_back(int(p[e]));
  for (auto& [key, positions] : lines) {
    std::sort(positions.begin(), positions.end());
    positions.erase(std::unique(positions.begin(), positions.end()), positions.end());
  }
  std::unordered_map<std::uint64_t, std::uint32_t> vertexIndex;
  auto vertex = [&](glm::i64vec3 doubled) {
    auto [it, added] = vertexIndex.try_emplace(pointKey(doubled), std::uint32_t(mesh.vertices.size() / 3));
    if (added)
      for (int c = 0; c < 3; ++c) mesh.vertices.push_back(float(doubled[c]) * 0.5f);
    return it->second;
  };
  constexpr std::int64_t kTwo = 2;  // brick space to the doubled grid
  std::vector<glm::i64vec3> ring;
  for (std::uint32_t ri = 0; ri < mesh.rects.size(); ++ri) {
    const Rect& r = mesh.rects[ri];
    const int u = (r.axis + 1) % 3, v = (r.axis + 2) % 3;
    // The boundary, counter-clockwise in (u, v), with every corner of any rectangle that lies on an edge.
    ring.clear();
    auto edge = [&](glm::i64vec3 from, glm::i64vec3 to, int e) {
      ring.push_back(from);
      const std::vector<int>& on = lines[lineKey(e, from[(e + 1) % 3], from[(e + 2) % 3])];
      const std::int64_t a = std::min(from[e], to[e]), b = std::max(from[e], to[e]);
      auto first = std::upper_bound(on.begin(), on.end(), a), last = std::lower_bound(on.begin(), on.end(), b);
      std::vector<int> inner(first, last);
      if (from[e] > to[e]) std::reverse(inner.begin(), inner.end());
      for (int x : inner) {
        glm::i64vec3 p = from;
        p[e] = x;
        ring.push_back(p);
      }
    };
    const glm::i64vec3 c00 = corner(r, r.u0, r.v0), c10 = corner(r, r.u1, r.v0), c11 = corner(r, r.u1, r.v1),
                       c01 = corner(r, r.u0, r.v1);
    edge(c00, c10, u);
    edge(c10, c11, v);
    edge(c11, c01, u);
    edge(c01, c00, v);
    auto emit = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
      mesh.indices.insert(mesh.indices.end(), {a, b, c});
      mesh.triangleRect.push_back(ri);
    };
    if (ring.size() == 4) {
      const std::uint32_t i0 = vertex(ring[0] * kTwo), i1 = vertex(ring[1] * kTwo), i2 = vertex(ring[2] * kTwo),
                          i3 = vertex(ring[3] * kTwo);
      emit(i0, i1, i2);
      emit(i0, i2, i3);
      continue;
    }
    const std::uint32_t centre = vertex(c00 + c11);  // doubled: (c00 + c11) / 2 * 2
    for (std::size_t k = 0; k < ring.size(); ++k)
      emit(centre, vertex(ring[k] * kTwo), vertex(ring[(k + 1) % ring.size()] * kTwo));
  }
  return mesh;
}

}  // namespace

struct EmbreePeer::State {
  RTCDevice device = nullptr;
  std::vector<RTCScene> objectScenes;
  RTCScene top = nullptr;
  std::vector<ObjectMesh> meshes;
  std::vector<gpu::InstanceRecord> instances;
  std::string error;

  ~State() {
    if (top) rtcReleaseScene(top);
    for (RTCScene s : objectScenes)
      if (s) rtcReleaseScene(s);
    if (device) rtcReleaseDevice(device);
  }
  void check(const char* what) {
    const RTCError code = rtcGetDeviceError(device);
    if (code != RTC_ERROR_NONE || !error.empty())
      throwRuntime(std::string("Embree peer: ") + what + " failed (error " + std::to_string(int(code)) +
                   (error.empty() ? "" : ": " + error) + ")");
  }

  // The RayHit of an Embree hit: the world point of the entry mapped into the instance's brick space, the voxel
  // behind the hit rectangle's plane, clamped into the rectangle (a hit on its edge belongs to it).
  gpu::RayHit hitRecord(const gpu::TraceRay& ray, float t, std::uint32_t instance, std::uint32_t prim) const {
    gpu::RayHit h{};
    h.hit = 1u;
    h.t = t;
    h.instance = instance;
    const gpu::InstanceRecord& rec = instances[instance];
    const ObjectMesh& mesh = meshes[rec.info.x];
    const Rect& r = mesh.rects[mesh.triangleRect[prim]];
    const glm::dvec3 origin = glm::dvec3(glm::vec3(ray.originHigh)) + glm::dvec3(glm::vec3(ray.originLow));
    const glm::dvec3 world = origin + glm::dvec3(glm::vec3(ray.direction)) * double(t);
    const glm::dvec3 rel = world - glm::dvec3(glm::vec3(rec.anchor));
    const glm::dvec4 p4(rel, 1.0);
    const glm::dvec3 p(glm::dot(glm::dvec4(rec.worldToBrick.row0), p4), glm::dot(glm::dvec4(rec.worldToBrick.row1), p4),
                       glm::dot(glm::dvec4(rec.worldToBrick.row2), p4));
    const int u = (r.axis + 1) % 3, v = (r.axis + 2) % 3;
    glm::ivec3 voxel(0);
    voxel[r.axis] = r.sign > 0 ? r.plane - 1 : r.plane;
    voxel[u] = std::clamp(int(std::floor(p[u])), r.u0, r.u1 - 1);
    voxel[v] = std::clamp(int(std::floor(p[v])), r.v0, r.v1 - 1);
    const std::uint32_t face = std::uint32_t(2 * r.axis + (r.sign > 0 ? 1 : 0));
    h.voxel = glm::ivec4(voxel, int(face));
    return h;
  }
};

namespace {

void onEmbreeError(void* user, RTCError, const char* message) {
  auto* state = static_cast<EmbreePeer::State*>(user);
  if (state->error.empty()) state->error = message ? message : "unknown";
}

// The Embree form of a ray: the origin as one float point (Embree has no split origin), t in [tMin, tMax].
// False for a ray that can hit nothing (tMax < tMin, or NaN).
bool embreeRay(const gpu::TraceRay& r, float org[3], float dir[3], float& tnear, float& tfar) {
  const glm::dvec3 o = glm::dvec3(glm::vec3(r.originHigh)) + glm::dvec3(glm::vec3(r.originLow));
  for (int c = 0; c < 3; ++c) {
    org[c] = float(o[c]);
    dir[c] = r.direction[c];
  }
  tnear = std::max(r.originHigh.w, 0.0f);
  tfar = r.originLow.w;
  return tfar >= tnear;
}

// Rays first .. first + 7 (those that exist) into an 8-wide packet (RTCRay8, or RTCRayHit8's ray); valid[k]
// is -1 for a lane that holds a ray that can hit something, else left 0.
template <class Ray8>
void loadPacket(std::span<const gpu::TraceRay> rays, std::size_t first, Ray8& packet, int valid[8]) {
  for (int k = 0; k < 8 && first + k < rays.size(); ++k) {
    float org[3], dir[3];
    if (!embreeRay(rays[first + k], org, dir, packet.tnear[k], packet.tfar[k])) continue;
    packet.org_x[k] = org[0], packet.org_y[k] = org[1], packet.org_z[k] = org[2];
    packet.dir_x[k] = dir[0], packet.dir_y[k] = dir[1], packet.dir_z[k] = dir[2];
    packet.mask[k] = 0xFFFFFFFFu;
    valid[k] = -1;
  }
}

template <class Body>
void inArena(int threads, std::size_t groups, Body&& body) {
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups, 64), [&](const tbb::blocked_range<std::size_t>& g) {
      for (std::size_t i = g.begin(); i != g.end(); ++i) body(i);
    });
  });
}

}  // namespace

EmbreePeer::EmbreePeer(std::span<const Brickmap* const> brickmaps, const SceneData& scene)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.device = rtcNewDevice(nullptr);
  if (!s.device) throwRuntime("Embree peer: rtcNewDevice failed (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(s.device, onEmbreeError, &s);
  s.instances = scene.instances;
  s.meshes.resize(brickmaps.size());
  for (std::size_t o = 0; o < brickmaps.size(); ++o) {
    s.meshes[o] = meshObject(*brickmaps[o]);
    const ObjectMesh& mesh = s.meshes[o];
    rectangles_ += mesh.rects.size();
    triangles_ += mesh.triangleRect.size();
    RTCScene object = rtcNewScene(s.device);
    s.objectScenes.push_back(object);
    rtcSetSceneBuildQuality(object, RTC_BUILD_QUALITY_HIGH);
    rtcSetSceneFlags(object, RTC_SCENE_FLAG_ROBUST);
    if (!mesh.triangleRect.empty()) {
      RTCGeometry g = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                             3 * sizeof(float), mesh.vertices.size() / 3));
      auto* ib = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                     3 * sizeof(std::uint32_t), mesh.triangleRect.size()));
      s.check("allocating a mesh's buffers");
      std::copy(mesh.vertices.begin(), mesh.vertices.end(), vb);
      std::copy(mesh.indices.begin(), mesh.indices.end(), ib);
      rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(object, g, 0);
      rtcReleaseGeometry(g);
    }
    rtcCommitScene(object);
    s.check("building an object's BVH");
  }
  s.top = rtcNewScene(s.device);
  rtcSetSceneBuildQuality(s.top, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(s.top, RTC_SCENE_FLAG_ROBUST);
  for (std::size_t i = 0; i < s.instances.size(); ++i) {
    const gpu::InstanceRecord& rec = s.instances[i];
    if (rec.info.x >= s.meshes.size()) throwRuntime("Embree peer: an instance names a missing object");
    if (s.meshes[rec.info.x].triangleRect.empty()) continue;
    // world = brickToWorld(p) + anchor, as a row-major 3x4 matrix.
    float rows[12];
    const glm::vec4 r[3] = {rec.brickToWorld.row0, rec.brickToWorld.row1, rec.brickToWorld.row2};
    for (int k = 0; k < 3; ++k) {
      rows[4 * k + 0] = r[k].x;
      rows[4 * k + 1] = r[k].y;
      rows[4 * k + 2] = r[k].z;
      rows[4 * k + 3] = float(double(r[k].w) + double(rec.anchor[k]));
    }
    RTCGeometry g = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(g, s.objectScenes[rec.info.x]);
    rtcSetGeometryTimeStepCount(g, 1);
    rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, rows);
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(s.top, g, std::uint32_t(i));
    rtcReleaseGeometry(g);
  }
  rtcCommitScene(s.top);
  s.check("building the instance BVH");
}

EmbreePeer::~EmbreePeer() = default;

const char* EmbreePeer::version() { return RTC_VERSION_STRING; }

std::uint64_t EmbreePeer::unpairedEdges() const {
  std::uint64_t unpaired = 0;
  for (const ObjectMesh& mesh : state_->meshes) {
    std::unordered_map<std::uint64_t, std::uint32_t> uses;
    for (std::size_t t = 0; t < mesh.indices.size(); t += 3)
      for (int e = 0; e < 3; ++e) {
        const std::uint64_t a = mesh.indices[t + e], b = mesh.indices[t + (e + 1) % 3];
        ++uses[(std::min(a, b) << 32) | std::max(a, b)];
      }
    for (const auto& [edge, count] : uses) unpaired += count % 2;
  }
  return unpaired;
}

void EmbreePeer::intersect(std::span<const gpu::TraceRay> rays, std::span<gpu::RayHit> hits, bool packets8,
                           int threads) const {
  if (hits.size() != rays.size()) throwBadInput("Embree peer: hit records and rays differ in number");
  const State& s = *state_;
  auto miss = [](const gpu::TraceRay& r) {
    gpu::RayHit h{};
    h.t = r.originLow.w;
    return h;
  };
  if (!packets8) {
    inArena(threads, rays.size(), [&](std::size_t i) {
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      RTCRayHit rh{};
      float org[3], dir[3];
      if (!embreeRay(rays[i], org, dir, rh.ray.tnear, rh.ray.tfar)) {
        hits[i] = miss(rays[i]);
        return;
      }
      rh.ray.org_x = org[0], rh.ray.org_y = org[1], rh.ray.org_z = org[2];
      rh.ray.dir_x = dir[0], rh.ray.dir_y = dir[1], rh.ray.dir_z = dir[2];
      rh.ray.mask = 0xFFFFFFFFu;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(s.top, &context, &rh);
      hits[i] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? miss(rays[i])
                                                         : s.hitRecord(rays[i], rh.ray.tfar, rh.hit.instID[0], rh.hit.primID);
    });
    return;
  }
  inArena(threads, (rays.size() + 7) / 8, [&](std::size_t group) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(32) RTCRayHit8 rh{};
    alignas(32) int valid[8] = {};
    const std::size_t first = group * 8;
    for (int k = 0; k < 8; ++k) {
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    loadPacket(rays, first, rh.ray, valid);
    rtcIntersect8(valid, s.top, &context, &rh);
    for (int k = 0; k < 8 && first + k < rays.size(); ++k) {
      const gpu::TraceRay& r = rays[first + k];
      hits[first + k] = valid[k] == 0 || rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID
                            ? miss(r)
                            : s.hitRecord(r, rh.ray.tfar[k], rh.hit.instID[0][k], rh.hit.primID[k]);
    }
  });
}

void EmbreePeer::occluded8(std::span<const gpu::TraceRay> rays, std::span<std::uint32_t> occluded, int threads) const {
  if (occluded.size() != rays.size()) throwBadInput("Embree peer: answers and rays differ in number");
  const State& s = *state_;
  inArena(threads, (rays.size() + 7) / 8, [&](std::size_t group) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(32) RTCRay8 ray{};
    alignas(32) int valid[8] = {};
    const std::size_t first = group * 8;
    loadPacket(rays, first, ray, valid);
    rtcOccluded8(valid, s.top, &context, &ray);
    for (int k = 0; k < 8 && first + k < rays.size(); ++k)
      occluded[first + k] = valid[k] != 0 && ray.tfar[k] == -std::numeric_limits<float>::infinity() ? 1u : 0u;
  });
}

}  // namespace vs
