// light_views.h: the shadow views of a scene's lights (DESIGN.md §2, §7, §9): one trace layer each.
#ifndef VOXSHADOW_LIGHT_VIEWS_H
#define VOXSHADOW_LIGHT_VIEWS_H

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/type_precision.hpp>

#include "bvh/bvh.h"
#include "compute/shared/trace_view.h"
#include "lighting/camera.h"
#include "lighting/scene_file.h"

namespace vs {

struct LightView {
  std::string light;    // the light's name
  std::string name;     // the layer's name: "<light>", "<light>.cascade<i>" or "<light>.face<+x|-x|+y|-y|+z|-z>"
  int lightIndex = 0;   // into SceneDesc::lights
  int resolution = 0;   // width = height, texels
  int encoding = 0;     // VS_ENCODING_NDC_DEPTH (directional) or VS_ENCODING_LINEAR_DISTANCE (spot, point)
  int depthPoint = 0;   // VS_DEPTH_POINT_*
  float range = 1.0f;   // the miss value: 1 for NDC depth views, the light's range for linear distance views
  glm::vec3 position{0.0f};  // spot and point: where rays start
  glm::mat4 viewProj{1.0f};  // world -> Vulkan clip space; texel column (ndc.x*0.5+0.5)*w, row (ndc.y*0.5+0.5)*h
  // The eye of the view's rays (spot, point: the light; directional: the centre of the scene bounds) and the
  // view-projection about it (clip = eyeToClip * (p - eye)), both in double: every texel's ray is rebuilt from
  // them at full precision (DESIGN.md §6, §9).
  glm::dvec3 eye{0.0};
  glm::dmat4 eyeToClip{1.0};
  gpu::TraceView trace{};    // the record the trace kernels read (the whole view as its rectangle)
  // Cascades: the index (-1 for every other view) and the camera view depths it covers.
  int cascade = -1;
  double splitNear = 0.0, splitFar = 0.0;
  // Cascades: the world-fixed texel grid the layer is a ring over (DESIGN.md §11; CascadeFit in
  // lighting/cascades.h): the layer stores global texel (gx, gy) at (gx mod resolution, gy mod resolution),
  // and the view's matrices describe the window of it that starts at global texel windowOrigin. Texels are
  // traced through cascadePageViews, never through `trace`, so a texel's ray is a function of its global
  // coordinates alone and does not change as the window scrolls. Other views: basis unused, origin 0.
  glm::dmat3 gridBasis{1.0};
  double gridNear = 0.0, gridFar = 0.0;
  glm::i64vec2 windowOrigin{0};
  // The world size of one texel: directional views everywhere; spot and point views at unit distance from
  // the light (it grows linearly with the distance).
  double texelWorld = 0.0;
};

// Builds every shadowed light's views, in light order (a light without `shadow`, or disabled, gives none):
// directional with a camera (`camera`, else the scene's own): `cascades` views "<light>.cascade<i>"
// (lighting/cascades.h), up to min(max_distance, the camera's far plane); directional without a camera: one
// orthographic view fitted to worldBounds, its near plane before every caster and far plane after the last; spot: a perspective view of fov 2 * outer cone; point: six 90-degree cube faces laid out as
// GPU cube maps sample them (+x, -x, +y, -y, +z, -z). Preconditions: `scene` as parseSceneJson returns it
// (normalised directions, valid ranges). worldBounds may be empty (a scene without voxels): the directional
// view then covers a unit box at the origin so its matrices stay finite.
std::vector<LightView> buildLightViews(const SceneDesc& scene, const Aabb& worldBounds,
                                      const CameraFrame* camera = nullptr);

// Whether the layer of `view` is a ring over a world-fixed grid (a cascade) rather than the view itself.
inline bool isRingView(const LightView& view) { return view.cascade >= 0; }

// Two cascades share their grid (basis, texel size, depth range, resolution and depth point, bit for bit):
// a layer traced for one holds for the other wherever their windows overlap.
bool sameGrid(const LightView& a, const LightView& b);

// Where window texel (0, 0) of a ring view is stored: windowOrigin mod resolution (0 for other views).
glm::ivec2 ringOffset(const LightView& view);

// A rectangle of global texels (a ring view's grid; for other views, the view's own texels), [x0, x1) x [y0, y1).
struct TexelRect {
  std::int64_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  std::int64_t area() const { return empty() ? 0 : (x1 - x0) * (y1 - y0); }
};

// Texels of a cascade grid are traced in pages of this many texels a side (or the whole layer when it is
// smaller): each page is a view of its own whose eye, the centre of the page's near plane, the host places in
// double, so that a texel's ray is that eye plus an offset of less than a page, exact however far from the
// origin the page lies. A page is also the unit of one trace dispatch: larger pages, fewer dispatches.
constexpr int kCascadePageTexels = 256;

// One piece of a traced rectangle: the view to trace (a cascade page, or the whole spot/point view) with its
// rect set, and where its texel (0, 0) is stored in the layer.
struct LayerTrace {
  gpu::TraceView view{};
  glm::ivec2 storeOrigin{0};
};

// The pieces that trace rectangle `rect` of `view`'s layer: for a ring view, its part inside the window, cut
// at page boundaries (global texel coordinates); for other views, the rect clipped to the view.
std::vector<LayerTrace> layerTraces(const LightView& view, const TexelRect& rect);

// The window of a view in its layer's texel coordinates (global texels for ring views).
TexelRect windowRect(const LightView& view);

// A layer as stored (ring order for cascades) copied into window order, row 0 first: what a bake writes.
std::vector<float> windowTexels(const LightView& view, std::span<const float> stored);

// The cube face names in layer order: "+x", "-x", "+y", "-y", "+z", "-z".
extern const char* const kCubeFaceNames[6];

}  // namespace vs

#endif
