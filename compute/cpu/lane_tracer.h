// lane_tracer.h: the CPU fast path. The portable object walk (compute/shared/traverse.h) of eight rays at
// once, one ray per AVX2 lane: every lane performs the very IEEE operations of vsObjectWalkStep in the same
// order (no fused multiply-add, glm's min/max operand order, floor by rounding toward -inf, the highest axis on
// exit ties), so each texel equals the reference per-ray traversal's bit for bit. What differs is how far a
// step goes: dense per-object tables (built once per scene from the brickmap) answer "brick full / partial /
// empty" with one gather, and give an empty brick the largest empty box grown around it, often many bricks
// long; the canonical voxel order of traverse.h makes the voxel where a lane stops, and its t, the same as
// the reference's however far each step went.
//
// Four groups of eight lanes are stepped in three parts each, so that the groups' gathers overlap. A lane
// whose ray finishes takes the next ray at once. Rays come from a source (compute/cpu/ray_sources.h: shadow
// texels, closest-hit or any-hit rays) and are set up by the portable scalar code (candidates from the BVH, the
// re-based instance ray, vsObjectWalkBegin); a scene whose BVH is one leaf holding one instance skips the
// candidate lists.
#ifndef VOXSHADOW_LANE_TRACER_H
#define VOXSHADOW_LANE_TRACER_H

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "compute/cpu/ray_sources.h"
#include "compute/cpu/scene_arrays.h"

namespace vs {

// Whether this processor runs the lane tracer (AVX2) and the scene's arrays fit its 32-bit gather indices.
bool laneTracerSupported(const SceneData& scene);

// Sector codes of every object: VS_REGION_LOG2 / VS_SECTOR_LOG2 negated where the region / sector is empty,
// else the sector's global index; objectBase[i] is object i's first code, laid out like its region table with
// 4^3 sectors per region slot (x fastest).
// When every object's bricks fit kMaxLaneBrickCodes, brickCodes holds one box-table code per brick coordinate
// (VS_BOX_* in compute/shared/trace_view.h; 16^3 per region slot): full, the first occupancy word, or the empty
// box around the brick (see encodeEmptyBoxes in lane_tracer.cpp). A step then reads one code and one occupancy
// word. The cell level comes from the occupancy word too (a cell's mask bit is its occupancy byte != 0,
// brickmap_layout.h); the table is built only when every brick of the scene satisfies that, so the answers are
// the cell mask's.
struct LaneTables {
  std::vector<std::int32_t> sectorCodes;
  std::vector<std::int32_t> objectBase;
  std::vector<std::int32_t> brickCodes;
  std::vector<std::int32_t> objectBrickBase;
};

// Fills `tables` for the scene; false (tables left empty) when they would exceed kMaxLaneSectorCodes. The brick
// level is built when it fits maxBrickCodes (0 keeps every step on the sector level and the lane brick cache).
constexpr std::size_t kMaxLaneSectorCodes = std::size_t(1) << 24;
constexpr std::size_t kMaxLaneBrickCodes = std::size_t(1) << 22;
constexpr std::int32_t kLaneFullBrick = gpu::VS_BOX_FULL;
// Largest extent (in bricks, per side) of the empty box recorded around an empty brick: a step crosses up to
// 2 * 15 + 1 bricks (248 voxels) at once; the code's extent fields hold no more.
constexpr int kLaneMaxBoxExtent = gpu::VS_BOX_EXTENT_MASK;
bool buildLaneTables(const SceneData& scene, LaneTables& tables, std::size_t maxBrickCodes = kMaxLaneBrickCodes);

// Traces every tile into layers[tile.view].texels (row stride layers[..].width).
// Preconditions: laneTracerSupported(scene) and buildLaneTables(scene, tables) succeeded for the scene behind
// `arrays`; tiles lie inside their views and layers[tile.view] has the view's size.
void traceTilesLanes(gpu::SceneArrays& arrays, const LaneTables& tables, std::span<const gpu::TraceView> views,
                     std::span<const TexelTile> tiles, std::vector<ShadowLayer>& layers);

// Closest hits of rays[i] into hits[i], and any-hit answers into occluded[i] (1: the segment holds a solid
// voxel). Preconditions as for traceTilesLanes; the outputs are as long as `rays`.
void traceClosestLanes(gpu::SceneArrays& arrays, const LaneTables& tables, std::span<const gpu::TraceRay> rays,
                       std::span<gpu::RayHit> hits);
void traceAnyLanes(gpu::SceneArrays& arrays, const LaneTables& tables, std::span<const gpu::TraceRay> rays,
                   std::span<std::uint32_t> occluded);

}  // namespace vs

#endif
