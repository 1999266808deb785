// cpu_shading.h: the shading code of lighting/shared/shading.h compiled as C++, the CPU side of "one source, two
// compilers". Its functions are members of a struct whose members carry the names of the shader's buffers, so
// that the same source reads the same records on both sides. Compiles the shared core's arithmetic: a
// translation unit that includes it links voxshadow::exact_fp (voxel/exact_fp.h).
#ifndef VOXSHADOW_CPU_SHADING_H
#define VOXSHADOW_CPU_SHADING_H

#include "compute/shared/trace_view.h"
#include "lighting/shared/evsm.h"
#include "lighting/shared/shading_layout.h"

namespace vs::gpu {

// Preconditions: the pointers reach every record that the shading calls read (shadeLights and shadeViews of
// the push's counts, shadowTexels of their layers, momentTexels of EVSM views, rayVisibility and shadowTerms of
// the pixels shaded).
struct CpuShading {
  const float* shadowTexels = nullptr;
  const ShadeView* shadeViews = nullptr;
  const ShadeLight* shadeLights = nullptr;
  const uint* rayVisibility = nullptr;
  float* shadowTerms = nullptr;
  const vec4* momentTexels = nullptr;
  vec4 vsLoadMoments(int i) const { return momentTexels[i]; }
  ShadeView vsLoadView(int i) const { return shadeViews[i]; }
  bool vsViewHoldsDepth(int i, float viewDepth) const {
    const ShadeView& v = shadeViews[i];
    return v.info.w < 0 || (viewDepth >= v.split.x && viewDepth < v.split.y);
  }
#include "lighting/shared/shading.h"
};

}  // namespace vs::gpu

#endif
