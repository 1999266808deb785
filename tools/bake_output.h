// bake_output.h: the baked shadow layers as files: a multi-subimage EXR with its JSON sidecar (DESIGN.md §9)
// and a PNG contact sheet for people to look at.
#ifndef VOXSHADOW_TOOLS_BAKE_OUTPUT_H
#define VOXSHADOW_TOOLS_BAKE_OUTPUT_H

#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json_fwd.hpp>

namespace vs {

// One baked shadow layer with everything a reader needs to use it.
struct BakedView {
  std::string light;       // the light's name
  std::string name;        // the subimage name: <light>, <light>.cascade<i> or <light>.face<+x|-x|...>
  std::string encoding;    // "ndc_depth" | "linear_distance"
  std::string depthPoint;  // "entry" | "voxel_center"
  float range = 0.0f;      // miss value of linear_distance views (also written for ndc_depth views)
  std::optional<glm::vec3> position;  // spot and point views: the light position, where rays start
  glm::mat4 worldToClip{1.0f};
  // The eye of the layer's rays and the view-projection about it, in double (DESIGN.md §6, §9): texel (x, y)'s
  // ray runs from eye + p(0) toward eye + p(1) (NDC depth) or from eye toward eye + p(1) (linear distance),
  // where p(z) unprojects NDC ((x + 0.5) / width * 2 - 1, (y + 0.5) / height * 2 - 1, z) through eyeToClip.
  glm::dvec3 eye{0.0};
  glm::dmat4 eyeToClip{1.0};
  int width = 0;
  int height = 0;
  std::vector<float> texels;  // width * height, row 0 first
  // EVSM (bake --evsm-moments, a light with "filter": "evsm"): the layer's blurred moments (p, p^2, n, n^2) per
  // texel, width * height, row 0 first, and the settings they were made with; empty for other views.
  std::vector<glm::vec4> moments;
  glm::vec2 evsmExponents{0.0f};
  int evsmBlur = 0;
  float lightBleedReduction = 0.0f;
};

// Throws vs::Error(BadInput) describing the first view that breaks the preconditions of the writers below:
// at least one view; names non-empty and unique; encoding and depthPoint one of the values above;
// width, height > 0; texels.size() == width * height; moments empty or width * height.
void validateBakedViews(std::span<const BakedView> views);

// The sidecar path of an EXR: its name with ".json" appended ("out.exr" -> "out.exr.json"), so that it can
// never be a scene file beside it.
std::filesystem::path sidecarPath(const std::filesystem::path& exr);

// The sidecar's content: {"version": 1, "views": [{name, light, encoding, depthPoint, range, position?,
// worldToClip (16 floats, GLM column-major order), eye (3 doubles), eyeToClip (16 doubles, column-major), width,
// height, subimage, and for views with moments evsm {exponents [positive, negative], blur, lightBleedReduction,
// channels}}]}.
nlohmann::json sidecarJson(std::span<const BakedView> views);

// Writes `out` (one EXR subimage per view, channel "Z" as 32-bit float, the voxshadow:* attributes of
// DESIGN.md §9; a view with moments has four more channels "evsm.p", "evsm.p2", "evsm.n", "evsm.n2" and the
// attributes voxshadow:evsmExponents, voxshadow:evsmBlur, voxshadow:lightBleedReduction) and its JSON sidecar. Each data window starts at (0, 0) with the view's size; OpenEXR makes
// all parts share one display window, so it is (0, 0) to the largest width and height among the views
// (equal to every data window when the views have one size). Preconditions: as
// validateBakedViews; out's directory exists and is writable. Both files go to temporaries in the same
// directory and are renamed on success: on failure neither file exists afterwards, nor does any temporary.
// Throws vs::Error (BadInput for bad views, Runtime for I/O failures) naming the file.
void writeShadowExr(const std::filesystem::path& out, std::span<const BakedView> views);

// The longest shadow-file name: its sidecar appends ".json" and must fit the usual 255-byte limit.
inline constexpr std::size_t kMaxShadowFileNameBytes = 250;

// writeShadowExr and, when `preview` is given, the contact sheet (as writeContactSheetPng), committed
// together: the EXR, its sidecar and the preview all change or none does (DESIGN.md §2).
void writeBakeOutputs(const std::filesystem::path& exr, const std::optional<std::filesystem::path>& preview,
                      std::span<const BakedView> views);

// Writes a PNG contact sheet of all views in a grid, each labelled with its name and normalised for
// display (ndc_depth as is, linear_distance / range; near is dark, misses are white), large layers scaled
// down. The sheet is at most 4096 pixels a side whatever the view count (cells shrink, labels go below 64
// pixels); more than 4,194,304 views are refused (BadInput). Preconditions and failure behaviour as writeShadowExr (no sidecar).
void writeContactSheetPng(const std::filesystem::path& out, std::span<const BakedView> views);

}  // namespace vs

#endif
