// scene_file.cpp: strict parser of the JSON scene file, version 1 (DESIGN.md §8).
#include "lighting/scene_file.h"

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "compute/shared/trace_view.h"
#include "voxel/error.h"
#include "voxel/valid_range.h"
#include "voxel/vox_reader.h"

namespace vs {

const char* lightTypeName(LightType type) {
  switch (type) {
    case LightType::Directional: return "directional";
    case LightType::Spot: return "spot";
    case LightType::Point: return "point";
  }
  return "?";
}

const char* shadowFilterName(ShadowFilter filter) {
  switch (filter) {
    case ShadowFilter::Hard: return "hard";
    case ShadowFilter::Pcf3: return "pcf3";
    case ShadowFilter::Pcf5: return "pcf5";
    case ShadowFilter::Poisson16: return "poisson16";
    case ShadowFilter::Pcss: return "pcss";
    case ShadowFilter::Evsm: return "evsm";
  }
  return "?";
}

namespace {

// ordered_json keeps the file's key order, so assets are indexed (and errors reported) in file order.
using Json = nlohmann::ordered_json;

constexpr const char* kRoot = "(top level)";

std::string typeName(const Json& j) {
  if (j.is_null()) return "null";
  if (j.is_boolean()) return "a boolean";
  if (j.is_number()) return "a number";
  if (j.is_string()) return "a string";
  if (j.is_array()) return "an array";
  return "an object";
}

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

class Parser {
 public:
  Parser(const std::filesystem::path& file) : file_(file) {}

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throwBadInput(file_.string() + ": " + (path.empty() ? kRoot : path) + ": " + what);
  }

  static std::string key(const std::string& path, const std::string& k) { return path.empty() ? k : path + "." + k; }
  static std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

  void requireObject(const Json& j, const std::string& path) const {
    if (!j.is_object()) fail(path, "must be an object, not " + typeName(j));
  }

  void checkKeys(const Json& j, const std::string& path, std::initializer_list<const char*> allowed,
                 const std::string& context = "") const {
    for (auto it = j.begin(); it != j.end(); ++it) {
      bool known = false;
      for (const char* a : allowed) known = known || it.key() == a;
      if (!known) {
        std::string expected;
        for (const char* a : allowed) expected += std::string(expected.empty() ? "" : ", ") + a;
        fail(key(path, it.key()), "unknown key" + context + " (expected one of: " + expected + ")");
      }
    }
  }

  const Json& required(const Json& obj, const std::string& path, const char* k) const {
    auto it = obj.find(k);
    if (it == obj.end()) fail(key(path, k), "missing required key");
    return *it;
  }

  double number(const Json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, "must be a number, not " + typeName(j));
    double v = j.get<double>();
    if (!std::isfinite(v)) fail(path, "must be a finite number");
    // Every number ends up as a float somewhere; one that rounds to infinity there is refused here.
    if (std::abs(v) > double(FLT_MAX)) fail(path, "must be a finite 32-bit float (magnitude at most 3.4e38), not " + fmt(v));
    return v;
  }

  double inRange(double v, const std::string& path, double lo, double hi, const char* what) const {
    if (!(v >= lo && v <= hi)) fail(path, std::string(what) + " must be between " + fmt(lo) + " and " + fmt(hi) + ", not " + fmt(v));
    return v;
  }

  // A world position: each component within the valid coordinate range (voxel/valid_range.h).
  glm::dvec3 position(const Json& j, const std::string& path) const {
    glm::dvec3 p = vec3(j, path);
    for (int a = 0; a < 3; ++a) inRange(p[a], index(path, std::size_t(a)), -limits::kMaxCoordinate, limits::kMaxCoordinate, "a coordinate");
    return p;
  }

  float distance(const Json& j, const std::string& path) const {
    float v = positive(j, path);
    if (v > limits::kMaxDistance) fail(path, "must be at most " + fmt(limits::kMaxDistance) + ", not " + fmt(v));
    return v;
  }

  float number(const Json& obj, const std::string& path, const char* k, float fallback) const {
    auto it = obj.find(k);
    return it == obj.end() ? fallback : float(number(*it, key(path, k)));
  }

  int integer(const Json& j, const std::string& path) const {
    double v = number(j, path);
    if (v != std::floor(v) || std::abs(v) > 2147483647.0) fail(path, "must be an integer, not " + fmt(v));
    return int(v);
  }

  std::string string(const Json& j, const std::string& path) const {
    if (!j.is_string()) fail(path, "must be a string, not " + typeName(j));
    return j.get<std::string>();
  }

  glm::dvec3 vec3(const Json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) fail(path, "must be an array of 3 numbers");
    return {number(j[0], index(path, 0)), number(j[1], index(path, 1)), number(j[2], index(path, 2))};
  }

  glm::vec3 vec3(const Json& obj, const std::string& path, const char* k, glm::vec3 fallback) const {
    auto it = obj.find(k);
    return it == obj.end() ? fallback : glm::vec3(vec3(*it, key(path, k)));
  }

  glm::vec3 direction(const Json& j, const std::string& path) const {
    glm::dvec3 d = vec3(j, path);
    double len = glm::length(d);
    if (!(len > 0.0) || !std::isfinite(len)) fail(path, "must be a non-zero vector");
    return glm::vec3(d / len);
  }

  glm::vec3 color(const Json& obj, const std::string& path, const char* k, glm::vec3 fallback) const {
    glm::vec3 c = vec3(obj, path, k, fallback);
    if (c.x < 0.0f || c.y < 0.0f || c.z < 0.0f) fail(key(path, k), "components must not be negative");
    if (std::max({c.x, c.y, c.z}) > limits::kMaxRadiometric)
      fail(key(path, k), "components must be at most " + fmt(limits::kMaxRadiometric));
    return c;
  }

  float positive(const Json& j, const std::string& path) const {
    double v = number(j, path);
    if (!(v > 0.0)) fail(path, "must be greater than 0, not " + fmt(v));
    return float(v);
  }

  float nonNegative(const Json& obj, const std::string& path, const char* k, float fallback,
                    double maxValue = limits::kMaxRadiometric) const {
    float v = number(obj, path, k, fallback);
    if (v < 0.0f) fail(key(path, k), "must not be negative, not " + fmt(v));
    if (v > maxValue) fail(key(path, k), "must be at most " + fmt(maxValue) + ", not " + fmt(v));
    return v;
  }

  SceneDesc parse(const std::string& text) {
    Json root;
    try {
      KeyTracker tracker(*this);
      root = Json::parse(text, [&tracker](int, nlohmann::json::parse_event_t event, Json& parsed) {
        return tracker.onEvent(event, parsed);
      });
    } catch (const nlohmann::json::parse_error& e) {
      syntaxError(text, e.byte, e.what());
    } catch (const nlohmann::json::exception& e) {
      // Number overflow (1e999) and similar come without a position: find the token to locate it.
      std::string what = e.what();
      std::size_t q0 = what.find('\''), q1 = what.rfind('\'');
      std::size_t at = std::string::npos;
      if (q0 != std::string::npos && q1 > q0) at = text.find(what.substr(q0 + 1, q1 - q0 - 1));
      syntaxError(text, at == std::string::npos ? 0 : at + 1, what + " (numbers must be finite)");
    }

    SceneDesc scene;
    scene.file = file_;
    requireObject(root, "");
    const Json& version = required(root, "", "version");
    scene.version = integer(version, "version");
    if (scene.version != 1) fail("version", "unsupported version " + std::to_string(scene.version) + " (this build reads version 1)");
    checkKeys(root, "", {"version", "assets", "instances", "camera", "ambient", "lights"});

    if (auto it = root.find("assets"); it != root.end()) parseAssets(*it, scene);
    if (auto it = root.find("instances"); it != root.end()) parseInstances(*it, scene);
    if (auto it = root.find("camera"); it != root.end()) scene.camera = parseCamera(*it, "camera");
    if (auto it = root.find("ambient"); it != root.end()) {
      requireObject(*it, "ambient");
      checkKeys(*it, "ambient", {"color", "intensity"});
      scene.ambient.color = color(*it, "ambient", "color", scene.ambient.color);
      scene.ambient.intensity = nonNegative(*it, "ambient", "intensity", scene.ambient.intensity);
    }
    if (auto it = root.find("lights"); it != root.end()) {
      float defaultMaxDistance = scene.camera ? scene.camera->farPlane : CameraDesc{}.farPlane;
      parseLights(*it, scene, defaultMaxDistance);
    }
    return scene;
  }


  // Follows the parser through the document to refuse what nlohmann accepts silently: a key given twice in
  // one object (the last would win) and NUL bytes in keys or strings (names and paths would disagree
  // between the EXR, the sidecar and the file system). Errors name the JSON path.
  class KeyTracker {
   public:
    explicit KeyTracker(const Parser& parser) : parser_(parser) {}

    bool onEvent(nlohmann::json::parse_event_t event, const Json& parsed) {
      using E = nlohmann::json::parse_event_t;
      switch (event) {
        case E::object_start:
        case E::array_start:
          frames_.push_back({event == E::object_start, childPath(), {}, {}, 0});
          break;
        case E::object_end:
        case E::array_end:
          frames_.pop_back();
          if (!frames_.empty() && !frames_.back().isObject) ++frames_.back().count;
          break;
        case E::key: {
          Frame& f = frames_.back();
          f.lastKey = parsed.get<std::string>();
          std::string at = key(f.path, f.lastKey);
          if (std::size_t nul = f.lastKey.find('\0'); nul != std::string::npos) {
            // Shown escaped: the raw NUL would end the message wherever it is printed as a C string.
            std::string shown = f.lastKey;
            for (std::size_t p = shown.find('\0'); p != std::string::npos; p = shown.find('\0', p)) shown.replace(p, 1, "\\u0000");
            parser_.fail(key(f.path, shown), "a key must not contain a NUL character");
          }
          if (!f.keys.insert(f.lastKey).second) parser_.fail(at, "duplicate key (each key may appear once per object)");
          break;
        }
        case E::value:
          if (parsed.is_string() && parsed.get_ref<const std::string&>().find('\0') != std::string::npos)
            parser_.fail(childPath(), "must not contain a NUL character");
          if (!frames_.empty() && !frames_.back().isObject) ++frames_.back().count;
          break;
      }
      return true;
    }

   private:
    struct Frame {
      bool isObject;
      std::string path;
      std::set<std::string> keys;
      std::string lastKey;
      std::size_t count;
    };
    // The path of the value about to start in the innermost container.
    std::string childPath() const {
      if (frames_.empty()) return "";
      const Frame& f = frames_.back();
      return f.isObject ? key(f.path, f.lastKey) : index(f.path, f.count);
    }
    const Parser& parser_;
    std::vector<Frame> frames_;
  };

 private:
  [[noreturn]] void syntaxError(const std::string& text, std::size_t byte, const std::string& what) const {
    // nlohmann counts bytes from 1 and points just past the offending character.
    std::size_t end = std::min(byte == 0 ? 0 : byte - 1, text.size());
    std::size_t line = 1, column = 1;
    for (std::size_t i = 0; i < end; ++i) {
      if (text[i] == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
    }
    throwBadInput(file_.string() + ": line " + std::to_string(line) + ", column " + std::to_string(column) +
                  ": invalid JSON: " + what);
  }

  void parseAssets(const Json& assets, SceneDesc& scene) const {
    requireObject(assets, "assets");
    for (auto it = assets.begin(); it != assets.end(); ++it) {
      std::string path = key("assets", it.key());
      if (it.key().empty()) fail("assets", "asset names must not be empty");
      const Json& a = it.value();
      requireObject(a, path);
      AssetDesc asset;
      asset.name = it.key();
      std::string file = string(required(a, path, "file"), key(path, "file"));
      if (file.empty()) fail(key(path, "file"), "must not be empty");
      asset.vox = isVoxPath(file);
      if (asset.vox) checkKeys(a, path, {"file", "voxel_size", "model", "frame"}, " for a .vox asset");
      else checkKeys(a, path, {"file", "grid", "density_threshold", "color"});
      std::filesystem::path resolved = file;
      if (resolved.is_relative()) resolved = file_.parent_path() / resolved;
      if (std::string kind = fileKindProblem(resolved); !kind.empty()) fail(key(path, "file"), resolved.string() + ": " + kind);
      asset.file = resolved;
      if (asset.vox) {
        parseVoxAsset(a, path, asset);
        scene.assets.push_back(std::move(asset));
        continue;
      }
      if (auto g = a.find("grid"); g != a.end()) {
        if (g->is_string()) {
          asset.grid = g->get<std::string>();
          if (asset.grid.empty()) fail(key(path, "grid"), "must not be empty");
        } else if (g->is_number()) {
          int gi = integer(*g, key(path, "grid"));
          if (gi < 0) fail(key(path, "grid"), "a grid index must not be negative");
          asset.grid = std::to_string(gi);
        } else {
          fail(key(path, "grid"), "must be a grid name (string) or index (integer), not " + typeName(*g));
        }
      }
      asset.densityThreshold = number(a, path, "density_threshold", asset.densityThreshold);
      asset.color = color(a, path, "color", asset.color);
      scene.assets.push_back(std::move(asset));
    }
  }

  static bool isVoxPath(const std::string& file) {
    std::string ext = std::filesystem::path(file).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".vox";
  }

  void parseVoxAsset(const Json& a, const std::string& path, AssetDesc& asset) const {
    if (auto v = a.find("voxel_size"); v != a.end()) {
      asset.voxelSize = number(*v, key(path, "voxel_size"));
      // Bounded like a .vdb asset's voxel size (voxel/valid_range.h).
      if (!(asset.voxelSize >= limits::kMinVoxelSize && asset.voxelSize <= limits::kMaxVoxelSize))
        fail(key(path, "voxel_size"), "must be between " + fmt(limits::kMinVoxelSize) + " and " +
                                          fmt(limits::kMaxVoxelSize) + ", not " + fmt(asset.voxelSize));
    }
    if (auto m = a.find("model"); m != a.end()) {
      if (m->is_string()) {
        asset.model = m->get<std::string>();
        if (asset.model.empty()) fail(key(path, "model"), "must not be empty");
        if (std::all_of(asset.model.begin(), asset.model.end(), [](unsigned char c) { return std::isdigit(c); }))
          fail(key(path, "model"), "a shape name made of digits reads as an index: give the index as a number");
      } else if (m->is_number()) {
        int mi = integer(*m, key(path, "model"));
        if (mi < 0) fail(key(path, "model"), "a model index must not be negative");
        asset.model = std::to_string(mi);
      } else {
        fail(key(path, "model"), "must be a model index (integer) or a shape name (string), not " + typeName(*m));
      }
    }
    if (auto f = a.find("frame"); f != a.end()) {
      // Checked here rather than by integer(), whose int range is not the frames a .vox file can hold.
      const std::string range = "must be a whole number from 0 to " + std::to_string(kVoxMaxFrame);
      if (!f->is_number()) fail(key(path, "frame"), range + ", not " + typeName(*f));
      double v = f->get<double>();
      if (!(v >= 0.0 && v <= kVoxMaxFrame) || v != std::floor(v)) fail(key(path, "frame"), range + ", not " + fmt(v));
      asset.frame = int(v);
    }
  }

  void parseInstances(const Json& instances, SceneDesc& scene) const {
    if (!instances.is_array()) fail("instances", "must be an array, not " + typeName(instances));
    for (std::size_t i = 0; i < instances.size(); ++i) {
      std::string path = index("instances", i);
      const Json& inst = instances[i];
      requireObject(inst, path);
      checkKeys(inst, path, {"asset", "matrix", "translate", "rotate_deg", "scale"});
      InstanceDesc desc;
      desc.asset = string(required(inst, path, "asset"), key(path, "asset"));
      bool found = false;
      for (std::size_t a = 0; a < scene.assets.size() && !found; ++a) {
        if (scene.assets[a].name == desc.asset) {
          desc.assetIndex = a;
          found = true;
        }
      }
      if (!found) fail(key(path, "asset"), "unknown asset \"" + desc.asset + "\" (not defined under \"assets\")");

      if (auto m = inst.find("matrix"); m != inst.end()) {
        for (const char* k : {"translate", "rotate_deg", "scale"})
          if (inst.contains(k)) fail(key(path, k), "cannot be combined with \"matrix\"");
        std::string mp = key(path, "matrix");
        if (!m->is_array() || m->size() != 16) fail(mp, "must be an array of 16 numbers (column-major)");
        for (int c = 0; c < 4; ++c)
          for (int r = 0; r < 4; ++r) desc.transform[c][r] = number((*m)[c * 4 + r], index(mp, c * 4 + r));
        if (desc.transform[0][3] != 0.0 || desc.transform[1][3] != 0.0 || desc.transform[2][3] != 0.0 ||
            desc.transform[3][3] != 1.0)
          fail(mp, "must be affine: elements 3, 7, 11, 15 (the last row) must be 0, 0, 0, 1");
        for (int r = 0; r < 3; ++r)
          inRange(desc.transform[3][r], index(mp, std::size_t(12 + r)), -limits::kMaxCoordinate, limits::kMaxCoordinate,
                  "a translation");
        for (int c = 0; c < 3; ++c) {
          double len = glm::length(glm::dvec3(desc.transform[c]));
          if (!(len >= limits::kMinScale && len <= limits::kMaxScale))
            fail(mp, "column " + std::to_string(c) + " has length " + fmt(len) + "; each axis's scale must be between " +
                         fmt(limits::kMinScale) + " and " + fmt(limits::kMaxScale));
        }
        checkInvertible(desc.transform, mp);
      } else {
        glm::dvec3 t(0.0), r(0.0), s(1.0);
        if (auto it = inst.find("translate"); it != inst.end()) t = position(*it, key(path, "translate"));
        if (auto it = inst.find("rotate_deg"); it != inst.end()) {
          r = vec3(*it, key(path, "rotate_deg"));
          for (int a = 0; a < 3; ++a)
            inRange(r[a], index(key(path, "rotate_deg"), std::size_t(a)), -limits::kMaxAngleDeg, limits::kMaxAngleDeg, "an angle");
        }
        if (auto it = inst.find("scale"); it != inst.end()) {
          if (it->is_number()) s = glm::dvec3(number(*it, key(path, "scale")));
          else if (it->is_array()) s = vec3(*it, key(path, "scale"));
          else fail(key(path, "scale"), "must be a number or an array of 3 numbers, not " + typeName(*it));
          for (int a = 0; a < 3; ++a)
            if (!(std::abs(s[a]) >= limits::kMinScale && std::abs(s[a]) <= limits::kMaxScale))
              fail(key(path, "scale"), "each factor's magnitude must be between " + fmt(limits::kMinScale) + " and " +
                                           fmt(limits::kMaxScale) + ", not " + fmt(s[a]));
        }
        glm::dmat4 tr = glm::translate(glm::dmat4(1.0), t);
        tr = glm::rotate(tr, glm::radians(r.z), glm::dvec3(0, 0, 1));
        tr = glm::rotate(tr, glm::radians(r.y), glm::dvec3(0, 1, 0));
        tr = glm::rotate(tr, glm::radians(r.x), glm::dvec3(1, 0, 0));
        tr = glm::scale(tr, s);
        desc.transform = tr;
        checkInvertible(desc.transform, inst.contains("scale") ? key(path, "scale") : path);
      }
      scene.instances.push_back(desc);
    }
  }

  void checkInvertible(const glm::dmat4& m, const std::string& path) const {
    glm::dmat3 l(m);
    double det = glm::determinant(l);
    // Relative to the column lengths, so a tiny but well-shaped scale stays valid while a collapsed axis does not.
    double scale = glm::length(l[0]) * glm::length(l[1]) * glm::length(l[2]);
    if (!std::isfinite(det) || !(std::abs(det) > 1e-12 * scale)) fail(path, "transform is singular (not invertible)");
  }

  CameraDesc parseCamera(const Json& cam, const std::string& path) const {
    requireObject(cam, path);
    checkKeys(cam, path, {"position", "target", "up", "fov_deg", "near", "far", "width", "height"});
    CameraDesc c;
    c.position = glm::vec3(position(required(cam, path, "position"), key(path, "position")));
    c.target = glm::vec3(position(required(cam, path, "target"), key(path, "target")));
    if (auto it = cam.find("up"); it != cam.end()) c.up = direction(*it, key(path, "up"));
    if (auto it = cam.find("fov_deg"); it != cam.end()) c.fovDeg = float(number(*it, key(path, "fov_deg")));
    if (auto it = cam.find("near"); it != cam.end()) c.nearPlane = distance(*it, key(path, "near"));
    if (auto it = cam.find("far"); it != cam.end()) c.farPlane = distance(*it, key(path, "far"));
    if (auto it = cam.find("width"); it != cam.end()) c.width = positiveInt(*it, key(path, "width"));
    if (auto it = cam.find("height"); it != cam.end()) c.height = positiveInt(*it, key(path, "height"));
    checkCamera(c, file_.string() + ": " + path);
    return c;
  }

  int positiveInt(const Json& j, const std::string& path) const {
    int v = integer(j, path);
    if (v <= 0) fail(path, "must be greater than 0, not " + std::to_string(v));
    if (v > limits::kMaxImageSide) fail(path, "must be at most " + std::to_string(limits::kMaxImageSide) + ", not " + std::to_string(v));
    return v;
  }

  void parseLights(const Json& lights, SceneDesc& scene, float defaultMaxDistance) const {
    if (!lights.is_array()) fail("lights", "must be an array, not " + typeName(lights));
    std::map<std::string, std::size_t> names;
    for (std::size_t i = 0; i < lights.size(); ++i) {
      std::string path = index("lights", i);
      const Json& lj = lights[i];
      requireObject(lj, path);
      LightDesc light;
      std::string type = string(required(lj, path, "type"), key(path, "type"));
      if (type == "directional") {
        light.type = LightType::Directional;
        checkKeys(lj, path, {"name", "type", "direction", "color", "intensity", "shadow"}, " for a directional light");
      } else if (type == "spot") {
        light.type = LightType::Spot;
        checkKeys(lj, path, {"name", "type", "position", "direction", "range", "inner_cone_deg", "outer_cone_deg",
                             "color", "intensity", "shadow"}, " for a spot light");
      } else if (type == "point") {
        light.type = LightType::Point;
        checkKeys(lj, path, {"name", "type", "position", "range", "color", "intensity", "shadow"}, " for a point light");
      } else {
        fail(key(path, "type"), "unknown light type \"" + type + "\" (expected directional, spot or point)");
      }

      light.name = "light" + std::to_string(i);
      if (auto it = lj.find("name"); it != lj.end()) {
        light.name = string(*it, key(path, "name"));
        if (light.name.empty()) fail(key(path, "name"), "must not be empty");
      }
      if (auto [prev, inserted] = names.emplace(light.name, i); !inserted)
        fail(key(path, "name"), "duplicate light name \"" + light.name + "\" (also lights[" + std::to_string(prev->second) + "])");

      if (light.type != LightType::Point)
        light.direction = direction(required(lj, path, "direction"), key(path, "direction"));
      if (light.type != LightType::Directional) {
        light.position = glm::vec3(position(required(lj, path, "position"), key(path, "position")));
        light.range = distance(required(lj, path, "range"), key(path, "range"));
      }
      if (light.type == LightType::Spot) {
        std::string op = key(path, "outer_cone_deg");
        light.outerConeDeg = float(number(required(lj, path, "outer_cone_deg"), op));
        if (!(light.outerConeDeg > 0.0f && light.outerConeDeg < 90.0f))
          fail(op, "must be greater than 0 and less than 90, not " + fmt(light.outerConeDeg));
        light.innerConeDeg = 0.8f * light.outerConeDeg;
        if (auto it = lj.find("inner_cone_deg"); it != lj.end()) {
          std::string ip = key(path, "inner_cone_deg");
          light.innerConeDeg = float(number(*it, ip));
          if (light.innerConeDeg < 0.0f) fail(ip, "must not be negative, not " + fmt(light.innerConeDeg));
          if (light.innerConeDeg > light.outerConeDeg)
            fail(ip, "must not exceed outer_cone_deg (" + fmt(light.outerConeDeg) + "), not " + fmt(light.innerConeDeg));
        }
      }
      light.color = color(lj, path, "color", light.color);
      light.intensity = nonNegative(lj, path, "intensity", light.intensity);
      if (auto it = lj.find("shadow"); it != lj.end())
        light.shadow = parseShadow(*it, key(path, "shadow"), light.type, defaultMaxDistance);
      scene.lights.push_back(std::move(light));
    }
    checkLayerNames(scene);
  }

  // Layer names must be unique in the EXR; a light named "lamp.face+x" beside a point light "lamp" would
  // give two layers one name. Found here, before any work, rather than when the file is written.
  void checkLayerNames(const SceneDesc& scene) const {
    std::map<std::string, std::size_t> owner;
    for (std::size_t i = 0; i < scene.lights.size(); ++i) {
      const LightDesc& l = scene.lights[i];
      std::vector<std::string> names;
      if (l.type == LightType::Point)
        for (const char* face : {"+x", "-x", "+y", "-y", "+z", "-z"}) names.push_back(l.name + ".face" + face);
      else if (l.type == LightType::Directional && scene.camera && l.shadow)
        for (int c = 0; c < l.shadow->cascades; ++c) names.push_back(l.name + ".cascade" + std::to_string(c));
      else
        names.push_back(l.name);
      for (const std::string& n : names) {
        auto [it, inserted] = owner.emplace(n, i);
        if (!inserted && it->second != i)
          fail(key(index("lights", i), "name"), "its shadow layer \"" + n + "\" has the same name as a layer of lights[" +
                                                  std::to_string(it->second) + "]");
      }
    }
  }

  ShadowDesc parseShadow(const Json& sj, const std::string& path, LightType type, float defaultMaxDistance) const {
    requireObject(sj, path);
    checkKeys(sj, path, {"resolution", "cascades", "lambda", "max_distance", "filter", "depth_bias", "normal_bias",
                         "slope_bias", "light_size", "contact_shadow", "cascade_blend", "depth_point", "evsm_exponent",
                         "evsm_blur", "light_bleed_reduction"});
    ShadowDesc s;
    s.maxDistance = defaultMaxDistance;
    if (auto it = sj.find("resolution"); it != sj.end()) {
      std::string rp = key(path, "resolution");
      if (!it->is_number()) fail(rp, "must be a number, not " + typeName(*it));
      double v = number(*it, rp);
      if (v != std::floor(v) || v < 16.0 || v > 16384.0 || (std::int64_t(v) & (std::int64_t(v) - 1)) != 0)
        fail(rp, "must be a power of two between 16 and 16384");
      s.resolution = int(v);
    }
    if (auto it = sj.find("cascades"); it != sj.end()) {
      std::string cp = key(path, "cascades");
      if (type != LightType::Directional)
        fail(cp, std::string("only directional lights have cascades, this is a ") + lightTypeName(type) + " light");
      s.cascades = integer(*it, cp);
      if (s.cascades < 1 || s.cascades > 4) fail(cp, "must be between 1 and 4, not " + std::to_string(s.cascades));
    }
    if (auto it = sj.find("lambda"); it != sj.end()) {
      s.lambda = float(number(*it, key(path, "lambda")));
      if (s.lambda < 0.0f || s.lambda > 1.0f) fail(key(path, "lambda"), "must be between 0 and 1, not " + fmt(s.lambda));
    }
    if (auto it = sj.find("max_distance"); it != sj.end()) s.maxDistance = distance(*it, key(path, "max_distance"));
    if (auto it = sj.find("filter"); it != sj.end()) {
      std::string f = string(*it, key(path, "filter"));
      bool found = false;
      for (ShadowFilter cand : {ShadowFilter::Hard, ShadowFilter::Pcf3, ShadowFilter::Pcf5, ShadowFilter::Poisson16,
                                ShadowFilter::Pcss, ShadowFilter::Evsm}) {
        if (f == shadowFilterName(cand)) {
          s.filter = cand;
          found = true;
        }
      }
      if (!found) fail(key(path, "filter"), "unknown filter \"" + f + "\" (expected hard, pcf3, pcf5, poisson16, pcss or evsm)");
    }
    s.depthBias = number(sj, path, "depth_bias", s.depthBias);
    if (std::abs(s.depthBias) > limits::kMaxDepthBias)
      fail(key(path, "depth_bias"), "must be between " + fmt(-limits::kMaxDepthBias) + " and " + fmt(limits::kMaxDepthBias) + ", not " + fmt(s.depthBias));
    s.normalBias = nonNegative(sj, path, "normal_bias", s.normalBias, limits::kMaxNormalBias);
    s.slopeBias = nonNegative(sj, path, "slope_bias", s.slopeBias, limits::kMaxDepthBias);
    s.lightSize = nonNegative(sj, path, "light_size", s.lightSize, limits::kMaxDistance);
    s.contactShadow = nonNegative(sj, path, "contact_shadow", s.contactShadow, limits::kMaxDistance);
    if (auto it = sj.find("cascade_blend"); it != sj.end()) {
      std::string bp = key(path, "cascade_blend");
      if (type != LightType::Directional)
        fail(bp, std::string("only directional lights have cascades, this is a ") + lightTypeName(type) + " light");
      s.cascadeBlend = float(inRange(number(*it, bp), bp, 0.0, 0.5, "the blend band"));
    }
    if (auto it = sj.find("evsm_exponent"); it != sj.end()) {
      // One number for both warps, or [positive, negative].
      const std::string ep = key(path, "evsm_exponent");
      const char* what = "an EVSM exponent";
      if (it->is_array()) {
        if (it->size() != 2) fail(ep, "must be a number or an array of 2 numbers [positive, negative]");
        s.evsmPositiveExponent = float(inRange(number((*it)[0], index(ep, 0)), index(ep, 0), 1.0, kMaxEvsmExponent, what));
        s.evsmNegativeExponent = float(inRange(number((*it)[1], index(ep, 1)), index(ep, 1), 1.0, kMaxEvsmExponent, what));
      } else {
        s.evsmPositiveExponent = s.evsmNegativeExponent = float(inRange(number(*it, ep), ep, 1.0, kMaxEvsmExponent, what));
      }
    }
    if (auto it = sj.find("evsm_blur"); it != sj.end()) {
      const std::string bp = key(path, "evsm_blur");
      s.evsmBlur = integer(*it, bp);
      if (s.evsmBlur < 0 || s.evsmBlur > kMaxEvsmBlur)
        fail(bp, "the blur radius (texels) must be between 0 and " + std::to_string(kMaxEvsmBlur) + ", not " +
                     std::to_string(s.evsmBlur));
    }
    if (auto it = sj.find("light_bleed_reduction"); it != sj.end()) {
      const std::string lp = key(path, "light_bleed_reduction");
      s.lightBleedReduction = float(inRange(number(*it, lp), lp, 0.0, 0.99, "the light-bleeding reduction"));
    }
    if (auto it = sj.find("depth_point"); it != sj.end()) {
      std::string d = string(*it, key(path, "depth_point"));
      if (d == "entry") s.depthPoint = gpu::VS_DEPTH_POINT_ENTRY;
      else if (d == "voxel_center") s.depthPoint = gpu::VS_DEPTH_POINT_VOXEL_CENTER;
      else fail(key(path, "depth_point"), "unknown depth point \"" + d + "\" (expected entry or voxel_center)");
    }
    return s;
  }

  std::filesystem::path file_;
};

}  // namespace

SceneDesc parseSceneJson(const std::string& text, const std::filesystem::path& file) {
  return Parser(file).parse(text);
}

SceneDesc parseSceneFile(const std::filesystem::path& file) {
  if (std::string kind = fileKindProblem(file); !kind.empty()) throwBadInput(file.string() + ": " + kind);
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
  if (ec) throwBadInput(file.string() + ": cannot read the scene file (" + ec.message() + ")");
  if (bytes > limits::kMaxSceneFileBytes)
    throwBadInput(file.string() + ": " + std::to_string(bytes) + " bytes; a scene file may have at most " +
                  std::to_string(limits::kMaxSceneFileBytes) + " (it names its assets, it does not hold them)");
  std::ifstream in(file, std::ios::binary);
  if (!in) throwBadInput(file.string() + ": cannot open the scene file");
  std::string text(bytes, '\0');
  in.read(text.data(), std::streamsize(bytes));
  if (in.bad() || std::uintmax_t(in.gcount()) != bytes) throwBadInput(file.string() + ": cannot read the scene file");
  return parseSceneJson(text, file);
}

void checkCamera(const CameraDesc& c, const std::string& where) {
  auto fail = [&](const char* field, const std::string& what) { throwBadInput(where + "." + field + ": " + what); };
  auto checkPoint = [&](const glm::vec3& p, const char* field) {
    for (int a = 0; a < 3; ++a)
      if (!limits::isWorldCoordinate(p[a]))
        fail(field, "coordinates must be between " + fmt(-limits::kMaxCoordinate) + " and " +
                        fmt(limits::kMaxCoordinate) + ", not " + fmt(p[a]));
  };
  checkPoint(c.position, "position");
  checkPoint(c.target, "target");
  if (c.position == c.target) fail("target", "must differ from position");
  if (!std::isfinite(glm::length(c.up)) || !(glm::length(c.up) > 0.0f)) fail("up", "must be a non-zero vector");
  if (glm::length(glm::cross(glm::normalize(c.target - c.position), glm::normalize(c.up))) < 1e-6f)
    fail("up", "must not be parallel to the view direction");
  if (!(c.fovDeg > 0.0f && c.fovDeg < 180.0f)) fail("fov_deg", "must be between 0 and 180 (exclusive), not " + fmt(c.fovDeg));
  for (auto [plane, field] : {std::pair{c.nearPlane, "near"}, std::pair{c.farPlane, "far"}})
    if (!(plane > 0.0f && plane <= limits::kMaxDistance))
      fail(field, "must be greater than 0 and at most " + fmt(limits::kMaxDistance) + ", not " + fmt(plane));
  if (!(c.farPlane > c.nearPlane)) fail("far", "must be greater than near");
  for (auto [side, field] : {std::pair{c.width, "width"}, std::pair{c.height, "height"}})
    if (side <= 0 || side > limits::kMaxImageSide)
      fail(field, "must be between 1 and " + std::to_string(limits::kMaxImageSide) + ", not " + std::to_string(side));
}

std::string fileKindProblem(const std::filesystem::path& file) {
  std::error_code ec;
  std::filesystem::file_status st = std::filesystem::status(file, ec);
  switch (st.type()) {
    case std::filesystem::file_type::regular: return {};
    case std::filesystem::file_type::not_found: return "no such file";
    case std::filesystem::file_type::directory: return "is a directory, not a file";
    case std::filesystem::file_type::fifo: return "is a FIFO, not a regular file";
    case std::filesystem::file_type::socket: return "is a socket, not a regular file";
    case std::filesystem::file_type::block:
    case std::filesystem::file_type::character: return "is a device, not a regular file";
    default: return ec ? "cannot be read (" + ec.message() + ")" : "is not a regular file";
  }
}

}  // namespace vs
