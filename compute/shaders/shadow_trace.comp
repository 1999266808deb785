// shadow_trace.comp: one invocation per shadow texel, running the portable traversal (compute/shared/traverse.h).
//
// Dispatch: one per layer (or per run of layers): x, y cover the texel rectangle (8x8 workgroups), z counts
// layers from layerBase. Each invocation offsets by its layer's rectangle origin and skips texels outside the
// rectangle, so a partial re-trace touches only the texels it was asked for.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/brickmap_layout.h"
#include "bvh/bvh_layout.h"
#include "compute/shared/trace_view.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

// Each per-object array may span several buffers of 2^shift elements, so no binding exceeds the device's
// maxStorageBufferRange. Unused chunks are bound to a small placeholder buffer.
#define VS_MAX_CHUNKS 4

layout(std430, set = 0, binding = 0) readonly buffer RegionTableChunk { uint data[]; } regionTableChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = 1) readonly buffer RegionChunk { Region data[]; } regionChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = 2) readonly buffer SectorChunk { Sector data[]; } sectorChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = 3) readonly buffer BrickChunk { Brick data[]; } brickChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = 4) readonly buffer OccupancyChunk { uint data[]; } occupancyChunks[VS_MAX_CHUNKS];
layout(std430, set = 0, binding = 5) readonly buffer ObjectBuffer { ObjectRecord objects[]; };
layout(std430, set = 0, binding = 6) readonly buffer InstanceBuffer { InstanceRecord instances[]; };
layout(std430, set = 0, binding = 7) readonly buffer NodeBuffer { BvhNode nodes[]; };
layout(std430, set = 0, binding = 8) readonly buffer InstanceIndexBuffer { uint instanceIndices[]; };
layout(std430, set = 0, binding = 9) readonly buffer ViewBuffer { TraceView views[]; };
layout(set = 0, binding = 10, r32f) uniform writeonly image2DArray shadowImage;
// The box table (traverse.h, vsObjectWalkStepBoxes): one first-code index per object, then the codes.
layout(std430, set = 0, binding = 11) readonly buffer BoxCodeBuffer { int boxCodes[]; };

layout(push_constant) uniform TracePush {
  uint nodeCount;
  uint layerCount;
  uint regionTableShift;
  uint regionShift;
  uint sectorShift;
  uint brickShift;
  uint occupancyShift;
  uint layerBase;  // layer of gl_GlobalInvocationID.z == 0
};

// False when every array fits one binding (the usual case). A specialization constant, so the pipeline
// without splits drops the chunk selection at compile time: llvmpipe runs every branch of a divergent `if`
// with lanes masked off, which made each read cost four loads.
layout(constant_id = 0) const bool VS_SPLIT_BINDINGS = true;
// True when the host uploaded a box table: the object walks read it instead of the brickmap hierarchy
// (fewer, cheaper steps; same texels). A specialization constant, so each pipeline holds one walk only.
layout(constant_id = 1) const bool VS_BOX_TABLE = false;

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

uint vsReadRegionTable(uint i) { VS_CHUNK_READ(uint, regionTableChunks, regionTableShift, i) }
Region vsReadRegion(uint i) { VS_CHUNK_READ(Region, regionChunks, regionShift, i) }
Sector vsReadSector(uint i) { VS_CHUNK_READ(Sector, sectorChunks, sectorShift, i) }
Brick vsReadBrick(uint i) { VS_CHUNK_READ(Brick, brickChunks, brickShift, i) }
uint vsReadOccupancy(uint i) { VS_CHUNK_READ(uint, occupancyChunks, occupancyShift, i) }

#define VS_READ_REGION_TABLE(i) vsReadRegionTable(i)
#define VS_READ_REGIONS(i) vsReadRegion(i)
#define VS_READ_SECTORS(i) vsReadSector(i)
#define VS_READ_BRICKS(i) vsReadBrick(i)
#define VS_READ_OCCUPANCY(i) vsReadOccupancy(i)
#define VS_READ_BOX_CODE(i) boxCodes[i]

#include "compute/shared/traverse.h"

void main() {
  uint layer = gl_GlobalInvocationID.z + layerBase;
  if (layer >= layerCount) return;
  TraceView view = views[layer];
  ivec2 texel = view.rect.xy + ivec2(gl_GlobalInvocationID.xy);
  if (texel.x >= view.rect.z || texel.y >= view.rect.w) return;
  imageStore(shadowImage, ivec3(texel, int(layer)), vec4(vsShadowTexel(view, texel)));
}
