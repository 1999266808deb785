// layout_probe.h: where the GLSL side places each member of the shared GPU records (DESIGN.md §4), measured
// by running compute/shaders/layout_probe.comp, for comparison with the C++ layout.
#ifndef VOXSHADOW_LAYOUT_PROBE_H
#define VOXSHADOW_LAYOUT_PROBE_H

#include <cstdint>
#include <string>
#include <vector>

#include "compute/vulkan/vulkan_tracer.h"

namespace vs {

struct GpuStructLayout {
  std::string name;     // Region, Sector, Brick, ObjectRecord, BvhNode, Affine, InstanceRecord, TraceView,
                        // TraceRay, RayHit
  std::int64_t stride;  // array stride in bytes (the std430 size); -1 when not found
  // Byte offset of each scalar of element 0, in declaration order (vectors component by component,
  // matrices column by column); -1 where the shader's write was not found.
  std::vector<std::int64_t> scalarOffsets;
};

struct LayoutProbeResult {
  std::vector<GpuStructLayout> layouts;  // in the order listed above
  std::vector<std::string> validationMessages;
  std::string device;
};

// Runs the probe shader once on the chosen device. Throws vs::Error(Runtime) when no device is usable.
LayoutProbeResult probeGpuLayouts(const VulkanOptions& options = {});

}  // namespace vs

#endif
