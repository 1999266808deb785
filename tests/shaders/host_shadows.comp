// host_shadows.comp: a host engine's own compute shader over its own G-buffer, getting each pixel's shadow
// term from a voxshadow frame's buffers through the installed include (tests/embedding_test.cpp).
#version 450
#extension GL_GOOGLE_include_directive : require
// The host's own bindings come first; voxshadow's five follow in set 0.
#define VS_SHADOWS_SET 0
#define VS_SHADOWS_FIRST_BINDING 3
#include "lighting/shared/shadows.glsl"

layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 0) readonly buffer HostGBuffer { GBufferTexel hostGBuffer[]; };
layout(std430, set = 0, binding = 1) readonly buffer HostVisibility { uint hostVisibility[]; };
layout(std430, set = 0, binding = 2) writeonly buffer HostTerms { float hostTerms[]; };
layout(push_constant) uniform HostPush { uint pixels; uint lights; } host;

void main() {
  uint pixel = gl_GlobalInvocationID.x;
  if (pixel >= host.pixels) return;
  GBufferTexel g = hostGBuffer[pixel];
  for (uint l = 0u; l < host.lights; ++l) {
    uint i = pixel * host.lights + l;
    // A pixel that shows no surface is lit (as the library's pass records it).
    hostTerms[i] = g.info.w == 0u ? 1.0f : vsShadowTerm(shadeLights[l], g, hostVisibility[i], false);
  }
}
