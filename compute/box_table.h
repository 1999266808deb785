// box_table.h: the box table that the object walks of every backend read (vsBoxWalkStep in
// compute/shared/lane_walk.h), built from a scene's brickmap arrays.
//
// Layout, one array of int32: each object's index of its first brick code; then, per object, one code per
// brick coordinate of its region table (16^3 per region slot, x fastest): VS_BOX_FULL for a full brick, the
// table index of its first occupancy word for a partial one, or the empty box grown around an empty brick
// (VS_BOX_* in compute/shared/trace_view.h); then a copy of the scene's occupancy words, to which the codes
// of partial bricks point. A step reads one code and, in a partial brick, one word of this one array. The
// cell level comes from the occupancy word too (a cell's mask bit is its occupancy byte != 0,
// voxel/brickmap_layout.h); the table is built only when every brick of the scene satisfies that, so the
// answers are the cell masks'.
#ifndef VOXSHADOW_BOX_TABLE_H
#define VOXSHADOW_BOX_TABLE_H

#include <cstdint>
#include <vector>

#include "compute/scene_data.h"

namespace vs {

// Largest extent (in bricks, per side) of the empty box recorded around an empty brick: a step crosses up to
// 2 * 15 + 1 bricks (248 voxels) at once; the code's extent fields hold no more.
constexpr int kMaxBoxExtent = gpu::VS_BOX_EXTENT_MASK;
// The default bound on a table's entries (256 MiB).
constexpr std::uint64_t kMaxBoxTableElements = std::uint64_t(1) << 26;

// The scene's box table, or an empty one when the scene cannot have one: more than maxElements entries (or
// 2^31), or a cell whose mask bit differs from its occupancy byte. The walks then read the brickmap
// hierarchy (vsObjectWalkStep), with the same results.
std::vector<std::int32_t> buildBoxTable(const SceneData& scene, std::uint64_t maxElements = kMaxBoxTableElements);

}  // namespace vs

#endif
