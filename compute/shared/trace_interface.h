// trace_interface.h: the trace shader's interface (compute/shaders/shadow_trace.comp), readable as C++ and GLSL:
// the workgroup size, the binding numbers, the push-constant block, the specialization-constant ids and the
// ray kinds, defined once so that the shader and the host (compute/vulkan/vulkan_tracer.cpp) cannot drift apart.
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
// region table, regions, sectors, bricks, occupancy, payload: bindings 0..5
const uint VS_SPLIT_ARRAY_COUNT = 6u;

// Binding numbers of descriptor set 0.
const uint VS_BINDING_REGION_TABLE = 0u;  // storage buffers, VS_MAX_CHUNKS each (VS_BINDING_REGION_TABLE + i for
const uint VS_BINDING_REGIONS = 1u;       // split array i)
const uint VS_BINDING_SECTORS = 2u;
const uint VS_BINDING_BRICKS = 3u;
const uint VS_BINDING_OCCUPANCY = 4u;
const uint VS_BINDING_PAYLOAD = 5u;
const uint VS_BINDING_OBJECTS = 6u;           // RGBA32UI texel buffer (VS_OBJECT_TEXELS per record)
const uint VS_BINDING_INSTANCES = 7u;         // RGBA32UI texel buffer (VS_INSTANCE_TEXELS per record)
const uint VS_BINDING_NODES = 8u;             // RGBA32UI texel buffer (VS_NODE_TEXELS per node)
const uint VS_BINDING_INSTANCE_INDICES = 9u;  // R32UI texel buffer
const uint VS_BINDING_VIEW = 10u;             // uniform buffer, dynamic offset: the dispatch's TraceView
const uint VS_BINDING_SHADOW_IMAGE = 11u;     // R32F 2D-array storage image
const uint VS_BINDING_BOX_TABLE = 12u;        // R32I texel buffer
const uint VS_BINDING_NODE_ESCAPES = 13u;     // R32UI texel buffer
const uint VS_BINDING_RAYS = 14u;             // storage buffer of TraceRay (closest- and any-hit dispatches)
const uint VS_BINDING_HITS = 15u;             // storage buffer of RayHit (closest-hit dispatches)
const uint VS_BINDING_OCCLUDED = 16u;         // storage buffer of uint (any-hit dispatches)
const uint VS_BINDING_CAMERA = 17u;           // storage buffer: the listed pixels (the record: VS_BINDING_VIEW)
const uint VS_BINDING_VISIBILITY = 18u;       // storage buffer: a VisibilityRays record, its lights, its receivers
                                              // or listed pixels
// storage buffer of VisibilityReceiver, one per pixel, made on the device (visibility dispatches whose record's
// counts.z is 1: VulkanTracer::traceVisibility with DeviceReceivers)
const uint VS_BINDING_RECEIVERS = 19u;
const uint VS_BINDING_COUNT = 20u;
// Storage buffers the shader declares: the split arrays' chunks, the three ray buffers, the camera's, the
// visibility rays' and the device's receivers. Within the 32 of lavapipe's maxPerStageDescriptorStorageBuffers.
const uint VS_STORAGE_BUFFER_COUNT = VS_SPLIT_ARRAY_COUNT * uint(VS_MAX_CHUNKS) + 6u;

// Specialization-constant ids (see the shader for what each removes).
const int VS_SPEC_SPLIT_BINDINGS = 0;   // bool
const int VS_SPEC_BOX_TABLE = 1;        // bool
const int VS_SPEC_DEPTH_AT_CENTER = 2;  // bool
const int VS_SPEC_RAY_KIND = 3;         // int: VS_RAY_*

// The ray kinds of one dispatch.
const int VS_RAY_SHADOW_TEXEL = 0;  // one texel of the view per invocation, into the shadow image
const int VS_RAY_CLOSEST = 1;       // one TraceRay per invocation, its RayHit out
const int VS_RAY_ANY = 2;           // one TraceRay per invocation, 1 out where its segment holds a solid voxel
const int VS_RAY_CAMERA = 3;        // one camera pixel per invocation, its ray made there, its RayHit out
const int VS_RAY_VISIBILITY = 4;    // one (receiver, light) per invocation, its ray made there, 1 out if occluded

// Rays per workgroup of a closest-hit, any-hit, camera or visibility dispatch: the 8 x 8 workgroup, read as one row.
const uint VS_RAYS_PER_GROUP = VS_TRACE_GROUP_WIDTH * VS_TRACE_GROUP_HEIGHT;

// The push-constant block of one dispatch.
struct TracePush {
  uint nodeCount;         // BVH nodes
  uint regionTableShift;  // log2 of the elements per chunk of each split array
  uint regionShift;
  uint sectorShift;
  uint brickShift;
  uint occupancyShift;
  uint payloadShift;
  uint layer;      // the image layer a shadow-texel dispatch writes
  uint rayOffset;  // the first ray of a closest-hit, any-hit, camera or visibility dispatch
  uint rayCount;   // rays in the whole buffer (camera: pixels in the frame or the list; visibility:
                   // receivers * lights)
};

VS_NAMESPACE_END

#ifndef VS_GLSL
#include <compare>

namespace vs::gpu {
VS_LAYOUT_CHECK(TracePush, 40);
VS_OFFSET_CHECK(TracePush, regionTableShift, 4);
VS_OFFSET_CHECK(TracePush, payloadShift, 24);
VS_OFFSET_CHECK(TracePush, layer, 28);
VS_OFFSET_CHECK(TracePush, rayOffset, 32);
VS_OFFSET_CHECK(TracePush, rayCount, 36);

enum class RayKind : int {
  ShadowTexel = VS_RAY_SHADOW_TEXEL,
  Closest = VS_RAY_CLOSEST,
  Any = VS_RAY_ANY,
  Camera = VS_RAY_CAMERA,
  Visibility = VS_RAY_VISIBILITY,
};

// A trace pipeline variant, by its named options (the specialization constants above).
struct TracePipelineOptions {
  bool splitBindings = false;  // some brickmap array spans more than one buffer
  bool boxTable = false;       // the object walk reads the box table instead of the brickmap hierarchy
  bool depthAtCenter = false;  // the view's depth point is the hit voxel's centre
  RayKind rayKind = RayKind::ShadowTexel;
  friend auto operator<=>(const TracePipelineOptions&, const TracePipelineOptions&) = default;
};
}  // namespace vs::gpu
#endif

#endif
