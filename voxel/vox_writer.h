// vox_writer.h: MagicaVoxel .vox files written by voxshadow (the demo world's asset, test files).
#ifndef VOXSHADOW_VOX_WRITER_H
#define VOXSHADOW_VOX_WRITER_H

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "voxel/vox_reader.h"

namespace vs {

using VoxDict = std::map<std::string, std::string>;

// One scene-graph node as the file stores it; ids and child ids are written as given, unchecked, so that
// tests can write graphs the reader must refuse.
struct VoxWriteNode {
  enum class Kind { Transform, Group, Shape };
  Kind kind = Kind::Transform;
  int id = 0;
  VoxDict attributes;                          // "_name", "_hidden"
  int child = -1;                              // Transform
  int layer = -1;                              // Transform
  std::vector<VoxDict> frames;                 // Transform: "_r", "_t", "_f"; none written as one empty frame
  std::vector<int> children;                   // Group
  std::vector<std::pair<int, VoxDict>> models; // Shape: model id and its "_f"
};

struct VoxWriteFile {
  int version = 200;
  std::optional<int> pack;                               // a PACK chunk with this model count, first in MAIN
  std::vector<VoxModel> models;                          // each written as SIZE + XYZI
  std::optional<std::array<std::uint32_t, 256>> palette; // by colour index (entry 0 unused); none: no RGBA chunk
  std::vector<VoxWriteNode> nodes;                       // in this order, after the models
  std::vector<VoxLayer> layers;
  std::vector<VoxMaterial> materials;
};

// The file's bytes. Preconditions: none (what is given is written; a model's voxels are written as they are).
std::vector<std::uint8_t> encodeVox(const VoxWriteFile& file);

// The usual three-level graph: root transform 0 -> group 1 -> for each instance a transform and a shape.
// Each entry is (model, "_r" packed rotation, translation).
struct VoxPlaced {
  int model = 0;
  int rotation = 4;  // the identity
  std::array<int, 3> translation{0, 0, 0};
  std::string name;
};
std::vector<VoxWriteNode> voxSceneGraph(const std::vector<VoxPlaced>& placed);

// Writes encodeVox(file) to path. Throws vs::Error(Runtime) naming the path when the write fails.
void writeVoxFile(const std::filesystem::path& path, const VoxWriteFile& file);

}  // namespace vs

#endif
