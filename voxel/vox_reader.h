// vox_reader.h: MagicaVoxel .vox files (versions 150 and 200) read into plain data: models, palette,
// materials, layers and the scene graph resolved into instances for one animation frame.
#ifndef VOXSHADOW_VOX_READER_H
#define VOXSHADOW_VOX_READER_H

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace vs {

// Limits that bound what a hostile file can make the reader allocate or compute. Every count in the file is
// also checked against the bytes that are actually there before anything is allocated.
inline constexpr int kVoxMaxModelSize = 2048;       // per axis; MagicaVoxel itself stops at 256
inline constexpr int kVoxMaxSceneDepth = 256;       // nested scene-graph nodes from the root to a shape
inline constexpr std::size_t kVoxMaxInstances = 1u << 20;
// Animation frames a caller may ask for, and keyframe indices a file may hold: 0..kVoxMaxFrame.
inline constexpr int kVoxMaxFrame = 1000000;

struct VoxVoxel {
  std::uint8_t x, y, z, colorIndex;  // colorIndex 1..255 (0 is refused)
};

struct VoxModel {
  glm::ivec3 size{0};  // each 1..kVoxMaxModelSize
  std::vector<VoxVoxel> voxels;  // every voxel inside [0, size); duplicates keep the last
};

struct VoxMaterial {
  int id = 0;                                // the palette index it describes (1..255)
  std::map<std::string, std::string> props;  // the file's dictionary as is: "_type", "_emit", "_ior", ...
  std::string type() const;                  // "_type" without the underscore, "diffuse" when absent
};

struct VoxLayer {
  int id = 0;
  std::string name;
  bool hidden = false;
};

// An integer rigid transform in MagicaVoxel's Z-up space: p' = rotation * p + translation, with rotation a
// signed permutation matrix (column-major, as GLM).
struct VoxTransform {
  glm::imat3x3 rotation{1};
  glm::ivec3 translation{0};
  VoxTransform then(const VoxTransform& child) const;  // this * child: child applied first
};

// One shape node reached from the root, with the product of every transform above it.
struct VoxInstance {
  int model = 0;          // index into VoxFile::models
  VoxTransform transform; // the shape's model space (pivot already removed, see voxModelPlacement) to scene
  std::string name;       // the nearest named transform node above the shape, else ""
  int shapeNode = -1;     // the shape node's id
  int layer = -1;         // layer of the nearest transform node above, -1 when none
};

struct VoxFile {
  std::string file;  // display name, as given
  int version = 0;
  std::vector<VoxModel> models;            // in file order
  std::array<std::uint32_t, 256> palette{};  // 0xAABBGGRR by colour index; entry 0 unused
  bool hasPaletteChunk = false;            // false: MagicaVoxel's default palette
  std::vector<VoxMaterial> materials;
  std::vector<VoxLayer> layers;
  bool hasSceneGraph = false;              // false: one instance per model at the origin, unrotated (but
                                           // see packFrames)
  int packModels = -1;                     // the PACK chunk's model count; -1 when the file has none
  // A PACK chunk and no scene graph: the models are the frames of an animation (MagicaVoxel 0.98 and
  // older), and only the model of the chosen frame is placed. With a scene graph the graph places the
  // models and PACK is only a count.
  bool packFrames = false;
  int frame = 0;                           // the frame asked for (VoxReadOptions::frame)
  std::vector<VoxInstance> instances;      // visible shapes for the chosen frame, depth-first in child order
  std::vector<std::string> notes;          // choices the reader made: hidden layers/nodes skipped, materials
                                           // not rendered, chunks skipped
};

struct VoxReadOptions {
  // Animation frame, 0..kVoxMaxFrame: each scene-graph node takes its last keyframe at or before it (else
  // its first); in a file of PACK frames (VoxFile::packFrames) it is the model shown, and must be one of them.
  int frame = 0;
};

// Reads a .vox file from memory. `name` is used in messages only. Preconditions: none on the bytes; every
// problem is vs::Error(BadInput) "<name>: <chunk> chunk at byte <offset>: <problem>": not a .vox file, an
// unsupported version, a truncated or overlong chunk, sizes outside 1..kVoxMaxModelSize, voxel counts larger
// than their chunk, voxels outside SIZE or with colour index 0, a scene graph with a dangling child, a cycle,
// more than 2^22 node visits (a shared subtree counts once per path to it), a depth beyond kVoxMaxSceneDepth,
// more than kVoxMaxInstances visible shapes, a shape naming a missing model, a second PACK chunk or one
// whose count is not positive, a frame outside 0..kVoxMaxFrame, or (PACK frames) a frame the file does not
// have, "<name>: frame F is beyond the N frames of its PACK animation (0..N-1)".
VoxFile readVox(std::span<const std::uint8_t> bytes, const std::string& name, const VoxReadOptions& options = {});

// Reads a .vox file from disk. Preconditions: none; a missing or unreadable file is vs::Error(BadInput)
// naming it, and so is everything readVox(bytes) refuses.
VoxFile readVoxFile(const std::string& path, const VoxReadOptions& options = {});

// MagicaVoxel's packed rotation byte (bits 0-1: column of row 0's non-zero entry, bits 2-3: row 1's, row 2
// takes the remaining column; bits 4, 5, 6: row 0, 1, 2 negative). Preconditions: none; returns false (and
// leaves `out` alone) when the two columns coincide or one is 3.
bool decodeVoxRotation(int packed, glm::imat3x3& out);

// The default palette MagicaVoxel uses when a file has no RGBA chunk, 0xAABBGGRR by colour index.
const std::array<std::uint32_t, 256>& voxDefaultPalette();

// An 8-bit sRGB channel as a linear value in [0, 1].
float srgbToLinear(std::uint8_t c);

}  // namespace vs

#endif
