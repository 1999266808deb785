#include "compute/cpu/lane_tracer.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VS_LANES_X86 1
#include <immintrin.h>
#endif

#include <bit>
#include <cstdint>
#include <memory>

#include "compute/cpu/tile_rays.h"
#include "voxel/error.h"

namespace vs {

namespace {

// The scene of a batch: a BVH that is one leaf holding one instance (a single object, as baked and benched).
struct SingleInstance {
  bool enabled = false;
  std::uint32_t instance = 0;
  std::uint32_t objectIndex = 0;
};

SingleInstance singleInstance(const gpu::SceneArrays& arrays) {
  SingleInstance one;
  if (arrays.nodeCount != 1u || arrays.nodes[0].count != 1u) return one;
  one.enabled = true;
  one.instance = arrays.instanceIndices[arrays.nodes[0].rightOrFirst];
  one.objectIndex = arrays.instances[one.instance].info.x;
  return one;
}

}  // namespace

// One scalar lane: the vocabulary of compute/shared/lanes.h as C++ compiles it for the reference.
namespace lanes_scalar {
namespace {
using namespace glm;
using gpu::LBool;
using gpu::LFloat;
using gpu::LInt;
using gpu::vsLaneAny;
using gpu::vsSelect;
using gpu::LVec3;
using gpu::vsMaskFloatBits;
constexpr int kLanes = 1;
inline void setLane(float& x, int, float value) { x = value; }
inline void setLane(int& x, int, int value) { x = value; }
inline void setLane(bool& x, int, bool value) { x = value; }
inline float laneOf(float x, int) { return x; }
inline int laneOf(int x, int) { return x; }
inline unsigned laneBits(bool b) { return b ? 1u : 0u; }
inline int gatherLanes(const std::int32_t* table, bool mask, int index) { return mask ? table[index] : 0; }
#include "compute/cpu/lane_driver.inc"
}  // namespace
}  // namespace lanes_scalar

#ifdef VS_LANES_X86
// clang ignores GCC's target pragma: it takes the same target through an attribute on every function.
#ifdef __clang__
#pragma clang attribute push(__attribute__((target("avx2,popcnt"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2,popcnt")
// GCC 12 reports lanes of a value-initialised walk read back through laneOf as maybe uninitialised.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
namespace lanes_avx2 {
namespace {
#include "compute/cpu/lanes_avx2.h"
#include "compute/cpu/lane_vec3.h"
#include "compute/cpu/lane_driver.inc"
}  // namespace
}  // namespace lanes_avx2
#ifdef __clang__
#pragma clang attribute pop
#else
#pragma GCC diagnostic pop
#pragma GCC pop_options
#endif

#ifdef __clang__
#pragma clang attribute push(__attribute__((target("avx512f,avx2,popcnt"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx512f,avx2,popcnt")
// GCC 12's AVX-512 intrinsics start from a self-initialised "undefined" register, which -Wuninitialized
// reports once per use (GCC bug 105593, fixed in GCC 13).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
namespace lanes_avx512 {
namespace {
#include "compute/cpu/lanes_avx512.h"
#include "compute/cpu/lane_vec3.h"
#include "compute/cpu/lane_driver.inc"
}  // namespace
}  // namespace lanes_avx512
#ifdef __clang__
#pragma clang attribute pop
#else
#pragma GCC diagnostic pop
#pragma GCC pop_options
#endif
#endif

bool laneWidthSupported(LaneWidth width) {
  switch (width) {
    case LaneWidth::Scalar:
      return true;
#ifdef VS_LANES_X86
    case LaneWidth::Avx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
    case LaneWidth::Avx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
#endif
    default:
      return false;
  }
}

LaneWidth widestLaneWidth() {
  if (laneWidthSupported(LaneWidth::Avx512)) return LaneWidth::Avx512;
  if (laneWidthSupported(LaneWidth::Avx2)) return LaneWidth::Avx2;
  return LaneWidth::Scalar;
}

const char* laneWidthName(LaneWidth width) {
  switch (width) {
    case LaneWidth::Avx2:
      return "AVX2 (8 lanes)";
    case LaneWidth::Avx512:
      return "AVX-512 (16 lanes)";
    default:
      return "scalar";
  }
}

namespace {

// Calls the drivers of `width`'s instruction set.
template <class Run>
void withLanes(LaneWidth width, gpu::SceneArrays& arrays, Run&& run) {
  if (!arrays.boxTable) throwBadInput("the lane tracer needs the scene's box table");
  if (!laneWidthSupported(width))
    throwBadInput(std::string("this processor does not run the ") + laneWidthName(width) + " lane tracer");
  switch (width) {
#ifdef VS_LANES_X86
    case LaneWidth::Avx512:
      run(lanes_avx512::traceTiles, lanes_avx512::traceClosest, lanes_avx512::traceAny);
      return;
    case LaneWidth::Avx2:
      run(lanes_avx2::traceTiles, lanes_avx2::traceClosest, lanes_avx2::traceAny);
      return;
#endif
    default:
      run(lanes_scalar::traceTiles, lanes_scalar::traceClosest, lanes_scalar::traceAny);
  }
}

}  // namespace

void traceTilesLanes(LaneWidth width, gpu::SceneArrays& arrays, std::span<const gpu::TraceView> views,
                     std::span<const TexelTile> tiles, std::vector<ShadowLayer>& layers) {
  withLanes(width, arrays, [&](auto tilesFn, auto, auto) { tilesFn(arrays, views, tiles, layers); });
}

void traceClosestLanes(LaneWidth width, gpu::SceneArrays& arrays, std::span<const gpu::TraceRay> rays,
                       std::span<gpu::RayHit> hits) {
  withLanes(width, arrays, [&](auto, auto closestFn, auto) { closestFn(arrays, rays, hits); });
}

void traceAnyLanes(LaneWidth width, gpu::SceneArrays& arrays, std::span<const gpu::TraceRay> rays,
                   std::span<std::uint32_t> occluded) {
  withLanes(width, arrays, [&](auto, auto, auto anyFn) { anyFn(arrays, rays, occluded); });
}

}  // namespace vs
