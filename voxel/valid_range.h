// valid_range.h: the valid range of every number a scene holds (DESIGN.md §2, README "Valid ranges").
// Chosen so that the float arithmetic of the tracers (shader and CPU) stays finite and its integer voxel
// coordinates stay far inside int range; values outside are refused where they are read, naming the file and
// the field.
#ifndef VOXSHADOW_VOXEL_VALID_RANGE_H
#define VOXSHADOW_VOXEL_VALID_RANGE_H

#include <cmath>
#include <cstdint>

namespace vs::limits {

// World positions (light and camera positions, targets, translations, matrix translations) and every corner
// of an instance's world box lie within [-kMaxCoordinate, kMaxCoordinate] on each axis: an open world of
// 200 km at metre units, with float coordinates still resolving about a centimetre at its edge.
inline constexpr double kMaxCoordinate = 1e5;
// Whether v is a world coordinate within that range (NaN is not).
inline bool isWorldCoordinate(double v) { return std::abs(v) <= kMaxCoordinate; }

// An asset's voxel size (the length of each axis of its index-to-object map) and an instance's scale (the
// length of each axis of its transform): a factor of 10^4 either way covers millimetre detail in metre scenes
// and kilometre tiles, while products of the two stay normal floats.
inline constexpr double kMinVoxelSize = 1e-4, kMaxVoxelSize = 1e4;
inline constexpr double kMinScale = 1e-4, kMaxScale = 1e4;

// Distances (light ranges, camera near and far planes, cascade distances) are positive and at most this:
// across the whole coordinate cube.
inline constexpr double kMaxDistance = 1e6;

// A ray's origin, expressed in an object's voxels, lies within this many voxels of the object's box. Rays are
// re-based near each object they enter (compute/shared/traverse.h, vsInstanceBaseT), at most 2^-15 of the
// distance before it: within 2^26 voxels that is 2^11 voxels, where float voxel coordinates still resolve
// 2^-13 of a voxel, well inside the 1e-3 voxel the depths are held to.
inline constexpr double kMaxRayVoxels = 67108864.0;  // 2^26

// Colours and intensities: non-negative and at most this, so that sums over many lights stay finite.
inline constexpr double kMaxRadiometric = 1e6;

// Biases, in world units (depth) and texels (normal offset).
inline constexpr double kMaxDepthBias = 1e3;
inline constexpr double kMaxNormalBias = 1e3;

// Camera images: at most this many pixels a side.
inline constexpr int kMaxImageSide = 16384;

// Rotation angles in degrees: beyond a few turns a float-sized angle has lost its sub-degree precision.
inline constexpr double kMaxAngleDeg = 3600.0;

// Largest scene file read into memory (scene files are small; this stops /dev/zero and runaway files).
inline constexpr std::uint64_t kMaxSceneFileBytes = 64ull << 20;

}  // namespace vs::limits

#endif
