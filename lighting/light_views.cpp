// light_views.cpp: view-projection matrices of directional, spot and point light shadow views.
#include "lighting/light_views.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <glm/gtc/matrix_transform.hpp>

#include "lighting/cascades.h"

namespace vs {

const char* const kCubeFaceNames[6] = {"+x", "-x", "+y", "-y", "+z", "-z"};

namespace {

// Rays of spot and point views start at the light (DESIGN.md §2); the near plane only has to be positive for
// a perspective matrix and far enough from zero to keep the inverse well conditioned.
constexpr double kNearOverRange = 1e-3;

// Vulkan's framebuffer row 0 is NDC y = -1 (DESIGN.md §9): flipping y puts the light's "up" in row 0, so a
// layer viewed as an image stands upright.
const glm::dmat4 kFlipY = glm::scale(glm::dmat4(1.0), glm::dvec3(1.0, -1.0, 1.0));

glm::dvec3 upFor(const glm::dvec3& forward) {
  return std::abs(forward.y) < 0.99 ? glm::dvec3(0.0, 1.0, 0.0) : glm::dvec3(0.0, 0.0, 1.0);
}

LightView makeView(const LightDesc& light, int lightIndex, const std::string& name, int encoding,
                   const glm::dmat4& viewProj, const glm::dvec3& eye, float range) {
  LightView v;
  v.light = light.name;
  v.name = name;
  v.lightIndex = lightIndex;
  v.resolution = light.shadow->resolution;
  v.encoding = encoding;
  v.depthPoint = light.shadow->depthPoint;
  v.range = range;
  v.position = encoding == gpu::VS_ENCODING_LINEAR_DISTANCE ? light.position : glm::vec3(0.0f);
  v.viewProj = glm::mat4(viewProj);
  v.eye = eye;
  v.eyeToClip = gpu::eyeToClip(viewProj, eye);
  v.trace = gpu::makeTraceView(viewProj, eye, v.resolution, v.resolution, encoding, v.depthPoint, range);
  return v;
}

// The centre of the bounds a directional view covers: the eye of its rays.
glm::dvec3 directionalEye(const Aabb& worldBounds) {
  if (worldBounds.empty()) return glm::dvec3(0.0);
  return (glm::dvec3(worldBounds.min) + glm::dvec3(worldBounds.max)) * 0.5;
}

glm::dmat4 directionalViewProj(const glm::dvec3& forward, const Aabb& worldBounds) {
  glm::dvec3 lo(-0.5), hi(0.5);
  if (!worldBounds.empty()) {
    lo = glm::dvec3(worldBounds.min);
    hi = glm::dvec3(worldBounds.max);
  }
  glm::dvec3 center = (lo + hi) * 0.5;
  glm::dmat4 view = glm::lookAtRH(center, center + forward, upFor(forward));
  glm::dvec3 vmin(std::numeric_limits<double>::infinity()), vmax(-std::numeric_limits<double>::infinity());
  for (int c = 0; c < 8; ++c) {
    glm::dvec3 corner((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
    glm::dvec3 p = glm::dvec3(view * glm::dvec4(corner, 1.0));
    vmin = glm::min(vmin, p);
    vmax = glm::max(vmax, p);
  }
  // A margin relative to the scene's size keeps casters on the bounds strictly inside the view after float
  // rounding; a scene shrunk to a point still gets a non-degenerate box.
  double size = std::max(glm::length(hi - lo), glm::length(center));
  double pad = 1e-3 * (size > 0.0 ? size : 1.0);
  // The view looks down -z: the distance along the light is -z.
  double nearDist = -vmax.z - pad, farDist = -vmin.z + pad;
  glm::dmat4 proj = glm::orthoRH_ZO(vmin.x - pad, vmax.x + pad, vmin.y - pad, vmax.y + pad, nearDist, farDist);
  return kFlipY * proj * view;
}

}  // namespace

std::vector<LightView> buildLightViews(const SceneDesc& scene, const Aabb& worldBounds, const CameraFrame* camera) {
  std::optional<CameraFrame> sceneCamera;
  if (!camera && scene.camera) camera = &sceneCamera.emplace(cameraFrame(*scene.camera));
  std::vector<LightView> views;
  for (std::size_t li = 0; li < scene.lights.size(); ++li) {
    const LightDesc& light = scene.lights[li];
    if (!light.shadow || !light.enabled) continue;
    const int index = int(li);
    const glm::dvec3 position(light.position);
    const double range = light.range;
    switch (light.type) {
      case LightType::Directional: {
        glm::dvec3 forward = glm::normalize(glm::dvec3(light.direction));
        if (camera) {
          const double farPlane = std::min(double(light.shadow->maxDistance), camera->farPlane);
          const double nearPlane = std::min(camera->nearPlane, 0.5 * farPlane);
          const std::vector<double> splits =
              cascadeSplits(nearPlane, farPlane, light.shadow->cascades, light.shadow->lambda);
          for (int c = 0; c < light.shadow->cascades; ++c) {
            const CascadeFit fit = fitCascade(*camera, splits[std::size_t(c)], splits[std::size_t(c) + 1], forward,
                                              light.shadow->resolution, worldBounds);
            LightView v = makeView(light, index, light.name + ".cascade" + std::to_string(c),
                                   gpu::VS_ENCODING_NDC_DEPTH, fit.worldToClip, fit.eye, 1.0f);
            v.cascade = c;
            v.splitNear = splits[std::size_t(c)];
            v.splitFar = splits[std::size_t(c) + 1];
            v.texelWorld = fit.texelWorld;
            v.gridBasis = fit.basis;
            v.gridNear = fit.nearDist;
            v.gridFar = fit.farDist;
            v.windowOrigin = fit.windowOrigin;
            views.push_back(std::move(v));
          }
          break;
        }
        const glm::dmat4 viewProj = directionalViewProj(forward, worldBounds);
        views.push_back(makeView(light, index, light.name, gpu::VS_ENCODING_NDC_DEPTH, viewProj,
                                 directionalEye(worldBounds), 1.0f));
        // The larger of the two texel sides (the fit is not square in world units).
        const glm::dmat4 inv = glm::inverse(viewProj);
        auto world = [&](double x, double y) {
          glm::dvec4 p = inv * glm::dvec4(x, y, 0.0, 1.0);
          return glm::dvec3(p) / p.w;
        };
        views.back().texelWorld = std::max(glm::length(world(1, -1) - world(-1, -1)),
                                           glm::length(world(-1, 1) - world(-1, -1))) /
                                  double(light.shadow->resolution);
        break;
      }
      case LightType::Spot: {
        glm::dvec3 forward = glm::normalize(glm::dvec3(light.direction));
        glm::dmat4 view = glm::lookAtRH(position, position + forward, upFor(forward));
        // fov 2 * outer: the cone is inscribed in the square frustum.
        glm::dmat4 proj = glm::perspectiveRH_ZO(glm::radians(2.0 * double(light.outerConeDeg)), 1.0,
                                                range * kNearOverRange, range);
        views.push_back(makeView(light, index, light.name, gpu::VS_ENCODING_LINEAR_DISTANCE, kFlipY * proj * view,
                                 position, light.range));
        views.back().texelWorld = 2.0 * std::tan(glm::radians(double(light.outerConeDeg))) / double(light.shadow->resolution);
        break;
      }
      case LightType::Point: {
        // GPU cube-map layout (Vulkan spec, cube map face selection): face +x maps s to -z and t to -y, and so
        // on. With column = s * width and row = t * height, NDC x must grow along `sAxis` and NDC y along
        // `tAxis`; lookAt with up = tAxis gives exactly that (its right axis is forward x up = sAxis).
        static const glm::dvec3 kForward[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        static const glm::dvec3 kTAxis[6] = {{0, -1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {0, -1, 0}, {0, -1, 0}};
        glm::dmat4 proj = glm::perspectiveRH_ZO(glm::radians(90.0), 1.0, range * kNearOverRange, range);
        for (int f = 0; f < 6; ++f) {
          glm::dmat4 view = glm::lookAtRH(position, position + kForward[f], kTAxis[f]);
          views.push_back(makeView(light, index, light.name + ".face" + kCubeFaceNames[f],
                                   gpu::VS_ENCODING_LINEAR_DISTANCE, proj * view, position, light.range));
          views.back().texelWorld = 2.0 / double(light.shadow->resolution);
        }
        break;
      }
    }
  }
  return views;
}

bool sameGrid(const LightView& a, const LightView& b) {
  return a.lightIndex == b.lightIndex && a.cascade == b.cascade && a.resolution == b.resolution &&
         a.encoding == b.encoding && a.depthPoint == b.depthPoint && a.texelWorld == b.texelWorld &&
         a.gridNear == b.gridNear && a.gridFar == b.gridFar && a.gridBasis == b.gridBasis;
}

namespace {

std::int64_t floorMod(std::int64_t a, std::int64_t n) { return ((a % n) + n) % n; }

int pageSide(const LightView& view) { return std::min(view.resolution, kCascadePageTexels); }

// The trace record of page (px, py) of a cascade grid. Its eye-relative projection is the same for every page
// (an orthographic box of one page about the centre of its near plane), built from the grid's constants
// alone; only the eye moves, placed in double.
gpu::TraceView pageView(const LightView& view, std::int64_t px, std::int64_t py) {
  const int side = pageSide(view);
  const double tw = view.texelWorld;
  const double half = 0.5 * double(side) * tw;
  const double depth = view.gridFar - view.gridNear;
  const glm::dmat4 rotation(view.gridBasis);
  const glm::dmat4 eyeToClip = kFlipY * glm::orthoRH_ZO(-half, half, -half, half, 0.0, depth) * rotation;
  const glm::dvec3 centre((double(px * side) + 0.5 * double(side)) * tw, -(double(py * side) + 0.5 * double(side)) * tw,
                          -view.gridNear);
  const glm::dvec3 eye = glm::transpose(view.gridBasis) * centre;
  gpu::TraceView t{};
  glm::dmat4 fromEye(1.0);
  fromEye[3] = glm::dvec4(-eye, 1.0);
  t.viewProj = glm::mat4(eyeToClip * fromEye);
  t.clipToEye = glm::mat4(glm::inverse(eyeToClip));
  glm::vec3 high, low;
  gpu::splitToFloats(eye, high, low);
  t.eyeHigh = glm::vec4(high, view.range);
  t.eyeLow = glm::vec4(low, 0.0f);
  t.rect = glm::ivec4(0, 0, side, side);
  t.info = glm::ivec4(side, side, view.encoding, view.depthPoint);
  return t;
}

std::int64_t floorDiv(std::int64_t a, std::int64_t n) { return a >= 0 ? a / n : -((-a + n - 1) / n); }

}  // namespace

glm::ivec2 ringOffset(const LightView& view) {
  if (!isRingView(view)) return glm::ivec2(0);
  return glm::ivec2(int(floorMod(view.windowOrigin.x, view.resolution)), int(floorMod(view.windowOrigin.y, view.resolution)));
}

TexelRect windowRect(const LightView& view) {
  return {view.windowOrigin.x, view.windowOrigin.y, view.windowOrigin.x + view.resolution,
          view.windowOrigin.y + view.resolution};
}

std::vector<LayerTrace> layerTraces(const LightView& view, const TexelRect& rect) {
  const TexelRect w = windowRect(view);
  const TexelRect r{std::max(rect.x0, w.x0), std::max(rect.y0, w.y0), std::min(rect.x1, w.x1), std::min(rect.y1, w.y1)};
  std::vector<LayerTrace> out;
  if (r.empty()) return out;
  if (!isRingView(view)) {
    LayerTrace t;
    t.view = view.trace;
    t.view.rect = glm::ivec4(int(r.x0), int(r.y0), int(r.x1), int(r.y1));
    out.push_back(t);
    return out;
  }
  const std::int64_t side = pageSide(view);
  for (std::int64_t py = floorDiv(r.y0, side); py * side < r.y1; ++py)
    for (std::int64_t px = floorDiv(r.x0, side); px * side < r.x1; ++px) {
      LayerTrace t;
      t.view = pageView(view, px, py);
      const std::int64_t x0 = std::max(r.x0, px * side), x1 = std::min(r.x1, (px + 1) * side);
      const std::int64_t y0 = std::max(r.y0, py * side), y1 = std::min(r.y1, (py + 1) * side);
      t.view.rect = glm::ivec4(int(x0 - px * side), int(y0 - py * side), int(x1 - px * side), int(y1 - py * side));
      // Pages tile the ring: the resolution is a multiple of the page side, so a page never wraps.
      t.storeOrigin = glm::ivec2(int(floorMod(px * side, view.resolution)), int(floorMod(py * side, view.resolution)));
      out.push_back(t);
    }
  return out;
}

std::vector<float> windowTexels(const LightView& view, std::span<const float> stored) {
  const int n = view.resolution;
  std::vector<float> out(std::size_t(n) * std::size_t(n));
  const glm::ivec2 o = ringOffset(view);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      out[std::size_t(y) * std::size_t(n) + std::size_t(x)] =
          stored[std::size_t((y + o.y) % n) * std::size_t(n) + std::size_t((x + o.x) % n)];
  return out;
}

}  // namespace vs
