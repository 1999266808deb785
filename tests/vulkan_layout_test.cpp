// The GLSL std430 layout of every shared GPU record, measured on the device, equals the C++ layout.
#include <cstddef>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bvh/bvh_layout.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "compute/vulkan/layout_probe.h"
#include "voxel/brickmap_layout.h"

namespace {

struct Member {
  const char* name;
  std::size_t offset;
  int scalars;
};

struct Expected {
  const char* name;
  std::size_t size;
  std::vector<Member> members;
};

// Scalar offsets in declaration order, as layout_probe.comp numbers its sentinels.
std::vector<std::int64_t> scalarOffsets(const Expected& e) {
  std::vector<std::int64_t> out;
  for (const Member& m : e.members)
    for (int c = 0; c < m.scalars; ++c) out.push_back(std::int64_t(m.offset) + 4 * c);
  return out;
}

#define VS_MEMBER(T, m, n) Member{#m, offsetof(vs::gpu::T, m), n}

std::vector<Expected> cppLayouts() {
  using namespace vs::gpu;
  return {
      {"Region", sizeof(Region),
       {VS_MEMBER(Region, sectorMask, 2), VS_MEMBER(Region, firstSector, 1), VS_MEMBER(Region, reserved, 1)}},
      {"Sector", sizeof(Sector),
       {VS_MEMBER(Sector, brickMask, 2), VS_MEMBER(Sector, firstBrick, 1), VS_MEMBER(Sector, reserved, 1)}},
      {"Brick", sizeof(Brick),
       {VS_MEMBER(Brick, cellMask, 2), VS_MEMBER(Brick, occupancy, 1), VS_MEMBER(Brick, payload, 1)}},
      {"ObjectRecord", sizeof(ObjectRecord),
       {VS_MEMBER(ObjectRecord, regionOrigin, 4), VS_MEMBER(ObjectRecord, regionDims, 4),
        VS_MEMBER(ObjectRecord, voxelMin, 4), VS_MEMBER(ObjectRecord, voxelMax, 4), VS_MEMBER(ObjectRecord, bases, 4),
        VS_MEMBER(ObjectRecord, bases2, 4)}},
      {"BvhNode", sizeof(BvhNode),
       {VS_MEMBER(BvhNode, boundsMin, 3), VS_MEMBER(BvhNode, rightOrFirst, 1), VS_MEMBER(BvhNode, boundsMax, 3),
        VS_MEMBER(BvhNode, count, 1)}},
      {"Affine", sizeof(Affine), {VS_MEMBER(Affine, row0, 4), VS_MEMBER(Affine, row1, 4), VS_MEMBER(Affine, row2, 4)}},
      {"InstanceRecord", sizeof(InstanceRecord),
       {Member{"worldToBrick.row0", offsetof(InstanceRecord, worldToBrick) + offsetof(Affine, row0), 4},
        Member{"worldToBrick.row1", offsetof(InstanceRecord, worldToBrick) + offsetof(Affine, row1), 4},
        Member{"worldToBrick.row2", offsetof(InstanceRecord, worldToBrick) + offsetof(Affine, row2), 4},
        Member{"brickToWorld.row0", offsetof(InstanceRecord, brickToWorld) + offsetof(Affine, row0), 4},
        Member{"brickToWorld.row1", offsetof(InstanceRecord, brickToWorld) + offsetof(Affine, row1), 4},
        Member{"brickToWorld.row2", offsetof(InstanceRecord, brickToWorld) + offsetof(Affine, row2), 4},
        VS_MEMBER(InstanceRecord, boundsMin, 4), VS_MEMBER(InstanceRecord, boundsMax, 4),
        VS_MEMBER(InstanceRecord, info, 4), VS_MEMBER(InstanceRecord, anchor, 4)}},
      {"TraceView", sizeof(TraceView),
       {VS_MEMBER(TraceView, viewProj, 16), VS_MEMBER(TraceView, clipToEye, 16), VS_MEMBER(TraceView, eyeHigh, 4),
        VS_MEMBER(TraceView, eyeLow, 4),
        VS_MEMBER(TraceView, rect, 4), VS_MEMBER(TraceView, info, 4)}},
      {"TraceRay", sizeof(TraceRay),
       {VS_MEMBER(TraceRay, originHigh, 4), VS_MEMBER(TraceRay, originLow, 4), VS_MEMBER(TraceRay, direction, 4)}},
      {"RayHit", sizeof(RayHit),
       {VS_MEMBER(RayHit, voxel, 4), VS_MEMBER(RayHit, t, 1), VS_MEMBER(RayHit, instance, 1),
        VS_MEMBER(RayHit, material, 1), VS_MEMBER(RayHit, hit, 1)}},
      {"CameraRays", sizeof(CameraRays),
       {VS_MEMBER(CameraRays, originHigh, 4), VS_MEMBER(CameraRays, originLow, 4), VS_MEMBER(CameraRays, forward, 4),
        VS_MEMBER(CameraRays, right, 4), VS_MEMBER(CameraRays, up, 4), VS_MEMBER(CameraRays, size, 4)}},
      {"VisibilityRays", sizeof(VisibilityRays),
       {VS_MEMBER(VisibilityRays, boundsMin, 4), VS_MEMBER(VisibilityRays, boundsMax, 4),
        VS_MEMBER(VisibilityRays, counts, 4)}},
      {"VisibilityLight", sizeof(VisibilityLight),
       {VS_MEMBER(VisibilityLight, target, 4), VS_MEMBER(VisibilityLight, kind, 4)}},
      {"VisibilityReceiver", sizeof(VisibilityReceiver),
       {VS_MEMBER(VisibilityReceiver, position, 4), VS_MEMBER(VisibilityReceiver, normal, 4)}},
  };
}

TEST(VulkanLayout, GlslRecordsMatchCpp) {
  vs::VulkanOptions options;
  options.validation = true;
  vs::LayoutProbeResult probe = vs::probeGpuLayouts(options);
  std::vector<Expected> expected = cppLayouts();
  ASSERT_EQ(probe.layouts.size(), expected.size()) << "on " << probe.device;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const vs::GpuStructLayout& gpu = probe.layouts[i];
    const Expected& cpp = expected[i];
    ASSERT_EQ(gpu.name, cpp.name);
    EXPECT_EQ(gpu.stride, std::int64_t(cpp.size)) << cpp.name << " size (array stride) on " << probe.device;
    std::vector<std::int64_t> want = scalarOffsets(cpp);
    ASSERT_EQ(gpu.scalarOffsets.size(), want.size()) << cpp.name << ": scalars found";
    std::size_t k = 0;
    for (const Member& m : cpp.members)
      for (int c = 0; c < m.scalars; ++c, ++k)
        EXPECT_EQ(gpu.scalarOffsets[k], want[k]) << cpp.name << "." << m.name << " component " << c;
  }
  EXPECT_TRUE(probe.validationMessages.empty()) << "first validation message: " << probe.validationMessages.front();
}

}  // namespace
