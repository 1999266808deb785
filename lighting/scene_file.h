// scene_file.h: the JSON scene file, version 1 (DESIGN.md §8), parsed and strictly validated.
#ifndef VOXSHADOW_SCENE_FILE_H
#define VOXSHADOW_SCENE_FILE_H

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace vs {

struct AssetDesc {
  std::string name;                 // the key under "assets"
  std::filesystem::path file;       // resolved against the scene file's directory; exists at parse time
  std::string grid;                 // name or decimal index as vs::LoadOptions::grid takes it; empty: automatic
  float densityThreshold = 0.0f;
  glm::vec3 color{0.8f, 0.8f, 0.8f};
  // .vox assets (file name ending in .vox, any case) take these instead of grid, density_threshold, color.
  bool vox = false;
  double voxelSize = 1.0;  // world units per voxel, > 0
  std::string model;       // vs::VoxAssetOptions::model: empty, a decimal index or a shape name
  int frame = 0;           // animation frame, >= 0
};

struct InstanceDesc {
  std::string asset;
  std::size_t assetIndex = 0;  // into SceneDesc::assets
  glm::dmat4 transform{1.0};   // object (asset world) -> scene world; affine and invertible
};

struct CameraDesc {
  glm::vec3 position{0.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fovDeg = 60.0f;
  float nearPlane = 0.1f;
  float farPlane = 1000.0f;
  int width = 1280;
  int height = 720;
};

struct AmbientDesc {
  glm::vec3 color{1.0f, 1.0f, 1.0f};
  float intensity = 0.2f;
};

enum class LightType { Directional, Spot, Point };
enum class ShadowFilter { Hard, Pcf3, Pcf5, Poisson16, Pcss, Evsm };

const char* lightTypeName(LightType type);
const char* shadowFilterName(ShadowFilter filter);

// The largest EVSM warp exponent: a moment reaches e^(2c) and a blur sums 2 * kMaxEvsmBlur + 1 of them before it
// scales, so 33 * e^84 (about 1.0e38) stays below FLT_MAX (3.4e38); on the small side e^(-84) (3.3e-37) stays a
// normal float, which a GPU that flushes denormals keeps as the CPU does.
inline constexpr float kMaxEvsmExponent = 42.0f;
inline constexpr int kMaxEvsmBlur = 16;

struct ShadowDesc {
  int resolution = 1024;    // power of two, 16..16384
  int cascades = 3;         // 1..4; directional lights only (others keep the default, unused)
  float lambda = 0.7f;      // split blend: 0 uniform, 1 logarithmic
  float maxDistance = 1000.0f;  // default: the camera's far plane
  ShadowFilter filter = ShadowFilter::Pcf3;
  float depthBias = 0.0f;   // world units
  // Layers of entry depths are compared at each texel's own ray against the receiver's plane, which a voxel
  // face is exactly (lighting/shared/shading.h), so the biases cover rounding and concave corners, not the
  // depth slope across a texel. Texels along the surface normal: moves the plane off the face.
  float normalBias = 0.5f;
  // Texels along the light, divided by max(N.L, 0.05): where a texel's ray meets the receiver's plane just
  // past a concave corner, inside the solid, the neighbouring face stands in front of it by an amount that
  // grows as the receiver turns from the light.
  float slopeBias = 0.5f;
  // pcss: the emitter's diameter in world units (a directional light's emitter lies on its view's near plane).
  float lightSize = 0.5f;
  // World length of the exact visibility ray toward the light that multiplies into the shadow-map term
  // (0: off). It restores the contact that depth biases take away.
  float contactShadow = 0.0f;
  // Cascades: the far share of each cascade's depth range over which it blends into the next (the last one
  // fades to lit), 0..0.5.
  float cascadeBlend = 0.1f;
  // evsm (lighting/shared/evsm.h): the exponents of the positive and negative warps of the depth (mapped to
  // [-1, 1] over the layer's depth range), each 1..kMaxEvsmExponent; the box blur's radius in texels
  // (0..kMaxEvsmBlur); and the light-bleeding reduction, the share of the Chebyshev bound cut away (0..1).
  float evsmPositiveExponent = 40.0f;
  float evsmNegativeExponent = 8.0f;
  int evsmBlur = 1;
  float lightBleedReduction = 0.2f;
  int depthPoint = 0;       // VS_DEPTH_POINT_ENTRY or VS_DEPTH_POINT_VOXEL_CENTER (compute/shared/trace_view.h)
};

struct LightDesc {
  std::string name;  // unique in the scene; default "light<i>"
  LightType type = LightType::Directional;
  glm::vec3 direction{0.0f, -1.0f, 0.0f};  // normalised; directional and spot: where the light travels
  glm::vec3 position{0.0f};                // spot and point
  float range = 0.0f;                      // spot and point: > 0
  float innerConeDeg = 0.0f;               // spot: 0 <= inner <= outer
  float outerConeDeg = 0.0f;               // spot: 0 < outer < 90
  glm::vec3 color{1.0f, 1.0f, 1.0f};
  float intensity = 1.0f;
  std::optional<ShadowDesc> shadow;  // absent: the light casts no shadow
  bool enabled = true;  // a disabled light lights nothing and traces nothing (Scene::setLightEnabled)
};

struct SceneDesc {
  std::filesystem::path file;  // the scene file as given
  int version = 1;
  std::vector<AssetDesc> assets;  // in file order
  std::vector<InstanceDesc> instances;
  std::optional<CameraDesc> camera;
  AmbientDesc ambient;
  std::vector<LightDesc> lights;
};

// Reads and parses a scene file. Preconditions: none; a missing, unreadable or non-regular file, or one larger
// than limits::kMaxSceneFileBytes, is vs::Error(BadInput), and so is every problem parseSceneJson reports.
SceneDesc parseSceneFile(const std::filesystem::path& file);

// Parses scene JSON text. `file` names the source in messages ("<file>: <json path>: <problem>") and its
// directory resolves relative asset paths. Every asset file must exist. Throws vs::Error(BadInput) on the
// first problem: syntax (with line and column), unknown keys, wrong types, missing required keys, values
// out of range (voxel/valid_range.h), non-finite numbers or numbers beyond float range, singular
// transforms, unknown assets/filters/depth points, duplicate keys (duplicate asset names among them), NUL
// characters in keys or strings, duplicate light or layer names, a missing or unsupported version.
SceneDesc parseSceneJson(const std::string& text, const std::filesystem::path& file);

// Checks a camera as the scene file's "camera" is checked: positions within limits::kMaxCoordinate, target
// apart from position, up non-zero and not parallel to the view, 0 < fov_deg < 180, 0 < near < far <=
// limits::kMaxDistance, sizes 1..limits::kMaxImageSide. Throws vs::Error(BadInput) "<where>.<field>: <problem>".
void checkCamera(const CameraDesc& camera, const std::string& where);

// Why `file` cannot be read as an input ("no such file", "is a directory, not a file", "is a FIFO, ...");
// empty for a regular file (symlinks followed). Inputs are only ever read from regular files, so that a
// FIFO or a device can neither hang a command nor feed it without end.
std::string fileKindProblem(const std::filesystem::path& file);

}  // namespace vs

#endif
