// shade_records.h (GLSL): the shadow records as a shader reads them, for the library's lighting shader and a
// host's (lighting/shared/shadows.glsl). The includer declares, by these names:
//   usamplerBuffer shadeViewTexels: the ShadeView records, VS_SHADE_VIEW_TEXELS RGBA32UI texels each (a
//     uniform texel buffer: llvmpipe reads a storage buffer one lane at a time);
//   vec2 momentPositive[], momentNegative[]: the EVSM moment store's two halves (lighting_interface.h).
// and gives shadow_lookup.h what it reads: vsLoadMoments, vsLoadView, vsViewHoldsDepth.
#ifndef VOXSHADOW_SHADE_RECORDS_H
#define VOXSHADOW_SHADE_RECORDS_H

vec4 vsLoadMoments(int i) { return vec4(momentPositive[i], momentNegative[i]); }

// ShadeView record i from its VS_SHADE_VIEW_TEXELS texels, each member at the texel VS_SHADE_VIEW_TEXEL_* names.
vec4 vsViewTexel(int i, int t) { return uintBitsToFloat(texelFetch(shadeViewTexels, i * VS_SHADE_VIEW_TEXELS + t)); }
ShadeView vsLoadView(int i) {
  ShadeView v;
  const int m = VS_SHADE_VIEW_TEXEL_EYE_TO_CLIP, n = VS_SHADE_VIEW_TEXEL_CLIP_TO_EYE;
  v.eyeToClip = mat4(vsViewTexel(i, m), vsViewTexel(i, m + 1), vsViewTexel(i, m + 2), vsViewTexel(i, m + 3));
  v.clipToEye = mat4(vsViewTexel(i, n), vsViewTexel(i, n + 1), vsViewTexel(i, n + 2), vsViewTexel(i, n + 3));
  v.eye = vsViewTexel(i, VS_SHADE_VIEW_TEXEL_EYE);
  v.eyeLow = vsViewTexel(i, VS_SHADE_VIEW_TEXEL_EYE_LOW);
  v.split = vsViewTexel(i, VS_SHADE_VIEW_TEXEL_SPLIT);
  v.info = ivec4(texelFetch(shadeViewTexels, i * VS_SHADE_VIEW_TEXELS + VS_SHADE_VIEW_TEXEL_INFO));
  v.trace = ivec4(texelFetch(shadeViewTexels, i * VS_SHADE_VIEW_TEXELS + VS_SHADE_VIEW_TEXEL_TRACE));
  return v;
}
// Whether view i holds a receiver at camera view depth `viewDepth` by its cascade range (ShadeView.split, for
// cascades; other views hold every depth): two texels of the record instead of all of them.
bool vsViewHoldsDepth(int i, float viewDepth) {
  vec4 split = vsViewTexel(i, VS_SHADE_VIEW_TEXEL_SPLIT);
  int cascade = int(texelFetch(shadeViewTexels, i * VS_SHADE_VIEW_TEXELS + VS_SHADE_VIEW_TEXEL_INFO).w);
  return cascade < 0 || (viewDepth >= split.x && viewDepth < split.y);
}

#endif
