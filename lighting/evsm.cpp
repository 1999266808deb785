// evsm.cpp: moment rectangles into jobs, the cube faces' border maps, and the moment pass on the CPU.
#include "lighting/evsm.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

#include "lighting/shared/evsm.h"
#include "voxel/error.h"

namespace vs {

namespace gpu {

// lighting/shared/evsm_pass.h compiled as members of a struct whose members carry the buffers' names.
struct CpuMomentPass {
  const float* shadowTexels;
  const EvsmView* evsmViews;
  const EvsmJob* evsmJobs;
  const int* evsmBorder;
  vec4* scratch;
  vec4* moments;
  vec4 vsLoadScratch(int i) const { return scratch[i]; }
  void vsStoreScratch(int i, vec4 m) { scratch[i] = m; }
  void vsStoreMoments(int i, vec4 m) { moments[i] = m; }
#include "lighting/shared/evsm_pass.h"
};

}  // namespace gpu

namespace {

// The border map of cube face `face` (evsm_pass.h's layout): for each texel within r past its edges, the layer
// store index of the texel that holds the same direction, found in double: the texel centre's direction
// unprojected through the face's view, then projected into each face of the light and taken from the one it
// lies deepest inside, nearest texel.
void appendBorder(std::span<const LightView> views, const ShadeInputs& inputs, std::size_t face, int r,
                  std::vector<std::int32_t>& border) {
  const LightView& f = views[face];
  const int n = f.resolution;
  const glm::dmat4 clipToEye = glm::inverse(f.eyeToClip);
  std::vector<std::size_t> faces;
  for (std::size_t i = 0; i < views.size(); ++i)
    if (views[i].lightIndex == f.lightIndex) faces.push_back(i);
  auto entry = [&](int x, int y) {
    const glm::dvec2 ndc((x + 0.5) / n * 2.0 - 1.0, (y + 0.5) / n * 2.0 - 1.0);
    const glm::dvec4 far = clipToEye * glm::dvec4(ndc, 1.0, 1.0);
    const glm::dvec3 world = f.eye + glm::dvec3(far) / far.w;
    double best = std::numeric_limits<double>::infinity();
    std::int32_t at = 0;
    for (std::size_t g : faces) {
      const LightView& v = views[g];
      const glm::dvec4 clip = v.eyeToClip * glm::dvec4(world - v.eye, 1.0);
      if (!(clip.w > 0.0)) continue;
      const glm::dvec2 q = glm::dvec2(clip) / clip.w;
      const double depth = std::max(std::abs(q.x), std::abs(q.y));
      if (depth >= best) continue;
      best = depth;
      const int m = v.resolution;
      const int tx = std::clamp(int(std::floor((q.x * 0.5 + 0.5) * m)), 0, m - 1);
      const int ty = std::clamp(int(std::floor((q.y * 0.5 + 0.5) * m)), 0, m - 1);
      at = std::int32_t(inputs.views[g].info.x + ty * m + tx);
    }
    border.push_back(at);
  };
  for (int y = -r; y < 0; ++y)
    for (int x = -r; x < n + r; ++x) entry(x, y);
  for (int y = n; y < n + r; ++y)
    for (int x = -r; x < n + r; ++x) entry(x, y);
  for (int y = 0; y < n; ++y) {
    for (int x = -r; x < 0; ++x) entry(x, y);
    for (int x = n; x < n + r; ++x) entry(x, y);
  }
}

}  // namespace

std::vector<MomentRect> wholeMomentRects(const ShadeInputs& inputs) {
  std::vector<MomentRect> rects;
  for (std::size_t i = 0; i < inputs.views.size(); ++i)
    if (hasMoments(inputs, i)) rects.push_back({int(i), 0, 0, inputs.views[i].info.y, inputs.views[i].info.y});
  return rects;
}

MomentWork momentWork(std::span<const LightView> views, const ShadeInputs& inputs, std::span<const MomentRect> rects) {
  if (views.size() != inputs.views.size()) throwBadInput("EVSM: the views and their records differ in number");
  MomentWork work;
  work.views.resize(views.size());
  std::vector<bool> borderNeeded(views.size(), false);
  for (const MomentRect& m : rects) {
    if (m.view < 0 || std::size_t(m.view) >= views.size() || !hasMoments(inputs, std::size_t(m.view)))
      throwBadInput("EVSM: a moment rectangle names view " + std::to_string(m.view) + ", which has no moments");
    const int n = views[std::size_t(m.view)].resolution;
    if (m.x0 < 0 || m.y0 < 0 || m.x1 > n || m.y1 > n)
      throwBadInput("EVSM: a moment rectangle of " + views[std::size_t(m.view)].name + " reaches outside its window");
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    const gpu::ShadeView& sv = inputs.views[i];
    gpu::EvsmView& ev = work.views[i];
    if (sv.trace.w < 0) {
      ev.layer = glm::ivec4(sv.info.x, sv.info.y, -1, 0);
      ev.place = glm::ivec4(0, 0, -1, 0);
      continue;
    }
    const gpu::ShadeLight& light = inputs.lights[std::size_t(views[i].lightIndex)];
    const int r = int(light.evsm.w);
    ev.layer = glm::ivec4(sv.info.x, sv.info.y, sv.trace.w, r);
    ev.place = glm::ivec4(sv.trace.y, sv.trace.z, -1, 0);
    ev.warp = glm::vec4(light.evsm.x, light.evsm.y, sv.eyeLow.w, float(1.0 / double(2 * r + 1)));
    for (const MomentRect& m : rects)
      if (std::size_t(m.view) == i && light.info.x == gpu::VS_LIGHT_POINT && r > 0) borderNeeded[i] = true;
  }
  for (std::size_t i = 0; i < views.size(); ++i)
    if (borderNeeded[i]) {
      work.views[i].place.z = int(work.border.size());
      appendBorder(views, inputs, i, work.views[i].layer.w, work.border);
    }
  std::uint64_t horizontal = 0, vertical = 0;
  for (const MomentRect& m : rects) {
    if (m.x1 <= m.x0 || m.y1 <= m.y0) continue;
    const int r = work.views[std::size_t(m.view)].layer.w;
    gpu::EvsmJob job{};
    job.rect = glm::ivec4(m.x0, m.y0, m.x1, m.y1);
    job.info = glm::ivec4(m.view, int(horizontal), int(vertical), int(horizontal));
    const std::uint64_t width = std::uint64_t(m.x1 - m.x0);
    horizontal += width * std::uint64_t(m.y1 - m.y0 + 2 * r);
    vertical += width * std::uint64_t(m.y1 - m.y0);
    if (horizontal > std::uint64_t(INT_MAX))
      throwRuntime("EVSM: a moment pass over " + std::to_string(horizontal) +
                   " texels exceeds 2^31 - 1; use smaller layers or fewer EVSM lights");
    work.jobs.push_back(job);
  }
  work.horizontal = std::size_t(horizontal);
  work.vertical = std::size_t(vertical);
  work.scratchTexels = std::size_t(horizontal);
  return work;
}

void computeMomentsOnCpu(const ShadeInputs& inputs, const MomentWork& work, std::vector<glm::vec4>& moments) {
  if (moments.size() != inputs.momentTexels) moments.resize(inputs.momentTexels, glm::vec4(0.0f));
  if (work.empty()) return;
  std::vector<glm::vec4> scratch(work.scratchTexels);
  gpu::CpuMomentPass pass{inputs.shadowTexels.data(), work.views.data(), work.jobs.data(), work.border.data(),
                          scratch.data(), moments.data()};
  const int jobs = int(work.jobs.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, work.horizontal, 4096), [&](const tbb::blocked_range<std::size_t>& b) {
    for (std::size_t i = b.begin(); i < b.end(); ++i) pass.vsEvsmHorizontal(int(i), jobs);
  });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, work.vertical, 4096), [&](const tbb::blocked_range<std::size_t>& b) {
    for (std::size_t i = b.begin(); i < b.end(); ++i) pass.vsEvsmVertical(int(i), jobs);
  });
}

std::vector<glm::vec4> windowMoments(const LightView& view, std::span<const glm::vec4> stored) {
  const int n = view.resolution;
  const glm::ivec2 ring = ringOffset(view);
  std::vector<glm::vec4> out(std::size_t(n) * std::size_t(n));
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      out[std::size_t(y) * std::size_t(n) + std::size_t(x)] =
          stored[std::size_t((y + ring.y) & (n - 1)) * std::size_t(n) + std::size_t((x + ring.x) & (n - 1))];
  return out;
}

}  // namespace vs
