// lane_tracer.h: the CPU fast path. The box-table walk of compute/shared/lane_walk.h (vsBoxWalkStep, the walk
// the shader runs) compiled for SIMD lanes: 16 rays at once with AVX-512, 8 with AVX2, or one lane of plain
// scalar code, chosen at run time. Every lane performs the IEEE operations of the scalar walk in the same
// order, so each result equals the reference's bit for bit.
//
// Four groups of lanes are stepped in turn, so that their gathers overlap. A lane whose ray finishes takes the
// next ray at once. Rays come from a source (compute/cpu/ray_sources.h: shadow texels, closest-hit or any-hit
// rays) and are set up by the portable scalar code (candidates from the BVH, the re-based instance ray,
// vsObjectWalkBegin); a scene whose BVH is one leaf holding one instance skips the candidate lists.
#ifndef VOXSHADOW_LANE_TRACER_H
#define VOXSHADOW_LANE_TRACER_H

#include <cstdint>
#include <span>
#include <vector>

#include "compute/cpu/cpu_tracer.h"
#include "compute/cpu/ray_sources.h"
#include "compute/cpu/scene_arrays.h"

namespace vs {

// Lanes per step of an instruction set's walk.
enum class LaneWidth { Scalar = 1, Avx2 = 8, Avx512 = 16 };

// Whether this processor runs `width` (AVX2 or AVX-512F where asked; the scalar lane everywhere).
bool laneWidthSupported(LaneWidth width);
// The widest lanes this processor runs.
LaneWidth widestLaneWidth();
// "scalar", "AVX2 (8 lanes)" or "AVX-512 (16 lanes)".
const char* laneWidthName(LaneWidth width);

// Traces every tile into layers[tile.view].texels (row stride layers[..].width).
// Preconditions: laneWidthSupported(width); arrays.boxTable is the box table (compute/box_table.h) of the
// scene behind `arrays`; tiles lie inside their views and layers[tile.view] has the view's size.
void traceTilesLanes(LaneWidth width, gpu::SceneArrays& arrays, std::span<const gpu::TraceView> views,
                     std::span<const TexelTile> tiles, std::vector<ShadowLayer>& layers);

// Closest hits of rays[i] into hits[i], and any-hit answers into occluded[i] (1: the segment holds a solid
// voxel). Preconditions as for traceTilesLanes; the outputs are as long as `rays`.
void traceClosestLanes(LaneWidth width, gpu::SceneArrays& arrays, std::span<const gpu::TraceRay> rays,
                       std::span<gpu::RayHit> hits);
void traceAnyLanes(LaneWidth width, gpu::SceneArrays& arrays, std::span<const gpu::TraceRay> rays,
                   std::span<std::uint32_t> occluded);

}  // namespace vs

#endif
