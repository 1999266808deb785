// test_scenes.h: scenes built in code for the trace tests (CPU reference, OpenVDB peer, Vulkan).
#ifndef VOXSHADOW_TEST_SCENES_H
#define VOXSHADOW_TEST_SCENES_H

#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "compute/scene_data.h"
#include "voxel/brickmap.h"

namespace vs::test {

struct TestScene {
  std::string name;
  std::vector<std::unique_ptr<Brickmap>> brickmaps;
  std::vector<SceneInstance> instances;
  SceneData data;

  std::vector<const Brickmap*> brickmapPointers() const;
  void finish();  // builds `data` from brickmaps and instances
};

// Brickmap from an inclusive-exclusive voxel box.
std::unique_ptr<Brickmap> boxObject(glm::ivec3 min, glm::ivec3 max, std::uint8_t material = 1);

// Floor slab (y in [0, 8), 96 x 96), a few boxes and pillars with walls on brick and sector borders.
TestScene floorScene();
// A single voxel at the origin.
TestScene singleVoxelScene();
// A thin beam 4096 voxels long with a post every 512 voxels.
TestScene longObjectScene();
// No instances at all, plus a scene whose only object is empty.
TestScene emptyScene();
TestScene emptyObjectScene();
// `count` instances of a small irregular object, rotated and scaled non-uniformly, on a jittered grid.
TestScene manyInstancesScene(int count);
// The city512 benchmark voxels (DESIGN.md §10), one identity instance.
TestScene city512Scene();
// One instance of every non-empty grid chosen by default in every ../shared/assets/vdb/*.vdb, each scaled to
// about 20 world units, rotated and stretched non-uniformly, side by side along x.
TestScene thirdPartyAssetsScene();

// Directional view (orthographic, NDC depth) looking along `direction` over a world box, res x res.
gpu::TraceView directionalView(const Aabb& bounds, glm::vec3 direction, int res);
// Perspective linear-distance view from `position` looking along `direction`, 90 degree fov.
gpu::TraceView distanceView(glm::vec3 position, glm::vec3 direction, float range, int res, float fovDeg = 90.0f);

// Appends, for every view in `views`, a copy with the voxel-centre depth point traced over the rectangle
// inset by `inset` (x0, y0, x1, y1 margins), chosen not to be a multiple of any tile or workgroup.
void appendVoxelCenterCopies(std::vector<gpu::TraceView>& views, glm::ivec4 inset);

}  // namespace vs::test

#endif
