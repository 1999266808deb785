// light_views.h: the shadow views of a scene's lights (DESIGN.md §2, §7, §9): one trace layer each.
#ifndef VOXSHADOW_LIGHT_VIEWS_H
#define VOXSHADOW_LIGHT_VIEWS_H

#include <string>
#include <vector>

#include <glm/glm.hpp>

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
  // The world size of one texel: directional views everywhere; spot and point views at unit distance from
  // the light (it grows linearly with the distance).
  double texelWorld = 0.0;
};

// Builds every shadowed light's views, in light order (a light without `shadow` gives none):
// directional with a camera (`camera`, else the scene's own): `cascades` views "<light>.cascade<i>"
// (lighting/cascades.h), up to min(max_distance, the camera's far plane); directional without a camera: one
// orthographic view fitted to worldBounds, its near plane before every caster and far plane after the last; spot: a perspective view of fov 2 * outer cone; point: six 90-degree cube faces laid out as
// GPU cube maps sample them (+x, -x, +y, -y, +z, -z). Preconditions: `scene` as parseSceneJson returns it
// (normalised directions, valid ranges). worldBounds may be empty (a scene without voxels): the directional
// view then covers a unit box at the origin so its matrices stay finite.
std::vector<LightView> buildLightViews(const SceneDesc& scene, const Aabb& worldBounds,
                                      const CameraFrame* camera = nullptr);

// The cube face names in layer order: "+x", "-x", "+y", "-y", "+z", "-z".
extern const char* const kCubeFaceNames[6];

}  // namespace vs

#endif
