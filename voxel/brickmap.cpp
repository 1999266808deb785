// Brickmap: build from solid voxels, queries, and local edits (DESIGN.md §4, layout in brickmap_layout.h).
#include "voxel/brickmap.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include "voxel/error.h"

namespace vs {

using gpu::VS_BRICK_LOG2;
using gpu::VS_EMPTY_SLOT;
using gpu::VS_FULL_BRICK;
using gpu::VS_OCCUPANCY_WORDS;
using gpu::VS_REGION_LOG2;
using gpu::VS_SECTOR_LOG2;
using gpu::VS_UNIFORM_PAYLOAD;

namespace {

using gpu::Brick;
using gpu::Region;
using gpu::Sector;

constexpr int kCoordLimit = Brickmap::kMaxCoordinate;

std::uint64_t toU64(glm::uvec2 m) { return (std::uint64_t(m.y) << 32) | m.x; }
glm::uvec2 toUvec2(std::uint64_t m) { return glm::uvec2(std::uint32_t(m), std::uint32_t(m >> 32)); }
bool testBit(std::uint64_t m, unsigned bit) { return (m >> bit) & 1u; }
unsigned rankBelow(std::uint64_t m, unsigned bit) {
  return unsigned(std::popcount(bit == 0 ? 0 : (m & ((std::uint64_t(1) << bit) - 1))));
}
unsigned childBit(glm::ivec3 v, int log2Child) {
  glm::ivec3 c = (v >> log2Child) & glm::ivec3(3);
  return unsigned(c.x + 4 * c.y + 16 * c.z);
}
// Voxel bit inside a brick for the brick-local coordinate l (0..7 per axis).
unsigned voxelBitLocal(glm::ivec3 l) {
  unsigned cell = unsigned((l.x >> 1) + 4 * (l.y >> 1) + 16 * (l.z >> 1));
  return cell * 8u + unsigned((l.x & 1) + 2 * (l.y & 1) + 4 * (l.z & 1));
}
glm::ivec3 localOfVoxelBit(unsigned b) {
  unsigned cell = b >> 3, sub = b & 7u;
  return glm::ivec3(int((cell & 3u) * 2u + (sub & 1u)), int(((cell >> 2) & 3u) * 2u + ((sub >> 1) & 1u)),
                    int((cell >> 4) * 2u + ((sub >> 2) & 1u)));
}
glm::ivec3 localOfChildBit(unsigned b) { return glm::ivec3(int(b & 3u), int((b >> 2) & 3u), int(b >> 4)); }

std::string boxText(glm::ivec3 a, glm::ivec3 b) {
  std::ostringstream s;
  s << "[" << a.x << "," << a.y << "," << a.z << "]..[" << b.x << "," << b.y << "," << b.z << "]";
  return s.str();
}

void checkCoord(glm::ivec3 v, const char* what) {
  for (int a = 0; a < 3; ++a) {
    if (v[a] < -kCoordLimit || v[a] > kCoordLimit) {
      throwBadInput(std::string("brickmap: ") + what + " coordinate " + std::to_string(v[a]) +
                    " is outside the supported range +-" + std::to_string(kCoordLimit));
    }
  }
}

// A single voxel's box ends at v + 1, so the voxel itself must stay below the limit.
void checkVoxel(glm::ivec3 v) {
  for (int a = 0; a < 3; ++a)
    if (v[a] < -kCoordLimit || v[a] >= kCoordLimit)
      throwBadInput("brickmap: voxel (" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " +
                    std::to_string(v.z) + ") is outside the editable range " + std::to_string(-kCoordLimit) + ".." +
                    std::to_string(kCoordLimit - 1) + " on axis " + "xyz"[a]);
}

// An edit's time follows its box (a clear's: the part inside the region table), so its volume is bounded.
void checkEditVolume(const VoxelBox& box, bool fill, const VoxelBox& asGiven) {
  std::uint64_t side[3];
  for (int a = 0; a < 3; ++a) side[a] = std::uint64_t(std::int64_t(box.max[a]) - std::int64_t(box.min[a]));
  // Each side is at most 2^31, so the product of two fits; the third only has to show it is over the limit.
  const std::uint64_t area = side[0] * side[1];
  const bool over = side[2] > Brickmap::kMaxEditVoxels || area > Brickmap::kMaxEditVoxels ||
                    area * side[2] > Brickmap::kMaxEditVoxels;
  if (!over) return;
  std::string size = std::to_string(side[0]) + " x " + std::to_string(side[1]) + " x " + std::to_string(side[2]);
  if (area <= Brickmap::kMaxEditVoxels && side[2] <= Brickmap::kMaxEditVoxels) size += " = " + std::to_string(area * side[2]);
  throwBadInput(std::string("brickmap: ") + (fill ? "fill" : "clear") + " box " + boxText(asGiven.min, asGiven.max) +
                (fill ? " is " : " covers ") + size + " voxels" + (fill ? "" : " of the region table") +
                ", more than the limit of " + std::to_string(Brickmap::kMaxEditVoxels) +
                " voxels per edit (split it into smaller edits)");
}

// Saturates instead of overflowing: three extents of up to 2^28 regions each multiply past int64, and a
// count above the limit only has to say so.
std::int64_t slotCount(glm::ivec3 dims) {
  constexpr std::int64_t kSaturated = std::int64_t(Brickmap::kMaxRegionSlots) + 1;
  std::int64_t slots = 1;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] <= 0) return 0;
    if (slots > kSaturated / dims[a]) return kSaturated;
    slots *= dims[a];
  }
  return slots;
}

void checkSlots(glm::ivec3 dims, glm::ivec3 vmin, glm::ivec3 vmax) {
  std::int64_t slots = slotCount(dims);
  if (slots > std::int64_t(Brickmap::kMaxRegionSlots)) {
    throwBadInput("brickmap: voxel bounds " + boxText(vmin, vmax) + " need a region table of " +
                  std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" + std::to_string(dims.z) +
                  " slots, more than the limit of " +
                  std::to_string(Brickmap::kMaxRegionSlots));
  }
}

std::uint64_t cellMaskOf(const std::uint64_t occ[8]) {
  std::uint64_t mask = 0;
  for (unsigned cell = 0; cell < 64; ++cell) {
    if ((occ[cell >> 3] >> ((cell & 7u) * 8u)) & 0xffu) mask |= std::uint64_t(1) << cell;
  }
  return mask;
}

}  // namespace

struct Brickmap::BrickContent {
  std::uint64_t occ[8];
  std::uint8_t mat[512];
  int count = 0;
  void clear() {
    std::memset(occ, 0, sizeof occ);
    std::memset(mat, 0, sizeof mat);
    count = 0;
  }
  bool test(unsigned b) const { return (occ[b >> 6] >> (b & 63u)) & 1u; }
};

// Collects what an edit writes, and hands out blocks from the free lists or the arrays' ends.
struct Brickmap::EditContext {
  Brickmap& bm;
  std::vector<DirtyRange> dirty;
  bool layoutChanged = false;
  bool tableRebuilt = false;
  bool track = true;  // false while building: everything is new

  void mark(DirtyRange::Array a, std::size_t offset, std::size_t size) {
    if (track) dirty.push_back({a, offset, size});
  }

  std::uint32_t allocLine() {
    if (!bm.freeOccupancyLines_.empty()) {
      auto l = bm.freeOccupancyLines_.back();
      bm.freeOccupancyLines_.pop_back();
      return l;
    }
    auto l = std::uint32_t(bm.occupancy_.size() / VS_OCCUPANCY_WORDS);
    bm.occupancy_.resize(bm.occupancy_.size() + VS_OCCUPANCY_WORDS, 0u);
    return l;
  }
  std::uint32_t allocPayload() {
    if (!bm.freePayloadBlocks_.empty()) {
      auto p = bm.freePayloadBlocks_.back();
      bm.freePayloadBlocks_.pop_back();
      return p;
    }
    auto p = std::uint32_t(bm.payload_.size());
    bm.payload_.resize(bm.payload_.size() + 128, 0u);
    return p;
  }
  std::uint32_t allocBricks(unsigned n) {
    auto& fl = bm.freeBrickBlocks_[n];
    if (!fl.empty()) {
      auto f = fl.back();
      fl.pop_back();
      return f;
    }
    auto f = std::uint32_t(bm.bricks_.size());
    bm.bricks_.resize(bm.bricks_.size() + n, Brick{});
    return f;
  }
  std::uint32_t allocSectors(unsigned n) {
    auto& fl = bm.freeSectorBlocks_[n];
    if (!fl.empty()) {
      auto f = fl.back();
      fl.pop_back();
      return f;
    }
    auto f = std::uint32_t(bm.sectors_.size());
    bm.sectors_.resize(bm.sectors_.size() + n, Sector{});
    return f;
  }
  std::uint32_t allocRegion() {
    if (!bm.freeRegions_.empty()) {
      auto r = bm.freeRegions_.back();
      bm.freeRegions_.pop_back();
      return r;
    }
    bm.regions_.push_back(Region{});
    return std::uint32_t(bm.regions_.size() - 1);
  }

  void releaseBrick(const Brick& b) {
    if (b.occupancy != VS_FULL_BRICK) bm.freeOccupancyLines_.push_back(b.occupancy);
    if (!(b.payload & VS_UNIFORM_PAYLOAD)) bm.freePayloadBlocks_.push_back(b.payload);
  }

  // Encodes content (count in 1..512) into a brick record, reusing old's line and payload block if it has them.
  Brick encode(const BrickContent& c, const Brick* old) {
    Brick b{};
    b.cellMask = toUvec2(cellMaskOf(c.occ));
    bool oldHasLine = old && old->occupancy != VS_FULL_BRICK;
    bool oldHasPayload = old && !(old->payload & VS_UNIFORM_PAYLOAD);
    if (c.count == 512) {
      b.occupancy = VS_FULL_BRICK;
      if (oldHasLine) bm.freeOccupancyLines_.push_back(old->occupancy);
    } else {
      b.occupancy = oldHasLine ? old->occupancy : allocLine();
      std::memcpy(&bm.occupancy_[std::size_t(b.occupancy) * VS_OCCUPANCY_WORDS], c.occ, 64);
      mark(DirtyRange::Array::Occupancy, std::size_t(b.occupancy) * 64, 64);
    }
    int uniform = -1;
    bool isUniform = true;
    for (unsigned i = 0; i < 512 && isUniform; ++i) {
      if (!c.test(i)) continue;
      if (uniform < 0) uniform = c.mat[i];
      else if (uniform != c.mat[i]) isUniform = false;
    }
    if (isUniform) {
      b.payload = VS_UNIFORM_PAYLOAD | std::uint32_t(uniform < 0 ? 0 : uniform);
      if (oldHasPayload) bm.freePayloadBlocks_.push_back(old->payload);
    } else {
      b.payload = oldHasPayload ? old->payload : allocPayload();
      std::uint8_t bytes[512];
      for (unsigned i = 0; i < 512; ++i) bytes[i] = c.test(i) ? c.mat[i] : 0;
      std::memcpy(&bm.payload_[b.payload], bytes, 512);
      mark(DirtyRange::Array::Payload, std::size_t(b.payload) * 4, 512);
    }
    return b;
  }
};

Brickmap Brickmap::build(std::span<const SolidVoxel> voxels) {
  Brickmap bm;
  if (voxels.empty()) return bm;
  glm::ivec3 vmin(voxels[0].coord), vmax(voxels[0].coord);
  for (const auto& v : voxels) {
    vmin = glm::min(vmin, v.coord);
    vmax = glm::max(vmax, v.coord);
  }
  checkCoord(vmin, "voxel");
  checkCoord(vmax, "voxel");
  glm::ivec3 rmin = vmin >> VS_REGION_LOG2, rmax = vmax >> VS_REGION_LOG2;
  glm::ivec3 dims = rmax - rmin + glm::ivec3(1);
  checkSlots(dims, vmin, vmax + glm::ivec3(1));
  bm.regionOrigin_ = rmin;
  bm.regionDims_ = dims;
  bm.regionTable_.assign(std::size_t(slotCount(dims)), VS_EMPTY_SLOT);

  // Sort by (table slot, sector bit, brick bit, voxel bit): exactly the packing order of every level.
  struct Key {
    std::uint64_t key;
    std::uint32_t index;
  };
  std::vector<Key> keys(voxels.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, voxels.size()), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      glm::ivec3 v = voxels[i].coord;
      glm::ivec3 r = (v >> VS_REGION_LOG2) - rmin;
      std::uint64_t slot = std::uint64_t(r.x) + std::uint64_t(dims.x) * (std::uint64_t(r.y) + std::uint64_t(dims.y) * std::uint64_t(r.z));
      std::uint64_t key = (slot << 21) | (std::uint64_t(childBit(v, VS_SECTOR_LOG2)) << 15) |
                          (std::uint64_t(childBit(v, VS_BRICK_LOG2)) << 9) | voxelBitLocal(v & glm::ivec3(7));
      keys[i] = {key, std::uint32_t(i)};
    }
  });
  tbb::parallel_sort(keys.begin(), keys.end(),
                     [](const Key& a, const Key& b) { return a.key != b.key ? a.key < b.key : a.index < b.index; });

  EditContext ctx{bm, {}};
  ctx.track = false;
  BrickContent content;
  std::size_t i = 0, n = keys.size();
  std::uint64_t solid = 0;
  while (i < n) {
    std::uint64_t slot = keys[i].key >> 21;
    std::uint32_t regionIndex = std::uint32_t(bm.regions_.size());
    Region region{};
    region.firstSector = std::uint32_t(bm.sectors_.size());
    std::uint64_t sectorMask = 0;
    std::vector<Sector> sectorRecords;
    while (i < n && (keys[i].key >> 21) == slot) {
      std::uint64_t sectorKey = keys[i].key >> 15;
      Sector sector{};
      sector.firstBrick = std::uint32_t(bm.bricks_.size());
      std::uint64_t brickMask = 0;
      while (i < n && (keys[i].key >> 15) == sectorKey) {
        std::uint64_t brickKey = keys[i].key >> 9;
        content.clear();
        while (i < n && (keys[i].key >> 9) == brickKey) {
          unsigned b = unsigned(keys[i].key & 511u);
          if (!content.test(b)) {
            content.occ[b >> 6] |= std::uint64_t(1) << (b & 63u);
            ++content.count;
          }
          content.mat[b] = voxels[keys[i].index].material;
          ++i;
        }
        brickMask |= std::uint64_t(1) << (brickKey & 63u);
        solid += std::uint64_t(content.count);
        bm.bricks_.push_back(ctx.encode(content, nullptr));
      }
      sector.brickMask = toUvec2(brickMask);
      sectorMask |= std::uint64_t(1) << (sectorKey & 63u);
      bm.sectors_.push_back(sector);
    }
    region.sectorMask = toUvec2(sectorMask);
    bm.regions_.push_back(region);
    bm.regionTable_[slot] = regionIndex;
  }
  bm.solidCount_ = solid;
  bm.bounds_ = VoxelBox{vmin, vmax + glm::ivec3(1)};
  return bm;
}

std::int64_t Brickmap::slotOf(glm::ivec3 r) const {
  glm::ivec3 d = r - regionOrigin_;
  if (d.x < 0 || d.y < 0 || d.z < 0 || d.x >= regionDims_.x || d.y >= regionDims_.y || d.z >= regionDims_.z)
    return -1;
  return std::int64_t(d.x) + std::int64_t(regionDims_.x) * (std::int64_t(d.y) + std::int64_t(regionDims_.y) * d.z);
}

const Brick* Brickmap::findBrick(glm::ivec3 v) const {
  if (regionTable_.empty()) return nullptr;
  std::int64_t slot = slotOf(v >> VS_REGION_LOG2);
  if (slot < 0) return nullptr;
  std::uint32_t ri = regionTable_[std::size_t(slot)];
  if (ri == VS_EMPTY_SLOT) return nullptr;
  const Region& region = regions_[ri];
  std::uint64_t sm = toU64(region.sectorMask);
  unsigned sb = childBit(v, VS_SECTOR_LOG2);
  if (!testBit(sm, sb)) return nullptr;
  const Sector& sector = sectors_[region.firstSector + rankBelow(sm, sb)];
  std::uint64_t bmask = toU64(sector.brickMask);
  unsigned bb = childBit(v, VS_BRICK_LOG2);
  if (!testBit(bmask, bb)) return nullptr;
  return &bricks_[sector.firstBrick + rankBelow(bmask, bb)];
}

bool Brickmap::isSolid(glm::ivec3 v) const {
  const Brick* b = findBrick(v);
  if (!b) return false;
  if (b->occupancy == VS_FULL_BRICK) return true;
  unsigned bit = voxelBitLocal(v & glm::ivec3(7));
  std::uint32_t word = occupancy_[std::size_t(b->occupancy) * VS_OCCUPANCY_WORDS + (bit >> 5)];
  return (word >> (bit & 31u)) & 1u;
}

std::uint8_t Brickmap::material(glm::ivec3 v) const {
  const Brick* b = findBrick(v);
  if (!b) return 0;
  unsigned bit = voxelBitLocal(v & glm::ivec3(7));
  if (b->occupancy != VS_FULL_BRICK) {
    std::uint32_t word = occupancy_[std::size_t(b->occupancy) * VS_OCCUPANCY_WORDS + (bit >> 5)];
    if (!((word >> (bit & 31u)) & 1u)) return 0;
  }
  if (b->payload & VS_UNIFORM_PAYLOAD) return std::uint8_t(b->payload & 0xffu);
  return std::uint8_t(payload_[b->payload + (bit >> 2)] >> ((bit & 3u) * 8u));
}

BrickmapMemory Brickmap::memory() const {
  BrickmapMemory m;
  m.regionTableBytes = regionTable_.size() * sizeof(std::uint32_t);
  m.regionBytes = regions_.size() * sizeof(Region);
  m.sectorBytes = sectors_.size() * sizeof(Sector);
  m.brickBytes = bricks_.size() * sizeof(Brick);
  m.occupancyBytes = occupancy_.size() * sizeof(std::uint32_t);
  m.payloadBytes = payload_.size() * sizeof(std::uint32_t);
  return m;
}

void Brickmap::decodeBrick(const Brick& b, BrickContent& c) const {
  if (b.occupancy == VS_FULL_BRICK) {
    std::memset(c.occ, 0xff, sizeof c.occ);
  } else {
    std::memcpy(c.occ, &occupancy_[std::size_t(b.occupancy) * VS_OCCUPANCY_WORDS], 64);
  }
  if (b.payload & VS_UNIFORM_PAYLOAD) {
    std::memset(c.mat, int(b.payload & 0xffu), 512);
  } else {
    std::memcpy(c.mat, &payload_[b.payload], 512);
  }
  c.count = 0;
  for (unsigned w = 0; w < 8; ++w) c.count += std::popcount(c.occ[w]);
  for (unsigned i = 0; i < 512; ++i)
    if (!c.test(i)) c.mat[i] = 0;
}

namespace {
// Visits every live brick with its brick-space origin.
template <class Fn>
void forEachBrick(glm::ivec3 origin, glm::ivec3 dims, std::span<const std::uint32_t> table,
                  std::span<const Region> regions, std::span<const Sector> sectors, std::span<const Brick> bricks,
                  Fn&& fn) {
  for (std::size_t slot = 0; slot < table.size(); ++slot) {
    if (table[slot] == VS_EMPTY_SLOT) continue;
    glm::ivec3 r(int(slot % std::size_t(dims.x)), int((slot / std::size_t(dims.x)) % std::size_t(dims.y)),
                 int(slot / (std::size_t(dims.x) * std::size_t(dims.y))));
    glm::ivec3 regionBase = (r + origin) * (1 << VS_REGION_LOG2);
    const Region& region = regions[table[slot]];
    std::uint64_t sm = toU64(region.sectorMask);
    unsigned si = 0;
    for (std::uint64_t m = sm; m; m &= m - 1, ++si) {
      unsigned sb = unsigned(std::countr_zero(m));
      glm::ivec3 sectorBase = regionBase + localOfChildBit(sb) * (1 << VS_SECTOR_LOG2);
      const Sector& sector = sectors[region.firstSector + si];
      std::uint64_t bmask = toU64(sector.brickMask);
      unsigned bi = 0;
      for (std::uint64_t m2 = bmask; m2; m2 &= m2 - 1, ++bi) {
        unsigned bb = unsigned(std::countr_zero(m2));
        fn(sectorBase + localOfChildBit(bb) * (1 << VS_BRICK_LOG2), bricks[sector.firstBrick + bi]);
      }
    }
  }
}
}  // namespace

void Brickmap::forEachSolid(const std::function<void(glm::ivec3, std::uint8_t)>& fn) const {
  BrickContent c;
  forEachBrick(regionOrigin_, regionDims_, regionTable_, regions_, sectors_, bricks_,
               [&](glm::ivec3 base, const Brick& b) {
                 decodeBrick(b, c);
                 for (unsigned i = 0; i < 512; ++i)
                   if (c.test(i)) fn(base + localOfVoxelBit(i), c.mat[i]);
               });
}

void Brickmap::recomputeBounds() const {
  glm::ivec3 lo(std::numeric_limits<int>::max()), hi(std::numeric_limits<int>::min());
  forEachBrick(regionOrigin_, regionDims_, regionTable_, regions_, sectors_, bricks_,
               [&](glm::ivec3 base, const Brick& b) {
                 if (b.occupancy == VS_FULL_BRICK) {
                   lo = glm::min(lo, base);
                   hi = glm::max(hi, base + glm::ivec3(8));
                   return;
                 }
                 const std::uint32_t* w = &occupancy_[std::size_t(b.occupancy) * VS_OCCUPANCY_WORDS];
                 for (unsigned cell = 0; cell < 64; ++cell) {
                   unsigned byte = (w[cell >> 2] >> ((cell & 3u) * 8u)) & 0xffu;
                   if (!byte) continue;
                   glm::ivec3 c = base + localOfChildBit(cell) * 2;
                   // Bits of a cell byte: x = bit&1, y = (bit>>1)&1, z = (bit>>2)&1.
                   glm::ivec3 cmin(byte & 0x55u ? 0 : 1, byte & 0x33u ? 0 : 1, byte & 0x0fu ? 0 : 1);
                   glm::ivec3 cmax(byte & 0xaau ? 2 : 1, byte & 0xccu ? 2 : 1, byte & 0xf0u ? 2 : 1);
                   lo = glm::min(lo, c + cmin);
                   hi = glm::max(hi, c + cmax);
                 }
               });
  bounds_ = lo.x > hi.x ? VoxelBox{} : VoxelBox{lo, hi};
  boundsStale_ = false;
}

VoxelBox Brickmap::bounds() const {
  if (boundsStale_) recomputeBounds();
  return bounds_;
}

void Brickmap::growRegionTable(glm::ivec3 rmin, glm::ivec3 rmax, EditContext& ctx) {
  glm::ivec3 newMin = rmin, newMax = rmax;
  if (!regionTable_.empty()) {
    newMin = glm::min(newMin, regionOrigin_);
    newMax = glm::max(newMax, regionOrigin_ + regionDims_ - glm::ivec3(1));
  }
  glm::ivec3 dims = newMax - newMin + glm::ivec3(1);
  checkSlots(dims, newMin * (1 << VS_REGION_LOG2), (newMax + glm::ivec3(1)) * (1 << VS_REGION_LOG2));
  std::vector<std::uint32_t> table(std::size_t(slotCount(dims)), VS_EMPTY_SLOT);
  for (int z = 0; z < regionDims_.z; ++z)
    for (int y = 0; y < regionDims_.y; ++y)
      for (int x = 0; x < regionDims_.x; ++x) {
        glm::ivec3 d = regionOrigin_ + glm::ivec3(x, y, z) - newMin;
        table[std::size_t(d.x) + std::size_t(dims.x) * (std::size_t(d.y) + std::size_t(dims.y) * std::size_t(d.z))] =
            regionTable_[std::size_t(x) + std::size_t(regionDims_.x) * (std::size_t(y) + std::size_t(regionDims_.y) * std::size_t(z))];
      }
  regionTable_ = std::move(table);
  regionOrigin_ = newMin;
  regionDims_ = dims;
  ctx.layoutChanged = true;
  ctx.tableRebuilt = true;
}

EditResult Brickmap::editBricks(const VoxelBox& boxIn, bool adds, const VoxelOp& op) {
  EditResult result;
  checkCoord(boxIn.min, "edit box");
  checkCoord(boxIn.max, "edit box");
  if (boxIn.empty()) return result;
  VoxelBox box = boxIn;
  EditContext ctx{*this, {}};
  std::array<std::size_t, 6> sizesBefore{regionTable_.size(), regions_.size(), sectors_.size(),
                                         bricks_.size(), occupancy_.size(), payload_.size()};
  glm::ivec3 rmin = box.min >> VS_REGION_LOG2, rmax = (box.max - glm::ivec3(1)) >> VS_REGION_LOG2;
  // Every refusal comes before the first change (growRegionTable checks its size before it builds).
  if (adds) {
    checkEditVolume(box, adds, boxIn);
    bool inside = !regionTable_.empty() && slotOf(rmin) >= 0 && slotOf(rmax) >= 0;
    if (!inside) growRegionTable(rmin, rmax, ctx);
  } else {
    if (regionTable_.empty()) return result;
    box.min = glm::max(box.min, regionOrigin_ * (1 << VS_REGION_LOG2));
    box.max = glm::min(box.max, (regionOrigin_ + regionDims_) * (1 << VS_REGION_LOG2));
    if (box.empty()) return result;
    checkEditVolume(box, adds, boxIn);
    rmin = box.min >> VS_REGION_LOG2;
    rmax = (box.max - glm::ivec3(1)) >> VS_REGION_LOG2;
  }

  glm::ivec3 dirtyLo(std::numeric_limits<int>::max()), dirtyHi(std::numeric_limits<int>::min());
  std::int64_t countDelta = 0;
  BrickContent content;
  struct BrickChange {
    unsigned bit;
    BrickContent content;
  };
  std::vector<BrickChange> brickChanges;
  struct SectorChange {
    unsigned bit;
    std::uint64_t brickMask;
    std::uint32_t firstBrick;
  };
  std::vector<SectorChange> sectorChanges;

  for (int rz = rmin.z; rz <= rmax.z; ++rz)
    for (int ry = rmin.y; ry <= rmax.y; ++ry)
      for (int rx = rmin.x; rx <= rmax.x; ++rx) {
        glm::ivec3 rc(rx, ry, rz);
        std::size_t slot = std::size_t(slotOf(rc));
        std::uint32_t regionIndex = regionTable_[slot];
        Region oldRegion = regionIndex == VS_EMPTY_SLOT ? Region{} : regions_[regionIndex];
        std::uint64_t oldSectorMask = toU64(oldRegion.sectorMask);
        glm::ivec3 regionBase = rc * (1 << VS_REGION_LOG2);
        glm::ivec3 smin = (glm::max(box.min, regionBase) - regionBase) >> VS_SECTOR_LOG2;
        glm::ivec3 smax = (glm::min(box.max, regionBase + glm::ivec3(128)) - glm::ivec3(1) - regionBase) >> VS_SECTOR_LOG2;
        sectorChanges.clear();
        for (int sz = smin.z; sz <= smax.z; ++sz)
          for (int sy = smin.y; sy <= smax.y; ++sy)
            for (int sx = smin.x; sx <= smax.x; ++sx) {
              unsigned sbit = unsigned(sx + 4 * sy + 16 * sz);
              glm::ivec3 sectorBase = regionBase + glm::ivec3(sx, sy, sz) * (1 << VS_SECTOR_LOG2);
              bool sectorExists = testBit(oldSectorMask, sbit);
              Sector oldSector = sectorExists ? sectors_[oldRegion.firstSector + rankBelow(oldSectorMask, sbit)] : Sector{};
              std::uint64_t oldBrickMask = toU64(oldSector.brickMask);
              glm::ivec3 bmin = (glm::max(box.min, sectorBase) - sectorBase) >> VS_BRICK_LOG2;
              glm::ivec3 bmax = (glm::min(box.max, sectorBase + glm::ivec3(32)) - glm::ivec3(1) - sectorBase) >> VS_BRICK_LOG2;
              brickChanges.clear();
              for (int bz = bmin.z; bz <= bmax.z; ++bz)
                for (int by = bmin.y; by <= bmax.y; ++by)
                  for (int bx = bmin.x; bx <= bmax.x; ++bx) {
                    unsigned bbit = unsigned(bx + 4 * by + 16 * bz);
                    glm::ivec3 brickBase = sectorBase + glm::ivec3(bx, by, bz) * (1 << VS_BRICK_LOG2);
                    bool brickExists = testBit(oldBrickMask, bbit);
                    if (brickExists) {
                      decodeBrick(bricks_[oldSector.firstBrick + rankBelow(oldBrickMask, bbit)], content);
                    } else {
                      if (!adds) continue;
                      content.clear();
                    }
                    BrickContent before = content;
                    op(content, brickBase);
                    if (std::memcmp(before.occ, content.occ, 64) == 0 && std::memcmp(before.mat, content.mat, 512) == 0)
                      continue;
                    countDelta += content.count - before.count;
                    dirtyLo = glm::min(dirtyLo, glm::max(box.min, brickBase));
                    dirtyHi = glm::max(dirtyHi, glm::min(box.max, brickBase + glm::ivec3(8)));
                    brickChanges.push_back({bbit, content});
                  }
              if (brickChanges.empty()) continue;

              std::uint64_t newBrickMask = oldBrickMask;
              for (const auto& ch : brickChanges) {
                if (ch.content.count > 0) newBrickMask |= std::uint64_t(1) << ch.bit;
                else newBrickMask &= ~(std::uint64_t(1) << ch.bit);
              }
              if (newBrickMask == oldBrickMask) {
                for (const auto& ch : brickChanges) {
                  std::size_t index = oldSector.firstBrick + rankBelow(oldBrickMask, ch.bit);
                  Brick old = bricks_[index];
                  bricks_[index] = ctx.encode(ch.content, &old);
                  ctx.mark(DirtyRange::Array::Bricks, index * sizeof(Brick), sizeof(Brick));
                }
                continue;
              }
              unsigned count = unsigned(std::popcount(newBrickMask));
              std::uint32_t first = count ? ctx.allocBricks(count) : 0u;
              unsigned k = 0;
              std::size_t ci = 0;
              for (unsigned bbit = 0; bbit < 64; ++bbit) {
                bool changed = ci < brickChanges.size() && brickChanges[ci].bit == bbit;
                bool existed = testBit(oldBrickMask, bbit);
                Brick old = existed ? bricks_[oldSector.firstBrick + rankBelow(oldBrickMask, bbit)] : Brick{};
                if (changed) {
                  const auto& ch = brickChanges[ci++];
                  if (ch.content.count == 0) {
                    if (existed) ctx.releaseBrick(old);
                    continue;
                  }
                  bricks_[first + k++] = ctx.encode(ch.content, existed ? &old : nullptr);
                } else if (existed) {
                  bricks_[first + k++] = old;
                }
              }
              if (count) ctx.mark(DirtyRange::Array::Bricks, std::size_t(first) * sizeof(Brick), count * sizeof(Brick));
              if (sectorExists) freeBrickBlocks_[std::popcount(oldBrickMask)].push_back(oldSector.firstBrick);
              sectorChanges.push_back({sbit, newBrickMask, first});
            }
        if (sectorChanges.empty()) continue;

        std::uint64_t newSectorMask = oldSectorMask;
        for (const auto& ch : sectorChanges) {
          if (ch.brickMask) newSectorMask |= std::uint64_t(1) << ch.bit;
          else newSectorMask &= ~(std::uint64_t(1) << ch.bit);
        }
        if (newSectorMask == oldSectorMask) {
          for (const auto& ch : sectorChanges) {
            std::size_t index = oldRegion.firstSector + rankBelow(oldSectorMask, ch.bit);
            sectors_[index].brickMask = toUvec2(ch.brickMask);
            sectors_[index].firstBrick = ch.firstBrick;
            ctx.mark(DirtyRange::Array::Sectors, index * sizeof(Sector), sizeof(Sector));
          }
          continue;
        }
        unsigned count = unsigned(std::popcount(newSectorMask));
        std::uint32_t first = count ? ctx.allocSectors(count) : 0u;
        unsigned k = 0;
        std::size_t ci = 0;
        for (unsigned sbit = 0; sbit < 64; ++sbit) {
          bool changed = ci < sectorChanges.size() && sectorChanges[ci].bit == sbit;
          bool existed = testBit(oldSectorMask, sbit);
          if (changed) {
            const auto& ch = sectorChanges[ci++];
            if (!ch.brickMask) continue;
            sectors_[first + k++] = Sector{toUvec2(ch.brickMask), ch.firstBrick, 0u};
          } else if (existed) {
            sectors_[first + k++] = sectors_[oldRegion.firstSector + rankBelow(oldSectorMask, sbit)];
          }
        }
        if (count) ctx.mark(DirtyRange::Array::Sectors, std::size_t(first) * sizeof(Sector), count * sizeof(Sector));
        if (regionIndex != VS_EMPTY_SLOT) freeSectorBlocks_[std::popcount(oldSectorMask)].push_back(oldRegion.firstSector);
        if (count == 0) {
          freeRegions_.push_back(regionIndex);
          regionTable_[slot] = VS_EMPTY_SLOT;
          ctx.mark(DirtyRange::Array::RegionTable, slot * 4, 4);
          continue;
        }
        if (regionIndex == VS_EMPTY_SLOT) {
          regionIndex = ctx.allocRegion();
          regionTable_[slot] = regionIndex;
          ctx.mark(DirtyRange::Array::RegionTable, slot * 4, 4);
        }
        regions_[regionIndex] = Region{toUvec2(newSectorMask), first, 0u};
        ctx.mark(DirtyRange::Array::Regions, std::size_t(regionIndex) * sizeof(Region), sizeof(Region));
      }

  solidCount_ = std::uint64_t(std::int64_t(solidCount_) + countDelta);
  std::array<std::size_t, 6> sizesAfter{regionTable_.size(), regions_.size(), sectors_.size(),
                                        bricks_.size(), occupancy_.size(), payload_.size()};
  if (sizesAfter != sizesBefore) ctx.layoutChanged = true;
  // A rebuilt region table moves every slot.
  if (ctx.tableRebuilt) ctx.mark(DirtyRange::Array::RegionTable, 0, regionTable_.size() * 4);
  if (dirtyLo.x <= dirtyHi.x) {
    result.dirtyVoxels = VoxelBox{dirtyLo, dirtyHi};
    if (!adds) {
      boundsStale_ = true;
    } else if (!boundsStale_) {
      // Every voxel of a fill box is solid afterwards, so the union stays tight.
      bounds_ = bounds_.empty() ? result.dirtyVoxels
                                : VoxelBox{glm::min(bounds_.min, dirtyLo), glm::max(bounds_.max, dirtyHi)};
    }
  }
  // Merge ranges per array.
  std::sort(ctx.dirty.begin(), ctx.dirty.end(), [](const DirtyRange& a, const DirtyRange& b) {
    return a.array != b.array ? a.array < b.array : a.byteOffset < b.byteOffset;
  });
  for (const auto& r : ctx.dirty) {
    if (!result.dirty.empty() && result.dirty.back().array == r.array &&
        result.dirty.back().byteOffset + result.dirty.back().byteSize >= r.byteOffset) {
      auto& last = result.dirty.back();
      last.byteSize = std::max(last.byteOffset + last.byteSize, r.byteOffset + r.byteSize) - last.byteOffset;
    } else {
      result.dirty.push_back(r);
    }
  }
  result.layoutChanged = ctx.layoutChanged;
  return result;
}

namespace {
// Sets (solid) or clears every voxel of `box` inside the brick at `base`.
void applyBox(const VoxelBox& box, bool solid, std::uint8_t material, std::uint64_t occ[8], std::uint8_t mat[512],
              int& count, glm::ivec3 base) {
  glm::ivec3 lo = glm::max(box.min, base) - base, hi = glm::min(box.max, base + glm::ivec3(8)) - base;
  for (int z = lo.z; z < hi.z; ++z)
    for (int y = lo.y; y < hi.y; ++y)
      for (int x = lo.x; x < hi.x; ++x) {
        unsigned b = voxelBitLocal(glm::ivec3(x, y, z));
        std::uint64_t bit = std::uint64_t(1) << (b & 63u);
        bool was = occ[b >> 6] & bit;
        if (solid) {
          if (!was) {
            occ[b >> 6] |= bit;
            ++count;
          }
          mat[b] = material;
        } else if (was) {
          occ[b >> 6] &= ~bit;
          mat[b] = 0;
          --count;
        }
      }
}
}  // namespace

EditResult Brickmap::fillBox(const VoxelBox& box, std::uint8_t material) {
  if (material == 0) return clearBox(box);
  return editBricks(box, true, [&](BrickContent& c, glm::ivec3 base) {
    applyBox(box, true, material, c.occ, c.mat, c.count, base);
  });
}

EditResult Brickmap::clearBox(const VoxelBox& box) {
  return editBricks(box, false, [&](BrickContent& c, glm::ivec3 base) {
    applyBox(box, false, 0, c.occ, c.mat, c.count, base);
  });
}

EditResult Brickmap::setVoxel(glm::ivec3 v, std::uint8_t material) {
  checkVoxel(v);
  return fillBox(VoxelBox{v, v + glm::ivec3(1)}, material);
}

EditResult Brickmap::clearVoxel(glm::ivec3 v) {
  checkVoxel(v);
  return clearBox(VoxelBox{v, v + glm::ivec3(1)});
}

EditResult Brickmap::compact() {
  std::vector<SolidVoxel> voxels;
  voxels.reserve(std::size_t(solidCount_));
  forEachSolid([&](glm::ivec3 v, std::uint8_t m) { voxels.push_back({v, m}); });
  *this = build(voxels);
  EditResult result;
  result.layoutChanged = true;
  result.rebuilt = true;
  auto whole = [&](DirtyRange::Array a, std::size_t bytes) {
    if (bytes) result.dirty.push_back({a, 0, bytes});
  };
  BrickmapMemory m = memory();
  whole(DirtyRange::Array::RegionTable, m.regionTableBytes);
  whole(DirtyRange::Array::Regions, m.regionBytes);
  whole(DirtyRange::Array::Sectors, m.sectorBytes);
  whole(DirtyRange::Array::Bricks, m.brickBytes);
  whole(DirtyRange::Array::Occupancy, m.occupancyBytes);
  whole(DirtyRange::Array::Payload, m.payloadBytes);
  return result;
}

void Brickmap::checkConsistency() const {
  auto fail = [](const std::string& what) { throw std::logic_error("brickmap inconsistent: " + what); };
  if (slotCount(regionDims_) != std::int64_t(regionTable_.size())) fail("region table size != dims product");
  std::vector<std::uint8_t> regionUsed(regions_.size()), sectorUsed(sectors_.size()), brickUsed(bricks_.size()),
      lineUsed(occupancy_.size() / VS_OCCUPANCY_WORDS), payloadUsed(payload_.size() / 128);
  if (occupancy_.size() % VS_OCCUPANCY_WORDS || payload_.size() % 128) fail("array size not a whole number of lines");
  for (auto r : freeRegions_) {
    if (r >= regions_.size() || regionUsed[r]++) fail("bad free region");
  }
  for (unsigned n = 1; n <= 64; ++n) {
    for (auto f : freeSectorBlocks_[n])
      for (unsigned k = 0; k < n; ++k)
        if (f + k >= sectors_.size() || sectorUsed[f + k]++) fail("bad free sector block");
    for (auto f : freeBrickBlocks_[n])
      for (unsigned k = 0; k < n; ++k)
        if (f + k >= bricks_.size() || brickUsed[f + k]++) fail("bad free brick block");
  }
  for (auto l : freeOccupancyLines_)
    if (l >= lineUsed.size() || lineUsed[l]++) fail("bad free occupancy line");
  for (auto p : freePayloadBlocks_)
    if (p % 128 || p / 128 >= payloadUsed.size() || payloadUsed[p / 128]++) fail("bad free payload block");

  std::uint64_t solid = 0;
  for (std::size_t slot = 0; slot < regionTable_.size(); ++slot) {
    std::uint32_t ri = regionTable_[slot];
    if (ri == VS_EMPTY_SLOT) continue;
    if (ri >= regions_.size() || regionUsed[ri]++) fail("slot " + std::to_string(slot) + " names a bad or shared region");
    const Region& region = regions_[ri];
    std::uint64_t sm = toU64(region.sectorMask);
    if (!sm) fail("region " + std::to_string(ri) + " has an empty sector mask");
    unsigned ns = unsigned(std::popcount(sm));
    for (unsigned k = 0; k < ns; ++k) {
      std::size_t si = std::size_t(region.firstSector) + k;
      if (si >= sectors_.size() || sectorUsed[si]++) fail("region " + std::to_string(ri) + " sector block out of range or shared");
      const Sector& sector = sectors_[si];
      std::uint64_t bmask = toU64(sector.brickMask);
      if (!bmask) fail("sector " + std::to_string(si) + " has an empty brick mask");
      unsigned nb = unsigned(std::popcount(bmask));
      for (unsigned j = 0; j < nb; ++j) {
        std::size_t bi = std::size_t(sector.firstBrick) + j;
        if (bi >= bricks_.size() || brickUsed[bi]++) fail("sector " + std::to_string(si) + " brick block out of range or shared");
        const Brick& b = bricks_[bi];
        std::uint64_t occ[8];
        if (b.occupancy == VS_FULL_BRICK) {
          std::memset(occ, 0xff, sizeof occ);
        } else {
          if (b.occupancy >= lineUsed.size() || lineUsed[b.occupancy]++) fail("brick " + std::to_string(bi) + " occupancy line bad or shared");
          std::memcpy(occ, &occupancy_[std::size_t(b.occupancy) * VS_OCCUPANCY_WORDS], 64);
        }
        std::uint64_t count = 0;
        for (auto w : occ) count += unsigned(std::popcount(w));
        if (count == 0) fail("brick " + std::to_string(bi) + " is empty");
        if (count == 512 && b.occupancy != VS_FULL_BRICK) fail("brick " + std::to_string(bi) + " is full but owns a line");
        if (cellMaskOf(occ) != toU64(b.cellMask)) fail("brick " + std::to_string(bi) + " cell mask != occupancy line");
        solid += count;
        if (!(b.payload & VS_UNIFORM_PAYLOAD)) {
          if (b.payload % 128 || b.payload / 128 >= payloadUsed.size() || payloadUsed[b.payload / 128]++)
            fail("brick " + std::to_string(bi) + " payload block bad or shared");
          const auto* bytes = reinterpret_cast<const std::uint8_t*>(&payload_[b.payload]);
          int first = -1;
          bool uniform = true;
          for (unsigned i = 0; i < 512; ++i) {
            bool on = (occ[i >> 6] >> (i & 63u)) & 1u;
            if (!on && bytes[i]) fail("brick " + std::to_string(bi) + " payload byte of an empty voxel is not 0");
            if (on) {
              if (first < 0) first = bytes[i];
              else if (first != bytes[i]) uniform = false;
            }
          }
          if (uniform) fail("brick " + std::to_string(bi) + " has one material but a payload block");
        }
      }
    }
  }
  if (solid != solidCount_) fail("solid count " + std::to_string(solidCount_) + " != " + std::to_string(solid));
  for (std::size_t i = 0; i < regionUsed.size(); ++i) if (!regionUsed[i]) fail("region " + std::to_string(i) + " is neither used nor free");
  for (std::size_t i = 0; i < sectorUsed.size(); ++i) if (!sectorUsed[i]) fail("sector " + std::to_string(i) + " is neither used nor free");
  for (std::size_t i = 0; i < brickUsed.size(); ++i) if (!brickUsed[i]) fail("brick " + std::to_string(i) + " is neither used nor free");
  for (std::size_t i = 0; i < lineUsed.size(); ++i) if (!lineUsed[i]) fail("occupancy line " + std::to_string(i) + " is neither used nor free");
  for (std::size_t i = 0; i < payloadUsed.size(); ++i) if (!payloadUsed[i]) fail("payload block " + std::to_string(i) + " is neither used nor free");

  VoxelBox stored = bounds_;
  bool stale = boundsStale_;
  recomputeBounds();
  VoxelBox tight = bounds_;
  if (!stale && (stored.min != tight.min || stored.max != tight.max) && !(stored.empty() && tight.empty()))
    fail("stored bounds differ from the tight bounds");
  if (!tight.empty()) {
    glm::ivec3 lo = regionOrigin_ * (1 << VS_REGION_LOG2), hi = (regionOrigin_ + regionDims_) * (1 << VS_REGION_LOG2);
    if (glm::any(glm::lessThan(tight.min, lo)) || glm::any(glm::greaterThan(tight.max, hi)))
      fail("bounds outside the region table");
  }
}

}  // namespace vs
