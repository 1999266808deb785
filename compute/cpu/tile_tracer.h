// tile_tracer.h: the portable CPU tile path (the fast path where AVX2 is missing; compute/cpu/lane_tracer.h
// is the other). The rays of a small texel tile walk the scene interleaved: each round advances every
// unfinished ray by one cell of the portable object walk (compute/shared/traverse.h).
//
// A single ray's walk is a long chain of dependent loads (region table, region, sector, brick, occupancy);
// interleaving independent rays lets the processor overlap those chains. Every arithmetic step is the
// portable one, so each texel equals the reference per-ray traversal's exactly.
#ifndef VOXSHADOW_TILE_TRACER_H
#define VOXSHADOW_TILE_TRACER_H

#include "compute/cpu/scene_arrays.h"

namespace vs {

// The most texels one call traces together: enough independent rays to hide load latency, few enough
// that their walk states stay in the L1 cache.
constexpr int kMaxTileRays = 64;

// Traces texels [x0, x1) x [y0, y1) of `view` into texels[y * stride + x].
// Preconditions: (x1 - x0) * (y1 - y0) <= kMaxTileRays; the rectangle lies inside the view.
void traceTileInterleaved(gpu::SceneArrays& arrays, const gpu::TraceView& view, int x0, int y0, int x1, int y1,
                          float* texels, int stride);

}  // namespace vs

#endif
