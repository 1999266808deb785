// lighting_scenes.h: small scenes for the lighting tests, written as real files (BoolGrid .vdb assets and a
// scene JSON), with a camera and one directional light at a chosen elevation.
#ifndef VOXSHADOW_TEST_LIGHTING_SCENES_H
#define VOXSHADOW_TEST_LIGHTING_SCENES_H

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "lighting/scene_file.h"
#include "lighting/shared/shading_layout.h"

namespace vs::test {

struct VoxelBoxSet {
  std::vector<std::pair<glm::ivec3, glm::ivec3>> boxes;  // [min, max] inclusive, index space
};

// Writes a BoolGrid .vdb whose active voxels are the union of the boxes (as active tiles where they fit).
void writeBoxesVdb(const std::filesystem::path& file, const VoxelBoxSet& set);

VoxelBoxSet floorBoxes();              // a 96 x 4 x 96 slab at y 0..3
VoxelBoxSet floorWithBoxBoxes();       // the slab and a 12 x 10 x 12 box standing on it at x, z 42..53
VoxelBoxSet terrainBoxes();            // a staircase slope (heights rising along x and z) on the slab
VoxelBoxSet cityBoxes();               // the slab and 40 buildings (std::mt19937 seed 7)

// The direction light travels for a sun at `elevationDeg` above the horizon, from azimuth `azimuthDeg`.
glm::dvec3 sunDirection(double elevationDeg, double azimuthDeg = 35.0);

// A scene JSON with the asset at `vdb`, a camera over the 96 x 96 slab and a directional light (cascades,
// resolution, hard filter unless `shadow` overrides keys), written to dir/name.json; returns its path.
std::filesystem::path writeLightingScene(const std::filesystem::path& dir, const std::string& name,
                                         const std::filesystem::path& vdb, const glm::dvec3& sunDir,
                                         const nlohmann::json& shadow = nlohmann::json::object(),
                                         const nlohmann::json& camera = nlohmann::json::object());

// Whether G-buffer texel g is a receiver of `light` as the ray-traced truth sees it: a hit within a spot or
// point light's range (and a spot light's cone, outside which its maps say lit) whose face turns to the light;
// toLight is set to the unit direction toward the light.
bool receivesLight(const LightDesc& light, const gpu::GBufferTexel& g, glm::dvec3& toLight);

}  // namespace vs::test

#endif
