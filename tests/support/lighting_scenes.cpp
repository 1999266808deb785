// lighting_scenes.cpp: the lighting tests' scenes.
#include "support/lighting_scenes.h"

#include <cmath>
#include <fstream>
#include <random>

#include <openvdb/openvdb.h>

namespace vs::test {

void writeBoxesVdb(const std::filesystem::path& file, const VoxelBoxSet& set) {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("solid");
  for (const auto& [lo, hi] : set.boxes)
    grid->tree().fill(openvdb::CoordBBox(openvdb::Coord(lo.x, lo.y, lo.z), openvdb::Coord(hi.x, hi.y, hi.z)), true, true);
  openvdb::io::File(file.string()).write({grid});
}

VoxelBoxSet floorBoxes() { return {{{glm::ivec3(0, 0, 0), glm::ivec3(95, 3, 95)}}}; }

VoxelBoxSet floorWithBoxBoxes() {
  VoxelBoxSet s = floorBoxes();
  s.boxes.push_back({glm::ivec3(42, 4, 42), glm::ivec3(53, 13, 53)});
  return s;
}

VoxelBoxSet terrainBoxes() {
  VoxelBoxSet s = floorBoxes();
  // Columns of 4 x 4 voxels whose height climbs one voxel per column along x and every other column along z:
  // a staircase slope with both kinds of step.
  for (int cx = 0; cx < 24; ++cx)
    for (int cz = 0; cz < 24; ++cz) {
      const int h = cx / 2 + cz / 3;
      if (h > 0) s.boxes.push_back({glm::ivec3(cx * 4, 4, cz * 4), glm::ivec3(cx * 4 + 3, 3 + h, cz * 4 + 3)});
    }
  return s;
}

VoxelBoxSet cityBoxes() {
  VoxelBoxSet s = floorBoxes();
  std::mt19937 rng(7);
  auto draw = [&](int lo, int hi) { return lo + int(rng() % unsigned(hi - lo + 1)); };
  for (int i = 0; i < 40; ++i) {
    const int sx = draw(3, 10), sz = draw(3, 10), sy = draw(4, 24);
    const int x0 = draw(2, 93 - sx), z0 = draw(2, 93 - sz);
    s.boxes.push_back({glm::ivec3(x0, 4, z0), glm::ivec3(x0 + sx - 1, 3 + sy, z0 + sz - 1)});
  }
  return s;
}

glm::dvec3 sunDirection(double elevationDeg, double azimuthDeg) {
  const double e = glm::radians(elevationDeg), a = glm::radians(azimuthDeg);
  return -glm::dvec3(std::cos(e) * std::cos(a), std::sin(e), std::cos(e) * std::sin(a));
}

std::filesystem::path writeLightingScene(const std::filesystem::path& dir, const std::string& name,
                                         const std::filesystem::path& vdb, const glm::dvec3& sunDir,
                                         const nlohmann::json& shadow, const nlohmann::json& camera) {
  nlohmann::json shadowJson = {{"resolution", 1024}, {"cascades", 3}, {"max_distance", 160}, {"filter", "hard"}};
  for (auto it = shadow.begin(); it != shadow.end(); ++it) shadowJson[it.key()] = it.value();
  nlohmann::json cameraJson = {{"position", {110, 60, 120}}, {"target", {48, 4, 48}}, {"fov_deg", 50},
                               {"near", 0.5},   {"far", 300},    {"width", 320},        {"height", 240}};
  for (auto it = camera.begin(); it != camera.end(); ++it) cameraJson[it.key()] = it.value();
  nlohmann::json scene = {
      {"version", 1},
      {"assets", {{"world", {{"file", vdb.filename().string()}, {"color", {0.7, 0.7, 0.7}}}}}},
      {"instances", {{{"asset", "world"}}}},
      {"camera", cameraJson},
      {"ambient", {{"color", {0.6, 0.7, 1.0}}, {"intensity", 0.2}}},
      {"lights",
       {{{"name", "sun"}, {"type", "directional"}, {"direction", {sunDir.x, sunDir.y, sunDir.z}}, {"intensity", 3},
         {"shadow", shadowJson}}}}};
  const std::filesystem::path file = dir / (name + ".json");
  std::ofstream(file) << scene.dump(2);
  return file;
}

bool receivesLight(const LightDesc& light, const gpu::GBufferTexel& g, glm::dvec3& toLight) {
  if (g.info.w == 0u) return false;
  const glm::dvec3 p(glm::vec3(g.position));
  toLight = light.type == LightType::Directional ? -glm::dvec3(light.direction) : glm::normalize(glm::dvec3(light.position) - p);
  if (light.type != LightType::Directional && glm::length(glm::dvec3(light.position) - p) > light.range) return false;
  if (light.type == LightType::Spot &&
      glm::dot(-toLight, glm::dvec3(light.direction)) < std::cos(glm::radians(double(light.outerConeDeg))))
    return false;
  return glm::dot(glm::dvec3(glm::vec3(g.normal)), toLight) > 0.0;
}

}  // namespace vs::test
