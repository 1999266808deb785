// host_engine.comp: the example host engine's own deferred pass (tools/examples/host_engine.cpp). It lights each
// pixel of a G-buffer from voxshadow's shadows, read in place through the installed include, summing each light's
// share as the library's own pass does, so that its image is the library's bit for bit.
#version 450
#extension GL_GOOGLE_include_directive : require
// The engine's own bindings first (0..2); voxshadow's five follow in set 0.
#define VS_SHADOWS_SET 0
#define VS_SHADOWS_FIRST_BINDING 3
#include "lighting/shared/shadows.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, set = 0, binding = 0) readonly buffer EngineGBuffer { GBufferTexel gbuffer[]; };
layout(std430, set = 0, binding = 1) readonly buffer EngineVisibility { uint contactClear[]; };
layout(std430, set = 0, binding = 2) writeonly buffer EngineImage { vec4 image[]; };
layout(push_constant) uniform EnginePush {
  vec4 ambient;  // rgb: the ambient light
  vec4 sky;      // rgb: what a pixel without a surface shows
  uvec4 size;    // x, y: the image's size; z: the light count
} engine;

void main() {
  uvec2 p = gl_GlobalInvocationID.xy;
  if (p.x >= engine.size.x || p.y >= engine.size.y) return;
  uint pixel = p.y * engine.size.x + p.x;
  GBufferTexel g = gbuffer[pixel];
  if (g.info.w == 0u) {
    image[pixel] = vec4(vec3(engine.sky), 0.0f);
    return;
  }
  vec3 radiance = vec3(engine.ambient);
  for (uint l = 0u; l < engine.size.z; ++l) {
    float s = vsShadowTerm(shadeLights[l], g, contactClear[pixel * engine.size.z + l], false);
    radiance += vsLightRadiance(shadeLights[l], g, s);
  }
  image[pixel] = vec4(vec3(g.albedo) * radiance, 1.0f);
}
