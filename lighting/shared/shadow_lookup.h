// shadow_lookup.h: a receiver's shadow term from the shadow layers (DESIGN.md §7): shadow lookup and filters,
// biases, cascade choice and blending, light falloff. One source compiled as GLSL (the library's lighting
// shader through shading.h, and a host engine's shader through lighting/shared/shadows.glsl) and as C++ (the
// CPU pass, lighting/cpu_shading.h), so that every one of them gives the same term for the same records.
//
// The includer provides, as arrays or buffer members of these names:
//   shadowTexels[i] (float): every shadow layer, row by row, one after another (ShadeView.info.x)
//   vsLoadView(i) (a function, ShadeView): shadow view i's record
//   vsViewHoldsDepth(i, viewDepth) (a function, bool): view i is no cascade (info.w < 0), or its split range
//     [split.x, split.y) holds viewDepth; read without the rest of the record, which the cascade choice then
//     loads for one view only (a shader reads a record as 13 texels)
//   vsLoadMoments(i) (a function, vec4): texel i of the EVSM moment store (lighting/shared/evsm_pass.h),
//     ShadeView.trace.w
// and includes lighting/shared/shading_layout.h and lighting/shared/evsm.h first. C++ includes this inside a
// struct that holds those members (lighting/cpu_shading.h).
#ifndef VOXSHADOW_SHADOW_LOOKUP_H
#define VOXSHADOW_SHADOW_LOOKUP_H

// A filter's loop over its taps, kept rolled where the includer asks (VS_ROLLED_TAP_LOOPS, with
// GL_EXT_control_flow_attributes enabled): a CPU device (llvmpipe) runs the code of every branch for every lane
// of a group whether or not a lane takes it, but leaves a loop once no lane goes on, so a group whose pixels a
// light does not reach (or whose lights face away) pays one tap instead of the kernel. The demo's lavapipe
// lighting pass: 251 -> 219 ms. Unrolled or not, the taps are summed in the same order.
#if defined(VS_GLSL) && defined(VS_ROLLED_TAP_LOOPS)
#define VS_TAP_LOOP [[dont_unroll]]
#else
#define VS_TAP_LOOP
#endif

// A world-space hash of the receiver's texel: the disc filters' rotation is a property of the surface point,
// not of the pixel, so the noise pattern stays on the surface as the camera moves.
uint vsHashCell(ivec3 c) {
  uint h = uint(c.x) * 73856093u ^ uint(c.y) * 19349663u ^ uint(c.z) * 83492791u;
  h ^= h >> 13u;
  h *= 0x5bd1e995u;
  h ^= h >> 15u;
  return h;
}

// The rotation (cos, sin) of the disc filters at world point p, for texels of world size texel.
vec2 vsDiscRotation(vec3 p, float texel) {
  uint h = vsHashCell(ivec3(floor(p / texel)));
  float angle = float(h & 65535u) * (6.2831853f / 65536.0f);
  return vec2(cos(angle), sin(angle));
}

// Sample i of 16 of a disc of unit radius, evenly spread (a Vogel spiral: blue-noise-like), rotated. The
// spiral's point is (cos(a), sin(a)) * r with a = i * 2.3999632 and r = sqrt((i + 0.5) / 16). The shader
// computes it: llvmpipe keeps a table indexed per tap in memory (the demo's lighting took 490 ms against 350).
// The CPU reads it from a table of the float bits that glibc's cosf and sinf give (the same images as the
// calls, which kept the filter loop's values in memory around each call: 20 ms of the demo frame's 90).
vec2 vsDiscSample(int i, vec2 rotation) {
#ifdef VS_GLSL
  float r = sqrt((float(i) + 0.5f) / 16.0f);
  float a = float(i) * 2.3999632f;
  vec2 d = vec2(cos(a), sin(a)) * r;
#else
  static constexpr uint spiral[32] = {
      0x3e3504f3u, 0x00000000u, 0xbe6730d2u, 0x3e53ca28u, 0x3d0d8cabu, 0xbec99c61u, 0x3e91b358u, 0x3ebe0a57u,
      0xbf05b06bu, 0xbdbd2e71u, 0x3efd48b5u, 0xbea11e5eu, 0xbe296fbcu, 0x3f1d930fu, 0xbea19158u, 0xbf1b8b4au,
      0x3f2f44b8u, 0x3e8003e5u, 0xbf365667u, 0x3e968865u, 0x3eafcc1fu, 0xbf3bd5a5u, 0x3e81e8f6u, 0x3f4f162au,
      0xbf43c672u, 0xbee2e90fu, 0x3f65aa8du, 0xbe49f7bbu, 0xbf0c2953u, 0x3f475daeu, 0xbe018626u, 0xbf79e100u};
  vec2 d = vec2(uintBitsToFloat(spiral[2 * i]), uintBitsToFloat(spiral[2 * i + 1]));
#endif
  return vec2(d.x * rotation.x - d.y * rotation.y, d.x * rotation.y + d.y * rotation.x);
}

// p projected into a view: texel coordinates (texel centres at .5) and the receiver's depth in the layer's
// encoding. False behind a perspective view's eye.
bool vsProjectToView(VS_IN(ShadeView) view, vec3 p, VS_OUT(vec2) texel, VS_OUT(float) depth) {
  vec3 rel = p - vec3(view.eye);
  vec4 clip = view.eyeToClip * vec4(rel, 1.0f);
  if (!(clip.w > 0.0f)) return false;
  vec3 ndc = vec3(clip) / clip.w;
  texel = (vec2(ndc) * 0.5f + vec2(0.5f)) * float(view.info.y);
  depth = view.info.z == VS_ENCODING_NDC_DEPTH ? ndc.z : length(rel);
  return true;
}

// Whether a kernel of `margin` texels around `texel` stays inside the layer (and the depth inside a
// directional view's range).
bool vsInsideView(VS_IN(ShadeView) view, vec2 texel, float depth, float margin) {
  float w = float(view.info.y);
  bool lateral = texel.x >= margin && texel.y >= margin && texel.x <= w - margin && texel.y <= w - margin;
  bool inDepth = view.info.z != VS_ENCODING_NDC_DEPTH || (depth >= 0.0f && depth <= 1.0f);
  return lateral && inDepth;
}

// The receiver as one view compares it: its (biased) plane, and its depth where no plane is compared.
struct VsReceiver {
  vec3 rel;     // a point of the receiver's plane, biased, relative to the view's eye (eye + eyeLow)
  vec3 normal;  // the plane's unit normal (the face normal)
  float depth;  // the biased receiver's own depth, in the layer's encoding
  int plane;    // VS_RECEIVER_* (shading_layout.h): what each texel is compared against
  // VS_RECEIVER_PLANE_AFFINE: the plane's depth at texel `base`'s ray (x) and its change per texel along x (y)
  // and y (z).
  vec3 slope;
  ivec2 base;
};


// m * p, summed column by column in a fixed order (as the trace kernels' vsMulPoint), so that both compilers
// round alike.
vec4 vsUnproject(VS_IN(mat4) m, vec4 p) {
  VS_PRECISE vec4 r = m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3] * p.w;
  return r;
}

// The depth, in the layer's encoding, at which texel t's own ray meets the receiver's plane. The ray is
// rebuilt with the trace kernels' arithmetic (vsViewRay in compute/shared/traverse.h), so where it hits the
// receiver's face (voxel faces are planar) this is the depth the texel stores, to rounding, wherever the
// texel lies in the kernel: no depth slope to cover with a bias. A stored depth below it is a blocker in
// front of the plane. The ray's slope against the plane is capped as the slope bias's is
// (VS_MIN_SLOPE_COSINE), so that a ray nearly in the plane does not put its depth at infinity.
float vsReceiverPlaneDepth(VS_IN(ShadeView) view, ivec2 t, vec3 rel, vec3 n) {
  VS_PRECISE float nx = (float(t.x) + 0.5f) / float(view.info.y) * 2.0f - 1.0f;
  VS_PRECISE float ny = (float(t.y) + 0.5f) / float(view.info.y) * 2.0f - 1.0f;
  vec4 farH = vsUnproject(view.clipToEye, vec4(nx, ny, 1.0f, 1.0f));
  VS_PRECISE vec3 farP = vec3(farH.x / farH.w, farH.y / farH.w, farH.z / farH.w);
  VS_PRECISE vec3 start = vec3(0.0f);
  VS_PRECISE vec3 d;
  if (view.info.z == VS_ENCODING_NDC_DEPTH) {
    vec4 nearH = vsUnproject(view.clipToEye, vec4(nx, ny, 0.0f, 1.0f));
    start = vec3(nearH.x / nearH.w, nearH.y / nearH.w, nearH.z / nearH.w);
    d = farP - start;
  } else {
    d = farP / length(farP);
  }
  VS_PRECISE float along = min(dot(n, d), -VS_MIN_SLOPE_COSINE * length(d));
  VS_PRECISE float s = dot(n, rel - start) / along;
  return s;
}

// An orthographic view's texel rays are parallel (direction clipToEye's z column) and start on its near plane
// at points affine in the texel, so the depth at which they meet a plane is affine in the texel too: the depth
// at texel `base` (x, by vsReceiverPlaneDepth's arithmetic) and its change per texel along x (y) and y (z). A
// filter kernel then costs two products a tap instead of two unprojections; the results match the per-texel
// form to rounding, far inside the biases (the kernel's taps lie within VS_PCSS_MAX_RADIUS of base, so the
// steps add no error that grows with the layer's size).
vec3 vsPlaneSlope(VS_IN(ShadeView) view, ivec2 base, vec3 rel, vec3 n) {
  mat4 m = view.clipToEye;
  VS_PRECISE vec3 d = vec3(m[2]) / m[3].w;
  VS_PRECISE float along = min(dot(n, d), -VS_MIN_SLOPE_COSINE * length(d));
  VS_PRECISE float step = 2.0f / float(view.info.y);
  VS_PRECISE float perX = -(dot(n, vec3(m[0])) / m[3].w) * step / along;
  VS_PRECISE float perY = -(dot(n, vec3(m[1])) / m[3].w) * step / along;
  return vec3(vsReceiverPlaneDepth(view, base, rel, n), perX, perY);
}

// The stored depth of texel t of the view's window, clamped to the window. A cascade's layer is a ring over
// its world-fixed grid (DESIGN.md §11): window texel t lives at (t + ring offset) mod w, w a power of two.
// The store index of the first texel of window row y (clamped), and the offset of window column x (clamped)
// within a row: a texel's place is their sum.
int vsStoredRow(VS_IN(ShadeView) view, int y) {
  int w = view.info.y;
  return view.info.x + ((clamp(y, 0, w - 1) + view.trace.z) & (w - 1)) * w;
}
int vsStoredColumn(VS_IN(ShadeView) view, int x) {
  int w = view.info.y;
  return (clamp(x, 0, w - 1) + view.trace.y) & (w - 1);
}
float vsStoredDepth(VS_IN(ShadeView) view, ivec2 t) {
  return shadowTexels[vsStoredRow(view, t.y) + vsStoredColumn(view, t.x)];
}

// The receiver's depth as texel t sees it: its plane at the texel's ray, but never deeper than the receiver
// itself. Where the plane recedes from the light, a texel past a concave corner meets it inside the solid,
// behind the neighbouring face; comparing that face with the receiver's own depth there keeps it from
// shadowing the receiver. On an unbroken face that texel's hit lies on the plane, behind the receiver's depth:
// lit either way.
float vsReceiverDepth(VS_IN(ShadeView) view, ivec2 t, VS_IN(VsReceiver) r) {
  if (r.plane == VS_RECEIVER_PLANE_AFFINE) {
    VS_PRECISE float s = r.slope.x + float(t.x - r.base.x) * r.slope.y + float(t.y - r.base.y) * r.slope.z;
    return min(s, r.depth);
  }
  return r.plane == VS_RECEIVER_PLANE ? min(vsReceiverPlaneDepth(view, t, r.rel, r.normal), r.depth) : r.depth;
}

// 1 where the receiver is in front of (or at) the stored depth of texel t.
float vsCompare(VS_IN(ShadeView) view, ivec2 t, VS_IN(VsReceiver) r) {
  return vsStoredDepth(view, t) < vsReceiverDepth(view, t, r) ? 0.0f : 1.0f;
}

float vsFilterBox(VS_IN(ShadeView) view, vec2 texel, VS_IN(VsReceiver) r, int radius) {
  ivec2 centre = ivec2(floor(texel));
  float sum = 0.0f;
  if (r.plane == VS_RECEIVER_PLANE_AFFINE) {
    // vsCompare's arithmetic with each row's share of it done once per row: the kernel is centred on the
    // plane's base texel (both are floor(texel)), so a tap's offset from the base is (dx, dy), and its plane
    // depth (slope.x + dx * slope.y) + dy * slope.z is the very sum vsReceiverDepth forms.
    VS_TAP_LOOP for (int dy = -radius; dy <= radius; ++dy) {
      VS_PRECISE float rowShare = float(dy) * r.slope.z;
      int row = vsStoredRow(view, centre.y + dy);
      VS_TAP_LOOP for (int dx = -radius; dx <= radius; ++dx) {
        VS_PRECISE float plane = (r.slope.x + float(dx) * r.slope.y) + rowShare;
        sum += shadowTexels[row + vsStoredColumn(view, centre.x + dx)] < min(plane, r.depth) ? 0.0f : 1.0f;
      }
    }
  } else {
    VS_TAP_LOOP for (int dy = -radius; dy <= radius; ++dy)
      VS_TAP_LOOP for (int dx = -radius; dx <= radius; ++dx) sum += vsCompare(view, centre + ivec2(dx, dy), r);
  }
  float side = float(2 * radius + 1);
  return sum / (side * side);
}

float vsFilterDisc(VS_IN(ShadeView) view, vec2 texel, VS_IN(VsReceiver) r, vec2 rotation, float radius) {
  float sum = 0.0f;
  VS_TAP_LOOP for (int i = 0; i < 16; ++i) sum += vsCompare(view, ivec2(floor(texel + vsDiscSample(i, rotation) * radius)), r);
  return sum / 16.0f;
}

// The world size of a texel of `view` at receiver lightDistance `lightDistance` (the lightDistance matters for perspective
// views only).
float vsTexelWorld(VS_IN(ShadeView) view, float lightDistance) {
  return view.info.z == VS_ENCODING_NDC_DEPTH ? view.eye.w : view.eye.w * lightDistance;
}

// Percentage-closer soft shadows: the blockers' mean distance from the emitter over a search disc, then a
// disc whose radius is the penumbra that a lightSize-wide emitter gives at that distance ratio. Distances are
// world units from the emitter (a directional light's emitter lies on its view's near plane).
float vsFilterPcss(VS_IN(ShadeView) view, vec2 texel, VS_IN(VsReceiver) r, vec2 rotation, float lightSize,
                   float texelWorld) {
  float scale = view.split.w;
  float search = clamp(0.5f * lightSize / texelWorld, 1.0f, VS_PCSS_MAX_RADIUS);
  float blockers = 0.0f;
  float receivers = 0.0f;
  float count = 0.0f;
  VS_TAP_LOOP for (int i = 0; i < 16; ++i) {
    ivec2 t = ivec2(floor(texel + vsDiscSample(i, rotation) * search));
    float stored = vsStoredDepth(view, t);
    float receiver = vsReceiverDepth(view, t, r);
    if (stored < receiver) {
      blockers += stored * scale;
      receivers += receiver * scale;
      count += 1.0f;
    }
  }
  if (count == 0.0f) return 1.0f;
  float blocker = max(blockers / count, 1e-4f * scale);
  float receiver = receivers / count;
  float penumbra = lightSize * (receiver - blocker) / blocker;
  float radius = clamp(0.5f * penumbra / texelWorld, 1.0f, VS_PCSS_MAX_RADIUS);
  return vsFilterDisc(view, texel, r, rotation, radius);
}

// The blurred moments of texel t of the view's window, clamped to the window, at its ring place.
vec4 vsStoredMoments(VS_IN(ShadeView) view, ivec2 t) {
  int w = view.info.y;
  ivec2 c = clamp(t, ivec2(0), ivec2(w - 1));
  ivec2 s = ivec2((c.x + view.trace.y) & (w - 1), (c.y + view.trace.z) & (w - 1));
  return vsLoadMoments(view.trace.w + s.y * w + s.x);
}

// EVSM: the moments bilinearly filtered where the receiver projects (the blur made them smooth: one fetch of
// four texels), against the biased receiver's depth.
float vsFilterEvsm(VS_IN(ShadeView) view, vec2 texel, VS_IN(VsReceiver) r, vec4 evsm) {
  vec2 at = texel - vec2(0.5f);
  ivec2 t = ivec2(floor(at));
  vec2 f = at - floor(at);
  vec4 top = mix(vsStoredMoments(view, t), vsStoredMoments(view, t + ivec2(1, 0)), f.x);
  vec4 bottom = mix(vsStoredMoments(view, t + ivec2(0, 1)), vsStoredMoments(view, t + ivec2(1, 1)), f.x);
  return vsEvsmShadow(mix(top, bottom, f.y), r.depth, view.eyeLow.w, evsm);
}

// How far (texels) a filter reads from its centre: the lateral check's margin.
float vsFilterReach(int kind) {
  if (kind == VS_FILTER_PCF3) return 1.5f;
  if (kind == VS_FILTER_PCF5) return 2.5f;
  if (kind == VS_FILTER_POISSON16) return VS_POISSON_RADIUS + 0.5f;
  if (kind == VS_FILTER_PCSS) return VS_PCSS_MAX_RADIUS + 0.5f;
  if (kind == VS_FILTER_EVSM) return 1.0f;
  return 0.5f;
}

// The receiver moved off its surface by the light's biases, for one view (texel sizes differ per view):
// along N by the normal offset, along L by the constant and the slope-scaled bias.
vec3 vsBiasedReceiver(VS_IN(ShadeLight) light, VS_IN(ShadeView) view, vec3 p, vec3 n, vec3 toLight, float nDotL,
                      float lightDistance) {
  float texel = vsTexelWorld(view, lightDistance);
  float alongLight = light.bias.x + light.bias.z * texel / max(nDotL, VS_MIN_SLOPE_COSINE);
  return p + n * (light.bias.y * texel) + toLight * alongLight;
}

// The receiver as `view` compares it (its biased plane or depth) and where its kernel is centred; false where
// the view does not cover the receiver. lateral: the kernel must lie inside the layer (cascades, spot views);
// cube faces leave it out, since a receiver near a face's edge is as near the edge of its neighbour, and read
// clamped texels instead.
// Layers of entry depths compare each texel with the receiver's plane, moved by the biases, at the texel's own
// ray; the kernel is centred where the receiver itself projects. Layers of voxel-centre depths compare the
// biased receiver's depth, centred where it projects.
bool vsViewReceiver(VS_IN(ShadeLight) light, VS_IN(ShadeView) view, vec3 p, vec3 n, vec3 toLight, float nDotL,
                    float lightDistance, bool lateral, VS_OUT(VsReceiver) r, VS_OUT(vec2) texel) {
  vec3 biased = vsBiasedReceiver(light, view, p, n, toLight, nDotL, lightDistance);
  r.plane = view.trace.x != VS_DEPTH_POINT_ENTRY ? VS_RECEIVER_DEPTH
      : view.info.z == VS_ENCODING_NDC_DEPTH ? VS_RECEIVER_PLANE_AFFINE : VS_RECEIVER_PLANE;
  r.normal = n;
  r.rel = (biased - vec3(view.eye)) - vec3(view.eyeLow);
  r.slope = vec3(0.0f);
  r.base = ivec2(0);
  if (!vsProjectToView(view, biased, texel, r.depth)) return false;
  float depth = r.depth;
  if (r.plane != VS_RECEIVER_DEPTH && !vsProjectToView(view, p, texel, depth)) return false;
  return !lateral || vsInsideView(view, texel, depth, vsFilterReach(light.info.y));
}

// The first of views first + from .. first + count - 1 that holds camera view depth viewDepth
// (vsViewHoldsDepth), as an index from `first`; count where none does.
int vsNextViewHolding(int first, int from, int count, float viewDepth) {
  int c = from;
  while (c < count && !vsViewHoldsDepth(first + c, viewDepth)) ++c;
  return c;
}

// The filtered shadow-map term of one view at a receiver it covers (vsViewReceiver gave r and texel).
float vsViewFilter(VS_IN(ShadeLight) light, VS_IN(ShadeView) view, vec3 p, vec3 n, float lightDistance,
                   VsReceiver r, vec2 texel) {
  int kind = light.info.y;
  r.base = ivec2(floor(texel));
  if (r.plane == VS_RECEIVER_PLANE_AFFINE) r.slope = vsPlaneSlope(view, r.base, r.rel, n);
  float texelWorld = vsTexelWorld(view, lightDistance);
  if (kind == VS_FILTER_HARD) return vsCompare(view, r.base, r);
  if (kind == VS_FILTER_PCF3) return vsFilterBox(view, texel, r, 1);
  if (kind == VS_FILTER_PCF5) return vsFilterBox(view, texel, r, 2);
  if (kind == VS_FILTER_EVSM) return vsFilterEvsm(view, texel, r, light.evsm);
  vec2 rotation = vsDiscRotation(p, texelWorld);
  if (kind == VS_FILTER_POISSON16) return vsFilterDisc(view, texel, r, rotation, VS_POISSON_RADIUS);
  return vsFilterPcss(view, texel, r, rotation, light.bias.w, texelWorld);
}

// The shadow-map term of a light at a receiver (1 lit, 0 shadowed). Cascades: the first whose depth range
// holds the pixel's view depth and whose layer holds the kernel; in the blend band at its far end it mixes
// with the next one, and the last one fades to lit. A receiver outside every view is lit.
// The view is chosen before any filter runs, and only the chosen view's whole record is read (a record is 208
// bytes).
float vsShadowMapTerm(VS_IN(ShadeLight) light, vec3 p, vec3 n, vec3 toLight, float nDotL, float lightDistance,
                      float viewDepth) {
  int first = light.info.z;
  int count = light.info.w;
  VsReceiver r;
  vec2 texel;
  if (light.info.x == VS_LIGHT_POINT) {
    // The cube face of the major axis, in layer order +x, -x, +y, -y, +z, -z.
    vec3 d = p - vec3(light.position);
    vec3 a = abs(d);
    int face = a.x >= a.y && a.x >= a.z ? (d.x >= 0.0f ? 0 : 1) : (a.y >= a.z ? (d.y >= 0.0f ? 2 : 3) : (d.z >= 0.0f ? 4 : 5));
    ShadeView faceView = vsLoadView(first + face);
    if (!vsViewReceiver(light, faceView, p, n, toLight, nDotL, lightDistance, false, r, texel)) return 1.0f;
    return vsViewFilter(light, faceView, p, n, lightDistance, r, texel);
  }
  // The first view that holds the depth and whose layer holds the kernel. Cascades' ranges do not overlap, so
  // one view's whole record is loaded and tried, and a second only where the first refuses the receiver and
  // another range holds it too.
  int chosen = vsNextViewHolding(first, 0, count, viewDepth);
  ShadeView view;
  while (chosen < count) {
    view = vsLoadView(first + chosen);
    if (vsViewReceiver(light, view, p, n, toLight, nDotL, lightDistance, true, r, texel)) break;
    chosen = vsNextViewHolding(first, chosen + 1, count, viewDepth);
  }
  if (chosen >= count) return 1.0f;
  // The chosen view's filter; in the blend band at the far end of a cascade's range, mixed with the next
  // cascade's (the last one's with lit). Both filters are one loop body run once or twice: a CPU device
  // (llvmpipe) runs the code of every branch for every lane whether or not a lane takes it, but leaves a loop
  // when no lane goes on, so a second filter costs only the lanes' groups with a pixel in a band.
  float band = view.info.w < 0 ? 0.0f : light.extra.z * (view.split.y - view.split.x);
  bool blend = band > 0.0f && viewDepth > view.split.y - band;
  float t = blend ? (viewDepth - (view.split.y - band)) / band : 0.0f;
  int passes = blend && chosen + 1 < count ? 2 : 1;
  float s = 1.0f;
#ifndef VS_GLSL
  // GCC kept the loop rolled, which cost the CPU pass 4 ms of the demo's 38.
#pragma GCC unroll 2
#endif
  for (int k = 0; k < passes; ++k) {
    bool covered = true;
    if (k == 1) {
      view = vsLoadView(first + chosen + 1);
      covered = vsViewReceiver(light, view, p, n, toLight, nDotL, lightDistance, true, r, texel);
    }
    float filtered = covered ? vsViewFilter(light, view, p, n, lightDistance, r, texel) : s;
    s = k == 0 ? filtered : mix(s, filtered, t);
  }
  if (blend && passes == 1) s = mix(s, 1.0f, t);
  return s;
}

// Which cascade of the light the receiver's shadow comes from (-1: none), for the cascade debug view.
int vsCascadeOf(VS_IN(ShadeLight) light, vec3 p, float viewDepth) {
  for (int c = 0; c < light.info.w; ++c) {
    if (!vsViewHoldsDepth(light.info.z + c, viewDepth)) continue;
    ShadeView view = vsLoadView(light.info.z + c);
    if (view.info.w < 0) continue;
    vec2 texel;
    float depth;
    if (vsProjectToView(view, p, texel, depth) && vsInsideView(view, texel, depth, vsFilterReach(light.info.y)))
      return c;
  }
  return -1;
}

// The direction toward the light, the lightDistance to it (0 for directional lights) and its attenuation
// (spot cone and range falloff; 1 for directional lights).
float vsLightGeometry(VS_IN(ShadeLight) light, vec3 p, VS_OUT(vec3) toLight, VS_OUT(float) lightDistance) {
  if (light.info.x == VS_LIGHT_DIRECTIONAL) {
    toLight = -vec3(light.direction);
    lightDistance = 0.0f;
    return 1.0f;
  }
  vec3 d = vec3(light.position) - p;
  lightDistance = length(d);
  toLight = lightDistance > 0.0f ? d / lightDistance : vec3(0.0f, 1.0f, 0.0f);
  float range = light.position.w;
  float ratio = lightDistance / range;
  float window = clamp(1.0f - ratio * ratio * ratio * ratio, 0.0f, 1.0f);
  float attenuation = window * window / max(lightDistance * lightDistance, 1e-4f);
  if (light.info.x == VS_LIGHT_SPOT) {
    float cosAngle = dot(-toLight, vec3(light.direction));
    float cosOuter = light.direction.w;
    float cosInner = light.extra.x;
    float cone = cosInner - cosOuter > 1e-6f ? smoothstep(cosOuter, cosInner, cosAngle) : (cosAngle >= cosOuter ? 1.0f : 0.0f);
    attenuation *= cone;
  }
  return attenuation;
}

// The shadow term of light `l` at G-buffer texel g (1 lit, 0 shadowed): the shadow maps, times the contact
// ray where the light has one, or the exact ray alone (raytraced). `visibility`: rayVisibility's answer for
// this pixel and light. Surfaces facing away from the light are in their own shadow (0). A receiver the light
// does not reach (zero attenuation: beyond its range, outside its cone) has nothing to shadow: 1, with no layer
// read and no ray's answer used. That is what a light's culling volume gives a deferred pass, and the lit
// colour is the same either way (the light adds nothing there); most of a point light's receivers in a large
// scene lie beyond its range, where each would cost a filter kernel of unprojected texel rays.
float vsShadowTerm(VS_IN(ShadeLight) light, VS_IN(GBufferTexel) g, uint visibility, bool raytraced) {
  vec3 p = vec3(g.position);
  vec3 n = vec3(g.normal);
  vec3 toLight;
  float lightDistance;
  float attenuation = vsLightGeometry(light, p, toLight, lightDistance);
  float nDotL = dot(n, toLight);
  if (!(nDotL > 0.0f)) return 0.0f;
  if (attenuation == 0.0f) return 1.0f;
  if (raytraced) return visibility != 0u ? 1.0f : 0.0f;
  float s = light.info.y == VS_FILTER_NONE ? 1.0f : vsShadowMapTerm(light, p, n, toLight, nDotL, lightDistance, g.position.w);
  if (light.extra.y > 0.0f && visibility == 0u) s = 0.0f;
  return s;
}

// What light `l` adds to texel g, its shadow term given.
vec3 vsLightRadiance(VS_IN(ShadeLight) light, VS_IN(GBufferTexel) g, float shadow) {
  vec3 toLight;
  float lightDistance;
  float attenuation = vsLightGeometry(light, vec3(g.position), toLight, lightDistance);
  float nDotL = max(dot(vec3(g.normal), toLight), 0.0f);
  return vec3(light.color) * (nDotL * attenuation * shadow);
}

#endif
