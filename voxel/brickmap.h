// brickmap.h: one object's sparse 64-ary occupancy tree (DESIGN.md §4) as flat GPU-ready arrays.
#ifndef VOXSHADOW_BRICKMAP_H
#define VOXSHADOW_BRICKMAP_H

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "voxel/brickmap_layout.h"

namespace vs {

// Integer voxel box in brick space, [min, max) per axis. Empty when any max <= min.
struct VoxelBox {
  glm::ivec3 min{0};
  glm::ivec3 max{0};
  bool empty() const { return max.x <= min.x || max.y <= min.y || max.z <= min.z; }
};

// A contiguous byte range of one of the brickmap's arrays that changed and must be re-uploaded.
struct DirtyRange {
  enum class Array { RegionTable, Regions, Sectors, Bricks, Occupancy, Payload };
  Array array;
  std::size_t byteOffset;
  std::size_t byteSize;
};

// What an edit touched: byte ranges to re-upload and the brick-space box whose voxels may have changed
// (callers map it to world space through the object's transform).
struct EditResult {
  std::vector<DirtyRange> dirty;
  VoxelBox dirtyVoxels;
  bool layoutChanged = false;  // an array grew or the region table was rebuilt: re-upload that array whole
  // Every array was rewritten from scratch (compaction): the dirty ranges cover whole arrays and no byte
  // keeps its old meaning. Only compact() sets it.
  bool rebuilt = false;
};

struct BrickmapMemory {
  std::size_t regionTableBytes = 0, regionBytes = 0, sectorBytes = 0, brickBytes = 0, occupancyBytes = 0;
  std::size_t payloadBytes = 0;
  // The occupancy structure: every level, payload excluded (the figure compared with OpenVDB's BoolGrid).
  std::size_t occupancyStructureBytes() const {
    return regionTableBytes + regionBytes + sectorBytes + brickBytes + occupancyBytes;
  }
};

// A solid voxel as the builder receives it: brick-space coordinate and palette index (0..255).
struct SolidVoxel {
  glm::ivec3 coord;
  std::uint8_t material;
};

class Brickmap {
 public:
  // Hard cap on the dense region table, so hostile or absurd bounds give an error, never a huge allocation.
  static constexpr std::size_t kMaxRegionSlots = std::size_t(1) << 24;
  // Coordinates an edit may name: -kMaxCoordinate .. kMaxCoordinate - 1 per axis (box ends up to
  // kMaxCoordinate), so that box ends and region arithmetic never overflow.
  static constexpr int kMaxCoordinate = 1 << 30;
  // Most voxels one edit's box may cover (a clear: the part of it inside the region table), the same as the
  // solid voxels a .vdb grid may expand to by default (LoadOptions::maxSolidVoxels). An edit's time follows
  // its box, so a larger box would run for minutes; split it into several edits.
  static constexpr std::uint64_t kMaxEditVoxels = std::uint64_t(1) << 26;

  Brickmap() = default;

  // Builds from solid voxels in any order; duplicates keep the last material.
  // Throws vs::Error(BadInput) when the voxels' bounds need more than kMaxRegionSlots table slots.
  static Brickmap build(std::span<const SolidVoxel> voxels);

  // Queries in brick space. Out-of-bounds coordinates are empty / material 0.
  bool isSolid(glm::ivec3 v) const;
  std::uint8_t material(glm::ivec3 v) const;
  std::uint64_t solidCount() const { return solidCount_; }
  VoxelBox bounds() const;  // tight box of solid voxels; empty() when none (recomputed lazily after clears)
  BrickmapMemory memory() const;
  // Calls fn for every solid voxel (brick-space coordinate, material), in no particular order.
  void forEachSolid(const std::function<void(glm::ivec3, std::uint8_t)>& fn) const;

  // Edits. Each rebuilds only the bricks/sectors/regions it touches and reports what changed.
  // Material 0 means empty, as everywhere else: setVoxel(v, 0) is clearVoxel(v) and fillBox(box, 0) is
  // clearBox(box). An edit is refused with vs::Error(BadInput), changing nothing, when a voxel or box end
  // lies outside +-kMaxCoordinate (the message names the coordinate), when its box covers more than
  // kMaxEditVoxels voxels (the message gives the box's size and the limit), or when it would grow the region
  // table past kMaxRegionSlots. An empty box inside the range changes nothing.
  EditResult setVoxel(glm::ivec3 v, std::uint8_t material);
  EditResult clearVoxel(glm::ivec3 v);
  EditResult fillBox(const VoxelBox& box, std::uint8_t material);
  EditResult clearBox(const VoxelBox& box);

  // Edits leave freed blocks (bricks, sectors, occupancy lines, payload blocks) on free lists for reuse.
  // compact() rebuilds the arrays densely; every index may change (result.rebuilt and layoutChanged are set).
  EditResult compact();

  // Throws std::logic_error describing the first inconsistency between levels (masks vs children,
  // cell masks vs occupancy lines, counts, bounds). Used by tests after edits.
  void checkConsistency() const;

  // The flat arrays, with indices relative to this object (see brickmap_layout.h).
  glm::ivec3 regionOrigin() const { return regionOrigin_; }
  glm::ivec3 regionDims() const { return regionDims_; }
  std::span<const std::uint32_t> regionTable() const { return regionTable_; }
  std::span<const gpu::Region> regions() const { return regions_; }
  std::span<const gpu::Sector> sectors() const { return sectors_; }
  std::span<const gpu::Brick> bricks() const { return bricks_; }
  std::span<const std::uint32_t> occupancyWords() const { return occupancy_; }
  std::span<const std::uint32_t> payloadWords() const { return payload_; }

 private:
  struct BrickContent;
  struct EditContext;
  using VoxelOp = std::function<void(BrickContent&, glm::ivec3 brickOrigin)>;
  // Applies `op` to every brick overlapping `box` (brick space) and commits the changes level by level.
  EditResult editBricks(const VoxelBox& box, bool adds, const VoxelOp& op);
  void growRegionTable(glm::ivec3 regionMin, glm::ivec3 regionMax, EditContext& ctx);
  std::int64_t slotOf(glm::ivec3 regionCoord) const;  // -1 when outside the table
  const gpu::Brick* findBrick(glm::ivec3 v) const;
  void decodeBrick(const gpu::Brick& brick, BrickContent& out) const;
  void recomputeBounds() const;

  glm::ivec3 regionOrigin_{0};
  glm::ivec3 regionDims_{0};
  std::vector<std::uint32_t> regionTable_;
  std::vector<gpu::Region> regions_;
  std::vector<gpu::Sector> sectors_;
  std::vector<gpu::Brick> bricks_;
  std::vector<std::uint32_t> occupancy_;
  std::vector<std::uint32_t> payload_;
  mutable VoxelBox bounds_;
  mutable bool boundsStale_ = false;
  std::uint64_t solidCount_ = 0;
  // Free blocks left by edits: brick and sector blocks by length (1..64), occupancy lines, payload blocks,
  // region records.
  std::array<std::vector<std::uint32_t>, 65> freeBrickBlocks_;
  std::array<std::vector<std::uint32_t>, 65> freeSectorBlocks_;
  std::vector<std::uint32_t> freeOccupancyLines_;
  std::vector<std::uint32_t> freePayloadBlocks_;
  std::vector<std::uint32_t> freeRegions_;
};

}  // namespace vs

#endif
