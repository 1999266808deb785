// layout_probe.comp: writes a distinct sentinel into every scalar of two elements of each shared record
// array, so the host can find where GLSL's std430 layout places each member (compute/vulkan/layout_probe.h).
//
// Sentinel of struct s, element e, scalar k (declaration order, matrices column by column):
// 0x40000000 | s << 16 | e << 8 | k, a normal float when stored through a float member.
#version 450
#extension GL_GOOGLE_include_directive : require
#define VS_GLSL 1
#include "voxel/brickmap_layout.h"
#include "bvh/bvh_layout.h"
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"

layout(local_size_x = 1, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) buffer RegionProbe { Region regionProbe[]; };
layout(std430, set = 0, binding = 1) buffer SectorProbe { Sector sectorProbe[]; };
layout(std430, set = 0, binding = 2) buffer BrickProbe { Brick brickProbe[]; };
layout(std430, set = 0, binding = 3) buffer ObjectProbe { ObjectRecord objectProbe[]; };
layout(std430, set = 0, binding = 4) buffer NodeProbe { BvhNode nodeProbe[]; };
layout(std430, set = 0, binding = 5) buffer AffineProbe { Affine affineProbe[]; };
layout(std430, set = 0, binding = 6) buffer InstanceProbe { InstanceRecord instanceProbe[]; };
layout(std430, set = 0, binding = 7) buffer ViewProbe { TraceView viewProbe[]; };
layout(std430, set = 0, binding = 8) buffer RayProbe { TraceRay rayProbe[]; };
layout(std430, set = 0, binding = 9) buffer HitProbe { RayHit hitProbe[]; };
layout(std430, set = 0, binding = 10) buffer CameraProbe { CameraRays cameraProbe[]; };
layout(std430, set = 0, binding = 11) buffer VisibilityProbe { VisibilityRays visibilityProbe[]; };
layout(std430, set = 0, binding = 12) buffer VisibilityLightProbe { VisibilityLight visibilityLightProbe[]; };
layout(std430, set = 0, binding = 13) buffer ReceiverProbe { VisibilityReceiver receiverProbe[]; };

uint S(uint s, uint e, uint k) { return 0x40000000u | (s << 16) | (e << 8) | k; }
float F(uint s, uint e, uint k) { return uintBitsToFloat(S(s, e, k)); }
int I(uint s, uint e, uint k) { return int(S(s, e, k)); }
uvec2 U2(uint s, uint e, uint k) { return uvec2(S(s, e, k), S(s, e, k + 1u)); }
vec3 F3(uint s, uint e, uint k) { return vec3(F(s, e, k), F(s, e, k + 1u), F(s, e, k + 2u)); }
vec4 F4(uint s, uint e, uint k) { return vec4(F(s, e, k), F(s, e, k + 1u), F(s, e, k + 2u), F(s, e, k + 3u)); }
ivec4 I4(uint s, uint e, uint k) { return ivec4(I(s, e, k), I(s, e, k + 1u), I(s, e, k + 2u), I(s, e, k + 3u)); }
uvec4 U4(uint s, uint e, uint k) { return uvec4(S(s, e, k), S(s, e, k + 1u), S(s, e, k + 2u), S(s, e, k + 3u)); }
mat4 M4(uint s, uint e, uint k) { return mat4(F4(s, e, k), F4(s, e, k + 4u), F4(s, e, k + 8u), F4(s, e, k + 12u)); }
Affine A(uint s, uint e, uint k) { return Affine(F4(s, e, k), F4(s, e, k + 4u), F4(s, e, k + 8u)); }

void main() {
  for (uint e = 0u; e < 2u; ++e) {
    regionProbe[e].sectorMask = U2(0u, e, 0u);
    regionProbe[e].firstSector = S(0u, e, 2u);
    regionProbe[e].reserved = S(0u, e, 3u);

    sectorProbe[e].brickMask = U2(1u, e, 0u);
    sectorProbe[e].firstBrick = S(1u, e, 2u);
    sectorProbe[e].reserved = S(1u, e, 3u);

    brickProbe[e].cellMask = U2(2u, e, 0u);
    brickProbe[e].occupancy = S(2u, e, 2u);
    brickProbe[e].payload = S(2u, e, 3u);

    objectProbe[e].regionOrigin = I4(3u, e, 0u);
    objectProbe[e].regionDims = I4(3u, e, 4u);
    objectProbe[e].voxelMin = I4(3u, e, 8u);
    objectProbe[e].voxelMax = I4(3u, e, 12u);
    objectProbe[e].bases = U4(3u, e, 16u);
    objectProbe[e].bases2 = U4(3u, e, 20u);

    nodeProbe[e].boundsMin = F3(4u, e, 0u);
    nodeProbe[e].rightOrFirst = S(4u, e, 3u);
    nodeProbe[e].boundsMax = F3(4u, e, 4u);
    nodeProbe[e].count = S(4u, e, 7u);

    affineProbe[e] = A(5u, e, 0u);

    instanceProbe[e].worldToBrick = A(6u, e, 0u);
    instanceProbe[e].brickToWorld = A(6u, e, 12u);
    instanceProbe[e].boundsMin = F4(6u, e, 24u);
    instanceProbe[e].boundsMax = F4(6u, e, 28u);
    instanceProbe[e].info = U4(6u, e, 32u);
    instanceProbe[e].anchor = F4(6u, e, 36u);

    viewProbe[e].viewProj = M4(7u, e, 0u);
    viewProbe[e].clipToEye = M4(7u, e, 16u);
    viewProbe[e].eyeHigh = F4(7u, e, 32u);
    viewProbe[e].eyeLow = F4(7u, e, 36u);
    viewProbe[e].rect = I4(7u, e, 40u);
    viewProbe[e].info = I4(7u, e, 44u);

    rayProbe[e].originHigh = F4(8u, e, 0u);
    rayProbe[e].originLow = F4(8u, e, 4u);
    rayProbe[e].direction = F4(8u, e, 8u);

    hitProbe[e].voxel = I4(9u, e, 0u);
    hitProbe[e].t = F(9u, e, 4u);
    hitProbe[e].instance = S(9u, e, 5u);
    hitProbe[e].material = S(9u, e, 6u);
    hitProbe[e].hit = S(9u, e, 7u);

    cameraProbe[e].originHigh = F4(10u, e, 0u);
    cameraProbe[e].originLow = F4(10u, e, 4u);
    cameraProbe[e].forward = F4(10u, e, 8u);
    cameraProbe[e].right = F4(10u, e, 12u);
    cameraProbe[e].up = F4(10u, e, 16u);
    cameraProbe[e].size = U4(10u, e, 20u);

    visibilityProbe[e].boundsMin = F4(11u, e, 0u);
    visibilityProbe[e].boundsMax = F4(11u, e, 4u);
    visibilityProbe[e].counts = U4(11u, e, 8u);

    visibilityLightProbe[e].target = F4(12u, e, 0u);
    visibilityLightProbe[e].kind = F4(12u, e, 4u);

    receiverProbe[e].position = F4(13u, e, 0u);
    receiverProbe[e].normal = F4(13u, e, 4u);
  }
}
