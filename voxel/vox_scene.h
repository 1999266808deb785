// vox_scene.h: a .vox file as voxshadow objects and placements (DESIGN.md §2, §3): each distinct model one
// object, each visible shape node one placement, in Y-up world space.
//
// Placement rule. MagicaVoxel shows voxel (x, y, z) of a model of size s = (sx, sy, sz) under a shape whose
// transform nodes compose to the integer rotation R (signed permutation) and translation T as the unit cube
//     T + R * ([x, x+1] x [y, y+1] x [z, z+1] - floor(s / 2))
// (the pivot floor(s/2) taken per axis, the rotation applied about it, in MagicaVoxel's Z-up space). The cube's
// centre is T + R * ((x, y, z) + 0.5 - floor(s/2)); its corners stay on the integer lattice for every rotation.
// voxshadow's Y-up world is reached by the right-handed rotation Zup->Yup: (x, y, z) -> (x, z, -y) (a -90 degree
// turn about x, determinant +1), then scaled by the asset's voxel size v. So brick space (voxel (x, y, z)
// covers [x, x+1) ...) maps to the asset's space by
//     brickToAsset = scale(v) * ZupToYup * [R | T] * translate(-floor(s / 2)).
#ifndef VOXSHADOW_VOX_SCENE_H
#define VOXSHADOW_VOX_SCENE_H

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "voxel/vox_reader.h"
#include "voxel/voxel_object.h"

namespace vs {

struct VoxAssetOptions {
  double voxelSize = 1.0;  // world units per voxel; > 0 and finite
  // Empty: the whole scene graph. Decimal digits: that model (0-based, file order) alone, unrotated, with its
  // pivot at the asset's origin. Anything else: the first visible shape (depth-first) whose shape node or
  // nearest named transform node above it has this name, placed where the scene graph puts it.
  std::string model;
  int frame = 0;  // animation frame (VoxReadOptions::frame)
};

struct VoxPlacement {
  std::size_t object = 0;       // into VoxAsset::objects
  int model = 0;                // the file's model index
  std::string name;             // VoxInstance::name
  glm::dmat4 brickToAsset{1.0}; // the placement rule above
};

struct VoxAsset {
  std::vector<VoxelObject> objects;   // one per distinct model that is placed, first use first
  std::vector<VoxPlacement> placements;
  std::vector<std::string> notes;     // the reader's notes, plus which model was taken and which were shared
};

// The 4x4 Z-up to Y-up rotation (x, y, z) -> (x, z, -y).
glm::dmat4 voxZupToYup();

// brickToAsset of the placement rule. Preconditions: size components >= 1, voxelSize > 0.
glm::dmat4 voxPlacementMatrix(glm::ivec3 size, const VoxTransform& transform, double voxelSize);

// The file's palette as voxshadow's: entry 0 unused (black), entries 1..255 the sRGB colours made linear.
std::vector<glm::vec3> voxLinearPalette(const std::array<std::uint32_t, 256>& palette);

// Objects and placements of a file already read. Preconditions: options.voxelSize > 0 and finite (else
// vs::Error(BadInput)); a model index out of range or a name no visible shape has is vs::Error(BadInput)
// naming the file and listing what it has.
VoxAsset buildVoxAsset(const VoxFile& file, const VoxAssetOptions& options = {});

// readVoxFile then buildVoxAsset.
VoxAsset loadVox(const std::string& path, const VoxAssetOptions& options = {});

// What `voxshadow info` reports of a .vox file.
struct VoxModelInfo {
  glm::ivec3 size{0};
  std::uint64_t voxelCount = 0;     // distinct voxels (the XYZI count less duplicates)
  int paletteEntriesUsed = 0;       // distinct colour indices
  int instanceCount = 0;            // visible placements of it in the whole scene graph
  int sharedWith = -1;              // the first model with identical voxels and size, else -1
  BrickmapMemory brickmapMemory;
};
struct VoxInstanceInfo {
  int model = 0;
  std::string name;
  int shapeNode = -1;
  glm::dvec3 boxMin{0.0}, boxMax{0.0};  // the model's SIZE box in Y-up world units (voxel size 1)
};
struct VoxInfo {
  int version = 0;
  bool hasPaletteChunk = false;
  bool hasSceneGraph = false;
  int packModels = -1;      // VoxFile::packModels
  bool packFrames = false;  // the models are PACK animation frames and `instances` shows `frame` alone
  int frame = 0;
  std::vector<VoxModelInfo> models;
  std::vector<VoxInstanceInfo> instances;
  std::vector<VoxMaterial> materials;
  std::vector<VoxLayer> layers;
  std::vector<std::string> notes;
};

// Preconditions: none; the reader's errors propagate.
VoxInfo inspectVox(const std::string& path, const VoxReadOptions& options = {});

}  // namespace vs

#endif
