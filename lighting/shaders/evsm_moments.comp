// evsm_moments.comp: the EVSM moment pass (lighting/shared/evsm_pass.h), one invocation per texel of its jobs:
// push.pass.x 0 sums rows into the scratch, 1 sums the scratch's columns into the moment store. The C++ build
// of the same source is lighting/evsm.cpp.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/portable.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "lighting/shared/shading_layout.h"
#include "lighting/shared/lighting_interface.h"
#include "lighting/shared/evsm.h"

layout(local_size_x = VS_EVSM_GROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = VS_LIGHTING_BINDING_SHADOW_TEXELS) readonly buffer TexelBlock { float shadowTexels[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_MOMENTS) writeonly buffer MomentBlock { vec2 momentPositive[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_MOMENTS_NEGATIVE) writeonly buffer MomentNegativeBlock { vec2 momentNegative[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_EVSM_VIEWS) readonly buffer EvsmViewBlock { EvsmView evsmViews[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_EVSM_JOBS) readonly buffer EvsmJobBlock { EvsmJob evsmJobs[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_EVSM_BORDER) readonly buffer EvsmBorderBlock { int evsmBorder[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_EVSM_SCRATCH) buffer EvsmScratchBlock { vec2 scratchPositive[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_EVSM_SCRATCH_NEGATIVE) buffer EvsmScratchNegativeBlock { vec2 scratchNegative[]; };

layout(push_constant) uniform PushBlock { EvsmPush push; };

vec4 vsLoadScratch(int i) { return vec4(scratchPositive[i], scratchNegative[i]); }
void vsStoreScratch(int i, vec4 m) {
  scratchPositive[i] = m.xy;
  scratchNegative[i] = m.zw;
}
void vsStoreMoments(int i, vec4 m) {
  momentPositive[i] = m.xy;
  momentNegative[i] = m.zw;
}

#include "lighting/shared/evsm_pass.h"

void main() {
  int invocation = int(gl_GlobalInvocationID.y) * push.pass.w + int(gl_GlobalInvocationID.x);
  if (invocation >= push.pass.z) return;
  if (push.pass.x == 0) vsEvsmHorizontal(invocation, push.pass.y);
  else vsEvsmVertical(invocation, push.pass.y);
}
