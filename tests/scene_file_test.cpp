// Scene file v1 (DESIGN.md §8): the full example parses with the documented defaults; every class of bad input
// is refused with "<file>: <json path>: <problem>"; Scene::load ties parsing, asset loading and trace arrays.
#include <gtest/gtest.h>

#include <fstream>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include "compute/shared/trace_view.h"
#include "lighting/scene.h"
#include "lighting/scene_file.h"
#include "support/test_paths.h"
#include "voxel/error.h"

namespace {

using namespace vs;
using Json = nlohmann::ordered_json;

void writeVdb(const std::filesystem::path& file, const std::string& gridName) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName(gridName);
  grid->setGridClass(openvdb::GRID_FOG_VOLUME);
  auto acc = grid->getAccessor();
  for (int i = 0; i < 4; ++i) acc.setValue(openvdb::Coord(i, 0, i % 2), 1.0f);
  openvdb::io::File out(file.string());
  out.write({grid});
  out.close();
}

// The example of DESIGN.md §8.
Json exampleScene() {
  return Json::parse(R"({
  "version": 1,
  "assets": {
    "castle": { "file": "castle.vdb", "grid": "density", "density_threshold": 0.1, "color": [0.8, 0.7, 0.6] },
    "ground": { "file": "ground.vdb" }
  },
  "instances": [
    { "asset": "ground" },
    { "asset": "castle", "translate": [4, 0, -3], "rotate_deg": [0, 30, 0], "scale": 2.0 },
    { "asset": "castle", "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1] }
  ],
  "camera": { "position": [30, 20, 30], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 60,
              "near": 0.1, "far": 400, "width": 1280, "height": 720 },
  "ambient": { "color": [0.6, 0.7, 1.0], "intensity": 0.25 },
  "lights": [
    { "name": "sun", "type": "directional", "direction": [-0.4, -1.0, -0.3], "color": [1, 0.95, 0.9], "intensity": 3,
      "shadow": { "resolution": 2048, "cascades": 3, "lambda": 0.7, "max_distance": 200,
                  "filter": "pcf5", "depth_bias": 0.02, "normal_bias": 1.0, "depth_point": "entry" } },
    { "name": "lamp", "type": "spot", "position": [0, 10, 0], "direction": [0, -1, 0], "range": 40,
      "inner_cone_deg": 20, "outer_cone_deg": 30, "color": [1, 0.8, 0.6], "intensity": 50,
      "shadow": { "resolution": 1024, "filter": "poisson16" } },
    { "name": "torch", "type": "point", "position": [5, 3, 5], "range": 20, "intensity": 20,
      "shadow": { "resolution": 512 } }
  ]
})");
}

class SceneFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::scratchDir("scene_file_test");
    writeVdb(dir_ / "castle.vdb", "density");
    writeVdb(dir_ / "ground.vdb", "density");
    sceneFile_ = dir_ / "scene.json";
  }

  SceneDesc parse(const Json& j) const { return parseSceneJson(j.dump(2), sceneFile_); }

  // Parses text that must be refused; the message must name the file, the JSON path and contain `what`.
  void expectError(const std::string& text, const std::string& path, const std::string& what) const {
    try {
      parseSceneJson(text, sceneFile_);
      ADD_FAILURE() << "accepted; expected an error at " << path;
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput);
      std::string msg = e.what();
      EXPECT_NE(msg.find(sceneFile_.string() + ": " + path + ": "), std::string::npos) << msg;
      EXPECT_NE(msg.find(what), std::string::npos) << msg;
    }
  }
  void expectError(const Json& j, const std::string& path, const std::string& what) const {
    expectError(j.dump(2), path, what);
  }

  std::filesystem::path dir_;
  std::filesystem::path sceneFile_;
};

glm::dvec3 apply(const glm::dmat4& m, glm::dvec3 p) { return glm::dvec3(m * glm::dvec4(p, 1.0)); }

TEST_F(SceneFileTest, DesignExampleParsesWithDefaults) {
  std::ofstream(sceneFile_) << exampleScene().dump(2);
  SceneDesc s = parseSceneFile(sceneFile_);
  EXPECT_EQ(s.version, 1);
  ASSERT_EQ(s.assets.size(), 2u);
  EXPECT_EQ(s.assets[0].name, "castle");
  EXPECT_EQ(s.assets[0].grid, "density");
  EXPECT_FLOAT_EQ(s.assets[0].densityThreshold, 0.1f);
  EXPECT_EQ(s.assets[0].color, glm::vec3(0.8f, 0.7f, 0.6f));
  EXPECT_TRUE(std::filesystem::equivalent(s.assets[0].file, dir_ / "castle.vdb"));
  EXPECT_EQ(s.assets[1].name, "ground");
  EXPECT_EQ(s.assets[1].grid, "");
  EXPECT_EQ(s.assets[1].densityThreshold, 0.0f);
  EXPECT_EQ(s.assets[1].color, glm::vec3(0.8f));

  ASSERT_EQ(s.instances.size(), 3u);
  EXPECT_EQ(s.instances[0].assetIndex, 1u);
  EXPECT_EQ(s.instances[0].transform, glm::dmat4(1.0));
  EXPECT_EQ(s.instances[1].assetIndex, 0u);
  // T * R * S: (1, 0, 0) scaled to (2, 0, 0), turned 30 degrees about +y, then moved by (4, 0, -3).
  glm::dvec3 p = apply(s.instances[1].transform, glm::dvec3(1, 0, 0));
  double a = glm::radians(30.0);
  EXPECT_NEAR(p.x, 4 + 2 * std::cos(a), 1e-12);
  EXPECT_NEAR(p.y, 0, 1e-12);
  EXPECT_NEAR(p.z, -3 - 2 * std::sin(a), 1e-12);
  EXPECT_EQ(apply(s.instances[2].transform, glm::dvec3(1, 2, 3)), glm::dvec3(11, 2, 3));

  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(s.camera->position, glm::vec3(30, 20, 30));
  EXPECT_FLOAT_EQ(s.camera->farPlane, 400.0f);
  EXPECT_EQ(s.camera->width, 1280);
  EXPECT_EQ(s.camera->height, 720);
  EXPECT_FLOAT_EQ(s.ambient.intensity, 0.25f);

  ASSERT_EQ(s.lights.size(), 3u);
  const LightDesc& sun = s.lights[0];
  EXPECT_EQ(sun.type, LightType::Directional);
  EXPECT_NEAR(glm::length(sun.direction), 1.0f, 1e-6f);
  EXPECT_GT(glm::dot(sun.direction, glm::normalize(glm::vec3(-0.4f, -1.0f, -0.3f))), 0.99999f);
  ASSERT_TRUE(sun.shadow.has_value());
  EXPECT_EQ(sun.shadow->resolution, 2048);
  EXPECT_EQ(sun.shadow->cascades, 3);
  EXPECT_FLOAT_EQ(sun.shadow->maxDistance, 200.0f);
  EXPECT_EQ(sun.shadow->filter, ShadowFilter::Pcf5);
  EXPECT_FLOAT_EQ(sun.shadow->depthBias, 0.02f);
  EXPECT_FLOAT_EQ(sun.shadow->normalBias, 1.0f);
  EXPECT_EQ(sun.shadow->depthPoint, gpu::VS_DEPTH_POINT_ENTRY);

  const LightDesc& lamp = s.lights[1];
  EXPECT_EQ(lamp.type, LightType::Spot);
  EXPECT_FLOAT_EQ(lamp.range, 40.0f);
  EXPECT_FLOAT_EQ(lamp.innerConeDeg, 20.0f);
  EXPECT_FLOAT_EQ(lamp.outerConeDeg, 30.0f);
  EXPECT_EQ(lamp.shadow->filter, ShadowFilter::Poisson16);
  EXPECT_FLOAT_EQ(lamp.shadow->maxDistance, 400.0f) << "defaults to the camera's far plane";
  EXPECT_FLOAT_EQ(lamp.shadow->lambda, 0.7f);
  EXPECT_FLOAT_EQ(lamp.shadow->normalBias, 0.5f);
  EXPECT_FLOAT_EQ(lamp.shadow->slopeBias, 0.5f);
  EXPECT_FLOAT_EQ(lamp.shadow->lightSize, 0.5f);
  EXPECT_FLOAT_EQ(lamp.shadow->contactShadow, 0.0f);
  EXPECT_FLOAT_EQ(lamp.shadow->depthBias, 0.0f);

  const LightDesc& torch = s.lights[2];
  EXPECT_EQ(torch.type, LightType::Point);
  EXPECT_EQ(torch.color, glm::vec3(1.0f));
  EXPECT_FLOAT_EQ(torch.intensity, 20.0f);
  EXPECT_EQ(torch.shadow->resolution, 512);
  EXPECT_EQ(torch.shadow->filter, ShadowFilter::Pcf3);
}

TEST_F(SceneFileTest, MinimalSceneDefaults) {
  Json j = Json::parse(R"({"version": 1, "lights": [
      {"type": "spot", "position": [0, 5, 0], "direction": [0, -2, 0], "range": 10, "outer_cone_deg": 40,
       "shadow": {}},
      {"type": "directional", "direction": [0, -1, 0]}]})");
  SceneDesc s = parse(j);
  EXPECT_FALSE(s.camera.has_value());
  EXPECT_EQ(s.ambient.color, glm::vec3(1.0f));
  EXPECT_FLOAT_EQ(s.ambient.intensity, 0.2f);
  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_EQ(s.lights[0].name, "light0");
  EXPECT_EQ(s.lights[1].name, "light1");
  EXPECT_FLOAT_EQ(s.lights[0].innerConeDeg, 0.8f * 40.0f);
  EXPECT_EQ(s.lights[0].direction, glm::vec3(0, -1, 0));
  ASSERT_TRUE(s.lights[0].shadow.has_value());
  EXPECT_EQ(s.lights[0].shadow->resolution, 1024);
  EXPECT_FLOAT_EQ(s.lights[0].shadow->maxDistance, 1000.0f);
  EXPECT_FALSE(s.lights[1].shadow.has_value());

  Json cam = Json::parse(R"({"version": 1, "camera": {"position": [1, 2, 3], "target": [0, 0, 0]}})");
  SceneDesc c = parse(cam);
  ASSERT_TRUE(c.camera.has_value());
  EXPECT_EQ(c.camera->up, glm::vec3(0, 1, 0));
  EXPECT_FLOAT_EQ(c.camera->fovDeg, 60.0f);
  EXPECT_FLOAT_EQ(c.camera->nearPlane, 0.1f);
  EXPECT_FLOAT_EQ(c.camera->farPlane, 1000.0f);
}

TEST_F(SceneFileTest, MirrorScalesAreAllowed) {
  Json j = exampleScene();
  j["instances"][1]["scale"] = {-1.0, 2.0, 1.0};
  SceneDesc s = parse(j);
  EXPECT_LT(glm::determinant(glm::dmat3(s.instances[1].transform)), 0.0);
}

TEST_F(SceneFileTest, UnknownKeys) {
  Json j = exampleScene();
  j["lightz"] = Json::array();
  expectError(j, "lightz", "unknown key");
  j = exampleScene();
  j["lights"][1]["shadow"]["resolutoin"] = 64;
  expectError(j, "lights[1].shadow.resolutoin", "unknown key");
  j = exampleScene();
  j["assets"]["castle"]["colour"] = {1, 1, 1};
  expectError(j, "assets.castle.colour", "unknown key");
  j = exampleScene();
  j["lights"][2]["direction"] = {0, -1, 0};  // point lights have no direction
  expectError(j, "lights[2].direction", "unknown key");
}

TEST_F(SceneFileTest, WrongTypes) {
  Json j = exampleScene();
  j["camera"]["fov_deg"] = "60";
  expectError(j, "camera.fov_deg", "must be a number");
  j = exampleScene();
  j["lights"] = Json::object();
  expectError(j, "lights", "must be an array");
  j = exampleScene();
  j["camera"]["position"] = {1, 2};
  expectError(j, "camera.position", "3 numbers");
  j = exampleScene();
  j["lights"][0]["direction"][1] = true;
  expectError(j, "lights[0].direction[1]", "must be a number");
  j = exampleScene();
  j["camera"]["width"] = 12.5;
  expectError(j, "camera.width", "integer");
}

TEST_F(SceneFileTest, MissingRequiredKeys) {
  Json j = exampleScene();
  j["instances"][0].erase("asset");
  expectError(j, "instances[0].asset", "missing");
  j = exampleScene();
  j["assets"]["ground"].erase("file");
  expectError(j, "assets.ground.file", "missing");
  j = exampleScene();
  j["camera"].erase("target");
  expectError(j, "camera.target", "missing");
  j = exampleScene();
  j["lights"][1].erase("range");
  expectError(j, "lights[1].range", "missing");
  j = exampleScene();
  j["lights"][1].erase("outer_cone_deg");
  expectError(j, "lights[1].outer_cone_deg", "missing");
  j = exampleScene();
  j["lights"][0].erase("type");
  expectError(j, "lights[0].type", "missing");
}

TEST_F(SceneFileTest, NonFiniteAndNonNumbers) {
  std::string text = exampleScene().dump(2);
  std::string overflow = text;
  overflow.replace(overflow.find("\"intensity\": 3"), 14, "\"intensity\": 1e999");
  // The parser gives no JSON path for an overflow: the message names the file and the position instead.
  try {
    parseSceneJson(overflow, sceneFile_);
    ADD_FAILURE() << "accepted 1e999";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_EQ(msg.rfind(sceneFile_.string() + ": line ", 0), 0u) << msg;
    EXPECT_NE(msg.find("1e999"), std::string::npos) << msg;
  }
  Json j = exampleScene();
  j["lights"][0]["intensity"] = "NaN";
  expectError(j, "lights[0].intensity", "must be a number");
  j = exampleScene();
  j["ambient"]["intensity"] = nullptr;
  expectError(j, "ambient.intensity", "must be a number");
}

TEST_F(SceneFileTest, NonPositiveSizes) {
  Json j = exampleScene();
  j["camera"]["width"] = 0;
  expectError(j, "camera.width", "greater than 0");
  j = exampleScene();
  j["camera"]["height"] = -5;
  expectError(j, "camera.height", "greater than 0");
  j = exampleScene();
  j["lights"][2]["range"] = 0;
  expectError(j, "lights[2].range", "greater than 0");
  j = exampleScene();
  j["lights"][1]["shadow"]["resolution"] = 0;
  expectError(j, "lights[1].shadow.resolution", "must be a power of two between 16 and 16384");
}

TEST_F(SceneFileTest, ZeroLengthVectors) {
  Json j = exampleScene();
  j["lights"][0]["direction"] = {0, 0, 0};
  expectError(j, "lights[0].direction", "non-zero");
  j = exampleScene();
  j["camera"]["up"] = {0, 0, 0};
  expectError(j, "camera.up", "non-zero");
}

TEST_F(SceneFileTest, FieldOfViewRange) {
  for (double fov : {0.0, -10.0, 180.0, 200.0}) {
    Json j = exampleScene();
    j["camera"]["fov_deg"] = fov;
    expectError(j, "camera.fov_deg", "between 0 and 180");
  }
}

TEST_F(SceneFileTest, SpotCones) {
  for (double outer : {90.0, 120.0, 0.0, -5.0}) {
    Json j = exampleScene();
    j["lights"][1]["outer_cone_deg"] = outer;
    expectError(j, "lights[1].outer_cone_deg", "less than 90");
  }
  Json j = exampleScene();
  j["lights"][1]["inner_cone_deg"] = 31;
  expectError(j, "lights[1].inner_cone_deg", "must not exceed outer_cone_deg");
}

TEST_F(SceneFileTest, ShadowResolution) {
  for (double res : {1000.0, 8.0, 32768.0, 512.5, -16.0}) {
    Json j = exampleScene();
    j["lights"][1]["shadow"]["resolution"] = res;
    expectError(j, "lights[1].shadow.resolution", "must be a power of two between 16 and 16384");
  }
  for (int res : {16, 16384}) {
    Json j = exampleScene();
    j["lights"][1]["shadow"]["resolution"] = res;
    EXPECT_EQ(parse(j).lights[1].shadow->resolution, res);
  }
}

TEST_F(SceneFileTest, Cascades) {
  for (int c : {0, 5}) {
    Json j = exampleScene();
    j["lights"][0]["shadow"]["cascades"] = c;
    expectError(j, "lights[0].shadow.cascades", "between 1 and 4");
  }
  Json j = exampleScene();
  j["lights"][1]["shadow"]["cascades"] = 2;
  expectError(j, "lights[1].shadow.cascades", "only directional lights");
}

TEST_F(SceneFileTest, MatrixWithTrs) {
  for (const char* k : {"translate", "rotate_deg", "scale"}) {
    Json j = exampleScene();
    j["instances"][2][k] = k == std::string("scale") ? Json(2.0) : Json({1, 2, 3});
    expectError(j, std::string("instances[2].") + k, "cannot be combined with \"matrix\"");
  }
  Json j = exampleScene();
  j["instances"][2]["matrix"] = {1, 0, 0};
  expectError(j, "instances[2].matrix", "16 numbers");
}

TEST_F(SceneFileTest, SingularTransforms) {
  Json j = exampleScene();
  // A zero scale is below the valid range before it is singular.
  j["instances"][1]["scale"] = 0;
  expectError(j, "instances[1].scale", "between 0.0001 and 10000");
  j = exampleScene();
  j["instances"][1]["scale"] = {1, 0, 1};
  expectError(j, "instances[1].scale", "between 0.0001 and 10000");
  j = exampleScene();
  j["instances"][2]["matrix"] = {1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // two parallel columns
  expectError(j, "instances[2].matrix", "singular");
}

TEST_F(SceneFileTest, UnknownAsset) {
  Json j = exampleScene();
  j["instances"][1]["asset"] = "tower";
  expectError(j, "instances[1].asset", "unknown asset \"tower\"");
}

TEST_F(SceneFileTest, UnknownNames) {
  Json j = exampleScene();
  j["lights"][0]["shadow"]["filter"] = "pcf7";
  expectError(j, "lights[0].shadow.filter", "unknown filter \"pcf7\"");
  j = exampleScene();
  j["lights"][0]["shadow"]["depth_point"] = "center";
  expectError(j, "lights[0].shadow.depth_point", "unknown depth point \"center\"");
  j = exampleScene();
  j["lights"][0]["type"] = "area";
  expectError(j, "lights[0].type", "unknown light type");
  j = exampleScene();
  j["lights"][0]["shadow"]["depth_point"] = "voxel_center";
  EXPECT_EQ(parse(j).lights[0].shadow->depthPoint, gpu::VS_DEPTH_POINT_VOXEL_CENTER);
}

TEST_F(SceneFileTest, Version) {
  Json j = exampleScene();
  j.erase("version");
  expectError(j, "version", "missing");
  j = exampleScene();
  j["version"] = 2;
  expectError(j, "version", "unsupported version 2");
  j = exampleScene();
  j["version"] = "1";
  expectError(j, "version", "must be a number");
}

TEST_F(SceneFileTest, DuplicateLightNames) {
  Json j = exampleScene();
  j["lights"][2]["name"] = "sun";
  expectError(j, "lights[2].name", "duplicate light name \"sun\"");
  // A default name counts too.
  j = exampleScene();
  j["lights"][0]["name"] = "light1";
  j["lights"][1].erase("name");
  expectError(j, "lights[1].name", "duplicate light name \"light1\"");
}

TEST_F(SceneFileTest, SyntaxErrorsGiveLineAndColumn) {
  std::string text = "{\n  \"version\": 1,\n  \"assets\" {}\n}\n";
  try {
    parseSceneJson(text, sceneFile_);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput);
    std::string msg = e.what();
    EXPECT_EQ(msg.rfind(sceneFile_.string() + ": line 3, column ", 0), 0u) << msg;
  }
}

TEST_F(SceneFileTest, MissingAssetFile) {
  Json j = exampleScene();
  j["assets"]["ground"]["file"] = "nowhere/ground.vdb";
  expectError(j, "assets.ground.file", "no such file");
  // Relative paths resolve against the scene file's directory, not the working directory.
  std::filesystem::create_directories(dir_ / "sub");
  writeVdb(dir_ / "sub" / "g.vdb", "density");
  j["assets"]["ground"]["file"] = "sub/g.vdb";
  EXPECT_TRUE(std::filesystem::equivalent(parse(j).assets[1].file, dir_ / "sub" / "g.vdb"));
  EXPECT_THROW(parseSceneJson(j.dump(), std::filesystem::path("/nonexistent-dir/scene.json")), Error);
}

TEST_F(SceneFileTest, UnreadableSceneFile) {
  try {
    parseSceneFile(dir_ / "absent.json");
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput);
    EXPECT_NE(std::string(e.what()).find("absent.json"), std::string::npos);
  }
}

TEST_F(SceneFileTest, SceneLoadBuildsInstancesAndViews) {
  std::ofstream(sceneFile_) << exampleScene().dump(2);
  Scene scene = Scene::load(sceneFile_);
  ASSERT_EQ(scene.objects().size(), 2u);
  ASSERT_EQ(scene.instances().size(), 3u);
  EXPECT_EQ(scene.instances()[1].object, 0u);
  for (std::size_t i = 0; i < 3; ++i) {
    const InstanceDesc& d = scene.desc().instances[i];
    EXPECT_EQ(scene.instances()[i].brickToWorld, d.transform * scene.objects()[d.assetIndex].brickToObject);
  }
  EXPECT_EQ(scene.data().instances.size(), 3u);
  EXPECT_FALSE(scene.worldBounds().empty());
  EXPECT_EQ(scene.lightViews().size(), 3u + 1u + 6u);  // three sun cascades (the scene has a camera)

  Aabb before = scene.data().instanceBounds[0];
  scene.moveInstance(0, glm::translate(glm::dmat4(1.0), glm::dvec3(0, 100, 0)));
  Aabb after = scene.data().instanceBounds[0];
  EXPECT_NEAR(after.min.y - before.min.y, 100.0f, 1e-3f);
  EXPECT_THROW(scene.moveInstance(7, glm::dmat4(1.0)), Error);
  EXPECT_THROW(scene.moveInstance(0, glm::dmat4(0.0)), Error);
}

TEST_F(SceneFileTest, AssetLoadErrorsNameTheJsonPath) {
  Json j = exampleScene();
  j["assets"]["castle"]["grid"] = "no_such_grid";
  std::ofstream(sceneFile_) << j.dump(2);
  try {
    Scene::load(sceneFile_);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_EQ(e.kind(), ErrorKind::BadInput) << msg;
    EXPECT_EQ(msg.rfind(sceneFile_.string() + ": assets.castle: ", 0), 0u) << msg;
    EXPECT_NE(msg.find("no_such_grid"), std::string::npos) << msg;
  }
}

}  // namespace
