// visibility_spread.comp: a visibility trace's answers into the lighting pass's answers per pixel and light, on
// the device that traced them: one invocation per receiver, which writes its pixel's row (1 where the ray
// toward the light was clear, and 1 for each light the frame traces no ray toward), as the host spreads them
// (lighting/renderer.cpp): the rows never cross from the host to the lighting pass.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/portable.h"
#include "lighting/shared/shading_layout.h"
#include "lighting/shared/lighting_interface.h"

layout(local_size_x = VS_SPREAD_GROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = VS_SPREAD_BINDING_ANSWERS) readonly buffer AnswerBlock { uint answers[]; };
layout(std430, set = 0, binding = VS_SPREAD_BINDING_SOURCE) readonly buffer SourceBlock { uint sourceWords[]; };
layout(std430, set = 0, binding = VS_SPREAD_BINDING_SLOTS) readonly buffer SlotBlock { int slots[]; };
layout(std430, set = 0, binding = VS_SPREAD_BINDING_VISIBILITY) writeonly buffer VisibilityBlock { uint visibility[]; };

layout(push_constant) uniform PushBlock { SpreadPush push; };

void main() {
  uint k = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * VS_SPREAD_GROUP_SIZE + gl_LocalInvocationID.x;
  if (k >= push.counts.x) return;
  uint pixel = push.counts.w != 0u ? sourceWords[push.counts.w + k] : k;
  uint lights = push.counts.z;
  for (uint l = 0u; l < lights; ++l) {
    int j = slots[l];
    visibility[pixel * lights + l] = j < 0 ? 1u : (answers[k * push.counts.y + uint(j)] == 0u ? 1u : 0u);
  }
}
