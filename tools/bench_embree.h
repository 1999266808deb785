// bench_embree.h: `voxshadow bench --embree`: each backend against the Embree peer (tools/peer/embree_peer.h)
// on the same rays, paired run by run, on city512 and on the demo scene (DESIGN.md §10).
#ifndef VOXSHADOW_BENCH_EMBREE_H
#define VOXSHADOW_BENCH_EMBREE_H

#include "compute/shared/trace_view.h"

namespace vs::cli {

// The calibration window of DESIGN.md §10: an orthographic view along (-0.4, -1, -0.3) over [0, 512]^3, res^2.
gpu::TraceView city512CalibrationView(int res);

struct EmbreeBenchOptions {
  int threads = 2;
  int resolution = 1024;  // city512's shadow view, texels per side
  int reps = 5;
  bool vulkan = false;
};

// Prints, per scene, ray kind, backend and Embree query, the Mrays/s of each and one line
// `vs-embree <scene> <kind> <backend> / <query>: <ratio>x (median of <n> pairs)` (Embree's seconds over the
// backend's, each pair run back to back). Throws vs::Error as the backends and the peer do.
void runEmbreeBench(const EmbreeBenchOptions& options);

}  // namespace vs::cli

#endif
