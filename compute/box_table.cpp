#include "compute/box_table.h"

#include <algorithm>
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
void encodeEmptyBoxes(std::int32_t* codes, int nx, int ny, int nz) {
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
  tbb::parallel_for(0, nz, [&](int z) {
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
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

}  // namespace

std::vector<std::int32_t> buildBoxTable(const SceneData& scene, std::uint64_t maxElements) {
  maxElements = std::min<std::uint64_t>(maxElements, std::uint64_t(std::numeric_limits<std::int32_t>::max()));
  const std::uint64_t heads = scene.objects.size();
  std::uint64_t codes = 0;
  for (const gpu::ObjectRecord& obj : scene.objects)
    codes += std::uint64_t(obj.regionDims.x) * std::uint64_t(obj.regionDims.y) * std::uint64_t(obj.regionDims.z) *
             4096u;
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
    encodeEmptyBoxes(objectCodes, dims.x, dims.y, dims.z);
    next += std::uint64_t(dims.x) * dims.y * dims.z;
  }
  for (std::size_t i = 0; i < scene.occupancy.size(); ++i)
    table[occupancyStart + i] = std::bit_cast<std::int32_t>(scene.occupancy[i]);
  return table;
}

}  // namespace vs
