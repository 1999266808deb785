// trace_interface.h: the trace shader's interface (compute/shaders/shadow_trace.comp), readable as C++ and GLSL:
// the workgroup size, the binding numbers, the push-constant block and the specialization-constant ids, defined
// once so that the shader and the host (compute/vulkan/vulkan_tracer.cpp) cannot drift apart.
#ifndef VOXSHADOW_TRACE_INTERFACE_H
#define VOXSHADOW_TRACE_INTERFACE_H

#include "voxel/portable.h"

VS_NAMESPACE_BEGIN

// One invocation per texel in 8 x 8 workgroups: 64 invocations fill a subgroup on most GPUs, and lavapipe
// runs them as eight 8-lane SIMD batches over neighbouring (coherent) texels.
const uint VS_TRACE_GROUP_WIDTH = 8u;
const uint VS_TRACE_GROUP_HEIGHT = 8u;

// The brickmap arrays may each span this many storage buffers (chunks of 2^shift elements), so that no binding
// exceeds the device's maxStorageBufferRange (128 MiB on lavapipe); four cover 512 MiB per array there.
const int VS_MAX_CHUNKS = 4;
const uint VS_SPLIT_ARRAY_COUNT = 5u;  // region table, regions, sectors, bricks, occupancy: bindings 0..4

// Binding numbers of descriptor set 0.
const uint VS_BINDING_REGION_TABLE = 0u;  // storage buffers, VS_MAX_CHUNKS each (VS_BINDING_REGION_TABLE + i for
const uint VS_BINDING_REGIONS = 1u;       // split array i)
const uint VS_BINDING_SECTORS = 2u;
const uint VS_BINDING_BRICKS = 3u;
const uint VS_BINDING_OCCUPANCY = 4u;
const uint VS_BINDING_OBJECTS = 5u;           // RGBA32UI texel buffer (VS_OBJECT_TEXELS per record)
const uint VS_BINDING_INSTANCES = 6u;         // RGBA32UI texel buffer (VS_INSTANCE_TEXELS per record)
const uint VS_BINDING_NODES = 7u;             // RGBA32UI texel buffer (VS_NODE_TEXELS per node)
const uint VS_BINDING_INSTANCE_INDICES = 8u;  // R32UI texel buffer
const uint VS_BINDING_VIEW = 9u;              // uniform buffer, dynamic offset: the dispatch's TraceView
const uint VS_BINDING_SHADOW_IMAGE = 10u;     // R32F 2D-array storage image
const uint VS_BINDING_BOX_TABLE = 11u;        // R32I texel buffer
const uint VS_BINDING_NODE_ESCAPES = 12u;     // R32UI texel buffer
const uint VS_BINDING_COUNT = 13u;

// Specialization-constant ids (each a bool; see the shader for what each removes).
const int VS_SPEC_SPLIT_BINDINGS = 0;
const int VS_SPEC_BOX_TABLE = 1;
const int VS_SPEC_DEPTH_AT_CENTER = 2;

// The push-constant block of one dispatch.
struct TracePush {
  uint nodeCount;         // BVH nodes
  uint regionTableShift;  // log2 of the elements per chunk of each split array
  uint regionShift;
  uint sectorShift;
  uint brickShift;
  uint occupancyShift;
  uint layer;  // the image layer this dispatch writes
};

VS_NAMESPACE_END

#ifndef VS_GLSL
#include <compare>

namespace vs::gpu {
VS_LAYOUT_CHECK(TracePush, 28);
VS_OFFSET_CHECK(TracePush, regionTableShift, 4);
VS_OFFSET_CHECK(TracePush, occupancyShift, 20);
VS_OFFSET_CHECK(TracePush, layer, 24);

// A trace pipeline variant, by its named options (the specialization constants above).
struct TracePipelineOptions {
  bool splitBindings = false;  // some brickmap array spans more than one buffer
  bool boxTable = false;       // the object walk reads the box table instead of the brickmap hierarchy
  bool depthAtCenter = false;  // the view's depth point is the hit voxel's centre
  friend auto operator<=>(const TracePipelineOptions&, const TracePipelineOptions&) = default;
};
}  // namespace vs::gpu
#endif

#endif
