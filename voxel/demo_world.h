// demo_world.h: the built-in demo world, written as real .vdb files and a scene file (DESIGN.md §8, §9).
#ifndef VOXSHADOW_DEMO_WORLD_H
#define VOXSHADOW_DEMO_WORLD_H

#include <filesystem>
#include <string>
#include <vector>

namespace vs {

// Writes ground.vdb (Int32 palette grid with relief, voxel size 0.5), building.vdb (Int32 palette grid),
// tower.vdb (bool grid), tree.vdb (vec3s colour grid `Cd`), blob.vdb (level-set sphere), crates.vox (a
// MagicaVoxel file with a scene graph, written by voxshadow) and demo.json
// (scene version 1) into `dir`, creating it if needed. Returns the written paths, the scene file last.
// Throws vs::Error(Runtime) naming the file when a write fails.
std::vector<std::string> writeDemoWorld(const std::filesystem::path& dir);

}  // namespace vs

#endif
