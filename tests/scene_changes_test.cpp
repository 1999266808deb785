// A frame loop's changes to a loaded scene: a refused change leaves every piece of the scene's state as it
// was, whatever was refused before it, and each refusal keeps its own message.
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "lighting/scene.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace vs {
namespace {

// Every byte of the state a change could touch: the description (camera, lights, instance transforms), the
// placed instances and the trace arrays with their BVH. Fields are appended one by one, never as structs
// with padding, so equal states give equal bytes.
class StateBytes {
 public:
  explicit StateBytes(const Scene& scene) {
    const SceneDesc& d = scene.desc();
    if (d.camera) {
      const CameraDesc& c = *d.camera;
      add(c.position), add(c.target), add(c.up), add(c.fovDeg), add(c.nearPlane), add(c.farPlane), add(c.width),
          add(c.height);
    }
    for (const LightDesc& l : d.lights) {
      bytes_.insert(bytes_.end(), l.name.begin(), l.name.end());
      add(int(l.type)), add(l.direction), add(l.position), add(l.range), add(l.innerConeDeg), add(l.outerConeDeg),
          add(l.color), add(l.intensity), add(l.shadow.has_value());
    }
    for (const InstanceDesc& i : d.instances) add(i.transform);
    for (const SceneInstance& i : scene.instances()) add(i.object), add(i.brickToWorld);
    const SceneData& s = scene.data();
    addAll(s.regionTable), addAll(s.regions), addAll(s.sectors), addAll(s.bricks), addAll(s.occupancy),
        addAll(s.payload), addAll(s.objects), addAll(s.instances);
    for (const Aabb& b : s.instanceBounds) add(b.min), add(b.max);
    add(s.worldBounds.min), add(s.worldBounds.max);
    for (const gpu::BvhNode& n : s.bvh.nodes()) add(n.boundsMin), add(n.rightOrFirst), add(n.boundsMax), add(n.count);
    for (std::uint32_t i : s.bvh.instanceIndices()) add(i);
    for (std::uint32_t e : s.bvh.nodeEscapes()) add(e);
    add(s.bvh.builtSahCost());
  }
  bool operator==(const StateBytes& o) const { return bytes_ == o.bytes_; }
  std::size_t size() const { return bytes_.size(); }

 private:
  template <class T>
  void add(const T& v) {
    const auto* p = reinterpret_cast<const unsigned char*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof v);
  }
  template <class T>
  void addAll(const std::vector<T>& v) {
    // GPU records are padding-free (their layouts are checked against GLSL's std430).
    const auto* p = reinterpret_cast<const unsigned char*>(v.data());
    bytes_.insert(bytes_.end(), p, p + v.size() * sizeof(T));
  }
  std::vector<unsigned char> bytes_;
};

struct Change {
  std::string name;
  std::function<void(Scene&)> apply;
};

glm::dmat4 translation(double x, double y, double z) { return glm::translate(glm::dmat4(1.0), glm::dvec3(x, y, z)); }

class SceneChanges : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto dir = test::scratchDir("scene_changes");
    demo_ = new Scene(Scene::load(writeDemoWorld(dir).back()));
  }
  static void TearDownTestSuite() { delete demo_; }
  static std::size_t lightNamed(const std::string& name) {
    for (std::size_t i = 0; i < demo_->desc().lights.size(); ++i)
      if (demo_->desc().lights[i].name == name) return i;
    ADD_FAILURE() << "the demo has no light " << name;
    return 0;
  }
  static Scene* demo_;
};
Scene* SceneChanges::demo_ = nullptr;

TEST_F(SceneChanges, RefusedChangesLeaveEveryStateAsItWas) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const std::size_t sun = lightNamed("sun"), lamp = lightNamed("lamp"), torch = lightNamed("torch");
  const std::size_t moved = 1;
  const glm::vec3 lampAt = demo_->desc().lights[lamp].position, lampDir = demo_->desc().lights[lamp].direction;
  const float fnan = std::numeric_limits<float>::quiet_NaN();
  glm::dmat4 shear(1.0);
  shear[1][0] = 1e6;
  glm::dmat4 projective(1.0);
  projective[0][3] = 0.5;
  auto camera = [&](std::function<void(CameraDesc&)> edit) {
    return [edit](Scene& s) {
      CameraDesc c = *s.desc().camera;
      edit(c);
      s.setCamera(c);
    };
  };
  const std::vector<Change> refused = {
      {"NaN translation", [&](Scene& s) { s.moveInstance(moved, translation(nan, 0, 0)); }},
      {"infinite translation", [&](Scene& s) { s.moveInstance(moved, translation(0, -inf, 0)); }},
      {"scale 1e-9", [&](Scene& s) { s.moveInstance(moved, glm::scale(glm::dmat4(1.0), glm::dvec3(1e-9))); }},
      {"scale 1e9", [&](Scene& s) { s.moveInstance(moved, glm::scale(glm::dmat4(1.0), glm::dvec3(1e9))); }},
      {"translation 2e5", [&](Scene& s) { s.moveInstance(moved, translation(2e5, 0, 0)); }},
      {"shear 1e6", [&](Scene& s) { s.moveInstance(moved, shear); }},
      {"projective transform", [&](Scene& s) { s.moveInstance(moved, projective); }},
      {"singular transform", [&](Scene& s) { s.moveInstance(moved, glm::dmat4(0.0)); }},
      {"instance out of range", [&](Scene& s) { s.moveInstance(s.instances().size(), glm::dmat4(1.0)); }},
      {"lamp moved with a zero direction", [&](Scene& s) { s.moveLight(lamp, lampAt + 1.0f, glm::vec3(0.0f)); }},
      {"lamp at NaN", [&](Scene& s) { s.moveLight(lamp, glm::vec3(fnan, 0, 0), lampDir); }},
      {"lamp beyond the coordinates", [&](Scene& s) { s.moveLight(lamp, glm::vec3(0, 2e5f, 0), lampDir); }},
      {"torch at infinity", [&](Scene& s) { s.moveLight(torch, glm::vec3(0, float(inf), 0), glm::vec3(0, -1, 0)); }},
      {"sun with a NaN direction", [&](Scene& s) { s.moveLight(sun, glm::vec3(0), glm::vec3(0, fnan, 0)); }},
      {"sun with a zero direction", [&](Scene& s) { s.moveLight(sun, glm::vec3(0), glm::vec3(0)); }},
      {"light out of range", [&](Scene& s) { s.moveLight(s.desc().lights.size(), glm::vec3(0), glm::vec3(0, -1, 0)); }},
      {"negative colour", [&](Scene& s) { s.setLightColor(lamp, glm::vec3(1, -1, 1), 1.0f); }},
      {"NaN intensity", [&](Scene& s) { s.setLightColor(torch, glm::vec3(1), fnan); }},
      {"colour of a light out of range", [&](Scene& s) { s.setLightColor(99, glm::vec3(1), 1.0f); }},
      {"camera at NaN", camera([&](CameraDesc& c) { c.position.x = fnan; })},
      {"camera near beyond far", camera([](CameraDesc& c) { c.nearPlane = c.farPlane * 2.0f; })},
      {"camera fov 180", camera([](CameraDesc& c) { c.fovDeg = 180.0f; })},
      {"camera width 0", camera([](CameraDesc& c) { c.width = 0; })},
  };

  const StateBytes original(*demo_);
  ASSERT_GT(original.size(), 1000u);
  // Each refusal's own message, from the scene as loaded.
  std::vector<std::string> messages;
  for (const Change& c : refused) {
    Scene scene = *demo_;
    try {
      c.apply(scene);
      ADD_FAILURE() << c.name << ": accepted";
      messages.emplace_back();
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput) << c.name;
      messages.emplace_back(e.what());
    }
    EXPECT_TRUE(StateBytes(scene) == original) << c.name << " changed the scene";
  }
  // Every refusal followed by every other: each still says what it said alone and changes nothing.
  for (const Change& first : refused) {
    Scene scene = *demo_;
    EXPECT_THROW(first.apply(scene), Error) << first.name;
    for (std::size_t k = 0; k < refused.size(); ++k) {
      try {
        refused[k].apply(scene);
        ADD_FAILURE() << refused[k].name << " after " << first.name << ": accepted";
      } catch (const Error& e) {
        EXPECT_EQ(messages[k], e.what()) << refused[k].name << " after " << first.name;
      }
      EXPECT_TRUE(StateBytes(scene) == original) << refused[k].name << " after " << first.name << " changed the scene";
    }
    // And an accepted change afterwards gives what it gives on the scene as loaded.
    Scene fresh = *demo_;
    const glm::dmat4 step = translation(0.5, 0.25, -0.75);
    scene.moveInstance(moved, step);
    fresh.moveInstance(moved, step);
    EXPECT_TRUE(StateBytes(scene) == StateBytes(fresh)) << "a move after " << first.name;
  }
}

TEST_F(SceneChanges, NonFiniteTransformsNameTheEntry) {
  Scene scene = *demo_;
  try {
    glm::dmat4 m(1.0);
    m[3][1] = std::numeric_limits<double>::quiet_NaN();
    scene.moveInstance(2, m);
    FAIL() << "accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("moveInstance: instance 2: transform[3][1] is nan"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace vs
