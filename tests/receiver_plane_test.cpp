// receiver_plane_test.cpp: the lighting pass's receiver-plane depths (lighting/shared/shading.h). An
// orthographic view's filter taps read the plane's depth through its affine form (vsPlaneSlope); here that
// form is held against the per-texel rays it replaces, over random views, planes and kernels.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "lighting/cpu_shading.h"
#include "lighting/deferred.h"

namespace {

// shading.h as the CPU pass compiles it; only the plane functions are called, so its buffers stay empty.
using PlaneProbe = vs::gpu::CpuShading;
using vs::gpu::ShadeView;

// An orthographic view about its eye looking along `forward`: clip x, y in [-1, 1] over the half extents,
// z in [0, 1] from near to far (distances along forward), w = 1; clipToEye inverted in double, as the
// tracer's views are.
ShadeView orthographicView(const glm::dvec3& forward, double halfWidth, double nearDist, double farDist, int size) {
  const glm::dvec3 f = glm::normalize(forward);
  const glm::dvec3 helper = std::abs(f.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 right = glm::normalize(glm::cross(helper, f));
  const glm::dvec3 up = glm::cross(f, right);
  glm::dmat4 eyeToClip(0.0);
  for (int c = 0; c < 3; ++c) {
    eyeToClip[c][0] = right[c] / halfWidth;
    eyeToClip[c][1] = up[c] / halfWidth;
    eyeToClip[c][2] = f[c] / (farDist - nearDist);
  }
  eyeToClip[3][2] = -nearDist / (farDist - nearDist);
  eyeToClip[3][3] = 1.0;
  ShadeView view{};
  view.eyeToClip = glm::mat4(eyeToClip);
  view.clipToEye = glm::mat4(glm::inverse(eyeToClip));
  view.info = glm::ivec4(0, size, vs::gpu::VS_ENCODING_NDC_DEPTH, 0);
  view.trace = glm::ivec4(vs::gpu::VS_DEPTH_POINT_ENTRY, 0, 0, -1);
  return view;
}

// The depth at which texel t's ray meets the plane through rel with normal n, in double from the view's matrix.
double exactPlaneDepth(const ShadeView& view, glm::ivec2 t, glm::vec3 rel, glm::vec3 n) {
  const glm::dmat4 m(view.clipToEye);
  const double nx = (t.x + 0.5) / view.info.y * 2.0 - 1.0;
  const double ny = (t.y + 0.5) / view.info.y * 2.0 - 1.0;
  const glm::dvec4 nearH = m * glm::dvec4(nx, ny, 0.0, 1.0);
  const glm::dvec4 farH = m * glm::dvec4(nx, ny, 1.0, 1.0);
  const glm::dvec3 start = glm::dvec3(nearH) / nearH.w;
  const glm::dvec3 d = glm::dvec3(farH) / farH.w - start;
  return glm::dot(glm::dvec3(n), glm::dvec3(rel) - start) / glm::dot(glm::dvec3(n), d);
}

TEST(ReceiverPlane, AffineFormMatchesEachTexelsOwnRay) {
  std::mt19937 rng(20261206);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const int sizes[] = {256, 1024, 2048, 4096};
  PlaneProbe probe;
  double worstRatio = 0.0;
  int compared = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const glm::dvec3 forward(unit(rng), -1.0 - std::abs(unit(rng)), unit(rng));
    const double halfWidth = 5.0 + 300.0 * std::abs(unit(rng));
    const double nearDist = -500.0 * std::abs(unit(rng));
    const double farDist = nearDist + 50.0 + 2000.0 * std::abs(unit(rng));
    const int size = sizes[trial % 4];
    const ShadeView view = orthographicView(forward, halfWidth, nearDist, farDist, size);
    // A receiver's plane that faces the light (its normal against the view's direction), through a point of
    // the view's volume.
    glm::dvec3 n;
    do n = glm::normalize(glm::dvec3(unit(rng), unit(rng), unit(rng)));
    while (glm::dot(n, glm::normalize(forward)) > -0.05);
    const glm::vec4 clipPoint(float(unit(rng) * 0.9), float(unit(rng) * 0.9), float(0.5 + 0.45 * unit(rng)), 1.0f);
    const glm::vec3 rel = glm::vec3(glm::dmat4(view.clipToEye) * glm::dvec4(clipPoint));
    const glm::ivec2 base(8 + int((size - 16) * (0.5 + 0.5 * unit(rng))), 8 + int((size - 16) * (0.5 + 0.5 * unit(rng))));

    PlaneProbe::VsReceiver r{};
    r.rel = rel;
    r.normal = glm::vec3(n);
    r.depth = std::numeric_limits<float>::infinity();
    r.plane = vs::gpu::VS_RECEIVER_PLANE_AFFINE;
    r.base = base;
    r.slope = probe.vsPlaneSlope(view, base, r.rel, r.normal);
    ASSERT_TRUE(std::isfinite(r.slope.x) && std::isfinite(r.slope.y) && std::isfinite(r.slope.z));
    // The widest kernel (pcss) reaches VS_PCSS_MAX_RADIUS texels from the centre.
    const int reach = int(vs::gpu::VS_PCSS_MAX_RADIUS);
    const double scale = std::abs(r.slope.x) + reach * (std::abs(r.slope.y) + std::abs(r.slope.z));
    for (int dy = -reach; dy <= reach; dy += 2)
      for (int dx = -reach; dx <= reach; dx += 2) {
        const glm::ivec2 t = base + glm::ivec2(dx, dy);
        const float affine = probe.vsReceiverDepth(view, t, r);
        const float perTexel = probe.vsReceiverPlaneDepth(view, t, r.rel, r.normal);
        // Rounding of the two forms only: a few float ulps of the largest term. A wrong slope is off by
        // up to `reach` whole steps.
        const double error = std::abs(double(affine) - double(perTexel));
        const double allowed = 1e-5 * scale + 1e-7;
        worstRatio = std::max(worstRatio, error / allowed);
        // Against the exact depth (the texel's ray from the same matrix, in double), the affine form is as
        // close as the per-texel one, give or take a millionth of the view's depth range.
        const double exact = exactPlaneDepth(view, t, r.rel, r.normal);
        EXPECT_LE(std::abs(double(affine) - exact), 2.0 * std::abs(double(perTexel) - exact) + 1e-6 * (scale + 1.0))
            << "trial " << trial << " texel offset (" << dx << ", " << dy << ")";
        ASSERT_LE(error, allowed) << "trial " << trial << " texel offset (" << dx << ", " << dy << "): affine "
                                  << affine << ", per texel " << perTexel << ", slope (" << r.slope.x << ", "
                                  << r.slope.y << ", " << r.slope.z << ")";
        ++compared;
      }
  }
  std::printf("compared %d taps; worst error %.3f of the allowance\n", compared, worstRatio);
}

// The slope is the plane's: a plane that faces the light head on has the same depth at every texel, and one
// tilted along x changes only along x.
TEST(ReceiverPlane, SlopeFollowsThePlanesTilt) {
  PlaneProbe probe;
  const ShadeView view = orthographicView(glm::dvec3(0, -1, 0), 64.0, 0.0, 200.0, 1024);
  const glm::vec3 rel = glm::vec3(glm::dmat4(view.clipToEye) * glm::dvec4(0.1, -0.2, 0.5, 1.0));
  const glm::vec3 facing = probe.vsPlaneSlope(view, glm::ivec2(500, 600), rel, glm::vec3(0, 1, 0));
  EXPECT_NEAR(facing.x, 0.5f, 1e-6f);
  EXPECT_EQ(facing.y, 0.0f);
  EXPECT_EQ(facing.z, 0.0f);
  const glm::vec3 tilted =
      probe.vsPlaneSlope(view, glm::ivec2(500, 600), rel, glm::normalize(glm::vec3(0.0f, 1.0f, 1.0f)));
  EXPECT_NE(tilted.y, 0.0f);
  EXPECT_NEAR(tilted.z, 0.0f, 1e-9f);
  // The view's x runs along world -z: a plane at 45 degrees about x rises one texel's width (128 / 1024 world units) per texel; the depth range is 200.
  EXPECT_NEAR(std::abs(tilted.y), (128.0 / 1024.0) / 200.0, 1e-7);
}

}  // namespace
