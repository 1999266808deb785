// tile_tracer.h: the portable CPU tile path (the fast path where AVX2 is missing; compute/cpu/lane_tracer.h
// is the other). The rays of a small batch walk the scene interleaved: each round advances every unfinished
// ray by one cell of the portable object walk (compute/shared/traverse.h).
//
// A single ray's walk is a long chain of dependent loads (region table, region, sector, brick, occupancy);
// interleaving independent rays lets the processor overlap those chains. Every arithmetic step is the
// portable one, so each result equals the reference per-ray traversal's exactly.
#ifndef VOXSHADOW_TILE_TRACER_H
#define VOXSHADOW_TILE_TRACER_H

#include "compute/cpu/ray_sources.h"

namespace vs {

// The most rays walked together: enough independent rays to hide load latency, few enough that their walk
// states stay in the L1 cache.
constexpr int kMaxTileRays = 64;

// Traces every ray of `source` (compute/cpu/ray_sources.h), kMaxTileRays at a time. Instantiated for
// rays::TexelSource, rays::ClosestSource and rays::AnySource.
template <class Source>
void traceInterleaved(gpu::SceneArrays& arrays, Source& source);

}  // namespace vs

#endif
