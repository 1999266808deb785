// shadow_trace.comp: the portable traversal (compute/shared/traverse.h), one ray per invocation, for the ray kind
// the pipeline is specialized for (VS_RAY_* in compute/shared/trace_interface.h).
//
// Shadow texels: one dispatch per layer: x, y cover the layer's texel rectangle (8x8 workgroups). Each
// invocation offsets by the rectangle's origin and skips texels outside it, so a partial re-trace touches only
// the texels it was asked for. Closest- and any-hit rays: each workgroup takes VS_RAYS_PER_GROUP consecutive
// rays of the ray buffer from push.rayOffset; camera dispatches as many pixels, each ray made from the camera
// record (compute/shared/camera_rays.h); visibility dispatches as many (receiver, light) pairs, each ray made
// from the receiver and the light (compute/shared/visibility_rays.h).
//
// How the scene is read matters on llvmpipe (lavapipe), which runs 8 invocations as the lanes of one SIMD
// register: it loads from a storage buffer at a per-invocation index one lane at a time, behind a branch per
// lane, which made the per-ray record loads cost more than the walk. A texel fetch is one gather for all lanes,
// and a uniform-buffer member at a uniform offset one scalar load. So the records every ray reads (view,
// instances, nodes, objects) and the box table come as uniform and texel buffers; only the brickmap hierarchy,
// read where no box table exists, stays in storage buffers (which may be split across bindings).
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/brickmap_layout.h"
#include "bvh/bvh_layout.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
#include "compute/shared/trace_interface.h"
#include "compute/shared/lanes.h"
#include "compute/shared/camera_rays.h"
#include "compute/shared/visibility_rays.h"

layout(local_size_x = VS_TRACE_GROUP_WIDTH, local_size_y = VS_TRACE_GROUP_HEIGHT, local_size_z = 1) in;

// Each per-object array may span VS_MAX_CHUNKS buffers of 2^shift elements, so no binding exceeds the device's
// maxStorageBufferRange. Unused chunks are bound to a small placeholder buffer.
layout(std430, set = 0, binding = VS_BINDING_REGION_TABLE) readonly buffer RegionTableChunk { uint data[]; }
regionTableChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = VS_BINDING_REGIONS) readonly buffer RegionChunk { Region data[]; }
regionChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = VS_BINDING_SECTORS) readonly buffer SectorChunk { Sector data[]; }
sectorChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = VS_BINDING_BRICKS) readonly buffer BrickChunk { Brick data[]; }
brickChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = VS_BINDING_OCCUPANCY) readonly buffer OccupancyChunk { uint data[]; }
occupancyChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = VS_BINDING_PAYLOAD) readonly buffer PayloadChunk { uint data[]; }
payloadChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = VS_BINDING_RAYS) readonly buffer RayBuffer { TraceRay rays[]; };
layout(std430, set = 0, binding = VS_BINDING_HITS) writeonly buffer HitBuffer { RayHit hits[]; };
layout(std430, set = 0, binding = VS_BINDING_OCCLUDED) writeonly buffer OccludedBuffer { uint occluded[]; };
// Camera dispatches: the row-major pixels to trace (the record's size.z of them; 0: every pixel). The record
// itself comes through the view's uniform binding (CameraViewBlock), which llvmpipe loads once for all lanes
// where it loaded a storage buffer's copy lane by lane for every ray.
layout(std430, set = 0, binding = VS_BINDING_CAMERA) readonly buffer CameraBuffer { uint cameraPixels[]; };
// Visibility dispatches: the record, then its counts.x lights and counts.y receivers, two vec4 each
// (VisibilityLight, VisibilityReceiver); or, when the receivers are the device's (counts.z = 1), the lights and
// then, where counts.w = 1, the receivers' pixels, read through a second view of the same buffer.
layout(std430, set = 0, binding = VS_BINDING_VISIBILITY) readonly buffer VisibilityBuffer {
  VisibilityRays visibility;
  vec4 visibilityEntries[];
};
layout(std430, set = 0, binding = VS_BINDING_VISIBILITY) readonly buffer VisibilityWordBuffer { uint visibilityWords[]; };
layout(std430, set = 0, binding = VS_BINDING_RECEIVERS) readonly buffer ReceiverBuffer { VisibilityReceiver deviceReceivers[]; };
// Records as RGBA32UI texels (the VS_*_TEXELS of the layout headers), instance indices and node escapes
// (Bvh::nodeEscapes) as R32UI.
layout(set = 0, binding = VS_BINDING_OBJECTS) uniform usamplerBuffer objectTexels;
layout(set = 0, binding = VS_BINDING_INSTANCES) uniform usamplerBuffer instanceTexels;
layout(set = 0, binding = VS_BINDING_NODES) uniform usamplerBuffer nodeTexels;
layout(set = 0, binding = VS_BINDING_INSTANCE_INDICES) uniform usamplerBuffer instanceIndexTexels;
layout(set = 0, binding = VS_BINDING_NODE_ESCAPES) uniform usamplerBuffer nodeEscapeTexels;
// The layer's view, bound at a dynamic offset per dispatch. Every TraceView member is 16-byte aligned, so its
// std140 layout is its std430 one.
layout(std140, set = 0, binding = VS_BINDING_VIEW) uniform ViewBlock { TraceView currentView; };
// The same binding in camera dispatches: the frame's camera record (every CameraRays member is a 16-byte vector,
// so std140 is its std430 layout), at the start of the view's range.
layout(std140, set = 0, binding = VS_BINDING_VIEW) uniform CameraViewBlock { CameraRays cameraView; };
layout(set = 0, binding = VS_BINDING_SHADOW_IMAGE, r32f) uniform writeonly image2DArray shadowImage;
// The box table (traverse.h, vsObjectWalkBoxes): one first-code index per object, the codes, then the
// occupancy words the codes of partial bricks point to, so that a step reads this one texel buffer.
layout(set = 0, binding = VS_BINDING_BOX_TABLE) uniform isamplerBuffer boxTable;

layout(push_constant) uniform TracePushBlock { TracePush push; };
#define nodeCount (push.nodeCount)

// False when every array fits one binding (the usual case). A specialization constant, so the pipeline
// without splits drops the chunk selection at compile time: llvmpipe runs every branch of a divergent `if`
// with lanes masked off, which made each read cost four loads.
layout(constant_id = VS_SPEC_SPLIT_BINDINGS) const bool VS_SPLIT_BINDINGS = true;
// True when the host uploaded a box table: the object walks read it instead of the brickmap hierarchy
// (fewer, cheaper steps; same texels). A specialization constant, so each pipeline holds one walk only.
layout(constant_id = VS_SPEC_BOX_TABLE) const bool VS_BOX_TABLE = false;
// True when the dispatch's view puts its depth at the hit voxel's centre (TraceView info.w): a specialization
// constant, so a dispatch runs only its own view's depth code (llvmpipe would run both, lanes masked off).
layout(constant_id = VS_SPEC_DEPTH_AT_CENTER) const bool VS_DEPTH_AT_CENTER = false;
#define VS_VIEW_DEPTH_AT_CENTER(view) VS_DEPTH_AT_CENTER
// Which ray kind this pipeline traces.
layout(constant_id = VS_SPEC_RAY_KIND) const int VS_RAY_KIND = VS_RAY_SHADOW_TEXEL;

// A chunk index differs between invocations, so each case indexes the block array with a constant:
// no non-uniform descriptor indexing is needed.
#define VS_CHUNK_READ(T, chunks, shift, index)                                  \
  if (!VS_SPLIT_BINDINGS) return chunks[0].data[index];                         \
  T value;                                                                      \
  uint c = (index) >> (shift);                                                  \
  uint j = (index) & ((1u << (shift)) - 1u);                                    \
  if (c == 0u) value = chunks[0].data[j];                                       \
  else if (c == 1u) value = chunks[1].data[j];                                  \
  else if (c == 2u) value = chunks[2].data[j];                                  \
  else value = chunks[3].data[j];                                               \
  return value;

uint vsReadRegionTable(uint i) { VS_CHUNK_READ(uint, regionTableChunks, push.regionTableShift, i) }
Region vsReadRegion(uint i) { VS_CHUNK_READ(Region, regionChunks, push.regionShift, i) }
Sector vsReadSector(uint i) { VS_CHUNK_READ(Sector, sectorChunks, push.sectorShift, i) }
Brick vsReadBrick(uint i) { VS_CHUNK_READ(Brick, brickChunks, push.brickShift, i) }
uint vsReadOccupancy(uint i) { VS_CHUNK_READ(uint, occupancyChunks, push.occupancyShift, i) }
uint vsReadPayload(uint i) { VS_CHUNK_READ(uint, payloadChunks, push.payloadShift, i) }

#define VS_READ_REGION_TABLE(i) vsReadRegionTable(i)
#define VS_READ_REGIONS(i) vsReadRegion(i)
#define VS_READ_SECTORS(i) vsReadSector(i)
#define VS_READ_BRICKS(i) vsReadBrick(i)
#define VS_READ_OCCUPANCY(i) vsReadOccupancy(i)
#define VS_READ_PAYLOAD(i) vsReadPayload(i)
#define VS_READ_BOX_CODE(i) texelFetch(boxTable, int(i)).x

// The walk over the box table reads no array bases: that pipeline skips their fetches, unless its rays look
// up the hit voxel's material (closest hits) down the hierarchy.
const bool VS_READ_BASES = !VS_BOX_TABLE || VS_RAY_KIND == VS_RAY_CLOSEST || VS_RAY_KIND == VS_RAY_CAMERA;
ObjectRecord vsReadObject(uint i) {
  int t = int(i * VS_OBJECT_TEXELS);
  return ObjectRecord(ivec4(texelFetch(objectTexels, t)), ivec4(texelFetch(objectTexels, t + 1)),
                      ivec4(texelFetch(objectTexels, t + 2)), ivec4(texelFetch(objectTexels, t + 3)),
                      VS_READ_BASES ? texelFetch(objectTexels, t + 4) : uvec4(0u),
                      VS_READ_BASES ? texelFetch(objectTexels, t + 5) : uvec4(0u));
}

BvhNode vsReadNode(uint i) {
  int t = int(i * VS_NODE_TEXELS);
  uvec4 lo = texelFetch(nodeTexels, t);
  uvec4 hi = texelFetch(nodeTexels, t + 1);
  return BvhNode(uintBitsToFloat(lo.xyz), lo.w, uintBitsToFloat(hi.xyz), hi.w);
}

Affine vsReadAffine(int t) {
  return Affine(uintBitsToFloat(texelFetch(instanceTexels, t)), uintBitsToFloat(texelFetch(instanceTexels, t + 1)),
                uintBitsToFloat(texelFetch(instanceTexels, t + 2)));
}

#define VS_READ_OBJECT(i) vsReadObject(i)
#define VS_READ_NODE(i) vsReadNode(i)
#define VS_READ_INSTANCE_INDEX(i) texelFetch(instanceIndexTexels, int(i)).x
#define VS_READ_NODE_ESCAPE(i) texelFetch(nodeEscapeTexels, int(i)).x
#define VS_READ_INSTANCE_OBJECT(i) texelFetch(instanceTexels, int((i) * VS_INSTANCE_TEXELS + VS_INSTANCE_INFO_TEXEL)).x
#define VS_READ_WORLD_TO_BRICK(i) vsReadAffine(int((i) * VS_INSTANCE_TEXELS))
#define VS_READ_BRICK_TO_WORLD(i) vsReadAffine(int((i) * VS_INSTANCE_TEXELS + VS_INSTANCE_BRICK_TO_WORLD_TEXEL))
#define VS_READ_INSTANCE_TEXEL_XYZ(i, t) uintBitsToFloat(texelFetch(instanceTexels, int((i) * VS_INSTANCE_TEXELS + (t))).xyz)
#define VS_READ_INSTANCE_BOUNDS_MIN(i) VS_READ_INSTANCE_TEXEL_XYZ(i, VS_INSTANCE_BOUNDS_MIN_TEXEL)
#define VS_READ_INSTANCE_BOUNDS_MAX(i) VS_READ_INSTANCE_TEXEL_XYZ(i, VS_INSTANCE_BOUNDS_MAX_TEXEL)
#define VS_READ_INSTANCE_ANCHOR(i) VS_READ_INSTANCE_TEXEL_XYZ(i, VS_INSTANCE_ANCHOR_TEXEL)

#include "compute/shared/traverse.h"

void main() {
  if (VS_RAY_KIND == VS_RAY_SHADOW_TEXEL) {
    ivec2 texel = currentView.rect.xy + ivec2(gl_GlobalInvocationID.xy);
    if (texel.x >= currentView.rect.z || texel.y >= currentView.rect.w) return;
    imageStore(shadowImage, ivec3(texel, int(push.layer)), vec4(vsShadowTexel(currentView, texel)));
    return;
  }
  uint index = push.rayOffset + gl_WorkGroupID.x * VS_RAYS_PER_GROUP + gl_LocalInvocationIndex;
  if (index >= push.rayCount) return;
  if (VS_RAY_KIND == VS_RAY_CAMERA) {
    uint pixel = cameraView.size.z == 0u ? index : cameraPixels[index];
    hits[index] = vsClosestHit(vsTraceRayToWorld(vsCameraRay(cameraView, pixel)));
    return;
  }
  if (VS_RAY_KIND == VS_RAY_VISIBILITY) {
    // Invocations run light by light (answers are stored receiver by receiver): the lanes of a group trace one
    // light's rays from neighbouring receivers, so a light without rays (no contact length) does not idle lanes
    // beside another's walks, and a device that runs every branch any lane takes (llvmpipe) does not walk for
    // the lanes of lights that have none.
    uint lightCount = visibility.counts.x;
    uint receiverCount = visibility.counts.y;
    uint lightIndex = index / receiverCount;
    uint receiverIndex = index % receiverCount;
    uint l = 2u * lightIndex;
    VisibilityLight light = VisibilityLight(visibilityEntries[l], visibilityEntries[l + 1u]);
    VisibilityReceiver receiver;
    if (visibility.counts.z != 0u) {
      // The words after the record and the lights.
      uint pixel = visibility.counts.w != 0u
                       ? visibilityWords[VS_VISIBILITY_RECORD_WORDS + VS_VISIBILITY_LIGHT_WORDS * lightCount + receiverIndex]
                       : receiverIndex;
      receiver = deviceReceivers[pixel];
    } else {
      uint r = 2u * (lightCount + receiverIndex);
      receiver = VisibilityReceiver(visibilityEntries[r], visibilityEntries[r + 1u]);
    }
    occluded[receiverIndex * lightCount + lightIndex] =
        vsAnyHit(vsTraceRayToWorld(vsVisibilityRay(visibility, light, receiver))) ? 1u : 0u;
    return;
  }
  WorldRay ray = vsTraceRayToWorld(rays[index]);
  if (VS_RAY_KIND == VS_RAY_CLOSEST) {
    hits[index] = vsClosestHit(ray);
  } else {
    occluded[index] = vsAnyHit(ray) ? 1u : 0u;
  }
}
