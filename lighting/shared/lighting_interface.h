// lighting_interface.h: the lighting shader's interface (lighting/shaders/deferred_lighting.comp), readable as
// C++ and GLSL: the workgroup size and the binding numbers, defined once for the shader and the host
// (lighting/vulkan_lighting.cpp).
#ifndef VOXSHADOW_LIGHTING_INTERFACE_H
#define VOXSHADOW_LIGHTING_INTERFACE_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// 8 x 8 pixels per workgroup, as the trace shader: neighbouring pixels read neighbouring shadow texels.
const uint VS_LIGHTING_GROUP_WIDTH = 8u;
const uint VS_LIGHTING_GROUP_HEIGHT = 8u;

// Storage buffers of descriptor set 0.
const uint VS_LIGHTING_BINDING_GBUFFER = 0u;        // GBufferTexel per pixel
const uint VS_LIGHTING_BINDING_LIGHTS = 1u;         // ShadeLight per light
const uint VS_LIGHTING_BINDING_VIEWS = 2u;          // ShadeView per shadow layer
const uint VS_LIGHTING_BINDING_SHADOW_TEXELS = 3u;  // float: every layer, one after another
const uint VS_LIGHTING_BINDING_VISIBILITY = 4u;     // uint per pixel and light
const uint VS_LIGHTING_BINDING_SHADOW_TERMS = 5u;   // float per pixel and light (written)
const uint VS_LIGHTING_BINDING_COLOR = 6u;          // vec4 per pixel (written)
// uint per listed pixel (row-major index): a frame that shades again only the pixels its changes touched runs
// one invocation per listed pixel (ShadePush.flags.y of them) instead of one per pixel of the frame.
const uint VS_LIGHTING_BINDING_PIXELS = 7u;
const uint VS_LIGHTING_BINDING_COUNT = 8u;

VS_NAMESPACE_END

#endif
