// evsm.h: the host side of exponential variance shadow maps (DESIGN.md §7): which rectangles of which layers a
// moment pass recomputes, the records it reads, and the pass on the CPU (lighting/shared/evsm_pass.h as C++;
// the Vulkan build runs in lighting/vulkan_lighting.cpp).
#ifndef VOXSHADOW_LIGHTING_EVSM_H
#define VOXSHADOW_LIGHTING_EVSM_H

#include <cstdint>
#include <span>
#include <vector>

#include "lighting/deferred.h"
#include "lighting/light_views.h"
#include "lighting/shared/shading_layout.h"

namespace vs {

// Window texels [x0, x1) x [y0, y1) of view `view` (an index into the frame's views) whose moments a pass
// recomputes. A moment depends on the depths within the blur radius r around it, so a traced rectangle changes
// the moments of that rectangle grown by r (and a scrolled ring the r texels inside each edge that moved).
struct MomentRect {
  int view = 0;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// What a moment pass reads besides the layer store.
struct MomentWork {
  std::vector<gpu::EvsmView> views;   // one per ShadeView; layer.z = -1 for views without moments
  std::vector<std::int32_t> border;   // the cube faces' texels past their edges (evsm_pass.h's vsEvsmSource)
  std::vector<gpu::EvsmJob> jobs;     // one per rectangle, in the order given
  std::size_t scratchTexels = 0;      // the horizontal pass's sums
  std::size_t horizontal = 0;         // invocations of the horizontal pass
  std::size_t vertical = 0;           // of the vertical pass (the texels whose moments are written)
  bool empty() const { return jobs.empty(); }
};

// Whether view i has moments (its light's filter is EVSM).
inline bool hasMoments(const ShadeInputs& inputs, std::size_t view) { return inputs.views[view].trace.w >= 0; }

// Every EVSM view's whole window: what a store with no valid moments needs.
std::vector<MomentRect> wholeMomentRects(const ShadeInputs& inputs);

// The work for `rects`: the views' records (from inputs' ShadeViews and lights), border maps for the cube faces
// that any rect names, and one job per non-empty rect. Preconditions: inputs from makeShadeRecords for `views`;
// each rect names a view with moments and lies inside its window (else vs::Error(BadInput)); rects of one view
// do not overlap (a texel in two would be written twice, with the same value). Throws vs::Error(Runtime) when
// a pass would have more than 2^31 - 1 invocations.
MomentWork momentWork(std::span<const LightView> views, const ShadeInputs& inputs, std::span<const MomentRect> rects);

// The pass on the CPU (TBB): the jobs' moments from inputs.shadowTexels into `moments`, which is resized to
// inputs.momentTexels first where it differs (its other texels are kept).
void computeMomentsOnCpu(const ShadeInputs& inputs, const MomentWork& work, std::vector<glm::vec4>& moments);

// A moment layer as stored (ring order for cascades) in window order, row 0 first (as windowTexels).
std::vector<glm::vec4> windowMoments(const LightView& view, std::span<const glm::vec4> stored);

}  // namespace vs

#endif
