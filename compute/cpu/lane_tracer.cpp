#include "compute/cpu/lane_tracer.h"

#include <immintrin.h>

#include <bit>
#include <cstdint>
#include <limits>
#include <memory>

#include <glm/gtc/type_ptr.hpp>
#include <tbb/parallel_for.h>

#include "compute/cpu/tile_rays.h"
#include "voxel/error.h"

namespace vs {

bool laneTracerSupported(const SceneData& scene) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  // Occupancy words are gathered with signed 32-bit indices.
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt") &&
         scene.occupancy.size() < std::size_t(std::numeric_limits<std::int32_t>::max());
#else
  (void)scene;
  return false;
#endif
}

namespace {

// Replaces the code of every empty brick of one object's brick grid (nx * ny * nz codes, x fastest) by the
// box-table code of the empty box around it (VS_BOX_* in trace_view.h). Bricks outside the grid hold no voxel,
// so a box may reach past the grid.
// The box grows from the largest empty cube of bricks centred on the brick (the chessboard distance to the
// nearest non-empty brick, less one, by two raster passes over the 26-neighbourhood), face by face in turn,
// each face by one brick while the slab it adds is empty (a summed-area table answers that), up to
// kLaneMaxBoxExtent per side: streets and courtyards become long boxes instead of small cubes. The brick's
// empty sector or region (extents 0, log2 5 or 7) is kept when it holds more voxels.
void encodeEmptyBoxes(std::int32_t* codes, int nx, int ny, int nz) {
  constexpr int kFar = kLaneMaxBoxExtent + 1;
  const int px = nx + 2, py = ny + 2, pz = nz + 2;
  const std::size_t plane = std::size_t(px) * py;
  std::vector<std::uint8_t> dist(plane * pz, std::uint8_t(kFar));
  auto at = [&](int x, int y, int z) { return (std::size_t(z) * py + y) * px + x; };
  auto codeAt = [&](int x, int y, int z) -> std::int32_t& { return codes[(std::size_t(z) * ny + y) * nx + x]; };
  auto solid = [](std::int32_t code) { return code >= 0 || code == kLaneFullBrick; };
  // Summed-area table of non-empty bricks: sat(x, y, z) counts those with coordinates below (x, y, z).
  const std::size_t sx = std::size_t(nx) + 1, sy = std::size_t(ny) + 1;
  std::vector<std::int32_t> sat(sx * sy * (std::size_t(nz) + 1), 0);
  auto satAt = [&](int x, int y, int z) -> std::int32_t& { return sat[(std::size_t(z) * sy + y) * sx + x]; };
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        int here = solid(codeAt(x, y, z)) ? 1 : 0;
        if (here) dist[at(x + 1, y + 1, z + 1)] = 0;
        satAt(x + 1, y + 1, z + 1) = here + satAt(x, y + 1, z + 1) + satAt(x + 1, y, z + 1) + satAt(x + 1, y + 1, z) -
                                     satAt(x, y, z + 1) - satAt(x, y + 1, z) - satAt(x + 1, y, z) + satAt(x, y, z);
      }
  // Whether the brick box [lo, hi] (inclusive, may reach past the grid) holds no non-empty brick.
  auto boxEmpty = [&](glm::ivec3 lo, glm::ivec3 hi) {
    lo = glm::max(lo, glm::ivec3(0));
    hi = glm::min(hi, glm::ivec3(nx, ny, nz) - 1);
    if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z) return true;
    const int x0 = lo.x, y0 = lo.y, z0 = lo.z, x1 = hi.x + 1, y1 = hi.y + 1, z1 = hi.z + 1;
    return satAt(x1, y1, z1) - satAt(x0, y1, z1) - satAt(x1, y0, z1) - satAt(x1, y1, z0) + satAt(x0, y0, z1) +
               satAt(x0, y1, z0) + satAt(x1, y0, z0) - satAt(x0, y0, z0) ==
           0;
  };
  // The 13 neighbours that come before a cell in raster order (the other 13 are their mirror images).
  std::ptrdiff_t before[13];
  int n = 0;
  for (int dz = -1; dz <= 0; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (dz == 0 && (dy > 0 || (dy == 0 && dx >= 0))) continue;
        before[n++] = (std::ptrdiff_t(dz) * py + dy) * px + dx;
      }
  auto relax = [&](std::size_t i, int sign) {
    int best = dist[i];
    for (std::ptrdiff_t off : before) best = std::min(best, dist[std::size_t(std::ptrdiff_t(i) + sign * off)] + 1);
    dist[i] = std::uint8_t(std::min(best, kFar));
  };
  for (int z = 1; z <= nz; ++z)
    for (int y = 1; y <= ny; ++y)
      for (int x = 1; x <= nx; ++x) relax(at(x, y, z), 1);
  for (int z = nz; z >= 1; --z)
    for (int y = ny; y >= 1; --y)
      for (int x = nx; x >= 1; --x) relax(at(x, y, z), -1);
  // Each brick's box depends only on the tables above: layers of bricks grow their boxes in parallel.
  tbb::parallel_for(0, nz, [&](int z) {
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        std::int32_t& code = codeAt(x, y, z);
        if (solid(code)) continue;
        const glm::ivec3 b(x, y, z);
        int r = std::min(int(dist[at(x + 1, y + 1, z + 1)]) - 1, kLaneMaxBoxExtent);
        int ext[6] = {r, r, r, r, r, r};  // -x, +x, -y, +y, -z, +z
        for (bool grew = true; grew;) {
          grew = false;
          for (int f = 0; f < 6; ++f) {
            if (ext[f] == kLaneMaxBoxExtent) continue;
            glm::ivec3 lo = b - glm::ivec3(ext[0], ext[2], ext[4]), hi = b + glm::ivec3(ext[1], ext[3], ext[5]);
            int axis = f / 2;
            // The slab one brick beyond face f.
            if (f % 2 == 0) {
              hi[axis] = lo[axis] - 1;
              lo[axis] = hi[axis];
            } else {
              lo[axis] = hi[axis] + 1;
              hi[axis] = lo[axis];
            }
            if (boxEmpty(lo, hi)) {
              ++ext[f];
              grew = true;
            }
          }
        }
        // The empty sector or region around the brick (code = its log2 negated) may be the larger box.
        int log2 = -code;
        double bricks = double(ext[0] + ext[1] + 1) * (ext[2] + ext[3] + 1) * (ext[4] + ext[5] + 1);
        double aligned = std::pow(double(1 << (log2 - gpu::VS_BRICK_LOG2)), 3.0);
        std::int32_t box = 0;
        if (aligned > bricks) {
          box = log2 << gpu::VS_BOX_LOG2_SHIFT;
        } else {
          for (int f = 0; f < 6; ++f) box |= ext[f] << (gpu::VS_BOX_EXTENT_BITS * f);
          box |= gpu::VS_BRICK_LOG2 << gpu::VS_BOX_LOG2_SHIFT;
        }
        code = -1 - box;
      }
  });
}

// The brick level of LaneTables, from its sector codes; left empty when too large.
void buildBrickCodes(const SceneData& scene, LaneTables& tables, std::size_t maxBrickCodes) {
  std::size_t total = tables.sectorCodes.size() * 64u;
  if (total > maxBrickCodes) return;
  tables.brickCodes.reserve(total);
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const gpu::ObjectRecord& obj = scene.objects[o];
    tables.objectBrickBase.push_back(std::int32_t(tables.brickCodes.size()));
    const int sdx = 4 * obj.regionDims.x, sdy = 4 * obj.regionDims.y, sdz = 4 * obj.regionDims.z;
    const int bdx = 4 * sdx, bdy = 4 * sdy;
    std::size_t base = tables.brickCodes.size();
    tables.brickCodes.resize(base + std::size_t(sdx) * sdy * sdz * 64u);
    for (int sz = 0; sz < sdz; ++sz)
      for (int sy = 0; sy < sdy; ++sy)
        for (int sx = 0; sx < sdx; ++sx) {
          std::int32_t code =
              tables.sectorCodes[std::size_t(tables.objectBase[o]) + std::size_t(sx + sdx * (sy + sdy * sz))];
          const gpu::Sector* sector = code >= 0 ? &scene.sectors[std::size_t(code)] : nullptr;
          for (std::uint32_t bit = 0; bit < 64u; ++bit) {
            int a = int(bit & 3u), b = int((bit >> 2) & 3u), c = int(bit >> 4);
            std::size_t index = base + std::size_t((4 * sx + a) + bdx * ((4 * sy + b) + bdy * (4 * sz + c)));
            std::int32_t value = code;
            if (sector) {
              std::uint32_t lo = sector->brickMask.x, hi = sector->brickMask.y;
              bool present = ((bit < 32u ? lo : hi) >> (bit & 31u)) & 1u;
              std::uint32_t rank = bit < 32u ? std::uint32_t(std::popcount(lo & ((1u << bit) - 1u)))
                                             : std::uint32_t(std::popcount(lo)) +
                                                   std::uint32_t(std::popcount(hi & ((1u << (bit - 32u)) - 1u)));
              value = -gpu::VS_BRICK_LOG2;
              if (present) {
                const gpu::Brick& brick = scene.bricks[std::size_t(obj.bases.w) + sector->firstBrick + rank];
                std::uint64_t word =
                    std::uint64_t(obj.bases2.x) + std::uint64_t(brick.occupancy) * gpu::VS_OCCUPANCY_WORDS;
                bool consistent =
                    brick.occupancy == gpu::VS_FULL_BRICK || word + gpu::VS_OCCUPANCY_WORDS <= scene.occupancy.size();
                for (std::uint32_t cell = 0; consistent && brick.occupancy != gpu::VS_FULL_BRICK && cell < 64u;
                     ++cell) {
                  bool maskBit = (((cell < 32u ? brick.cellMask.x : brick.cellMask.y) >> (cell & 31u)) & 1u) != 0u;
                  bool anyVoxel = ((scene.occupancy[word + cell / 4u] >> ((cell & 3u) * 8u)) & 0xffu) != 0u;
                  consistent = maskBit == anyVoxel;
                }
                bool full = brick.occupancy == gpu::VS_FULL_BRICK;
                if (!consistent || (!full && word > std::uint64_t(std::numeric_limits<std::int32_t>::max() - 16))) {
                  tables.brickCodes.clear();
                  tables.objectBrickBase.clear();
                  return;
                }
                value = full ? kLaneFullBrick : std::int32_t(word);
              }
            }
            tables.brickCodes[index] = value;
          }
        }
    encodeEmptyBoxes(tables.brickCodes.data() + base, bdx, bdy, 4 * sdz);
  }
}

}  // namespace

bool buildLaneTables(const SceneData& scene, LaneTables& tables, std::size_t maxBrickCodes) {
  tables.brickCodes.clear();
  tables.objectBrickBase.clear();
  tables.sectorCodes.clear();
  tables.objectBase.clear();
  std::size_t total = 0;
  for (const gpu::ObjectRecord& obj : scene.objects)
    total += std::size_t(obj.regionDims.x) * std::size_t(obj.regionDims.y) * std::size_t(obj.regionDims.z) * 64u;
  if (total > kMaxLaneSectorCodes) return false;
  tables.sectorCodes.reserve(total);
  for (const gpu::ObjectRecord& obj : scene.objects) {
    tables.objectBase.push_back(std::int32_t(tables.sectorCodes.size()));
    const int dx = obj.regionDims.x, dy = obj.regionDims.y, dz = obj.regionDims.z;
    const int sdx = 4 * dx, sdy = 4 * dy;
    std::size_t base = tables.sectorCodes.size();
    tables.sectorCodes.resize(base + std::size_t(dx) * dy * dz * 64u, -gpu::VS_REGION_LOG2);
    for (int rz = 0; rz < dz; ++rz)
      for (int ry = 0; ry < dy; ++ry)
        for (int rx = 0; rx < dx; ++rx) {
          std::uint32_t slot = scene.regionTable[obj.bases.x + std::uint32_t(rx + dx * (ry + dy * rz))];
          if (slot == gpu::VS_EMPTY_SLOT) continue;
          const gpu::Region& region = scene.regions[obj.bases.y + slot];
          for (std::uint32_t bit = 0; bit < 64u; ++bit) {
            int a = int(bit & 3u), b = int((bit >> 2) & 3u), c = int(bit >> 4);
            std::size_t index = base + std::size_t((4 * rx + a) + sdx * ((4 * ry + b) + sdy * (4 * rz + c)));
            std::uint32_t lo = region.sectorMask.x, hi = region.sectorMask.y;
            bool present = ((bit < 32u ? lo : hi) >> (bit & 31u)) & 1u;
            if (!present) {
              tables.sectorCodes[index] = -gpu::VS_SECTOR_LOG2;
              continue;
            }
            std::uint32_t rank = bit < 32u ? std::uint32_t(std::popcount(lo & ((1u << bit) - 1u)))
                                           : std::uint32_t(std::popcount(lo)) +
                                                 std::uint32_t(std::popcount(hi & ((1u << (bit - 32u)) - 1u)));
            std::uint64_t sector = std::uint64_t(obj.bases.z) + region.firstSector + rank;
            if (sector > std::uint64_t(std::numeric_limits<std::int32_t>::max() / 4)) {
              tables.sectorCodes.clear();
              tables.objectBase.clear();
              return false;
            }
            tables.sectorCodes[index] = std::int32_t(sector);
          }
        }
  }
  buildBrickCodes(scene, tables, maxBrickCodes);
  return true;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// clang ignores GCC's target pragma: it takes the same target through an attribute on every function.
#ifdef __clang__
#pragma clang attribute push(__attribute__((target("avx2,popcnt"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2,popcnt")
#endif

namespace {

constexpr int kLanes = 8;
static_assert(sizeof(gpu::Sector) == 16 && offsetof(gpu::Sector, firstBrick) == 8,
              "sectors are gathered as four words");

// The walk states of eight rays, one per lane, in structure-of-arrays form (the fields of ObjectWalk).
struct alignas(32) Lanes {
  float o[3][kLanes], d[3][kLanes], invD[3][kLanes];
  int v[3][kLanes];
  float tEnter[kLanes], t1[kLanes];
  int stepsLeft[kLanes];
  int voxelMin[3][kLanes], voxelMax[3][kLanes];
  int dPositive[3][kLanes];  // all ones where d > 0
  int dNonZero[3][kLanes];   // all ones where d != 0
  // vsNearPlane's band for the whole walk: 2^-16 (1 + |o| + |d| max|t|), never below the band of any step.
  float nearBand[3][kLanes];
  int live[kLanes];          // all ones while the lane walks
  // Between the parts of a step (beginStepLanes, lookupLanes, advanceLanes): the voxel's cell log2, whether
  // it is solid, and which lanes walk this step.
  int stepLog2[kLanes], stepHit[kLanes], stepWalking[kLanes];
  // The empty box of the step in cells of 2^stepLog2 voxels around the voxel's cell: the six extents of a
  // box-table code (VS_BOX_*; 0: the aligned cell itself).
  int stepBox[kLanes];
  int stepCode[kLanes];  // the voxel's brick code (LaneTables::brickCodes), read before lookupLanes
  // The object's sector-code table: first code, sector coordinate of code 0, codes per row and per layer.
  int sectorBase[kLanes];
  int sectorOrigin[3][kLanes];
  int sectorDims[2][kLanes];
  int brickBase[kLanes];  // the object's first brick
  // The object's brick-code table (when LaneTables has one), laid out like the sector codes.
  int brickCodeBase[kLanes];
  int brickOrigin[3][kLanes];
  int brickDims[2][kLanes];
  int occupancyWordBase[kLanes];  // the object's first occupancy word
  // The current sector's brick mask and global first brick (read every step).
  std::uint32_t brickMask[2][kLanes];
  std::uint32_t firstBrick[kLanes];
  // Cached brick: coordinate, cell mask, whether it is full, its first occupancy word.
  int brick[3][kLanes];
  std::uint32_t cellMask[2][kLanes];
  int fullBrick[kLanes];
  int occupancyBase[kLanes];
};

// What vsRankBelow and vsChildBit compute, for the scalar refills.
inline std::uint32_t rankBelow(std::uint32_t lo, std::uint32_t hi, std::uint32_t bit) {
  if (bit < 32u) return std::uint32_t(__builtin_popcount(lo & ((1u << bit) - 1u)));
  return std::uint32_t(__builtin_popcount(lo)) + std::uint32_t(__builtin_popcount(hi & ((1u << (bit - 32u)) - 1u)));
}

inline std::uint32_t childBit(int x, int y, int z, int log2Child) {
  return std::uint32_t(((x >> log2Child) & 3) + 4 * ((y >> log2Child) & 3) + 16 * ((z >> log2Child) & 3));
}

inline bool testBit(std::uint32_t lo, std::uint32_t hi, std::uint32_t bit) {
  std::uint32_t word = bit < 32u ? lo : hi;
  return ((word >> (bit & 31u)) & 1u) != 0u;
}

// The brick lookup of vsWalkCellLog2 for lane i (its brick is present and the cache missed).
void refillBrick(const gpu::SceneArrays& arrays, Lanes& L, int i) {
  int x = L.v[0][i], y = L.v[1][i], z = L.v[2][i];
  L.brick[0][i] = x >> gpu::VS_BRICK_LOG2;
  L.brick[1][i] = y >> gpu::VS_BRICK_LOG2;
  L.brick[2][i] = z >> gpu::VS_BRICK_LOG2;
  std::uint32_t brickBit = childBit(x, y, z, gpu::VS_BRICK_LOG2);
  const gpu::Brick& b = arrays.bricks[L.firstBrick[i] + rankBelow(L.brickMask[0][i], L.brickMask[1][i], brickBit)];
  L.cellMask[0][i] = b.cellMask.x;
  L.cellMask[1][i] = b.cellMask.y;
  L.fullBrick[i] = b.occupancy == gpu::VS_FULL_BRICK ? -1 : 0;
  L.occupancyBase[i] = b.occupancy == gpu::VS_FULL_BRICK
                           ? 0
                           : int(std::uint32_t(L.occupancyWordBase[i]) + b.occupancy * gpu::VS_OCCUPANCY_WORDS);
}

// The per-ray fields of lane i: the brick-space ray, its first voxel and span, and empty caches.
void loadLaneRay(Lanes& L, int i, const float* o, const float* d, const float* invD, const int* v, float tEnter,
                 float t1, int stepsLeft) {
  const float tLargest = std::max(std::abs(tEnter), std::abs(t1));
  for (int a = 0; a < 3; ++a) {
    L.o[a][i] = o[a];
    L.d[a][i] = d[a];
    L.invD[a][i] = invD[a];
    L.v[a][i] = v[a];
    L.dPositive[a][i] = d[a] > 0.0f ? -1 : 0;
    L.dNonZero[a][i] = d[a] != 0.0f ? -1 : 0;
    L.nearBand[a][i] = (1.0f + std::abs(o[a]) + std::abs(d[a]) * tLargest) * (1.0f / 65536.0f) * 1.001f;
    L.brick[a][i] = gpu::VS_NO_CELL;
  }
  L.tEnter[i] = tEnter;
  L.t1[i] = t1;
  L.stepsLeft[i] = stepsLeft;
  L.live[i] = -1;
}

// Places a walk begun by vsObjectWalkBegin in lane i, with empty caches: its object's fields, then the ray's.
void loadLane(Lanes& L, int i, const gpu::SceneArrays::ObjectWalk& w, const LaneTables& tables,
              std::uint32_t objectIndex) {
  for (int a = 0; a < 3; ++a) {
    L.voxelMin[a][i] = w.obj.voxelMin[a];
    L.voxelMax[a][i] = w.obj.voxelMax[a];
    L.sectorOrigin[a][i] = 4 * w.obj.regionOrigin[a];
    L.brickOrigin[a][i] = 16 * w.obj.regionOrigin[a];
  }
  L.sectorBase[i] = tables.objectBase[objectIndex];
  L.sectorDims[0][i] = 4 * w.obj.regionDims.x;
  L.sectorDims[1][i] = 4 * w.obj.regionDims.y;
  L.brickBase[i] = int(w.obj.bases.w);
  L.brickCodeBase[i] = tables.brickCodes.empty() ? 0 : tables.objectBrickBase[objectIndex];
  L.brickDims[0][i] = 16 * w.obj.regionDims.x;
  L.brickDims[1][i] = 16 * w.obj.regionDims.y;
  L.occupancyWordBase[i] = int(w.obj.bases2.x);
  loadLaneRay(L, i, glm::value_ptr(w.o), glm::value_ptr(w.d), glm::value_ptr(w.invD), glm::value_ptr(w.v), w.tEnter,
              w.t1, w.stepsLeft);
}

inline __m256i load(const int* p) { return _mm256_load_si256(reinterpret_cast<const __m256i*>(p)); }
inline __m256i load(const std::uint32_t* p) { return _mm256_load_si256(reinterpret_cast<const __m256i*>(p)); }
inline void store(int* p, __m256i x) { _mm256_store_si256(reinterpret_cast<__m256i*>(p), x); }
inline __m256i select(__m256i no, __m256i yes, __m256i mask) { return _mm256_blendv_epi8(no, yes, mask); }
inline int laneMask(__m256i m) { return _mm256_movemask_ps(_mm256_castsi256_ps(m)); }

// One vsObjectWalkStep for every live lane runs in three parts, each issued for every group in turn so that
// the groups' gathers overlap: beginStepLanes (the step bound and the brick-code gather), lookupLanes (the
// rest of vsWalkCellLog2) and advanceLanes (the move past the empty cell).
void beginStepLanes(const LaneTables& tables, Lanes& L) {
  const __m256i one = _mm256_set1_epi32(1);
  const __m256i live = load(L.live);
  // if (w.stepsLeft <= 0) return VS_WALK_MISS; w.stepsLeft -= 1;
  __m256i steps = load(L.stepsLeft);
  __m256i exhausted = _mm256_and_si256(live, _mm256_cmpgt_epi32(one, steps));
  store(L.stepsLeft, _mm256_sub_epi32(steps, one));
  __m256i walking = _mm256_andnot_si256(exhausted, live);
  store(L.stepWalking, walking);
  if (tables.brickCodes.empty()) return;
  __m256i rel[3];
  for (int a = 0; a < 3; ++a)
    rel[a] = _mm256_sub_epi32(_mm256_srai_epi32(load(L.v[a]), gpu::VS_BRICK_LOG2), load(L.brickOrigin[a]));
  __m256i codeIndex = _mm256_add_epi32(
      load(L.brickCodeBase),
      _mm256_add_epi32(rel[0],
                       _mm256_mullo_epi32(load(L.brickDims[0]),
                                          _mm256_add_epi32(rel[1], _mm256_mullo_epi32(load(L.brickDims[1]), rel[2])))));
  store(L.stepCode,
        _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), tables.brickCodes.data(), codeIndex, walking, 4));
}

// The rest of vsWalkCellLog2 (the occupancy gather).
void lookupLanes(const gpu::SceneArrays& arrays, const LaneTables& tables, Lanes& L) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i one = _mm256_set1_epi32(1);
  const __m256i three = _mm256_set1_epi32(3);
  const __m256i walking = load(L.stepWalking);

  __m256i v[3];
  for (int a = 0; a < 3; ++a) v[a] = load(L.v[a]);
  auto child = [&](int log2Child) {
    __m256i x = _mm256_and_si256(_mm256_srai_epi32(v[0], log2Child), three);
    __m256i y = _mm256_and_si256(_mm256_srai_epi32(v[1], log2Child), three);
    __m256i z = _mm256_and_si256(_mm256_srai_epi32(v[2], log2Child), three);
    return _mm256_add_epi32(x, _mm256_add_epi32(_mm256_slli_epi32(y, 2), _mm256_slli_epi32(z, 4)));
  };
  auto maskBit = [&](const std::uint32_t* lo, const std::uint32_t* hi, __m256i bit) {
    __m256i word = select(load(lo), load(hi), _mm256_cmpgt_epi32(bit, _mm256_set1_epi32(31)));
    return _mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_srlv_epi32(word, _mm256_and_si256(bit, _mm256_set1_epi32(31))), one), one);
  };

  // vsWalkCellLog2 up to the brick: whether the voxel's brick is present, else the empty cell's log2; the
  // brick's cell mask, fullness and first occupancy word.
  __m256i brickPresent, emptyLog2, fullBrick, occupancyBase, brickCode;
  __m256i emptyBox = zero;
  __m256i cellLo = zero, cellHi = zero;  // read on the sector level only
  const bool brickLevel = !tables.brickCodes.empty();
  if (brickLevel) {
    brickCode = load(L.stepCode);
    fullBrick = _mm256_and_si256(walking, _mm256_cmpeq_epi32(brickCode, _mm256_set1_epi32(kLaneFullBrick)));
    brickPresent =
        _mm256_or_si256(fullBrick, _mm256_and_si256(walking, _mm256_cmpgt_epi32(brickCode, _mm256_set1_epi32(-1))));
    __m256i box = _mm256_sub_epi32(_mm256_set1_epi32(-1), brickCode);  // extents | log2 (VS_BOX_*)
    emptyLog2 = _mm256_srai_epi32(box, gpu::VS_BOX_LOG2_SHIFT);
    emptyBox = _mm256_and_si256(box, _mm256_set1_epi32((1 << gpu::VS_BOX_LOG2_SHIFT) - 1));
    occupancyBase = brickCode;
  } else {
    // The sector's code (region empty, sector empty, or its index) from the dense table, then the brick from
    // the lane's cache.
    __m256i sectorPresent, sectorLog2;
    __m256i sectorRel[3];
    for (int a = 0; a < 3; ++a) {
      sectorRel[a] = _mm256_sub_epi32(_mm256_srai_epi32(v[a], gpu::VS_SECTOR_LOG2), load(L.sectorOrigin[a]));
    }
    __m256i codeIndex = _mm256_add_epi32(
        load(L.sectorBase),
        _mm256_add_epi32(sectorRel[0],
                         _mm256_mullo_epi32(
                             load(L.sectorDims[0]),
                             _mm256_add_epi32(sectorRel[1], _mm256_mullo_epi32(load(L.sectorDims[1]), sectorRel[2])))));
    __m256i sectorCode = _mm256_mask_i32gather_epi32(zero, tables.sectorCodes.data(), codeIndex, walking, 4);
    sectorPresent = _mm256_and_si256(walking, _mm256_cmpgt_epi32(sectorCode, _mm256_set1_epi32(-1)));
    sectorLog2 = _mm256_sub_epi32(zero, sectorCode);
    {
      const int* sectors = reinterpret_cast<const int*>(arrays.sectors);
      __m256i field =
          _mm256_slli_epi32(sectorCode, 2);  // a Sector is four words: brickMask.x, .y, firstBrick, reserved
      store(reinterpret_cast<int*>(L.brickMask[0]),
            _mm256_mask_i32gather_epi32(zero, sectors, field, sectorPresent, 4));
      store(reinterpret_cast<int*>(L.brickMask[1]),
            _mm256_mask_i32gather_epi32(zero, sectors, _mm256_add_epi32(field, one), sectorPresent, 4));
      __m256i first =
          _mm256_mask_i32gather_epi32(zero, sectors, _mm256_add_epi32(field, _mm256_set1_epi32(2)), sectorPresent, 4);
      store(reinterpret_cast<int*>(L.firstBrick), _mm256_add_epi32(first, load(L.brickBase)));
    }

    brickPresent = _mm256_and_si256(sectorPresent, maskBit(L.brickMask[0], L.brickMask[1], child(gpu::VS_BRICK_LOG2)));
    __m256i sameBrick = brickPresent;
    for (int a = 0; a < 3; ++a)
      sameBrick = _mm256_and_si256(sameBrick,
                                   _mm256_cmpeq_epi32(_mm256_srai_epi32(v[a], gpu::VS_BRICK_LOG2), load(L.brick[a])));
    for (int m = laneMask(_mm256_andnot_si256(sameBrick, brickPresent)); m != 0; m &= m - 1)
      refillBrick(arrays, L, __builtin_ctz(unsigned(m)));
    fullBrick = _mm256_and_si256(brickPresent, load(L.fullBrick));
    cellLo = load(L.cellMask[0]);
    cellHi = load(L.cellMask[1]);
    occupancyBase = load(L.occupancyBase);
    emptyLog2 = select(sectorLog2, _mm256_set1_epi32(gpu::VS_BRICK_LOG2), sectorPresent);
  }
  __m256i cellBit = child(gpu::VS_CELL_LOG2);
  __m256i voxelBit =
      _mm256_add_epi32(_mm256_slli_epi32(cellBit, 3),
                       _mm256_add_epi32(_mm256_and_si256(v[0], one),
                                        _mm256_add_epi32(_mm256_slli_epi32(_mm256_and_si256(v[1], one), 1),
                                                         _mm256_slli_epi32(_mm256_and_si256(v[2], one), 2))));
  __m256i wordIndex = _mm256_add_epi32(occupancyBase, _mm256_srli_epi32(voxelBit, 5));
  __m256i cellPresent, word;
  if (brickLevel) {
    // The cell's byte of the occupancy line stands for its mask bit (checked when the table was built).
    __m256i partial = _mm256_andnot_si256(fullBrick, brickPresent);
    word = _mm256_mask_i32gather_epi32(zero, reinterpret_cast<const int*>(arrays.occupancy), wordIndex, partial, 4);
    __m256i cellByte = _mm256_and_si256(_mm256_srlv_epi32(word, _mm256_slli_epi32(_mm256_and_si256(cellBit, three), 3)),
                                        _mm256_set1_epi32(0xff));
    cellPresent = _mm256_andnot_si256(_mm256_cmpeq_epi32(cellByte, zero), partial);
  } else {
    __m256i cellWord = select(cellLo, cellHi, _mm256_cmpgt_epi32(cellBit, _mm256_set1_epi32(31)));
    __m256i cellBitSet = _mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_srlv_epi32(cellWord, _mm256_and_si256(cellBit, _mm256_set1_epi32(31))), one), one);
    cellPresent = _mm256_andnot_si256(fullBrick, _mm256_and_si256(brickPresent, cellBitSet));
    word = _mm256_mask_i32gather_epi32(zero, reinterpret_cast<const int*>(arrays.occupancy), wordIndex, cellPresent, 4);
  }
  __m256i voxelSolid = _mm256_cmpeq_epi32(
      _mm256_and_si256(_mm256_srlv_epi32(word, _mm256_and_si256(voxelBit, _mm256_set1_epi32(31))), one), one);
  __m256i hit = _mm256_or_si256(fullBrick, _mm256_and_si256(cellPresent, voxelSolid));
  __m256i log2Size = select(emptyLog2, _mm256_set1_epi32(gpu::VS_CELL_LOG2), brickPresent);
  log2Size = select(log2Size, zero, cellPresent);
  store(L.stepLog2, log2Size);
  store(L.stepBox, _mm256_andnot_si256(brickPresent, emptyBox));
  store(L.stepHit, hit);
}

// vsSettleCoord per lane: c lies between `near` (where the ray comes from) and `far`; moves it one voxel back
// when the plane it was entered through is not crossed at t, or one forward when the plane ahead is. A plane at
// exactly t counts as crossed where tieCrossed is set.
inline __m256i settleLanes(__m256i c, __m256i near, __m256i far, __m256i dPositive, __m256 o, __m256 invD, __m256 t,
                           __m256i tieCrossed) {
  const __m256i one = _mm256_set1_epi32(1);
  auto crossed = [&](__m256i plane) {
    __m256 tp = _mm256_mul_ps(_mm256_sub_ps(_mm256_cvtepi32_ps(plane), o), invD);
    __m256i below = _mm256_castps_si256(_mm256_cmp_ps(tp, t, _CMP_LT_OQ));
    __m256i tie = _mm256_and_si256(_mm256_castps_si256(_mm256_cmp_ps(tp, t, _CMP_EQ_OQ)), tieCrossed);
    return _mm256_or_si256(below, tie);
  };
  __m256i step = select(_mm256_set1_epi32(-1), one, dPositive);
  __m256i entryPlane = select(_mm256_add_epi32(c, one), c, dPositive);
  __m256i aheadPlane = select(c, _mm256_add_epi32(c, one), dPositive);
  __m256i back = _mm256_andnot_si256(_mm256_or_si256(_mm256_cmpeq_epi32(c, near), crossed(entryPlane)),
                                     _mm256_set1_epi32(-1));
  __m256i forward = _mm256_andnot_si256(_mm256_or_si256(back, _mm256_cmpeq_epi32(c, far)), crossed(aheadPlane));
  c = select(c, _mm256_sub_epi32(c, step), back);
  return select(c, _mm256_add_epi32(c, step), forward);
}

// The second half: moves every walking lane past its empty cell. Returns the lanes that finished (bit i) and
// sets `hits` to those of them that stopped on a solid voxel (w.v, w.tEnter hold the hit, as in the reference).
int advanceLanes(Lanes& L, int& hits) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i one = _mm256_set1_epi32(1);
  const __m256i live = load(L.live);
  const __m256i walking = load(L.stepWalking);
  const __m256i hit = load(L.stepHit);
  const __m256i log2Size = load(L.stepLog2);
  __m256i v[3];
  for (int a = 0; a < 3; ++a) v[a] = load(L.v[a]);

  // The exit of the empty box: the smallest exact t over the axes, the highest axis on ties. The reference
  // walks aligned cells only; a larger empty box around the voxel leads to the same voxels (the canonical
  // order of traverse.h), with fewer steps.
  const __m256i box = load(L.stepBox);
  const __m256i extentMask = _mm256_set1_epi32(gpu::VS_BOX_EXTENT_MASK);
  __m256i cellMin[3], cellEnd[3], dPositive[3], dNonZero[3];
  __m256 tExit = _mm256_set1_ps(gpu::VS_T_INFINITY);
  __m256i exitAxis = _mm256_set1_epi32(-1);
  for (int a = 0; a < 3; ++a) {
    __m256i cell = _mm256_srav_epi32(v[a], log2Size);
    __m256i below = _mm256_and_si256(_mm256_srli_epi32(box, 2 * a * gpu::VS_BOX_EXTENT_BITS), extentMask);
    __m256i above = _mm256_and_si256(_mm256_srli_epi32(box, (2 * a + 1) * gpu::VS_BOX_EXTENT_BITS), extentMask);
    cellMin[a] = _mm256_sllv_epi32(_mm256_sub_epi32(cell, below), log2Size);
    cellEnd[a] = _mm256_sllv_epi32(_mm256_add_epi32(_mm256_add_epi32(cell, above), one), log2Size);
    dPositive[a] = load(L.dPositive[a]);
    dNonZero[a] = load(L.dNonZero[a]);
    __m256i bound = select(cellMin[a], cellEnd[a], dPositive[a]);
    __m256 ta =
        _mm256_mul_ps(_mm256_sub_ps(_mm256_cvtepi32_ps(bound), _mm256_load_ps(L.o[a])), _mm256_load_ps(L.invD[a]));
    __m256i closer = _mm256_and_si256(dNonZero[a], _mm256_castps_si256(_mm256_cmp_ps(ta, tExit, _CMP_LE_OQ)));
    tExit = _mm256_blendv_ps(tExit, ta, _mm256_castsi256_ps(closer));
    exitAxis = select(exitAxis, _mm256_set1_epi32(a), closer);
  }
  __m256i leaves = _mm256_or_si256(_mm256_cmpeq_epi32(exitAxis, _mm256_set1_epi32(-1)),
                                   _mm256_castps_si256(_mm256_cmp_ps(tExit, _mm256_load_ps(L.t1), _CMP_GE_OQ)));
  // tExit = max(tExit, w.tEnter): glm's max(x, y) is (x < y) ? y : x, which is maxps(y, x).
  __m256 tEnter = _mm256_load_ps(L.tEnter);
  tExit = _mm256_max_ps(tEnter, tExit);

  __m256i next[3];
  __m256i settle[3];
  __m256i anySettle = zero;
  for (int a = 0; a < 3; ++a) {
    __m256 p = _mm256_add_ps(_mm256_load_ps(L.o[a]), _mm256_mul_ps(_mm256_load_ps(L.d[a]), tExit));
    __m256i isExit = _mm256_cmpeq_epi32(exitAxis, _mm256_set1_epi32(a));
    __m256i exitCoord = select(_mm256_sub_epi32(cellMin[a], one), cellEnd[a], dPositive[a]);
    // clamp(floor(p), cell) and then never against the ray: floor(p) clamped to [v, cell max] (d > 0) or to
    // [cell min, v] (d < 0). p lies within the object's bounds here, so the clamp may follow the conversion.
    __m256i far = _mm256_sub_epi32(cellEnd[a], one);
    __m256i f = _mm256_cvttps_epi32(_mm256_round_ps(p, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
    __m256i moved = _mm256_min_epi32(_mm256_max_epi32(f, select(cellMin[a], v[a], dPositive[a])),
                                     select(v[a], far, dPositive[a]));
    // vsNearPlane: lanes whose coordinate needs vsSettleCoord (the test may differ from the reference's in
    // rounding; either way the settled coordinate is the canonical one).
    const __m256 absMask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    __m256 dist = _mm256_and_ps(absMask, _mm256_sub_ps(p, _mm256_round_ps(p, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC)));
    settle[a] = _mm256_andnot_si256(
        isExit, _mm256_and_si256(dNonZero[a], _mm256_castps_si256(_mm256_cmp_ps(dist, _mm256_load_ps(L.nearBand[a]), _CMP_LE_OQ))));
    anySettle = _mm256_or_si256(anySettle, settle[a]);
    next[a] = select(select(v[a], moved, dNonZero[a]), exitCoord, isExit);
    __m256i outside = _mm256_or_si256(_mm256_cmpgt_epi32(load(L.voxelMin[a]), next[a]),
                                      _mm256_cmpeq_epi32(_mm256_cmpgt_epi32(load(L.voxelMax[a]), next[a]), zero));
    leaves = _mm256_or_si256(leaves, _mm256_and_si256(isExit, outside));
  }

  if (!_mm256_testz_si256(anySettle, anySettle)) {
    // vsSettleCoord between the current voxel and the cell's far face, ties crossed above the exit axis.
    for (int a = 0; a < 3; ++a) {
      __m256i far = select(cellMin[a], _mm256_sub_epi32(cellEnd[a], one), dPositive[a]);
      // The settled coordinate lies between the current voxel and the far face whatever the estimate.
      __m256i settled = settleLanes(next[a], v[a], far, dPositive[a], _mm256_load_ps(L.o[a]),
                                    _mm256_load_ps(L.invD[a]), tExit, _mm256_cmpgt_epi32(_mm256_set1_epi32(a), exitAxis));
      next[a] = select(next[a], settled, settle[a]);
    }
  }
  __m256i continuing = _mm256_andnot_si256(_mm256_or_si256(hit, leaves), walking);
  for (int a = 0; a < 3; ++a) store(L.v[a], select(v[a], next[a], continuing));
  _mm256_store_ps(L.tEnter, _mm256_blendv_ps(tEnter, tExit, _mm256_castsi256_ps(continuing)));
  hits = laneMask(hit);
  return laneMask(_mm256_andnot_si256(continuing, live));
}


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

// A ray of a single-instance scene, set up and waiting for a lane: what loadSingleLane and the result need.
template <class Target>
struct SingleRay {
  tile::WorldRay ray;           // the world ray
  float tBase;                  // vsInstanceBaseT: the walk's t is relative to it
  float lo[3], ld[3], invD[3];  // the brick-space ray and vsObjectWalkBegin's inverse direction
  int v[3];                     // the walk's first voxel
  float t0, t1;                 // its entry t and the end of its span
  Target target;
};

// One ray through a single-instance scene, set up by the portable code as collectCandidates and beginNextWalk
// would (the one leaf's box, the instance's box, the re-based instance ray, vsObjectWalkBegin); false when it
// begins no walk (a miss).
template <class Target>
bool setupSingle(gpu::SceneArrays& arrays, const SingleInstance& one, SingleRay<Target>& r) {
  r.tBase = 0.0f;
  if (!arrays.vsRayIsFinite(r.ray)) return false;
  const tile::WorldRay& ray = r.ray;
  // The one leaf's box is the instance's: one test says whether the ray enters it.
  const float entry = arrays.vsInstanceEntry(ray, one.instance);
  if (entry == gpu::VS_T_INFINITY) return false;
  r.tBase = arrays.vsBaseT(ray, entry);
  glm::vec3 lo, ld;
  arrays.vsInstanceRay(ray, one.instance, r.tBase, lo, ld);
  gpu::SceneArrays::ObjectWalk w;
  if (!arrays.vsObjectWalkBegin(one.objectIndex, lo, ld, arrays.vsLocalT(ray.tMin, r.tBase),
                                arrays.vsLocalT(ray.tMax, r.tBase), w))
    return false;
  for (int k = 0; k < 3; ++k) {
    r.lo[k] = w.o[k];
    r.ld[k] = w.d[k];
    r.invD[k] = w.invD[k];
    r.v[k] = w.v[k];
  }
  r.t0 = w.tEnter;
  r.t1 = w.t1;
  return true;
}

// Gives every lane of the groups a ray (refill(k, i)), then steps all groups until no lane walks. A lane that
// finishes is handed to finished(k, i, hit), which gives it its next ray (or leaves it idle).
template <class Refill, class Finished>
void stepLaneGroups(const gpu::SceneArrays& arrays, const LaneTables& tables, Lanes* groups, int groupCount,
                    Refill refill, Finished finished) {
  int liveCount = 0;
  for (int k = 0; k < groupCount; ++k)
    for (int i = 0; i < kLanes; ++i) {
      refill(k, i);
      liveCount += groups[k].live[i] != 0;
    }
  while (liveCount > 0) {
    for (int k = 0; k < groupCount; ++k) beginStepLanes(tables, groups[k]);
    for (int k = 0; k < groupCount; ++k) lookupLanes(arrays, tables, groups[k]);
    for (int k = 0; k < groupCount; ++k) {
      Lanes& L = groups[k];
      int hits = 0;
      for (int done = advanceLanes(L, hits); done != 0; done &= done - 1) {
        int i = __builtin_ctz(unsigned(done));
        finished(k, i, ((hits >> i) & 1) != 0);
        if (L.live[i] == 0) --liveCount;
      }
    }
  }
}

// The single-instance driver: rays are set up a batch at a time straight into compact records, lanes take
// them as they free up, and a finished lane hands its result to the source at once (one object, one
// candidate: nothing else to walk, so no per-ray candidate state, and an any-hit ray ends like any other).
template <class Source>
void traceSingle(gpu::SceneArrays& arrays, const LaneTables& tables, const SingleInstance& one, Source& source) {
  using Ray = SingleRay<typename Source::Target>;
  constexpr int kGroups = 4;
  constexpr int kReady = 64;
  std::unique_ptr<Lanes[]> groups(new Lanes[kGroups]);
  std::unique_ptr<Ray[]> laneRay(new Ray[kGroups * kLanes]);
  std::unique_ptr<Ray[]> ready(new Ray[kReady]);
  int readyHead = 0, readyCount = 0;
  const gpu::ObjectRecord& obj = arrays.objects[one.objectIndex];
  const int stepsLeft = (obj.voxelMax.x - obj.voxelMin.x) + (obj.voxelMax.y - obj.voxelMin.y) +
                        (obj.voxelMax.z - obj.voxelMin.z) + 3;
  {
    // Every lane's object fields, once (loadLane's per-object part).
    gpu::SceneArrays::ObjectWalk w{};
    w.obj = obj;
    for (int k = 0; k < kGroups; ++k)
      for (int i = 0; i < kLanes; ++i) {
        loadLane(groups[k], i, w, tables, one.objectIndex);
        groups[k].live[i] = 0;
      }
  }
  // tLocal: the hit's t relative to the ray's base.
  auto finish = [&](const Ray& r, bool hit, float tLocal, glm::ivec3 voxel) {
    float t = hit ? arrays.vsWorldT(tLocal, r.tBase) : r.ray.tMax;
    source.finish(arrays, r.target, r.ray, hit, t, one.instance, voxel);
  };
  // Sets up rays until `ready` is full (rays without a walk are finished as misses on the way).
  auto prepare = [&] {
    readyHead = readyCount = 0;
    while (readyCount < kReady) {
      Ray& r = ready[readyCount];
      if (!source.next(arrays, r.ray, r.target)) break;
      if (setupSingle(arrays, one, r)) {
        ++readyCount;
      } else {
        finish(r, false, 0.0f, glm::ivec3(0));
      }
    }
  };
  auto refill = [&](int k, int i) {
    groups[k].live[i] = 0;
    if (readyHead == readyCount) prepare();
    if (readyHead == readyCount) return;
    const Ray& r = laneRay[k * kLanes + i] = ready[readyHead++];
    loadLaneRay(groups[k], i, r.lo, r.ld, r.invD, r.v, r.t0, r.t1, stepsLeft);
  };

  stepLaneGroups(arrays, tables, groups.get(), kGroups, refill, [&](int k, int i, bool hit) {
    const Lanes& L = groups[k];
    finish(laneRay[k * kLanes + i], hit, L.tEnter[i], glm::ivec3(L.v[0][i], L.v[1][i], L.v[2][i]));
    refill(k, i);
  });
}

// The general driver: each ray visits its candidate instances (compute/cpu/tile_rays.h) one walk at a time,
// a lane per walk.
template <class Source>
void traceLanes(gpu::SceneArrays& arrays, const LaneTables& tables, Source& source) {
  const SingleInstance one = singleInstance(arrays);
  if (one.enabled) {
    traceSingle(arrays, tables, one, source);
    return;
  }
  // Several independent groups of eight lanes, stepped in turn: a group's step is one long chain of
  // dependent gathers, and the next group's chain overlaps it in the processor.
  constexpr int kGroups = 4;
  // Rays are set up (ray, candidates, first walk) a batch at a time, in one tight scalar loop, and wait in
  // `ready` until a lane frees up.
  constexpr int kBatch = 16;
  constexpr int kPool = kGroups * kLanes + kBatch;
  struct Ray {
    tile::RayState state;
    typename Source::Target target;
  };
  std::unique_ptr<Ray[]> pool(new Ray[kPool]);
  std::unique_ptr<Lanes[]> groups(new Lanes[kGroups]);
  int laneRay[kGroups][kLanes] = {};
  int freeSlots[kPool];
  int freeCount = kPool;
  for (int s = 0; s < kPool; ++s) freeSlots[s] = kPool - 1 - s;
  int ready[kBatch];
  int readyHead = 0, readyCount = 0;

  auto finish = [&](int slot) {
    const tile::RayState& r = pool[slot].state;
    source.finish(arrays, pool[slot].target, r.ray, r.hit, r.tBest, r.instanceHit, r.voxel);
    freeSlots[freeCount++] = slot;
  };
  // Sets up the next batch of rays that need a walk (rays that need none are finished on the way).
  auto prepare = [&] {
    readyHead = readyCount = 0;
    while (readyCount < kBatch) {
      int slot = freeSlots[freeCount - 1];
      Ray& ray = pool[slot];
      tile::WorldRay worldRay;
      if (!source.next(arrays, worldRay, ray.target)) break;
      --freeCount;
      tile::RayState& r = ray.state;
      tile::beginRay(arrays, r, worldRay);
      if (!tile::collectCandidates(arrays, r)) {
        source.traceAlone(arrays, ray.target, worldRay);
        freeSlots[freeCount++] = slot;
        continue;
      }
      if (tile::beginNextWalk(arrays, r)) {
        ready[readyCount++] = slot;
        continue;
      }
      finish(slot);
    }
  };
  // Gives lane i of group k the next ready ray, or leaves it idle when the source is exhausted.
  auto refill = [&](int k, int i) {
    groups[k].live[i] = 0;
    if (readyHead == readyCount) prepare();
    if (readyHead == readyCount) return;
    int slot = ready[readyHead++];
    laneRay[k][i] = slot;
    const tile::RayState& r = pool[slot].state;
    loadLane(groups[k], i, r.walk, tables, arrays.instances[r.walkingInstance].info.x);
  };

  stepLaneGroups(arrays, tables, groups.get(), kGroups, refill, [&](int k, int i, bool hit) {
    Lanes& L = groups[k];
    int slot = laneRay[k][i];
    tile::RayState& r = pool[slot].state;
    if (hit) tile::recordHit(arrays, r, L.tEnter[i], glm::ivec3(L.v[0][i], L.v[1][i], L.v[2][i]));
    if (!(Source::kAnyHit && r.hit) && tile::beginNextWalk(arrays, r)) {
      loadLane(L, i, r.walk, tables, arrays.instances[r.walkingInstance].info.x);
      return;
    }
    finish(slot);
    refill(k, i);
  });
}

}  // namespace

void traceTilesLanes(gpu::SceneArrays& arrays, const LaneTables& tables, std::span<const gpu::TraceView> views,
                     std::span<const TexelTile> tiles, std::vector<ShadowLayer>& layers) {
  rays::TexelSource source(views, tiles, layers);
  traceLanes(arrays, tables, source);
}

void traceClosestLanes(gpu::SceneArrays& arrays, const LaneTables& tables, std::span<const gpu::TraceRay> rays,
                       std::span<gpu::RayHit> hits) {
  rays::ClosestSource source;
  source.rays = rays;
  source.end = rays.size();
  source.hits = hits.data();
  traceLanes(arrays, tables, source);
}

void traceAnyLanes(gpu::SceneArrays& arrays, const LaneTables& tables, std::span<const gpu::TraceRay> rays,
                   std::span<std::uint32_t> occluded) {
  rays::AnySource source;
  source.rays = rays;
  source.end = rays.size();
  source.occluded = occluded.data();
  traceLanes(arrays, tables, source);
}

#ifdef __clang__
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif
#else
void traceTilesLanes(gpu::SceneArrays&, const LaneTables&, std::span<const gpu::TraceView>, std::span<const TexelTile>,
                     std::vector<ShadowLayer>&) {
  throwBadInput("the lane tracer needs x86-64 with AVX2");
}
void traceClosestLanes(gpu::SceneArrays&, const LaneTables&, std::span<const gpu::TraceRay>, std::span<gpu::RayHit>) {
  throwBadInput("the lane tracer needs x86-64 with AVX2");
}
void traceAnyLanes(gpu::SceneArrays&, const LaneTables&, std::span<const gpu::TraceRay>, std::span<std::uint32_t>) {
  throwBadInput("the lane tracer needs x86-64 with AVX2");
}
#endif

}  // namespace vs
