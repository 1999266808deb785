// brickmap_layout.h: the GPU-visible records of an object's brickmap (DESIGN.md §4), readable as C++ and GLSL.
//
// Coordinates: "brick space" is the grid's index space shifted by +0.5, so that voxel v covers [v, v+1).
// Levels: region 128^3 (4^3 sectors) -> sector 32^3 (4^3 bricks) -> brick 8^3 (4^3 cells of 2^3) -> voxel.
// Every 64-bit mask is a uvec2 (x = bits 0..31, y = bits 32..63) because GLSL 4.50 has no portable uint64.
// Child order inside a 4^3 block: bit = x + 4*y + 16*z. Children are packed in mask order; a child's index
// is its parent's `first` plus the popcount of the parent's mask bits below it.
// Voxel bits inside a brick: the 8 voxels of one 2^3 cell are contiguous, bit = cell*8 + (x&1) + 2*(y&1) + 4*(z&1),
// so a cell's occupancy is one byte of the 512-bit line and its cell-mask bit is that byte != 0.
#ifndef VOXSHADOW_BRICKMAP_LAYOUT_H
#define VOXSHADOW_BRICKMAP_LAYOUT_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

const int VS_REGION_LOG2 = 7;  // 128 voxels
const int VS_SECTOR_LOG2 = 5;  // 32 voxels
const int VS_BRICK_LOG2 = 3;   // 8 voxels
const int VS_CELL_LOG2 = 1;    // 2 voxels
const uint VS_OCCUPANCY_WORDS = 16u;  // 512 bits per brick line
// Marks a region-table slot with no region.
const uint VS_EMPTY_SLOT = 0xffffffffu;
// Brick.occupancy value of a brick whose 512 voxels are all solid: it owns no occupancy line.
const uint VS_FULL_BRICK = 0xffffffffu;
// Brick.payload with this bit set: every voxel of the brick has material (payload & 0xff); no payload bytes.
const uint VS_UNIFORM_PAYLOAD = 0x80000000u;
// An ObjectRecord read as 16-byte texels (a shader may fetch records from an RGBA32 texel buffer; each member
// is one texel, in declaration order).
const uint VS_OBJECT_TEXELS = 6u;

struct Region {
  uvec2 sectorMask;  // which of the 4^3 sectors hold any solid voxel
  uint firstSector;  // index into the object's sector array
  uint reserved;
};

struct Sector {
  uvec2 brickMask;  // which of the 4^3 bricks hold any solid voxel
  uint firstBrick;  // index into the object's brick array
  uint reserved;
};

struct Brick {
  uvec2 cellMask;  // which of the 4^3 cells of 2^3 voxels hold any solid voxel
  uint occupancy;  // line index into the object's occupancy words (x16), or VS_FULL_BRICK
  uint payload;    // word offset of 512 palette bytes (128 words), or VS_UNIFORM_PAYLOAD | material
};

// One object's brickmap as placed in the scene-wide arrays. Indices stored inside the object's records
// are relative to the object; these bases make them global.
struct ObjectRecord {
  ivec4 regionOrigin;  // xyz: region coordinate of region-table slot 0
  ivec4 regionDims;    // xyz: region-table size in regions per axis
  ivec4 voxelMin;      // xyz: first solid voxel (inclusive)
  ivec4 voxelMax;      // xyz: last solid voxel + 1 (exclusive); empty object when any max <= min
  uvec4 bases;         // x: region-table slot, y: region, z: sector, w: brick base
  uvec4 bases2;        // x: occupancy-word base, y: payload-word base, zw: reserved
};

VS_NAMESPACE_END

#ifndef VS_GLSL
namespace vs::gpu {
VS_LAYOUT_CHECK(Region, 16);
VS_OFFSET_CHECK(Region, firstSector, 8);
VS_LAYOUT_CHECK(Sector, 16);
VS_OFFSET_CHECK(Sector, firstBrick, 8);
VS_LAYOUT_CHECK(Brick, 16);
VS_OFFSET_CHECK(Brick, occupancy, 8);
VS_OFFSET_CHECK(Brick, payload, 12);
VS_LAYOUT_CHECK(ObjectRecord, 16 * VS_OBJECT_TEXELS);
VS_OFFSET_CHECK(ObjectRecord, regionDims, 16);
VS_OFFSET_CHECK(ObjectRecord, voxelMin, 32);
VS_OFFSET_CHECK(ObjectRecord, voxelMax, 48);
VS_OFFSET_CHECK(ObjectRecord, bases, 64);
VS_OFFSET_CHECK(ObjectRecord, bases2, 80);
}  // namespace vs::gpu
#endif

#endif
