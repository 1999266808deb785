// shadows.glsl: the shadows of a voxshadow frame in a host engine's shader (README "Embedding in an engine").
// The very source of the library's own lighting pass (lighting/shared/shadow_lookup.h), so that the host's
// shadow terms equal the library's bit for bit on the same device.
//
//   #define VS_SHADOWS_SET 1            // optional: the descriptor set (default 0)
//   #define VS_SHADOWS_FIRST_BINDING 4  // optional: the first of its five bindings (default 0)
//   #define VS_ROLLED_TAP_LOOPS 1       // optional, with GL_EXT_control_flow_attributes enabled: the filters'
//                                       // tap loops kept rolled (the library's pass does: faster on llvmpipe)
//   #include "lighting/shared/shadows.glsl"   // with -I <prefix>/include/voxshadow
//   ...
//   float s = vsShadowTerm(shadeLights[l], g, visibility, false);  // 1 lit, 0 shadowed
//   vec3 added = vsLightRadiance(shadeLights[l], g, s);            // the light's share, as the library adds it
//
// Bindings, in order from VS_SHADOWS_FIRST_BINDING, each the buffer vs::FrameRenderer::vulkanShadows() names:
//   +0 storage buffer: the shadow layers' texels (VulkanShadows::texels)
//   +1 uniform texel buffer (RGBA32UI): the views' records (VulkanShadows::viewTexels)
//   +2 storage buffer: the lights' records (VulkanShadows::lights)
//   +3, +4 storage buffers: the EVSM moment store's halves (VulkanShadows::momentsPositive, momentsNegative)
// The receiver is a GBufferTexel (lighting/shared/shading_layout.h): world position in xyz and the distance
// along the camera's forward axis in w (the cascade choice), the unit face normal, info.w 1 where a surface
// was hit. `visibility` is 1 where the light's contact ray is clear (VulkanShadows::visibility holds the
// library's answers per pixel and light; 1 where the light has no contact shadow).
#ifndef VOXSHADOW_SHADOWS_GLSL
#define VOXSHADOW_SHADOWS_GLSL

#ifndef VS_GLSL
#define VS_GLSL 1
#endif
#include "voxel/portable.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "lighting/shared/shading_layout.h"
#include "lighting/shared/lighting_interface.h"
#include "lighting/shared/evsm.h"

#ifndef VS_SHADOWS_SET
#define VS_SHADOWS_SET 0
#endif
#ifndef VS_SHADOWS_FIRST_BINDING
#define VS_SHADOWS_FIRST_BINDING 0
#endif

layout(std430, set = VS_SHADOWS_SET, binding = VS_SHADOWS_FIRST_BINDING + 0) readonly buffer VsShadowTexelBlock {
  float shadowTexels[];
};
layout(set = VS_SHADOWS_SET, binding = VS_SHADOWS_FIRST_BINDING + 1) uniform usamplerBuffer shadeViewTexels;
layout(std430, set = VS_SHADOWS_SET, binding = VS_SHADOWS_FIRST_BINDING + 2) readonly buffer VsShadowLightBlock {
  ShadeLight shadeLights[];
};
layout(std430, set = VS_SHADOWS_SET, binding = VS_SHADOWS_FIRST_BINDING + 3) readonly buffer VsMomentPositiveBlock {
  vec2 momentPositive[];
};
layout(std430, set = VS_SHADOWS_SET, binding = VS_SHADOWS_FIRST_BINDING + 4) readonly buffer VsMomentNegativeBlock {
  vec2 momentNegative[];
};

#include "lighting/shared/shade_records.h"
#include "lighting/shared/shadow_lookup.h"

#endif
