// scene_data.h: a scene's objects, instances and BVH as the flat arrays that both trace backends read.
#ifndef VOXSHADOW_SCENE_DATA_H
#define VOXSHADOW_SCENE_DATA_H

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "bvh/bvh.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "voxel/brickmap.h"

namespace vs {

// One placed copy of an object: `brickToWorld` maps the object's brick space to world space
// (instance transform * the asset's own brickToObject).
struct SceneInstance {
  std::uint32_t object = 0;
  glm::dmat4 brickToWorld{1.0};
};

// Which scene array a dirty range belongs to. Bvh stands for the BVH's three arrays taken as one byte
// sequence, in this order: Bvh::nodes(), Bvh::instanceIndices(), Bvh::nodeEscapes().
enum class SceneArray { RegionTable, Regions, Sectors, Bricks, Occupancy, Payload, Objects, Instances, Bvh };
struct SceneDirtyRange {
  SceneArray array;
  std::size_t byteOffset = 0, byteSize = 0;
};
struct ObjectBricks {
  std::uint32_t object = 0;
  VoxelBox bricks;  // brick coordinates (voxel / 8), [min, max)
};

// What a change did to SceneData's arrays, so that a trace backend copies and rebuilds only that.
struct SceneDelta {
  std::vector<SceneDirtyRange> ranges;     // bytes to copy again, in the arrays as they are now
  std::vector<ObjectBricks> editedBricks;  // where voxels changed: the box table is rebuilt around these only
  // The voxel arrays were laid out anew (an object's array grew or moved, the arrays were compacted, or the last
  // object's region table grew, which moves box-table codes): copy them whole, rebuild the box table. The last
  // object's arrays growing at the arrays' end, and added objects, do not set it: their ranges say it all.
  bool voxelLayout = false;
  bool instances = false;  // instance records, their boxes or the BVH changed
  // Union of two deltas (a frame with several changes): ranges are merged per array (sorted, overlapping and
  // touching ones joined), edited bricks appended, flags or'ed.
  void merge(const SceneDelta& other);
  bool empty() const { return ranges.empty() && editedBricks.empty() && !voxelLayout && !instances; }
  // Bytes the ranges cover.
  std::size_t rangeBytes() const;
};

// The scene-wide arrays named as the shader's buffers (compute/shared/traverse.h). Objects' records are
// concatenated, densely and in object order; each ObjectRecord holds its bases. Built once, then updated in
// place by edits, added objects and instance changes, each of which reports what it changed (SceneDelta).
//
// Anchors: an instance's records are taken about its anchor (makeInstanceRecord), the image of a brick-space
// point fixed per object when the object is added (the centre of its voxel box then; for an object without
// voxels, the centre of its first voxels). Edits never move it, so an edit changes no ray that misses what
// it edited; a move or a switch to another object places it anew. A SceneData built from scratch from edited
// brickmaps therefore takes the anchors of the edited voxel boxes, and its instance records (not its
// voxel arrays) may differ from the edited scene's in the last bits of their affines.
//
// Instance slots: removeInstance leaves an empty slot (instanceActive false, an empty box, a record no ray
// can hit, left out of the BVH) that the next addInstance reuses, lowest first: indices never move, and an
// instance's id (InstanceRecord::info.y) is its slot.
struct SceneData {
  std::vector<std::uint32_t> regionTable;
  std::vector<gpu::Region> regions;
  std::vector<gpu::Sector> sectors;
  std::vector<gpu::Brick> bricks;
  std::vector<std::uint32_t> occupancy;
  std::vector<std::uint32_t> payload;  // palette bytes of the bricks with more than one material
  std::vector<gpu::ObjectRecord> objects;
  std::vector<gpu::InstanceRecord> instances;
  std::vector<Aabb> instanceBounds;  // world boxes, the BVH's input
  Bvh bvh;
  Aabb worldBounds;  // union of all instance boxes; empty when the scene has no solid voxel
  // Per object: the brick-space point its instances' anchors are the images of (see above).
  std::vector<glm::dvec3> objectAnchors;
  // Per object: how many elements of each voxel array (regionTable .. payload) its brickmap holds at its bases.
  // Its slice, up to the next object's bases, may be longer: an object that outgrew its slice is given
  // headroom when the arrays are laid out again, so that its next edits grow in place (zeros, read by no one).
  static constexpr std::size_t kVoxelArrayCount = 6;
  std::vector<std::array<std::size_t, kVoxelArrayCount>> objectSizes;
  // Per instance slot: its brick-to-world map (identity for an empty slot), and whether an instance holds it.
  std::vector<glm::dmat4> instanceTransforms;
  std::vector<std::uint8_t> instanceSlots;

  // Preconditions: every instance's object index < brickmaps.size(); transforms finite and invertible.
  // Throws vs::Error(BadInput) otherwise.
  static SceneData build(std::span<const Brickmap* const> brickmaps, std::span<const SceneInstance> instances);

  // --- Changes. Each checks everything before it changes anything: a refused call throws
  // vs::Error(BadInput) naming the call and what is wrong, and leaves every array as it was. A delta, when
  // given, receives what the call changed (merged into what it already holds).

  // After brickmaps[object] was edited (Brickmap::setVoxel, fillBox, clearBox, compact; `edit` is what the
  // edit returned; several edits' results may be given one call each, in order). Without a layout change the
  // edit's dirty ranges are copied into the scene's arrays at the object's bases and reported as scene
  // ranges. When the object's arrays changed size (edit.layoutChanged), they grow or shrink in place where
  // they fit the object's slice (the last object's always do: the arrays end there): the delta lists the
  // copied ranges, and sets voxelLayout only when the region table grew, which moves the object's box-table
  // codes. An object that outgrew its slice, and a compaction, lay out every voxel array again from
  // `brickmaps` and set voxelLayout: the one that outgrew its slice (unless last) gets half its size again as
  // headroom, the others (and a compacted one) none. The object's record takes its new voxel
  // bounds, and every instance of it its new world box about its kept anchor; the world's bounds and the BVH
  // follow (Bvh::update). editedBricks gets the edit's dirty voxels in bricks, rounded outward.
  // Preconditions: object < objects.size(); brickmaps.size() == objects.size(), every brickmap but
  // brickmaps[object] as the scene holds it (the same array sizes); each dirty range inside its array;
  // the arrays within 2^32 entries.
  SceneDelta updateObject(std::uint32_t object, std::span<const Brickmap* const> brickmaps, const EditResult& edit);
  // The object's box (ObjectRecord voxelMin/voxelMax) keeps its extent through edits while the voxels fit in
  // it, and grows past a fill that leaves it by boxHeadroom (within the region table): the box decides the last
  // bits of every t on the object, so an edit inside it changes no texel away from the edit. A grown box
  // changes the object's instance records (SceneDelta::instances) and every ray through them, so it grows in
  // proportion to the object (as a vector's capacity does): a game that keeps building upward on its ground
  // pays for a whole re-trace a logarithmic number of times, not once every few blocks.
  static constexpr int kBoxHeadroomVoxels = 16;
  // The headroom of a box that has to grow: half its largest side, at least kBoxHeadroomVoxels.
  // Precondition: box not empty.
  static int boxHeadroom(const VoxelBox& box);
  // Appends an object (no instance places it yet); the other objects' bases do not move, so the delta lists
  // the appended ranges only. Returns its index. Precondition: the arrays stay within 2^32 entries.
  std::uint32_t addObject(const Brickmap& brickmap, SceneDelta* delta = nullptr);
  // Places an instance in the lowest empty slot, else a new one, and returns its index. Preconditions:
  // instance.object < objects.size(); the transform finite and invertible.
  std::size_t addInstance(const SceneInstance& instance, SceneDelta* delta = nullptr);
  // Empties slot i (see "Instance slots" above). Precondition: instanceActive(i).
  void removeInstance(std::size_t i, SceneDelta* delta = nullptr);
  // Shows another object at instance i, placed by brickToWorld (e.g. a .vox animation's next frame); its
  // anchor becomes the image of the new object's anchor point. Preconditions: instanceActive(i),
  // object < objects.size(), brickToWorld finite and invertible.
  void setInstanceObject(std::size_t i, std::uint32_t object, const glm::dmat4& brickToWorld,
                         SceneDelta* delta = nullptr);
  bool instanceActive(std::size_t i) const { return i < instanceSlots.size() && instanceSlots[i] != 0; }

  // Where instance i would be after a move, computed aside from the arrays, so that a caller can check the
  // moved world before anything changes: the instance's record and world box, and the world's new bounds.
  struct Placement {
    gpu::InstanceRecord record{};
    Aabb box;
    Aabb worldBounds;
    glm::dmat4 brickToWorld{1.0};
  };
  // Preconditions: instanceActive(i), brickToWorld finite and invertible; throws vs::Error(BadInput)
  // otherwise, and changes nothing.
  Placement placeInstance(std::size_t i, const glm::dmat4& brickToWorld) const;
  // Takes a placement of instance i made by placeInstance on these arrays, and refits the BVH (rebuilding
  // it when refit quality drops, Bvh::update). Precondition: instanceActive(i).
  void applyPlacement(std::size_t i, const Placement& placement, SceneDelta* delta = nullptr);
  // placeInstance, then applyPlacement: a refused move changes nothing.
  void moveInstance(std::size_t i, const glm::dmat4& brickToWorld, SceneDelta* delta = nullptr);

 private:
  void placeAndCommit(std::size_t i, const gpu::InstanceRecord& record, const Aabb& box,
                      const glm::dmat4& brickToWorld, SceneDelta* delta);
  void refreshBvh(SceneDelta* delta);
};

// Builds the GPU record of one instance (both affine maps and the world box of its object's solid voxels),
// anchored at the image of the brick-space point `anchorPoint`.
gpu::InstanceRecord makeInstanceRecord(const glm::dmat4& brickToWorld, const VoxelBox& objectVoxels,
                                       const glm::dvec3& anchorPoint, std::uint32_t objectIndex,
                                       std::uint32_t instanceId, Aabb* worldBox);
// The same, anchored at the centre of objectVoxels (anchorPointOf).
gpu::InstanceRecord makeInstanceRecord(const glm::dmat4& brickToWorld, const VoxelBox& objectVoxels,
                                       std::uint32_t objectIndex, std::uint32_t instanceId, Aabb* worldBox);
// The anchor point an object with these voxels takes when it is added: their box's centre (0 when empty).
glm::dvec3 anchorPointOf(const VoxelBox& objectVoxels);

}  // namespace vs

#endif
