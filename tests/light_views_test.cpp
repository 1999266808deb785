// Light views: projection and ray generation agree, directional depth range covers the bounds, cube faces
// partition the sphere, spot frustum holds the cone.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lighting/light_views.h"
#include "lighting/scene_file.h"

namespace {

using namespace vs;

// DESIGN.md §6: unproject a texel position at NDC z = 0 and z = 1.
struct Ray {
  glm::dvec3 nearP, farP;
};

Ray texelRay(const LightView& v, glm::dvec2 texel) {
  glm::dmat4 inv = glm::inverse(v.eyeToClip);
  double nx = texel.x / v.resolution * 2.0 - 1.0, ny = texel.y / v.resolution * 2.0 - 1.0;
  glm::dvec4 n = inv * glm::dvec4(nx, ny, 0.0, 1.0), f = inv * glm::dvec4(nx, ny, 1.0, 1.0);
  return {v.eye + glm::dvec3(n) / n.w, v.eye + glm::dvec3(f) / f.w};
}

// Texel position (column, row) and NDC of a world point (DESIGN.md §9).
glm::dvec3 project(const LightView& v, const glm::dvec3& p, glm::dvec2* texel) {
  glm::dvec4 clip = glm::dmat4(v.viewProj) * glm::dvec4(p, 1.0);
  glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
  *texel = glm::dvec2((ndc.x * 0.5 + 0.5) * v.resolution, (ndc.y * 0.5 + 0.5) * v.resolution);
  return ndc;
}

double distanceToLine(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
  glm::dvec3 d = glm::normalize(b - a);
  glm::dvec3 r = p - a;
  return glm::length(r - d * glm::dot(r, d));
}

LightDesc shadowed(LightType type, const std::string& name, int resolution) {
  LightDesc l;
  l.name = name;
  l.type = type;
  l.shadow = ShadowDesc{};
  l.shadow->resolution = resolution;
  return l;
}

SceneDesc testScene() {
  SceneDesc s;
  LightDesc sun = shadowed(LightType::Directional, "sun", 256);
  sun.direction = glm::normalize(glm::vec3(-0.4f, -1.0f, -0.3f));
  LightDesc lamp = shadowed(LightType::Spot, "lamp", 128);
  lamp.position = glm::vec3(10, 30, 5);
  lamp.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
  lamp.range = 80.0f;
  lamp.outerConeDeg = 35.0f;
  lamp.innerConeDeg = 25.0f;
  LightDesc unshadowed;
  unshadowed.name = "fill";
  LightDesc torch = shadowed(LightType::Point, "torch", 64);
  torch.position = glm::vec3(20, 5, 20);
  torch.range = 40.0f;
  LightDesc down = shadowed(LightType::Directional, "down", 64);  // parallel to the default up vector
  down.direction = glm::vec3(0, -1, 0);
  s.lights = {sun, lamp, unshadowed, torch, down};
  return s;
}

Aabb testBounds() { return Aabb{glm::vec3(-10, 0, -20), glm::vec3(60, 25, 40)}; }

TEST(LightViews, NamesOrderAndRecords) {
  auto views = buildLightViews(testScene(), testBounds());
  ASSERT_EQ(views.size(), 1u + 1u + 6u + 1u);
  EXPECT_EQ(views[0].name, "sun");
  EXPECT_EQ(views[0].encoding, gpu::VS_ENCODING_NDC_DEPTH);
  EXPECT_EQ(views[1].name, "lamp");
  EXPECT_EQ(views[1].encoding, gpu::VS_ENCODING_LINEAR_DISTANCE);
  const char* faces[] = {"torch.face+x", "torch.face-x", "torch.face+y", "torch.face-y", "torch.face+z", "torch.face-z"};
  for (int f = 0; f < 6; ++f) {
    EXPECT_EQ(views[2 + f].name, faces[f]);
    EXPECT_EQ(views[2 + f].light, "torch");
    EXPECT_EQ(views[2 + f].lightIndex, 3);
  }
  EXPECT_EQ(views[8].name, "down");
  for (const LightView& v : views) {
    EXPECT_EQ(v.trace.rect, glm::ivec4(0, 0, v.resolution, v.resolution));
    EXPECT_EQ(v.trace.info, glm::ivec4(v.resolution, v.resolution, v.encoding, v.depthPoint));
    EXPECT_EQ(v.trace.viewProj, v.viewProj);
    // clipToEye inverts eyeToClip, which is worldToClip about the eye.
    glm::dmat4 id = v.eyeToClip * glm::dmat4(v.trace.clipToEye);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) EXPECT_NEAR(id[c][r], c == r ? 1.0 : 0.0, 1e-5) << v.name;
    glm::dvec3 probe(1.25, -3.5, 7.0);
    glm::dvec4 a = glm::dmat4(v.viewProj) * glm::dvec4(v.eye + probe, 1.0), b = v.eyeToClip * glm::dvec4(probe, 1.0);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(a[k], b[k], 1e-4 * (1.0 + std::abs(b[k]))) << v.name;
    EXPECT_LE(glm::length(gpu::viewEye(v.trace) - v.eye), 1e-12 * (1.0 + glm::length(v.eye))) << v.name;
    if (v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE) {
      EXPECT_EQ(glm::vec3(v.trace.eyeHigh), v.position);
      EXPECT_EQ(v.trace.eyeHigh.w, v.range);
    }
  }
  EXPECT_EQ(views[1].range, 80.0f);
  EXPECT_EQ(views[1].position, glm::vec3(10, 30, 5));
}

TEST(LightViews, ProjectedTexelRayPassesThroughThePoint) {
  auto views = buildLightViews(testScene(), testBounds());
  Aabb b = testBounds();
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int checked = 0;
  for (const LightView& v : views) {
    for (int i = 0; i < 200; ++i) {
      glm::dvec3 p = glm::mix(glm::dvec3(b.min), glm::dvec3(b.max), glm::dvec3(u(rng), u(rng), u(rng)));
      glm::dvec2 texel;
      glm::dvec3 ndc = project(v, p, &texel);
      if (v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE) {
        // Points outside this view's frustum (behind the light, another cube face) are not its business.
        if (glm::dot(p - glm::dvec3(v.position), p - glm::dvec3(v.position)) > double(v.range) * v.range) continue;
        if (std::abs(ndc.x) > 1.0 || std::abs(ndc.y) > 1.0 || ndc.z < 0.0 || ndc.z > 1.0) continue;
      } else {
        ASSERT_LE(std::abs(ndc.x), 1.0) << v.name;
        ASSERT_LE(std::abs(ndc.y), 1.0) << v.name;
        ASSERT_GT(ndc.z, 0.0) << v.name;
        ASSERT_LT(ndc.z, 1.0) << v.name;
      }
      // The ray through the point's exact texel position passes through it.
      Ray exact = texelRay(v, texel);
      glm::dvec3 start = v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE ? glm::dvec3(v.position) : exact.nearP;
      EXPECT_LT(distanceToLine(p, start, exact.farP), 1e-3) << v.name;
      if (v.encoding == gpu::VS_ENCODING_NDC_DEPTH) {
        // ...and the point lies at the fraction ndc.z of the near-to-far segment (the stored depth).
        glm::dvec3 q = glm::mix(exact.nearP, exact.farP, ndc.z);
        EXPECT_LT(glm::length(q - p), 1e-3) << v.name;
      }
      // The texel-centre ray (what the kernels trace) passes within one texel footprint of it.
      glm::dvec2 centre = glm::floor(texel) + 0.5;
      Ray c = texelRay(v, centre);
      Ray nb = texelRay(v, centre + glm::dvec2(1.0, 0.0));
      bool linear = v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE;
      glm::dvec3 cs = linear ? glm::dvec3(v.position) : c.nearP;
      glm::dvec3 ns = linear ? glm::dvec3(v.position) : nb.nearP;
      double along = glm::length(p - cs) / glm::length(c.farP - cs);
      double footprint = glm::length(glm::mix(ns, nb.farP, along) - glm::mix(cs, c.farP, along));
      EXPECT_LT(distanceToLine(p, cs, c.farP), footprint) << v.name;
      ++checked;
    }
  }
  EXPECT_GT(checked, 500);
}

TEST(LightViews, DirectionalNearBeforeAndFarAfterEveryCorner) {
  for (glm::vec3 dir : {glm::vec3(-0.4f, -1.0f, -0.3f), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0), glm::vec3(0.3f, 0.9f, -0.2f)}) {
    SceneDesc s;
    LightDesc l = shadowed(LightType::Directional, "sun", 512);
    l.direction = glm::normalize(dir);
    s.lights = {l};
    Aabb b = testBounds();
    auto views = buildLightViews(s, b);
    ASSERT_EQ(views.size(), 1u);
    const LightView& v = views[0];
    for (int c = 0; c < 8; ++c) {
      glm::dvec3 corner((c & 1) ? b.max.x : b.min.x, (c & 2) ? b.max.y : b.min.y, (c & 4) ? b.max.z : b.min.z);
      glm::dvec2 texel;
      glm::dvec3 ndc = project(v, corner, &texel);
      EXPECT_GT(ndc.z, 0.0) << "corner " << c << " before the near plane";
      EXPECT_LT(ndc.z, 1.0) << "corner " << c << " after the far plane";
      EXPECT_LT(std::abs(ndc.x), 1.0);
      EXPECT_LT(std::abs(ndc.y), 1.0);
    }
    // Rays travel along the light direction: from the near plane (depth 0) to the far plane (depth 1).
    Ray r = texelRay(v, glm::dvec2(v.resolution / 2.0));
    glm::dvec3 along = glm::normalize(r.farP - r.nearP);
    EXPECT_GT(glm::dot(along, glm::dvec3(l.direction)), 0.9999);
  }
}

TEST(LightViews, EmptyBoundsStillGiveFiniteMatrices) {
  SceneDesc s;
  LightDesc l = shadowed(LightType::Directional, "sun", 64);
  s.lights = {l};
  auto views = buildLightViews(s, Aabb{});
  ASSERT_EQ(views.size(), 1u);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) {
      EXPECT_TRUE(std::isfinite(views[0].trace.viewProj[c][r]));
      EXPECT_TRUE(std::isfinite(views[0].trace.clipToEye[c][r]));
    }
}

TEST(LightViews, CubeFacesCoverEveryDirectionOnce) {
  SceneDesc s = testScene();
  auto all = buildLightViews(s, testBounds());
  std::vector<LightView> faces(all.begin() + 2, all.begin() + 8);
  std::mt19937 rng(4);
  std::normal_distribution<double> g;
  glm::dvec3 pos(faces[0].position);
  for (int i = 0; i < 5000; ++i) {
    glm::dvec3 d(g(rng), g(rng), g(rng));
    if (glm::length(d) < 1e-6) continue;
    d = glm::normalize(d);
    // A point at half range in that direction.
    glm::dvec3 p = pos + d * (0.5 * faces[0].range);
    int inside = 0, which = -1;
    for (int f = 0; f < 6; ++f) {
      glm::dvec2 texel;
      glm::dvec3 ndc = project(faces[f], p, &texel);
      glm::dvec4 clip = glm::dmat4(faces[f].viewProj) * glm::dvec4(p, 1.0);
      // Half-open texel ranges so a direction on a face edge belongs to exactly one face.
      if (clip.w > 0.0 && texel.x >= 0.0 && texel.x < faces[f].resolution && texel.y >= 0.0 &&
          texel.y < faces[f].resolution && ndc.z >= 0.0 && ndc.z <= 1.0) {
        ++inside;
        which = f;
      }
    }
    ASSERT_EQ(inside, 1) << "direction " << d.x << " " << d.y << " " << d.z;
    // GPU cube-map face selection: the major axis and its sign pick the face.
    int axis = std::abs(d.x) >= std::abs(d.y) && std::abs(d.x) >= std::abs(d.z) ? 0 : (std::abs(d.y) >= std::abs(d.z) ? 1 : 2);
    EXPECT_EQ(which, axis * 2 + (d[axis] < 0.0 ? 1 : 0));
  }
}

TEST(LightViews, CubeFacesFollowCubeMapOrientation) {
  // Vulkan cube-map addressing: face +x has s along -z and t along -y; +y has s along +x, t along +z; etc.
  auto all = buildLightViews(testScene(), testBounds());
  const glm::dvec3 sAxis[6] = {{0, 0, -1}, {0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {1, 0, 0}, {-1, 0, 0}};
  const glm::dvec3 tAxis[6] = {{0, -1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {0, -1, 0}, {0, -1, 0}};
  const glm::dvec3 major[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int f = 0; f < 6; ++f) {
    const LightView& v = all[2 + f];
    glm::dvec3 pos(v.position);
    glm::dvec2 t0, ts, tt;
    project(v, pos + major[f] * 10.0, &t0);
    project(v, pos + major[f] * 10.0 + sAxis[f] * 2.0, &ts);
    project(v, pos + major[f] * 10.0 + tAxis[f] * 2.0, &tt);
    EXPECT_NEAR(t0.x, v.resolution / 2.0, 1e-3) << v.name;
    EXPECT_NEAR(t0.y, v.resolution / 2.0, 1e-3) << v.name;
    EXPECT_GT(ts.x, t0.x + 1.0) << v.name << ": column grows along s";
    EXPECT_NEAR(ts.y, t0.y, 1e-3) << v.name;
    EXPECT_GT(tt.y, t0.y + 1.0) << v.name << ": row grows along t";
    EXPECT_NEAR(tt.x, t0.x, 1e-3) << v.name;
  }
}

TEST(LightViews, SpotFrustumContainsTheCone) {
  SceneDesc s = testScene();
  const LightDesc& lamp = s.lights[1];
  auto views = buildLightViews(s, testBounds());
  const LightView& v = views[1];
  glm::dvec3 axis = glm::normalize(glm::dvec3(lamp.direction));
  glm::dvec3 side = glm::normalize(glm::cross(axis, glm::dvec3(0, 0, 1)));
  glm::dvec3 side2 = glm::cross(axis, side);
  double half = glm::radians(double(lamp.outerConeDeg)) * 0.9999;
  double widest = 0.0;
  for (int i = 0; i < 360; ++i) {
    double phi = glm::radians(double(i));
    glm::dvec3 d = std::cos(half) * axis + std::sin(half) * (std::cos(phi) * side + std::sin(phi) * side2);
    for (double dist : {0.01 * lamp.range, 0.5 * lamp.range, 0.999 * lamp.range}) {
      glm::dvec3 p = glm::dvec3(lamp.position) + d * dist;
      glm::dvec2 texel;
      glm::dvec3 ndc = project(v, p, &texel);
      widest = std::max(widest, std::max(std::abs(ndc.x), std::abs(ndc.y)));
      EXPECT_LE(std::abs(ndc.x), 1.0) << i;
      EXPECT_LE(std::abs(ndc.y), 1.0) << i;
      EXPECT_GE(ndc.z, 0.0);
      EXPECT_LE(ndc.z, 1.0);
    }
  }
  // The cone touches the frustum's side planes: the view is no wider than needed.
  EXPECT_NEAR(widest, 1.0, 1e-3);
}

}  // namespace
