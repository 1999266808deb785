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
#include <utility>
#include <vector>

#include "compute/scene_data.h"

namespace vs {

// Largest extent (in bricks, per side) of the empty box recorded around an empty brick: a step crosses up to
// 2 * 15 + 1 bricks (248 voxels) at once; the code's extent fields hold no more.
constexpr int kMaxBoxExtent = gpu::VS_BOX_EXTENT_MASK;
// The one bound on a table's entries (256 MiB), the same on every backend, so that a scene is walked through
// its box table on all of them or on none: the CPU tracer builds its table under it, and the Vulkan tracer
// under it too (it is below every texel-buffer limit lavapipe and the usual GPUs have, 2^27 and up; a device
// whose limit is lower, or a test's VulkanOptions::maxBindingBytes, can only lower it there).
constexpr std::uint64_t kMaxBoxTableElements = std::uint64_t(1) << 26;

// The scene's box table, or an empty one when the scene cannot have one: more than maxElements entries (or
// 2^31), or a cell whose mask bit differs from its occupancy byte. The walks then read the brickmap
// hierarchy (vsObjectWalkStep), with the same results.
std::vector<std::int32_t> buildBoxTable(const SceneData& scene, std::uint64_t maxElements = kMaxBoxTableElements);

// What updateBoxTable did.
struct BoxTableUpdate {
  // The table was built whole with buildBoxTable (it may now be empty: no table): the delta laid the voxel
  // arrays out again, an object was added (the codes moved), the table was empty, or the edited scene's table
  // exceeds maxElements. Every element may differ.
  bool rebuilt = false;
  // Otherwise the element ranges whose values changed (with, at most, a few unchanged elements between changed
  // ones), as (first, count), sorted, disjoint and not touching: every other element kept its value. The table
  // kept its size, or grew at its end (the occupancy copy of an extended last object), which they cover.
  std::vector<std::pair<std::size_t, std::size_t>> rewritten;
};

// Brings a table built by buildBoxTable (or updated here) for the scene before `delta` up to date with the
// scene after it: the codes of the bricks within kMaxBoxExtent of delta.editedBricks (the only ones an edit
// can change: an empty brick's code records the empty box grown around it, up to kMaxBoxExtent bricks each
// side, and its empty sector or region) and the occupancy copy's words of delta's occupancy ranges. The
// result equals buildBoxTable(scene, maxElements) element for element. Preconditions: delta covers every
// change since the table was made (merge several); maxElements as when it was made.
BoxTableUpdate updateBoxTable(std::vector<std::int32_t>& table, const SceneData& scene, const SceneDelta& delta,
                              std::uint64_t maxElements = kMaxBoxTableElements);

}  // namespace vs

#endif
