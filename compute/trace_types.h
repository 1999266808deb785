// trace_types.h: what every trace backend takes and gives, whichever runs the rays: the layers shadow texels
// are written to, the statistics of a trace, the CPU paths. compute/tracer.h, the one interface, needs no
// backend's header.
#ifndef VOXSHADOW_TRACE_TYPES_H
#define VOXSHADOW_TRACE_TYPES_H

#include <cstdint>
#include <vector>

namespace vs {

// One shadow layer: width x height R32F texels, row 0 first.
struct ShadowLayer {
  int width = 0;
  int height = 0;
  std::vector<float> texels;
};

struct TraceStats {
  std::uint64_t rays = 0;      // texels traced (sum of the views' rectangle areas)
  double gpuMs = -1.0;         // dispatch time from GPU timestamps; < 0 when the queue has none
  std::vector<double> viewGpuMs;  // per view (views order), from timestamps; empty when the queue has none
  double wallMs = 0.0;         // host time of the whole call: descriptor updates, dispatch, readback
  double mraysPerSecond = 0.0; // from gpuMs when known, else from wallMs
  int dispatches = 0;          // compute dispatches recorded (0 on the CPU backend)
};

enum class CpuTracePath {
  // The portable per-ray traversal, exactly what the shader runs: the walk over the scene's box table
  // (compute/box_table.h) where the scene has one, else the brickmap hierarchy.
  Reference,
  // The fast path (compute/cpu/lane_tracer.h): the box-table walk of the widest SIMD lanes this processor
  // runs (AVX-512, AVX2, else one scalar lane), equal to Reference ray for ray; the portable tiles where the
  // scene has no box table.
  Interleaved,
  // Round-robin tiles over the brickmap hierarchy walk (compute/cpu/tile_tracer.h), whatever the processor:
  // the walk that does not read the box table, kept as a check on it.
  PortableTiles,
  // The fast path with the lanes named (vs::Error(BadInput) where the processor or the scene cannot run it).
  LanesScalar,
  LanesAvx2,
  LanesAvx512,
};

}  // namespace vs

#endif
