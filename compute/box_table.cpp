#include "compute/box_table.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

namespace vs {

namespace {

// Replaces the code of every empty brick of one object's brick grid (nx * ny * nz codes, x fastest) by the
// box-table code of the empty box around it (VS_BOX_* in trace_view.h). Bricks outside the grid hold no voxel,
// so a box may reach past the grid.
// The box grows from the largest empty cube of bricks centred on the brick (the chessboard distance to the
// nearest non-empty brick, less one, by two raster passes over the 26-neighbourhood), face by face in turn,
// each face by one brick while the slab it adds is empty (a summed-area table answers that), up to
// kMaxBoxExtent per side: streets and courtyards become long boxes instead of small cubes. The brick's
// empty sector or region (extents 0, log2 5 or 7) is kept when it holds more voxels.
// Only the bricks in [outLo, outHi) are encoded; the others keep their codes and are read as empty or not.
// A brick's code depends only on the bricks within kMaxBoxExtent of it (its box reaches no farther, and the
// distance is exact within any box holding the brick and its nearest non-empty one), so a grid cut out of a
// larger one around the encoded bricks, kMaxBoxExtent wider on every side where that one goes on, gives the
// codes the whole grid gives (updateBoxTable).
void encodeEmptyBoxes(std::int32_t* codes, int nx, int ny, int nz, glm::ivec3 outLo, glm::ivec3 outHi) {
  constexpr int kFar = kMaxBoxExtent + 1;
  const int px = nx + 2, py = ny + 2, pz = nz + 2;
  const std::size_t plane = std::size_t(px) * py;
  std::vector<std::uint8_t> dist(plane * pz, std::uint8_t(kFar));
  auto at = [&](int x, int y, int z) { return (std::size_t(z) * py + y) * px + x; };
  auto codeAt = [&](int x, int y, int z) -> std::int32_t& { return codes[(std::size_t(z) * ny + y) * nx + x]; };
  auto solid = [](std::int32_t code) { return code >= 0 || code == gpu::VS_BOX_FULL; };
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
  tbb::parallel_for(outLo.z, outHi.z, [&](int z) {
    for (int y = outLo.y; y < outHi.y; ++y)
      for (int x = outLo.x; x < outHi.x; ++x) {
        std::int32_t& code = codeAt(x, y, z);
        if (solid(code)) continue;
        const glm::ivec3 b(x, y, z);
        int r = std::min(int(dist[at(x + 1, y + 1, z + 1)]) - 1, kMaxBoxExtent);
        int ext[6] = {r, r, r, r, r, r};  // -x, +x, -y, +y, -z, +z
        for (bool grew = true; grew;) {
          grew = false;
          for (int f = 0; f < 6; ++f) {
            if (ext[f] == kMaxBoxExtent) continue;
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

// How many bits of `mask` lie below `bit`.
std::uint32_t rankBelow(glm::uvec2 mask, std::uint32_t bit) {
  if (bit < 32u) return std::uint32_t(std::popcount(mask.x & ((1u << bit) - 1u)));
  return std::uint32_t(std::popcount(mask.x)) + std::uint32_t(std::popcount(mask.y & ((1u << (bit - 32u)) - 1u)));
}

bool testBit(glm::uvec2 mask, std::uint32_t bit) { return (((bit < 32u ? mask.x : mask.y) >> (bit & 31u)) & 1u) != 0u; }

// The code of one brick before empty boxes are grown: VS_BOX_FULL, its first occupancy word (an index of the
// scene's occupancy array, offset later), or the log2 of its empty cell (region, sector or brick) negated.
// False when its cells' masks disagree with their occupancy bytes.
bool brickCode(const SceneData& scene, const gpu::ObjectRecord& obj, glm::ivec3 brick, std::int32_t& code) {
  const glm::ivec3 region = (brick >> (gpu::VS_REGION_LOG2 - gpu::VS_BRICK_LOG2)) - glm::ivec3(obj.regionOrigin);
  const int slotIndex = region.x + obj.regionDims.x * (region.y + obj.regionDims.y * region.z);
  const std::uint32_t slot = scene.regionTable[obj.bases.x + std::uint32_t(slotIndex)];
  code = -gpu::VS_REGION_LOG2;
  if (slot == gpu::VS_EMPTY_SLOT) return true;
  const glm::ivec3 voxel = brick << gpu::VS_BRICK_LOG2;
  const gpu::Region& r = scene.regions[obj.bases.y + slot];
  const glm::ivec3 sectorInRegion = (voxel >> gpu::VS_SECTOR_LOG2) & 3;
  const std::uint32_t sectorBit = std::uint32_t(sectorInRegion.x + 4 * sectorInRegion.y + 16 * sectorInRegion.z);
  code = -gpu::VS_SECTOR_LOG2;
  if (!testBit(r.sectorMask, sectorBit)) return true;
  const gpu::Sector& sector = scene.sectors[obj.bases.z + r.firstSector + rankBelow(r.sectorMask, sectorBit)];
  const std::uint32_t brickBit = std::uint32_t((brick.x & 3) + 4 * (brick.y & 3) + 16 * (brick.z & 3));
  code = -gpu::VS_BRICK_LOG2;
  if (!testBit(sector.brickMask, brickBit)) return true;
  const gpu::Brick& b =
      scene.bricks[std::size_t(obj.bases.w) + sector.firstBrick + rankBelow(sector.brickMask, brickBit)];
  if (b.occupancy == gpu::VS_FULL_BRICK) {
    code = gpu::VS_BOX_FULL;
    return true;
  }
  const std::uint64_t word = std::uint64_t(obj.bases2.x) + std::uint64_t(b.occupancy) * gpu::VS_OCCUPANCY_WORDS;
  if (word + gpu::VS_OCCUPANCY_WORDS > scene.occupancy.size()) return false;
  for (std::uint32_t cell = 0; cell < 64u; ++cell) {
    const bool maskBit = testBit(b.cellMask, cell);
    const bool anyVoxel = ((scene.occupancy[word + cell / 4u] >> ((cell & 3u) * 8u)) & 0xffu) != 0u;
    if (maskBit != anyVoxel) return false;
  }
  code = std::int32_t(word);
  return true;
}

// Bricks of one object's table (16^3 per region slot).
std::uint64_t codeCount(const gpu::ObjectRecord& obj) {
  return std::uint64_t(obj.regionDims.x) * std::uint64_t(obj.regionDims.y) * std::uint64_t(obj.regionDims.z) * 4096u;
}

std::uint64_t clampedLimit(std::uint64_t maxElements) {
  return std::min<std::uint64_t>(maxElements, std::uint64_t(std::numeric_limits<std::int32_t>::max()));
}

}  // namespace

std::vector<std::int32_t> buildBoxTable(const SceneData& scene, std::uint64_t maxElements) {
  maxElements = clampedLimit(maxElements);
  const std::uint64_t heads = scene.objects.size();
  std::uint64_t codes = 0;
  for (const gpu::ObjectRecord& obj : scene.objects) codes += codeCount(obj);
  const std::uint64_t occupancyStart = heads + codes;
  if (occupancyStart + scene.occupancy.size() > maxElements) return {};
  std::vector<std::int32_t> table(occupancyStart + scene.occupancy.size());
  std::uint64_t next = heads;
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const gpu::ObjectRecord& obj = scene.objects[o];
    table[o] = std::int32_t(next);
    const glm::ivec3 dims = glm::ivec3(obj.regionDims) * 16, origin = glm::ivec3(obj.regionOrigin) * 16;
    std::int32_t* objectCodes = table.data() + next;
    bool consistent = true;
    for (int z = 0; z < dims.z && consistent; ++z)
      for (int y = 0; y < dims.y && consistent; ++y)
        for (int x = 0; x < dims.x && consistent; ++x) {
          std::int32_t& code = objectCodes[(std::size_t(z) * dims.y + y) * dims.x + x];
          consistent = brickCode(scene, obj, origin + glm::ivec3(x, y, z), code);
          if (code >= 0) code += std::int32_t(occupancyStart);
        }
    if (!consistent) return {};
    encodeEmptyBoxes(objectCodes, dims.x, dims.y, dims.z, glm::ivec3(0), dims);
    next += std::uint64_t(dims.x) * dims.y * dims.z;
  }
  for (std::size_t i = 0; i < scene.occupancy.size(); ++i)
    table[occupancyStart + i] = std::bit_cast<std::int32_t>(scene.occupancy[i]);
  return table;
}

// Changed codes closer than this apart in a row are reported as one range: a copy region costs about as much
// as a few words of data.
constexpr int kRewriteGap = 8;

BoxTableUpdate updateBoxTable(std::vector<std::int32_t>& table, const SceneData& scene, const SceneDelta& delta,
                              std::uint64_t maxElements) {
  BoxTableUpdate result;
  auto rebuild = [&] {
    table = buildBoxTable(scene, maxElements);
    result.rebuilt = true;
    result.rewritten.clear();
    return result;
  };
  maxElements = clampedLimit(maxElements);
  if (delta.voxelLayout || table.empty()) return rebuild();
  // The table's codes must sit where this scene's layout puts them: a head per object, each object's codes
  // where its head says. An added object or a grown region table moves them (a grown table of any object but
  // the last one also lays the voxel arrays out again, and of the last one the delta says so).
  const std::size_t heads = scene.objects.size();
  if (table.size() < heads) return rebuild();
  std::uint64_t next = heads;
  for (std::size_t o = 0; o < heads; ++o) {
    if (std::uint64_t(table[o]) != next || table[o] < 0) return rebuild();
    next += codeCount(scene.objects[o]);
  }
  const std::uint64_t occupancyStart = next;
  if (table.size() < occupancyStart) return rebuild();
  const std::uint64_t copied = table.size() - occupancyStart;
  const std::uint64_t words = scene.occupancy.size();
  if (copied > words || occupancyStart + words > maxElements) return rebuild();

  auto rewrote = [&](std::uint64_t first, std::uint64_t count) {
    if (count > 0) result.rewritten.push_back({std::size_t(first), std::size_t(count)});
  };
  // The occupancy copy: the words the delta rewrote, and those the array gained at its end.
  if (words > copied) {
    table.resize(std::size_t(occupancyStart + words));
    for (std::uint64_t i = copied; i < words; ++i)
      table[std::size_t(occupancyStart + i)] = std::bit_cast<std::int32_t>(scene.occupancy[std::size_t(i)]);
    rewrote(occupancyStart + copied, words - copied);
  }
  for (const SceneDirtyRange& r : delta.ranges) {
    if (r.array != SceneArray::Occupancy) continue;
    const std::uint64_t first = r.byteOffset / sizeof(std::uint32_t);
    const std::uint64_t end = std::min<std::uint64_t>(words, (r.byteOffset + r.byteSize + 3) / sizeof(std::uint32_t));
    for (std::uint64_t i = first; i < end; ++i)
      table[std::size_t(occupancyStart + i)] = std::bit_cast<std::int32_t>(scene.occupancy[std::size_t(i)]);
    if (end > first) rewrote(occupancyStart + first, end - first);
  }

  // The codes around each edited box: a brick's code changes only where a brick within kMaxBoxExtent of it
  // changed (its empty box, its empty sector or region), and depends only on bricks within kMaxBoxExtent of it.
  std::vector<std::int32_t> window;
  for (const ObjectBricks& edited : delta.editedBricks) {
    if (edited.object >= heads) return rebuild();
    const gpu::ObjectRecord& obj = scene.objects[edited.object];
    const glm::ivec3 dims = glm::ivec3(obj.regionDims) * 16, origin = glm::ivec3(obj.regionOrigin) * 16;
    // In the object's brick grid, as 64-bit so that boxes near the coordinate limits do not overflow.
    auto clip = [&](glm::i64vec3 lo, glm::i64vec3 hi, glm::ivec3& outLo, glm::ivec3& outHi) {
      lo = glm::max(lo, glm::i64vec3(0));
      hi = glm::min(hi, glm::i64vec3(dims));
      outLo = glm::ivec3(lo);
      outHi = glm::ivec3(glm::max(hi, lo));
      return outLo.x < outHi.x && outLo.y < outHi.y && outLo.z < outHi.z;
    };
    const glm::i64vec3 eLo = glm::i64vec3(edited.bricks.min) - glm::i64vec3(origin);
    const glm::i64vec3 eHi = glm::i64vec3(edited.bricks.max) - glm::i64vec3(origin);
    glm::ivec3 bLo, bHi, aLo, aHi, wLo, wHi;
    if (edited.bricks.empty() || !clip(eLo, eHi, bLo, bHi)) continue;
    clip(glm::i64vec3(bLo) - std::int64_t(kMaxBoxExtent), glm::i64vec3(bHi) + std::int64_t(kMaxBoxExtent), aLo, aHi);
    clip(glm::i64vec3(aLo) - std::int64_t(kMaxBoxExtent), glm::i64vec3(aHi) + std::int64_t(kMaxBoxExtent), wLo, wHi);
    const glm::ivec3 w = wHi - wLo;
    window.assign(std::size_t(w.x) * w.y * w.z, 0);
    std::atomic<bool> consistent{true};
    tbb::parallel_for(0, w.z, [&](int z) {
      for (int y = 0; y < w.y; ++y)
        for (int x = 0; x < w.x; ++x) {
          std::int32_t& code = window[(std::size_t(z) * w.y + y) * w.x + x];
          if (!brickCode(scene, obj, origin + wLo + glm::ivec3(x, y, z), code)) consistent.store(false);
          if (code >= 0) code += std::int32_t(occupancyStart);
        }
    });
    if (!consistent.load()) return rebuild();
    encodeEmptyBoxes(window.data(), w.x, w.y, w.z, aLo - wLo, aHi - wLo);
    const std::uint64_t objectFirst = std::uint64_t(table[edited.object]);
    for (int z = aLo.z; z < aHi.z; ++z)
      for (int y = aLo.y; y < aHi.y; ++y) {
        const std::uint64_t first = objectFirst + (std::uint64_t(z) * dims.y + y) * dims.x + aLo.x;
        const std::int32_t* src = &window[(std::size_t(z - wLo.z) * w.y + (y - wLo.y)) * w.x + (aLo.x - wLo.x)];
        // Only the codes that differ are reported (runs closer than kRewriteGap apart joined): most codes of the
        // neighbourhood keep their value, and each reported one is copied to the device again.
        std::int32_t* dst = table.data() + first;
        const int n = aHi.x - aLo.x;
        int run = -1, last = -1;
        for (int x = 0; x < n; ++x) {
          if (dst[x] == src[x]) continue;
          dst[x] = src[x];
          if (run >= 0 && x - last > kRewriteGap) {
            rewrote(first + std::uint64_t(run), std::uint64_t(last + 1 - run));
            run = -1;
          }
          if (run < 0) run = x;
          last = x;
        }
        if (run >= 0) rewrote(first + std::uint64_t(run), std::uint64_t(last + 1 - run));
      }
  }

  std::sort(result.rewritten.begin(), result.rewritten.end());
  std::vector<std::pair<std::size_t, std::size_t>> merged;
  for (const auto& r : result.rewritten) {
    if (!merged.empty() && merged.back().first + merged.back().second >= r.first)
      merged.back().second =
          std::max(merged.back().first + merged.back().second, r.first + r.second) - merged.back().first;
    else
      merged.push_back(r);
  }
  result.rewritten = std::move(merged);
  return result;
}

}  // namespace vs
