// deferred_lighting.comp: the deferred lighting pass (DESIGN.md §7), one invocation per pixel, running the
// arithmetic of lighting/shared/shading.h, which the CPU pass (lighting/deferred.cpp) compiles as C++.
#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#define VS_ROLLED_TAP_LOOPS 1
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
layout(set = 0, binding = VS_LIGHTING_BINDING_VIEWS) uniform usamplerBuffer shadeViewTexels;
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_SHADOW_TEXELS) readonly buffer TexelBlock { float shadowTexels[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_VISIBILITY) readonly buffer VisibilityBlock { uint rayVisibility[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_SHADOW_TERMS) writeonly buffer TermBlock { float shadowTerms[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_COLOR) writeonly buffer ColorBlock { vec4 color[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_PIXELS) readonly buffer PixelBlock { uint listedPixels[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_MOMENTS) readonly buffer MomentBlock { vec2 momentPositive[]; };
layout(std430, set = 0, binding = VS_LIGHTING_BINDING_MOMENTS_NEGATIVE) readonly buffer MomentNegativeBlock { vec2 momentNegative[]; };

layout(push_constant) uniform PushBlock { ShadePush push; };

#include "lighting/shared/shade_records.h"

#ifdef VS_LIGHTING_VARIANT
// The build that pipeline variants specialise (lighting/lighting_variant.h): the variant's constants
// (lighting_interface.h, VS_LIGHTING_SPEC_*; -1: read from the records) and shading.h's hooks that read them.
layout(constant_id = VS_LIGHTING_SPEC_LIGHT_COUNT) const int vsSpecLightCount = -1;
layout(constant_id = VS_LIGHTING_SPEC_MODE) const int vsSpecMode = -1;
layout(constant_id = VS_LIGHTING_SPEC_RAYTRACED) const int vsSpecRaytraced = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 0u) const int vsSpecKind0 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 1u) const int vsSpecFilter0 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 2u) const int vsSpecViews0 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 3u) const int vsSpecKind1 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 4u) const int vsSpecFilter1 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 5u) const int vsSpecViews1 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 6u) const int vsSpecKind2 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 7u) const int vsSpecFilter2 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 8u) const int vsSpecViews2 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 9u) const int vsSpecKind3 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 10u) const int vsSpecFilter3 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 11u) const int vsSpecViews3 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 12u) const int vsSpecKind4 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 13u) const int vsSpecFilter4 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 14u) const int vsSpecViews4 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 15u) const int vsSpecKind5 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 16u) const int vsSpecFilter5 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 17u) const int vsSpecViews5 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 18u) const int vsSpecKind6 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 19u) const int vsSpecFilter6 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 20u) const int vsSpecViews6 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 21u) const int vsSpecKind7 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 22u) const int vsSpecFilter7 = -1;
layout(constant_id = VS_LIGHTING_SPEC_FIRST_LIGHT + 23u) const int vsSpecViews7 = -1;

int vsSpecializedLightCount(int n) { return vsSpecLightCount >= 0 ? vsSpecLightCount : n; }
int vsSpecializedMode(int m) { return vsSpecMode >= 0 ? vsSpecMode : m; }
bool vsSpecializedRaytraced(bool r) { return vsSpecRaytraced >= 0 ? vsSpecRaytraced != 0 : r; }

// Light l's record with its kind, filter and view count replaced by the variant's (l a constant after inlining,
// so each is one constant).
ShadeLight vsSpecializedLight(int l, ShadeLight light) {
  if (vsSpecLightCount < 0) return light;
  if (l == 0) { light.info.x = vsSpecKind0; light.info.y = vsSpecFilter0; light.info.w = vsSpecViews0; }
  if (l == 1) { light.info.x = vsSpecKind1; light.info.y = vsSpecFilter1; light.info.w = vsSpecViews1; }
  if (l == 2) { light.info.x = vsSpecKind2; light.info.y = vsSpecFilter2; light.info.w = vsSpecViews2; }
  if (l == 3) { light.info.x = vsSpecKind3; light.info.y = vsSpecFilter3; light.info.w = vsSpecViews3; }
  if (l == 4) { light.info.x = vsSpecKind4; light.info.y = vsSpecFilter4; light.info.w = vsSpecViews4; }
  if (l == 5) { light.info.x = vsSpecKind5; light.info.y = vsSpecFilter5; light.info.w = vsSpecViews5; }
  if (l == 6) { light.info.x = vsSpecKind6; light.info.y = vsSpecFilter6; light.info.w = vsSpecViews6; }
  if (l == 7) { light.info.x = vsSpecKind7; light.info.y = vsSpecFilter7; light.info.w = vsSpecViews7; }
  return light;
}
#endif

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
