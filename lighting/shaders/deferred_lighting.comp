// deferred_lighting.comp: the deferred lighting pass (DESIGN.md §7), one invocation per pixel, running the
// arithmetic of lighting/shared/shading.h, which the CPU pass (lighting/deferred.cpp) compiles as C++.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/portable.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "lighting/shared/shading_layout.h"
#include "lighting/shared/lighting_interface.h"
#include "lighting/shared/evsm.h"

layout(local_size_x = VS_LIGHTING_GROUP_WIDTH, local_size_y = VS_LIGHTING_GROUP_HEIGHT, local_size_z = 1) in;

layout(std430, set = 0, binding = VS_LIGHTING_BINDING_GBUFFER) readonly buffer GBufferBlock { GBufferTexel gbuffer[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_LIGHTS) readonly buffer LightBlock { ShadeLight shadeLights[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_VIEWS) readonly buffer ViewBlock { ShadeView shadeViews[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_SHADOW_TEXELS) readonly buffer TexelBlock { float shadowTexels[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_VISIBILITY) readonly buffer VisibilityBlock { uint rayVisibility[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_SHADOW_TERMS) writeonly buffer TermBlock { float shadowTerms[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_COLOR) writeonly buffer ColorBlock { vec4 color[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_PIXELS) readonly buffer PixelBlock { uint listedPixels[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_MOMENTS) readonly buffer MomentBlock { vec2 momentPositive[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_MOMENTS_NEGATIVE) readonly buffer MomentNegativeBlock { vec2 momentNegative[]; };

layout(push_constant) uniform PushBlock { ShadePush push; };

vec4 vsLoadMoments(int i) { return vec4(momentPositive[i], momentNegative[i]); }

#include "lighting/shared/shading.h"

void main() {
  int pixel;
  if (push.flags.y > 0) {
    // A list: workgroups in a row along x, one listed pixel per invocation.
    uint listed = gl_WorkGroupID.x * (VS_LIGHTING_GROUP_WIDTH * VS_LIGHTING_GROUP_HEIGHT) + gl_LocalInvocationIndex;
    if (listed >= uint(push.flags.y)) return;
    pixel = int(listedPixels[listed]);
  } else {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= push.size.x || p.y >= push.size.y) return;
    pixel = p.y * push.size.x + p.x;
  }
  color[pixel] = vsShadePixel(push, pixel, gbuffer[pixel]);
}
