// city512.h: the benchmark scene of DESIGN.md §10, generated in code.
#ifndef VOXSHADOW_CITY512_H
#define VOXSHADOW_CITY512_H

#include <cstdint>
#include <vector>

#include "voxel/brickmap.h"

namespace vs {

// Side of the city512 grid in voxels.
inline constexpr int kCity512Size = 512;
// The solid voxel count DESIGN.md §10 states for city512.
inline constexpr std::uint64_t kCity512SolidVoxels = 6458356;

// Solid voxels of city512 (each once, material 1, coordinates in [0, 512)^3), in x-fastest scan order.
// Deterministic: std::mt19937 seed 1, boxes drawn before spheres, in the order DESIGN.md §10 writes.
std::vector<SolidVoxel> city512Voxels();

}  // namespace vs

#endif
