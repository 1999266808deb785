// Unit tests of the shared trace pieces (compute/shared/traverse.h) at exact ties: the exit selection of an
// empty box, the settle of a coordinate, and the texel value when two instances are entered at the same t.
#include <gtest/gtest.h>

#include <cstring>

#include <glm/gtc/matrix_transform.hpp>

#include "compute/cpu/scene_arrays.h"
#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "support/test_scenes.h"

namespace vs {
namespace {

gpu::SceneArrays noArrays;

struct Exit {
  bool stays;
  glm::ivec3 next;
  float t;
};

Exit boxExit(glm::vec3 o, glm::vec3 d, glm::ivec3 v, float tEnter, glm::ivec3 boxMin, glm::ivec3 boxEnd,
             float t1 = 100.0f, glm::ivec3 vmin = glm::ivec3(-64), glm::ivec3 vmax = glm::ivec3(64)) {
  gpu::SceneArrays::BoxWalk w{};
  w.ox = o.x, w.oy = o.y, w.oz = o.z;
  w.dx = d.x, w.dy = d.y, w.dz = d.z;
  w.ix = noArrays.vsInverseAxis(d.x), w.iy = noArrays.vsInverseAxis(d.y), w.iz = noArrays.vsInverseAxis(d.z);
  w.t1 = t1;
  w.minX = vmin.x, w.minY = vmin.y, w.minZ = vmin.z, w.maxX = vmax.x, w.maxY = vmax.y, w.maxZ = vmax.z;
  w.vx = v.x, w.vy = v.y, w.vz = v.z;
  w.tEnter = tEnter;
  Exit e{};
  e.stays = noArrays.vsBoxExit(w, boxMin.x, boxMin.y, boxMin.z, boxEnd.x, boxEnd.y, boxEnd.z, e.next.x, e.next.y,
                               e.next.z, e.t);
  return e;
}

TEST(TraverseShared, ExitSelectionTakesTheNearestFace) {
  Exit e = boxExit({0.5f, 0.5f, 0.5f}, {1.0f, 0.25f, 0.0f}, {0, 0, 0}, 0.0f, {0, 0, 0}, {4, 4, 4});
  EXPECT_TRUE(e.stays);
  EXPECT_EQ(e.next, glm::ivec3(4, 1, 0));  // x leaves at t = 3.5; y is at 1.375 then, z never moves
  EXPECT_EQ(e.t, 3.5f);
  // Toward -x: the voxel after the box is boxMin - 1.
  e = boxExit({3.5f, 0.5f, 0.5f}, {-1.0f, 0.0f, 0.0f}, {3, 0, 0}, 0.0f, {2, 0, 0}, {4, 1, 1});
  EXPECT_EQ(e.next, glm::ivec3(1, 0, 0));
  EXPECT_EQ(e.t, 1.5f);
}

TEST(TraverseShared, ExitTiesAreCrossedFromTheHighestAxisDown) {
  // Through the corner (1, 1, 1) of voxel 0 along the diagonal: z first, then y, then x, all at t = 0.5.
  const glm::vec3 o(0.5f), d(1.0f);
  Exit e = boxExit(o, d, {0, 0, 0}, 0.0f, {0, 0, 0}, {1, 1, 1});
  EXPECT_EQ(e.next, glm::ivec3(0, 0, 1));
  EXPECT_EQ(e.t, 0.5f);
  e = boxExit(o, d, e.next, e.t, e.next, e.next + 1);
  EXPECT_EQ(e.next, glm::ivec3(0, 1, 1));
  EXPECT_EQ(e.t, 0.5f);
  e = boxExit(o, d, e.next, e.t, e.next, e.next + 1);
  EXPECT_EQ(e.next, glm::ivec3(1, 1, 1));
  EXPECT_EQ(e.t, 0.5f);
  // A larger box on the same ray leaves through its own far corner, again z first.
  e = boxExit(o, d, {0, 0, 0}, 0.0f, {0, 0, 0}, {2, 2, 2});
  EXPECT_EQ(e.next, glm::ivec3(1, 1, 2));
  EXPECT_EQ(e.t, 1.5f);
}

TEST(TraverseShared, ExitEndsAtTheObjectOrTheSpan) {
  // The next voxel would lie outside the object's voxels [0, 4).
  EXPECT_FALSE(boxExit({0.5f, 0.5f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0, 0, 0}, 0.0f, {0, 0, 0}, {4, 4, 4}, 100.0f,
                       glm::ivec3(0), glm::ivec3(4))
                   .stays);
  // The face lies at t = 3.5, past the span's end t1 = 3; a face exactly at t1 is past it too.
  EXPECT_FALSE(boxExit({0.5f, 0.5f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0, 0, 0}, 0.0f, {0, 0, 0}, {4, 4, 4}, 3.0f).stays);
  EXPECT_FALSE(boxExit({0.5f, 0.5f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0, 0, 0}, 0.0f, {0, 0, 0}, {4, 4, 4}, 3.5f).stays);
  EXPECT_TRUE(boxExit({0.5f, 0.5f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0, 0, 0}, 0.0f, {0, 0, 0}, {4, 4, 4}, 3.6f).stays);
}

TEST(TraverseShared, SettleCorrectsAnEstimateOffByOne) {
  // Along +x from 0: at t = 2.5 the voxel is 2, whichever neighbour the estimate gave.
  for (int c : {1, 2, 3}) EXPECT_EQ(noArrays.vsSettleCoord(0.0f, 1.0f, 1.0f, c, 0, 5, 2.5f, false), 2) << c;
  // At t = 2 exactly, on the plane x = 2: crossed when ties count, not crossed otherwise.
  EXPECT_EQ(noArrays.vsSettleCoord(0.0f, 1.0f, 1.0f, 2, 0, 5, 2.0f, true), 2);
  EXPECT_EQ(noArrays.vsSettleCoord(0.0f, 1.0f, 1.0f, 2, 0, 5, 2.0f, false), 1);
  // Toward -x from 5: at t = 2 on the plane x = 3, the voxel below it once crossed.
  EXPECT_EQ(noArrays.vsSettleCoord(5.0f, -1.0f, -1.0f, 3, 0, 4, 2.0f, true), 2);
  EXPECT_EQ(noArrays.vsSettleCoord(5.0f, -1.0f, -1.0f, 3, 0, 4, 2.0f, false), 3);
  // Never outside [lo, hi].
  EXPECT_EQ(noArrays.vsSettleCoord(0.0f, 1.0f, 1.0f, 4, 0, 4, 9.0f, true), 4);
}

// Two instances entered at the same t: instance 0 is a unit voxel at [0, 1)^3, instance 1 the same voxel
// scaled by 2 about the origin. A ray along +x at y = z = 0.5 enters both at x = 0; the lower instance index
// wins, and the texel value at the voxel centre is measured to that instance's centre.
TEST(TraverseShared, TexelValueAtATieTakesTheLowerInstance) {
  for (bool scaledFirst : {false, true}) {
    test::TestScene s;
    s.brickmaps.push_back(test::boxObject({0, 0, 0}, {1, 1, 1}));
    glm::dmat4 unit(1.0), twice = glm::scale(glm::dmat4(1.0), glm::dvec3(2.0));
    s.instances.push_back({0u, scaledFirst ? twice : unit});
    s.instances.push_back({0u, scaledFirst ? unit : twice});
    s.finish();
    gpu::TraceView view = test::distanceView({-5.0f, 0.5f, 0.5f}, {1.0f, 0.0f, 0.0f}, 50.0f, 1, 1.0f);
    view.info.w = gpu::VS_DEPTH_POINT_VOXEL_CENTER;
    const double expected = scaledFirst ? std::sqrt(36.0 + 0.25 + 0.25) : 5.5;
    std::vector<float> values;
    for (CpuTracePath path : {CpuTracePath::Reference, CpuTracePath::Interleaved, CpuTracePath::PortableTiles}) {
      auto tracer = makeCpuTracer({path, 1});
      tracer->setScene(s.data);
      std::vector<ShadowLayer> layers;
      tracer->traceShadow(std::span<const gpu::TraceView>(&view, 1), layers);
      values.push_back(layers[0].texels[0]);
    }
    SCOPED_TRACE(scaledFirst ? "scaled instance first" : "unit instance first");
    EXPECT_NEAR(values[0], expected, 1e-4);
    for (float v : values) EXPECT_EQ(std::memcmp(&v, &values[0], sizeof v), 0);
    // The entry point is the same for both instances: x = 0, five units from the light.
    view.info.w = gpu::VS_DEPTH_POINT_ENTRY;
    auto tracer = makeCpuTracer({CpuTracePath::Reference, 1});
    tracer->setScene(s.data);
    std::vector<ShadowLayer> layers;
    tracer->traceShadow(std::span<const gpu::TraceView>(&view, 1), layers);
    EXPECT_NEAR(layers[0].texels[0], 5.0, 1e-4);
  }
}

}  // namespace
}  // namespace vs
