#include "tools/peer/openvdb_peer.h"

#include <mutex>

#include <openvdb/math/DDA.h>
#include <openvdb/math/Ray.h>
#include <openvdb/tools/RayIntersector.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "compute/cpu/scene_arrays.h"

namespace vs {

using PeerRay = openvdb::math::Ray<double>;
using Intersector = openvdb::tools::VolumeRayIntersector<openvdb::BoolGrid, 0, PeerRay>;

struct OpenVdbPeer::Object {
  openvdb::BoolGrid::Ptr grid;
  std::unique_ptr<Intersector> master;  // null for an empty grid (the intersector refuses those)
};

namespace {

std::unique_ptr<OpenVdbPeer::Object> makeObject(openvdb::BoolGrid::Ptr grid) {
  auto object = std::make_unique<OpenVdbPeer::Object>();
  object->grid = std::move(grid);
  if (!object->grid->empty()) object->master = std::make_unique<Intersector>(*object->grid);
  return object;
}

void initOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

}  // namespace

// Per-thread intersector copies: each holds its own accessor caches, so threads never share one.
struct ThreadState {
  std::vector<std::unique_ptr<Intersector>> intersectors;
  std::vector<std::unique_ptr<openvdb::BoolGrid::ConstAccessor>> accessors;
};
struct OpenVdbPeer::ThreadStates {
  tbb::enumerable_thread_specific<ThreadState> states;
};

OpenVdbPeer::OpenVdbPeer(std::span<const Brickmap* const> brickmaps, const SceneData& scene) {
  initOpenVdb();
  for (const Brickmap* bm : brickmaps) {
    auto grid = openvdb::BoolGrid::create(false);
    auto acc = grid->getAccessor();
    bm->forEachSolid([&](glm::ivec3 v, std::uint8_t) { acc.setValueOn(openvdb::Coord(v.x, v.y, v.z), true); });
    objects_.push_back(makeObject(grid));
  }
  threads_ = std::make_unique<ThreadStates>();
  instances_ = scene.instances;
}

OpenVdbPeer::OpenVdbPeer(openvdb::BoolGrid::Ptr grid) {
  initOpenVdb();
  objects_.push_back(makeObject(std::move(grid)));
  gpu::InstanceRecord identity{};
  identity.worldToBrick = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
  identity.brickToWorld = identity.worldToBrick;
  identity.boundsMin = glm::vec4(glm::vec3(-gpu::VS_T_INFINITY), 0.0f);
  identity.boundsMax = glm::vec4(glm::vec3(gpu::VS_T_INFINITY), 0.0f);
  instances_.push_back(identity);
  threads_ = std::make_unique<ThreadStates>();
}

OpenVdbPeer::~OpenVdbPeer() = default;

namespace {

// First active voxel along the index-space ray within [t0, t1]: the intersector yields the spans of
// active leaf nodes, and a voxel DDA walks each span.
bool traceGrid(Intersector& inter, const openvdb::BoolGrid::ConstAccessor& acc, const PeerRay& ray, double& tHit,
               openvdb::Coord& voxel) {
  if (!inter.setIndexRay(ray)) return false;
  double a = 0.0, b = 0.0;
  while (inter.march(a, b)) {
    PeerRay span(ray.eye(), ray.dir(), a, b);
    openvdb::math::DDA<PeerRay, 0> dda(span);
    do {
      if (acc.isValueOn(dda.voxel())) {
        tHit = std::max(dda.time(), ray.t0());
        voxel = dda.voxel();
        return true;
      }
    } while (dda.step());
  }
  return false;
}

// Runs `run` on `threads` threads (<= 0: all).
template <class Run>
void inArena(int threads, const Run& run) {
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(run);
  } else {
    run();
  }
}

}  // namespace

bool OpenVdbPeer::trace(const glm::vec3& o, const glm::vec3& d, double tMin, double tMax, double& tHit,
                        std::uint32_t& instance, glm::ivec3& voxel) const {
  gpu::SceneArrays arrays;
  return trace(arrays.vsWorldRay(o, d, float(tMin), float(tMax)), tHit, instance, voxel);
}

bool OpenVdbPeer::trace(const gpu::SceneArrays::WorldRay& ray, double& tHit, std::uint32_t& instance,
                        glm::ivec3& voxel) const {
  return trace(ray, tHit, instance, voxel, false);
}

std::vector<std::uint8_t> OpenVdbPeer::traceRays(std::span<const gpu::TraceRay> rays, bool anyHit, int threads) const {
  std::vector<std::uint8_t> out(rays.size(), 0);
  gpu::SceneArrays arrays;
  auto run = [&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), 1024), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) {
        double t = 0.0;
        std::uint32_t inst = 0;
        glm::ivec3 v(0);
        out[i] = trace(arrays.vsTraceRayToWorld(rays[i]), t, inst, v, anyHit) ? 1 : 0;
      }
    });
  };
  inArena(threads, run);
  return out;
}

bool OpenVdbPeer::trace(const gpu::SceneArrays::WorldRay& ray, double& tHit, std::uint32_t& instance,
                        glm::ivec3& voxel, bool anyHit) const {
  ThreadState& state = threads_->states.local();
  if (state.intersectors.size() != objects_.size()) {
    for (const auto& obj : objects_) {
      state.intersectors.push_back(obj->master ? std::make_unique<Intersector>(*obj->master) : nullptr);
      state.accessors.push_back(std::make_unique<openvdb::BoolGrid::ConstAccessor>(obj->grid->getConstAccessor()));
    }
  }
  // The traversal's instance set-up reads only the instance records.
  gpu::SceneArrays arrays;
  arrays.instances = instances_.data();
  bool hit = false;
  double best = ray.tMax;
  for (std::size_t i = 0; i < instances_.size(); ++i) {
    const std::uint32_t object = instances_[i].info.x;
    if (!state.intersectors[object]) continue;
    const auto index = static_cast<std::uint32_t>(i);
    const float tBase = arrays.vsInstanceBaseT(ray, index);
    glm::vec3 lo, ld;
    arrays.vsInstanceRay(ray, index, tBase, lo, ld);
    // The intersector expects t >= 0: the local ray starts at the world ray's tMin (in double).
    const double tStart = double(ray.tMin);
    const glm::dvec3 start = glm::dvec3(lo) + glm::dvec3(ld) * (tStart - double(tBase));
    PeerRay local(openvdb::Vec3d(start.x, start.y, start.z), openvdb::Vec3d(ld.x, ld.y, ld.z), 0.0, best - tStart);
    double t = 0.0;
    openvdb::Coord c;
    if (traceGrid(*state.intersectors[object], *state.accessors[object], local, t, c) && t + tStart <= best) {
      if (!hit || t + tStart < best) {
        best = t + tStart;
        instance = index;
        voxel = glm::ivec3(c.x(), c.y(), c.z());
      }
      hit = true;
      if (anyHit) break;
    }
  }
  if (hit) tHit = best;
  return hit;
}

std::vector<std::vector<float>> OpenVdbPeer::traceViews(const SceneData& scene, std::span<const gpu::TraceView> views,
                                                        int threads) const {
  std::vector<std::vector<float>> out(views.size());
  gpu::SceneArrays arrays(scene);
  auto run = [&] {
    for (std::size_t i = 0; i < views.size(); ++i) {
      const gpu::TraceView& view = views[i];
      out[i].assign(std::size_t(view.info.x) * view.info.y, 0.0f);
      tbb::parallel_for(tbb::blocked_range<int>(view.rect.y, view.rect.w), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y) {
          for (int x = view.rect.x; x < view.rect.z; ++x) {
            gpu::SceneArrays::WorldRay ray;
            arrays.vsViewRay(view, glm::ivec2(x, y), ray);
            double t = ray.tMax;
            std::uint32_t inst = 0;
            glm::ivec3 v(0);
            bool hit = trace(ray, t, inst, v);
            out[i][std::size_t(y) * view.info.x + x] = hit ? float(t) : ray.tMax;
          }
        }
      });
    }
  };
  inArena(threads, run);
  return out;
}

}  // namespace vs
