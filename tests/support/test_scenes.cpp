#include "support/test_scenes.h"

#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "voxel/city512.h"

namespace vs::test {

std::vector<const Brickmap*> TestScene::brickmapPointers() const {
  std::vector<const Brickmap*> out;
  for (const auto& b : brickmaps) out.push_back(b.get());
  return out;
}

void TestScene::finish() {
  auto pointers = brickmapPointers();
  data = SceneData::build(pointers, instances);
}

std::unique_ptr<Brickmap> boxObject(glm::ivec3 min, glm::ivec3 max, std::uint8_t material) {
  std::vector<SolidVoxel> voxels;
  for (int z = min.z; z < max.z; ++z)
    for (int y = min.y; y < max.y; ++y)
      for (int x = min.x; x < max.x; ++x) voxels.push_back({{x, y, z}, material});
  return std::make_unique<Brickmap>(Brickmap::build(voxels));
}

namespace {

void addBox(std::vector<SolidVoxel>& voxels, glm::ivec3 min, glm::ivec3 max) {
  for (int z = min.z; z < max.z; ++z)
    for (int y = min.y; y < max.y; ++y)
      for (int x = min.x; x < max.x; ++x) voxels.push_back({{x, y, z}, 1});
}

TestScene single(std::string name, std::vector<SolidVoxel> voxels) {
  TestScene s;
  s.name = std::move(name);
  s.brickmaps.push_back(std::make_unique<Brickmap>(Brickmap::build(voxels)));
  s.instances.push_back({0u, glm::dmat4(1.0)});
  s.finish();
  return s;
}

}  // namespace

TestScene floorScene() {
  std::vector<SolidVoxel> v;
  addBox(v, {0, 0, 0}, {96, 8, 96});      // floor, top face at y = 8
  addBox(v, {8, 8, 8}, {16, 40, 16});     // pillar exactly one brick wide, on brick borders
  addBox(v, {32, 8, 40}, {64, 24, 41});   // a wall one voxel thick on a sector border (x = 32)
  addBox(v, {70, 8, 70}, {73, 11, 73});   // small block not aligned to anything
  addBox(v, {40, 30, 8}, {41, 31, 9});    // a floating voxel
  addBox(v, {-20, 0, -20}, {-4, 4, -4});  // negative coordinates
  return single("floor", std::move(v));
}

TestScene singleVoxelScene() { return single("single-voxel", {{{0, 0, 0}, 1}}); }

TestScene longObjectScene() {
  std::vector<SolidVoxel> v;
  addBox(v, {0, 0, 0}, {4096, 1, 1});
  for (int x = 0; x < 4096; x += 512) addBox(v, {x, 1, 0}, {x + 1, 9, 1});
  return single("long-4096", std::move(v));
}

TestScene emptyScene() {
  TestScene s;
  s.name = "empty";
  s.finish();
  return s;
}

TestScene emptyObjectScene() { return single("empty-object", {}); }

TestScene manyInstancesScene(int count) {
  TestScene s;
  s.name = "instances-" + std::to_string(count);
  std::vector<SolidVoxel> v;
  addBox(v, {0, 0, 0}, {3, 2, 2});
  addBox(v, {0, 2, 0}, {1, 4, 1});
  s.brickmaps.push_back(std::make_unique<Brickmap>(Brickmap::build(v)));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int side = int(std::ceil(std::sqrt(double(count))));
  for (int i = 0; i < count; ++i) {
    glm::dvec3 pos((i % side) * 6.0 + unit(rng) * 2.0, unit(rng) * 10.0, (i / side) * 6.0 + unit(rng) * 2.0);
    glm::dmat4 m = glm::translate(glm::dmat4(1.0), pos);
    m = glm::rotate(m, unit(rng) * 6.283, glm::normalize(glm::dvec3(unit(rng) - 0.5, 1.0, unit(rng) - 0.5)));
    m = glm::scale(m, glm::dvec3(0.5 + unit(rng), 0.5 + unit(rng), 0.5 + unit(rng)));
    s.instances.push_back({0u, m});
  }
  s.finish();
  return s;
}

TestScene city512Scene() { return single("city512", city512Voxels()); }

gpu::TraceView directionalView(const Aabb& bounds, glm::vec3 direction, int res) {
  glm::vec3 d = glm::normalize(direction);
  glm::vec3 center = (bounds.min + bounds.max) * 0.5f;
  float radius = glm::length(bounds.max - bounds.min) * 0.5f + 1.0f;
  glm::vec3 up = std::abs(d.y) > 0.99f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
  glm::mat4 view = glm::lookAtRH(center - d * radius * 2.0f, center, up);
  glm::mat4 proj = glm::orthoRH_ZO(-radius, radius, -radius, radius, radius * 0.5f, radius * 3.5f);
  gpu::TraceView tv{};
  tv.viewProj = proj * view;
  tv.invViewProj = glm::inverse(tv.viewProj);
  tv.origin = glm::vec4(0.0f);
  tv.rect = glm::ivec4(0, 0, res, res);
  tv.info = glm::ivec4(res, res, gpu::VS_ENCODING_NDC_DEPTH, gpu::VS_DEPTH_POINT_ENTRY);
  return tv;
}

gpu::TraceView distanceView(glm::vec3 position, glm::vec3 direction, float range, int res, float fovDeg) {
  glm::vec3 d = glm::normalize(direction);
  glm::vec3 up = std::abs(d.y) > 0.99f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
  glm::mat4 view = glm::lookAtRH(position, position + d, up);
  glm::mat4 proj = glm::perspectiveRH_ZO(glm::radians(fovDeg), 1.0f, range * 1e-3f, range);
  gpu::TraceView tv{};
  tv.viewProj = proj * view;
  tv.invViewProj = glm::inverse(tv.viewProj);
  tv.origin = glm::vec4(position, range);
  tv.rect = glm::ivec4(0, 0, res, res);
  tv.info = glm::ivec4(res, res, gpu::VS_ENCODING_LINEAR_DISTANCE, gpu::VS_DEPTH_POINT_ENTRY);
  return tv;
}

}  // namespace vs::test
