// traverse.h: the portable shadow-ray traversal, one ray through the instance BVH and each object's brickmap.
//
// This is a *body*: it is included where the scene arrays are in scope under these names:
//   regionTable (uint), regions (Region), sectors (Sector), bricks (Brick), occupancy (uint), payload (uint),
//   objects (ObjectRecord), instances (InstanceRecord), nodes (BvhNode), instanceIndices (uint),
//   nodeEscapes (uint, Bvh::nodeEscapes), nodeCount (uint).
// GLSL reads them from storage and texel buffers (and nodeCount from a push constant); C++ includes this body inside a
// struct whose members carry those names (compute/cpu/scene_arrays.h). The same arithmetic, in the same order,
// runs on both sides, so that GPU and CPU agree texel for texel (DESIGN.md §6).
//
// Robust stepping: cells are integer coordinates; the exit axis of a cell is the smallest exact t at which the
// ray crosses one of its faces; the coordinates of the other axes come from the exit point, clamped to the cell,
// never moving against the ray, and then settled by comparing the t of the voxel planes themselves, so no voxel
// is skipped by an epsilon and every loop ends.
//
// Canonical voxel order: the walk visits exactly the voxels of a voxel-by-voxel walk (a DDA) in which a plane
// x = k counts as crossed at parameter t when (k - o.x) / d.x, computed as (float(k) - o.x) * invD.x, is below t;
// planes crossed at the same t are taken from the highest axis down (z, then y, then x), which is the order
// of OpenVDB's DDA. The walk's start voxel is the one the ray runs into at its entry t (every plane at that t
// already crossed). So the voxel at which a ray stops, and its t, depend only on the ray and the voxels, not on
// the sizes of the empty cells that were skipped: a tracer that skips larger empty boxes (compute/cpu) returns
// the same texels bit for bit.
//
// The per-object arrays can outgrow one storage-buffer binding (maxStorageBufferRange); an includer that
// splits them, or reads records some other way (texel fetches), defines these readers before including this
// body. By default they index the named array.
#ifndef VS_READ_REGION_TABLE
#define VS_READ_REGION_TABLE(i) regionTable[i]
#endif
#ifndef VS_READ_REGIONS
#define VS_READ_REGIONS(i) regions[i]
#endif
#ifndef VS_READ_SECTORS
#define VS_READ_SECTORS(i) sectors[i]
#endif
#ifndef VS_READ_BRICKS
#define VS_READ_BRICKS(i) bricks[i]
#endif
#ifndef VS_READ_OCCUPANCY
#define VS_READ_OCCUPANCY(i) occupancy[i]
#endif
#ifndef VS_READ_PAYLOAD
#define VS_READ_PAYLOAD(i) payload[i]
#endif
// Whether a view's depth is taken at the hit voxel's centre; an includer that compiles one view kind at a time
// defines it as a constant.
#ifndef VS_VIEW_DEPTH_AT_CENTER
#define VS_VIEW_DEPTH_AT_CENTER(view) ((view).info.w == VS_DEPTH_POINT_VOXEL_CENTER)
#endif
#ifndef VS_READ_OBJECT
#define VS_READ_OBJECT(i) objects[i]
#endif
#ifndef VS_READ_NODE
#define VS_READ_NODE(i) nodes[i]
#endif
#ifndef VS_READ_INSTANCE_INDEX
#define VS_READ_INSTANCE_INDEX(i) instanceIndices[i]
#endif
#ifndef VS_READ_NODE_ESCAPE
#define VS_READ_NODE_ESCAPE(i) nodeEscapes[i]
#endif
#ifndef VS_READ_INSTANCE_OBJECT
#define VS_READ_INSTANCE_OBJECT(i) instances[i].info.x
#endif
#ifndef VS_READ_WORLD_TO_BRICK
#define VS_READ_WORLD_TO_BRICK(i) instances[i].worldToBrick
#endif
#ifndef VS_READ_BRICK_TO_WORLD
#define VS_READ_BRICK_TO_WORLD(i) instances[i].brickToWorld
#endif
#ifndef VS_READ_INSTANCE_BOUNDS_MIN
#define VS_READ_INSTANCE_BOUNDS_MIN(i) vec3(instances[i].boundsMin)
#endif
#ifndef VS_READ_INSTANCE_BOUNDS_MAX
#define VS_READ_INSTANCE_BOUNDS_MAX(i) vec3(instances[i].boundsMax)
#endif
#ifndef VS_READ_INSTANCE_ANCHOR
#define VS_READ_INSTANCE_ANCHOR(i) vec3(instances[i].anchor)
#endif

// Rank of `bit` inside a 64-bit mask: how many set bits lie below it.
uint vsRankBelow(uvec2 mask, uint bit) {
  if (bit < 32u) return uint(bitCount(mask.x & ((1u << bit) - 1u)));
  return uint(bitCount(mask.x)) + uint(bitCount(mask.y & ((1u << (bit - 32u)) - 1u)));
}

bool vsTestBit(uvec2 mask, uint bit) {
  uint word = bit < 32u ? mask.x : mask.y;
  return ((word >> (bit & 31u)) & 1u) != 0u;
}

uint vsChildBit(ivec3 v, int log2Child) {
  ivec3 c = (v >> log2Child) & ivec3(3);
  return uint(c.x + 4 * c.y + 16 * c.z);
}

// One ray's walk through one object's brickmap, advanced one cell at a time by vsObjectWalkStep, so that a
// caller may interleave the walks of many rays (compute/cpu/tile_tracer.cpp) without changing any result.
struct ObjectWalk {
  ObjectRecord obj;
  vec3 o;        // ray origin in the object's brick space
  vec3 d;        // ray direction in brick space (t is the caller's parameter, kept through the affine map)
  vec3 invD;     // 1 / d per axis, 0 where d is 0
  ivec3 v;       // current voxel
  float tEnter;  // t at which the ray enters v's cell (the hit's depth)
  float t1;      // end of the ray's span inside the object
  int stepsLeft; // hard bound: every step moves at least one voxel along its exit axis, never back
  // The last sector and brick looked up. A ray crosses many cells of one sector and of one brick in a row;
  // keeping their records saves the chain of dependent loads from the region table down.
  ivec3 sectorCoord;   // v >> VS_SECTOR_LOG2 of the cached sector
  int sectorLog2;      // VS_REGION_LOG2 or VS_SECTOR_LOG2 when that region or sector is empty, else 0
  uvec2 brickMask;     // the cached sector's brick mask (sectorLog2 == 0)
  uint firstBrick;     // global index of its first brick
  ivec3 brickCoord;    // v >> VS_BRICK_LOG2 of the cached brick
  Brick brick;
};

// log2 of the largest empty aligned cell around the walk's voxel (7, 5, 3, 1 or 0), or -1 when it is solid.
// Precondition: w.v lies inside the object's voxel bounds.
int vsWalkCellLog2(VS_INOUT(ObjectWalk) w) {
  ivec3 sectorCoord = w.v >> VS_SECTOR_LOG2;
  if (sectorCoord != w.sectorCoord) {
    w.sectorCoord = sectorCoord;
    w.brickCoord = ivec3(VS_NO_CELL);
    ivec3 r = (w.v >> VS_REGION_LOG2) - ivec3(w.obj.regionOrigin);
    uint slotIndex = w.obj.bases.x + uint(r.x + w.obj.regionDims.x * (r.y + w.obj.regionDims.y * r.z));
    uint slot = VS_READ_REGION_TABLE(slotIndex);
    if (slot == VS_EMPTY_SLOT) {
      w.sectorLog2 = VS_REGION_LOG2;
    } else {
      Region region = VS_READ_REGIONS(w.obj.bases.y + slot);
      uint sectorBit = vsChildBit(w.v, VS_SECTOR_LOG2);
      if (!vsTestBit(region.sectorMask, sectorBit)) {
        w.sectorLog2 = VS_SECTOR_LOG2;
      } else {
        Sector sector = VS_READ_SECTORS(w.obj.bases.z + region.firstSector + vsRankBelow(region.sectorMask, sectorBit));
        w.sectorLog2 = 0;
        w.brickMask = sector.brickMask;
        w.firstBrick = w.obj.bases.w + sector.firstBrick;
      }
    }
  }
  if (w.sectorLog2 != 0) return w.sectorLog2;
  uint brickBit = vsChildBit(w.v, VS_BRICK_LOG2);
  if (!vsTestBit(w.brickMask, brickBit)) return VS_BRICK_LOG2;
  ivec3 brickCoord = w.v >> VS_BRICK_LOG2;
  if (brickCoord != w.brickCoord) {
    w.brickCoord = brickCoord;
    w.brick = VS_READ_BRICKS(w.firstBrick + vsRankBelow(w.brickMask, brickBit));
  }
  if (w.brick.occupancy == VS_FULL_BRICK) return -1;
  uint cellBit = vsChildBit(w.v, VS_CELL_LOG2);
  if (!vsTestBit(w.brick.cellMask, cellBit)) return VS_CELL_LOG2;
  uint voxelBit = cellBit * 8u + uint((w.v.x & 1) + 2 * (w.v.y & 1) + 4 * (w.v.z & 1));
  uint word = VS_READ_OCCUPANCY(w.obj.bases2.x + w.brick.occupancy * VS_OCCUPANCY_WORDS + (voxelBit >> 5u));
  return ((word >> (voxelBit & 31u)) & 1u) != 0u ? -1 : 0;
}

// The box table's entry `index` where mask is set (compute/shared/lane_walk.h); index 0 is read elsewhere.
LInt vsReadBoxCodeLanes(LBool mask, LInt index) { return VS_READ_BOX_CODE(mask ? index : 0); }

#include "compute/shared/lane_walk.h"

// Clips o + t*d, t in [tMin, tMax], to the object's voxel bounds and places the walk on its first voxel
// (vsBoxWalkBegin). Returns false when the ray misses the bounds (or the object is empty).
bool vsObjectWalkBegin(uint objectIndex, vec3 o, vec3 d, float tMin, float tMax, VS_INOUT(ObjectWalk) w) {
  w.obj = VS_READ_OBJECT(objectIndex);
  BoxWalk b;
  if (!vsBoxWalkBegin(w.obj, o, d, tMin, tMax, b)) return false;
  w.o = o;
  w.d = d;
  w.invD = vec3(b.ix, b.iy, b.iz);
  w.v = ivec3(b.vx, b.vy, b.vz);
  w.tEnter = b.tEnter;
  w.t1 = b.t1;
  w.stepsLeft = b.stepsLeft;
  w.sectorCoord = ivec3(VS_NO_CELL);
  w.sectorLog2 = 0;
  w.brickMask = uvec2(0u);
  w.firstBrick = 0u;
  w.brickCoord = ivec3(VS_NO_CELL);
  // Member by member: C++ compilers without parenthesised aggregate initialisation (clang < 16) reject
  // the GLSL constructor form Brick(...).
  w.brick.cellMask = uvec2(0u);
  w.brick.occupancy = 0u;
  w.brick.payload = 0u;
  return true;
}

// The walk's ray, bounds and voxel in the form of the lane walk (compute/shared/lane_walk.h), with no box table.
BoxWalk vsBoxWalkOf(VS_IN(ObjectWalk) w) {
  BoxWalk b;
  b.ox = w.o.x;
  b.oy = w.o.y;
  b.oz = w.o.z;
  b.dx = w.d.x;
  b.dy = w.d.y;
  b.dz = w.d.z;
  b.ix = w.invD.x;
  b.iy = w.invD.y;
  b.iz = w.invD.z;
  b.t1 = w.t1;
  b.minX = w.obj.voxelMin.x;
  b.minY = w.obj.voxelMin.y;
  b.minZ = w.obj.voxelMin.z;
  b.maxX = w.obj.voxelMax.x;
  b.maxY = w.obj.voxelMax.y;
  b.maxZ = w.obj.voxelMax.z;
  b.table = 0;
  b.rowStride = 0;
  b.sliceStride = 0;
  b.vx = w.v.x;
  b.vy = w.v.y;
  b.vz = w.v.z;
  b.tEnter = w.tEnter;
  b.stepsLeft = w.stepsLeft;
  b.hit = false;
  return b;
}

// Moves the walk past the empty box [boxMin, boxEnd) that holds its voxel (vsBoxExit): returns
// VS_WALK_CONTINUE on the box's next voxel in canonical order, or VS_WALK_MISS once the ray has left the object
// or its span.
int vsWalkLeaveBox(VS_INOUT(ObjectWalk) w, ivec3 boxMin, ivec3 boxEnd) {
  int nx = 0, ny = 0, nz = 0;
  float tNext = 0.0f;
  if (!vsBoxExit(vsBoxWalkOf(w), boxMin.x, boxMin.y, boxMin.z, boxEnd.x, boxEnd.y, boxEnd.z, nx, ny, nz, tNext))
    return VS_WALK_MISS;
  w.v = ivec3(nx, ny, nz);
  w.tEnter = tNext;
  return VS_WALK_CONTINUE;
}

// Looks at the walk's current voxel: VS_WALK_HIT when it is solid (w.v, w.tEnter hold the hit), else moves
// past the largest empty aligned cell around it and returns VS_WALK_CONTINUE, or VS_WALK_MISS once the ray
// has left the object or its span.
int vsObjectWalkStep(VS_INOUT(ObjectWalk) w) {
  if (w.stepsLeft <= 0) return VS_WALK_MISS;
  w.stepsLeft -= 1;
  int log2Size = vsWalkCellLog2(w);
  if (log2Size < 0) return VS_WALK_HIT;
  int size = 1 << log2Size;
  ivec3 cellMin = w.v & ivec3(~(size - 1));
  return vsWalkLeaveBox(w, cellMin, cellMin + ivec3(size));
}

// The walk over a box table (vsBoxWalkStep) from the walk's first voxel: returns true on a hit (w.v, w.tEnter
// hold it). `table` is the index of the code of brick (0, 0, 0) (it may lie outside the table), `rowStride`
// and `sliceStride` the code index steps along y and z. The whole walk is one loop with a single exit, so
// that a SIMD shader keeps no per-step status.
bool vsObjectWalkBoxes(VS_INOUT(ObjectWalk) w, int table, int rowStride, int sliceStride) {
  BoxWalk b = vsBoxWalkOf(w);
  b.table = table;
  b.rowStride = rowStride;
  b.sliceStride = sliceStride;
  bool walking = true;
  while (walking) walking = vsBoxWalkStep(b, walking);
  w.v = ivec3(b.vx, b.vy, b.vz);
  w.tEnter = b.tEnter;
  return b.hit;
}

// The box table's arguments of vsObjectWalkBoxes for one object: its first code's index, less the code index
// of brick (0, 0, 0) relative to the object's brick origin; and the row and slice strides.
ivec3 vsBoxTableOf(uint objectIndex, ObjectRecord obj) {
  ivec3 dims = ivec3(obj.regionDims) * 16;  // bricks per axis
  ivec3 origin = ivec3(obj.regionOrigin) * 16;
  // The table starts with each object's first code.
  int table = VS_READ_BOX_CODE(objectIndex) - (origin.x + dims.x * (origin.y + dims.y * origin.z));
  return ivec3(table, dims.x, dims.x * dims.y);
}

// Closest solid voxel of one object along o + t*d (brick space; t is the caller's parameter, kept through
// the affine map), for t in [tMin, tMax]. On a hit returns true with tHit the entry t and voxel its coordinate.
bool vsTraceObject(uint objectIndex, vec3 o, vec3 d, float tMin, float tMax, VS_INOUT(float) tHit,
                   VS_INOUT(ivec3) voxel) {
  ObjectWalk w;
  if (!vsObjectWalkBegin(objectIndex, o, d, tMin, tMax, w)) return false;
  int status = VS_WALK_CONTINUE;
  // VS_BOX_TABLE is a specialization constant in the shader: each pipeline holds one of the two loops, and the
  // host binds a box table covering every object whenever it is set. (A loop left in the code costs llvmpipe
  // one masked pass through its body even when no lane takes it.) In C++ it says whether a table is bound.
  if (VS_BOX_TABLE) {
    ivec3 table = vsBoxTableOf(objectIndex, w.obj);
    status = vsObjectWalkBoxes(w, table.x, table.y, table.z) ? VS_WALK_HIT : VS_WALK_MISS;
  } else
  while (status == VS_WALK_CONTINUE) status = vsObjectWalkStep(w);
  if (status != VS_WALK_HIT) return false;
  tHit = w.tEnter;
  voxel = w.v;
  return true;
}

// The ray origin + t*d, t in [tMin, tMax], of a float origin.
WorldRay vsWorldRay(vec3 origin, vec3 d, float tMin, float tMax) {
  WorldRay ray;
  ray.eyeHigh = origin;
  ray.eyeLow = vec3(0.0f);
  ray.start = vec3(0.0f);
  ray.d = d;
  ray.tMin = tMin;
  ray.tMax = tMax;
  return ray;
}

// Where a ray enters an instance's world box grown by vsCullPad, or VS_T_INFINITY when it misses it.
float vsInstanceEntry(VS_IN(WorldRay) ray, uint instanceIndex) {
  return vsInstanceBoxEntry(ray, VS_READ_INSTANCE_BOUNDS_MIN(instanceIndex), VS_READ_INSTANCE_BOUNDS_MAX(instanceIndex));
}
float vsInstanceBaseT(VS_IN(WorldRay) ray, uint instanceIndex) {
  return vsBaseT(ray, vsInstanceEntry(ray, instanceIndex));
}

// The brick-space ray of one instance, re-based at tBase: brick-space t is the world t less tBase.
void vsInstanceRay(WorldRay ray, uint instanceIndex, float tBase, VS_OUT(vec3) lo, VS_OUT(vec3) ld) {
  vsInstanceRayOf(ray, VS_READ_WORLD_TO_BRICK(instanceIndex), VS_READ_INSTANCE_ANCHOR(instanceIndex), tBase, lo, ld);
}

// A walk's hit in world t, from the instance's re-based t.
float vsWorldT(float tLocal, float tBase) {
  VS_PRECISE float world = tBase + tLocal;
  return world;
}

// The end, in an instance's re-based t, of the walk that looks for a hit closer than the best so far (tBest,
// `hit` whether there is one): the ray's own end before any hit; after one, tBest's local t moved up by more
// than the rounding of vsLocalT and vsWorldT (2^-21 of tBest, four ulps), so that a voxel whose world t rounds
// to tBest is found whatever order the instances are walked in, and vsCloserHit alone decides the tie. What the
// slack lets in beyond tBest, vsCloserHit rejects.
float vsWalkEnd(bool hit, float tBest, float tMax, float tBase) {
  VS_PRECISE float local = (hit ? tBest : tMax) - tBase;
  VS_PRECISE float widened = local + abs(tBest) * (1.0f / 2097152.0f);
  return hit ? widened : local;
}

// The closest-hit rule of every tracer: a hit at t on `instance` replaces the best so far (tBest on
// instanceBest, `hit` whether there is one) when it is nearer, or as near on a lower instance index.
bool vsCloserHit(bool hit, float t, uint instance, float tBest, uint instanceBest) {
  return !hit || t < tBest || (t == tBest && instance < instanceBest);
}

// Advances a depth-first walk of the instance BVH to the next leaf entry whose leaf box (grown by `pad`) the
// ray o + t*d enters within [tMin, tBest]: `node` is the next node to visit (nodeCount when none is left),
// [entry, entryEnd) the current leaf's entries not yet taken. Returns false when no entry is left. Stackless
// (Bvh::nodeEscapes), so a SIMD shader keeps no per-lane stack array.
bool vsNextLeafEntry(vec3 o, vec3 d, float pad, float tMin, float tBest, VS_INOUT(uint) node, VS_INOUT(uint) entry,
                     VS_INOUT(uint) entryEnd) {
  while (entry >= entryEnd && node < nodeCount) {
    BvhNode n = VS_READ_NODE(node);
    bool entered = vsBoxEntry(n.boundsMin - vec3(pad), n.boundsMax + vec3(pad), o, d, tMin, tBest) != VS_T_INFINITY;
    bool leaf = n.count > 0u;
    entry = entered && leaf ? n.rightOrFirst : entry;
    entryEnd = entered && leaf ? n.rightOrFirst + n.count : entryEnd;
    node = entered && !leaf ? node + 1u : VS_READ_NODE_ESCAPE(node);  // into the left child, or past the subtree
  }
  return entry < entryEnd;
}

// The first solid voxel of one instance along a world ray, walked re-based (vsInstanceBaseT) up to vsWalkEnd:
// on a hit, tWorld is its world t and voxel its coordinate in the object's brick space.
bool vsTraceInstance(WorldRay ray, uint instanceIndex, bool hit, float tBest, VS_INOUT(float) tWorld,
                     VS_INOUT(ivec3) voxel) {
  float tBase = vsInstanceBaseT(ray, instanceIndex);
  vec3 lo = vec3(0.0f);
  vec3 ld = vec3(0.0f);
  vsInstanceRay(ray, instanceIndex, tBase, lo, ld);
  float t = VS_T_INFINITY;
  if (!vsTraceObject(VS_READ_INSTANCE_OBJECT(instanceIndex), lo, ld, vsLocalT(ray.tMin, tBase),
                     vsWalkEnd(hit, tBest, ray.tMax, tBase), t, voxel))
    return false;
  tWorld = vsWorldT(t, tBase);
  return true;
}

// Closest hit of a world ray over every instance. On a hit, tHit is the entry t, instanceHit the instance index
// and voxel the hit voxel in that object's brick space. Instances are taken in depth-first BVH order, left child
// first; the closest-hit rule is vsCloserHit.
bool vsTraceClosest(WorldRay ray, VS_INOUT(float) tHit, VS_INOUT(uint) instanceHit, VS_INOUT(ivec3) voxel) {
  bool hit = false;
  float tBest = ray.tMax;
  uint node = 0u;
  uint entry = 0u;
  uint entryEnd = 0u;
  vec3 o = vsCullOrigin(ray);
  float pad = vsCullPad(ray);
  // One loop over instances, the walk the only loop inside it: llvmpipe runs nested loops much slower.
  bool more = vsNextLeafEntry(o, ray.d, pad, ray.tMin, tBest, node, entry, entryEnd);
  while (more) {
    uint instanceIndex = VS_READ_INSTANCE_INDEX(entry);
    entry += 1u;
    float tWorld = VS_T_INFINITY;
    ivec3 v = ivec3(0);
    if (vsTraceInstance(ray, instanceIndex, hit, tBest, tWorld, v)) {
      if (vsCloserHit(hit, tWorld, instanceIndex, tBest, instanceHit)) {
        tBest = tWorld;
        instanceHit = instanceIndex;
        voxel = v;
      }
      hit = true;
    }
    more = vsNextLeafEntry(o, ray.d, pad, ray.tMin, tBest, node, entry, entryEnd);
  }
  if (hit) tHit = tBest;
  return hit;
}

vec4 vsMulPoint(mat4 m, vec4 p) {
  VS_PRECISE vec4 r = m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3] * p.w;
  return r;
}

// The ray of one texel of a view (DESIGN.md §2, §6), eye-relative: the texel centre's NDC point unprojected
// through clipToEye gives a point relative to the eye, with no translation to cancel.
// Directional (NDC-depth) views: the ray starts on the near plane and reaches the far plane at t = 1, so t is
// the NDC depth. Linear-distance views: the ray starts at the eye (the light), |d| = 1, t in [0, range] is the
// distance.
void vsViewRay(TraceView view, ivec2 texel, VS_OUT(WorldRay) ray) {
  VS_PRECISE float nx = VS_DIV(float(texel.x) + 0.5f, float(view.info.x)) * 2.0f - 1.0f;
  VS_PRECISE float ny = VS_DIV(float(texel.y) + 0.5f, float(view.info.y)) * 2.0f - 1.0f;
  vec4 farH = vsMulPoint(view.clipToEye, vec4(nx, ny, 1.0f, 1.0f));
  VS_PRECISE vec3 farP = vec3(VS_DIV(farH.x, farH.w), VS_DIV(farH.y, farH.w), VS_DIV(farH.z, farH.w));
  ray.eyeHigh = vec3(view.eyeHigh);
  ray.eyeLow = vec3(view.eyeLow);
  ray.tMin = 0.0f;
  if (view.info.z == VS_ENCODING_NDC_DEPTH) {
    vec4 nearH = vsMulPoint(view.clipToEye, vec4(nx, ny, 0.0f, 1.0f));
    VS_PRECISE vec3 nearP = vec3(VS_DIV(nearH.x, nearH.w), VS_DIV(nearH.y, nearH.w), VS_DIV(nearH.z, nearH.w));
    VS_PRECISE vec3 d = farP - nearP;
    ray.start = nearP;
    ray.d = d;
    ray.tMax = 1.0f;
  } else {
    VS_PRECISE float len = VS_SQRT(farP.x * farP.x + farP.y * farP.y + farP.z * farP.z);
    VS_PRECISE vec3 d = vec3(VS_DIV(farP.x, len), VS_DIV(farP.y, len), VS_DIV(farP.z, len));
    ray.start = vec3(0.0f);
    ray.d = d;
    ray.tMax = view.eyeHigh.w;
  }
}

// The texel value of a traced ray (DESIGN.md §2): the hit's t (entry point) or that of the hit voxel's
// centre, and the miss value (the t range end) when nothing was hit. The centre is measured from the ray's
// re-based point on the hit instance (vsRebasedPoint), so it keeps the walk's precision far from the origin.
float vsTexelValue(TraceView view, WorldRay ray, bool hit, float tHit, uint instanceHit, ivec3 voxel) {
  if (!hit) return ray.tMax;
  if (VS_VIEW_DEPTH_AT_CENTER(view)) {
    float tBase = vsInstanceBaseT(ray, instanceHit);
    vec3 base = vsRebasedPoint(ray, tBase, VS_READ_INSTANCE_ANCHOR(instanceHit));
    vec3 c = vsApplyAffine(VS_READ_BRICK_TO_WORLD(instanceHit), vec3(voxel) + vec3(0.5f));
    VS_PRECISE vec3 rel = c - base;  // from the ray's point at tBase to the centre
    vec3 d = ray.d;
    if (view.info.z == VS_ENCODING_NDC_DEPTH) {
      VS_PRECISE float dd = d.x * d.x + d.y * d.y + d.z * d.z;
      VS_PRECISE float t = tBase + VS_DIV(rel.x * d.x + rel.y * d.y + rel.z * d.z, dd);
      return clamp(t, 0.0f, 1.0f);
    }
    VS_PRECISE vec3 fromEye = ray.start + d * tBase + rel;
    VS_PRECISE float dist = VS_SQRT(fromEye.x * fromEye.x + fromEye.y * fromEye.y + fromEye.z * fromEye.z);
    return min(dist, ray.tMax);
  }
  return tHit;
}


// The texel value of one view texel.
float vsShadowTexel(TraceView view, ivec2 texel) {
  WorldRay ray;
  vsViewRay(view, texel, ray);
  float tHit = ray.tMax;
  uint instanceHit = 0u;
  ivec3 voxel = ivec3(0);
  bool hit = vsRayIsFinite(ray) && vsTraceClosest(ray, tHit, instanceHit, voxel);
  return vsTexelValue(view, ray, hit, tHit, instanceHit, voxel);
}

// Whether any solid voxel lies on a world ray within [tMin, tMax]: the walks of vsTraceClosest, over the whole
// span, ending at the first voxel any of them finds. It says true exactly when vsTraceClosest finds a hit.
bool vsTraceAny(WorldRay ray) {
  uint node = 0u;
  uint entry = 0u;
  uint entryEnd = 0u;
  vec3 o = vsCullOrigin(ray);
  float pad = vsCullPad(ray);
  bool hit = false;
  bool more = vsNextLeafEntry(o, ray.d, pad, ray.tMin, ray.tMax, node, entry, entryEnd);
  while (more) {
    uint instanceIndex = VS_READ_INSTANCE_INDEX(entry);
    entry += 1u;
    float t = VS_T_INFINITY;
    ivec3 v = ivec3(0);
    hit = vsTraceInstance(ray, instanceIndex, false, ray.tMax, t, v);
    more = !hit && vsNextLeafEntry(o, ray.d, pad, ray.tMin, ray.tMax, node, entry, entryEnd);
  }
  return hit;
}

// The palette index of voxel v of an object (1..255), 0 where v is empty or outside the object, read down the
// hierarchy to the brick's payload (a material for the whole brick, or one byte per voxel in occupancy-bit order).
uint vsVoxelMaterial(uint objectIndex, ivec3 v) {
  ObjectRecord obj = VS_READ_OBJECT(objectIndex);
  ivec3 vmin = ivec3(obj.voxelMin);
  ivec3 vmax = ivec3(obj.voxelMax);
  if (v.x < vmin.x || v.y < vmin.y || v.z < vmin.z || v.x >= vmax.x || v.y >= vmax.y || v.z >= vmax.z) return 0u;
  ivec3 r = (v >> VS_REGION_LOG2) - ivec3(obj.regionOrigin);
  uint slot = VS_READ_REGION_TABLE(obj.bases.x + uint(r.x + obj.regionDims.x * (r.y + obj.regionDims.y * r.z)));
  if (slot == VS_EMPTY_SLOT) return 0u;
  Region region = VS_READ_REGIONS(obj.bases.y + slot);
  uint sectorBit = vsChildBit(v, VS_SECTOR_LOG2);
  if (!vsTestBit(region.sectorMask, sectorBit)) return 0u;
  Sector sector = VS_READ_SECTORS(obj.bases.z + region.firstSector + vsRankBelow(region.sectorMask, sectorBit));
  uint brickBit = vsChildBit(v, VS_BRICK_LOG2);
  if (!vsTestBit(sector.brickMask, brickBit)) return 0u;
  Brick brick = VS_READ_BRICKS(obj.bases.w + sector.firstBrick + vsRankBelow(sector.brickMask, brickBit));
  if ((brick.payload & VS_UNIFORM_PAYLOAD) != 0u) return brick.payload & 0xffu;
  uint voxelBit = vsChildBit(v, VS_CELL_LOG2) * 8u + uint((v.x & 1) + 2 * (v.y & 1) + 4 * (v.z & 1));
  uint word = VS_READ_PAYLOAD(obj.bases2.y + brick.payload + (voxelBit >> 2u));
  return (word >> ((voxelBit & 3u) * 8u)) & 0xffu;
}

// The face through which the brick-space ray o + t*d (1/d = invD, vsInverseAxis) entered voxel v, for a walk
// that began at tStart: the voxel's near plane crossed last. In the canonical voxel order planes crossed at the
// same t are taken z, then y, then x, so on a tie the lowest axis is the one crossed last. VS_FACE_NONE when
// every near plane lies before tStart: the walk began inside the voxel. It depends on the ray and the voxel
// only, so every backend derives it after the walk, from the same values.
uint vsEntryFace(vec3 o, vec3 d, vec3 invD, ivec3 v, float tStart) {
  VS_PRECISE float tx = (float(d.x > 0.0f ? v.x : v.x + 1) - o.x) * invD.x;
  VS_PRECISE float ty = (float(d.y > 0.0f ? v.y : v.y + 1) - o.y) * invD.y;
  VS_PRECISE float tz = (float(d.z > 0.0f ? v.z : v.z + 1) - o.z) * invD.z;
  tx = d.x != 0.0f ? tx : -VS_T_INFINITY;
  ty = d.y != 0.0f ? ty : -VS_T_INFINITY;
  tz = d.z != 0.0f ? tz : -VS_T_INFINITY;
  float tLast = max(max(tx, ty), tz);
  uint axis = tx == tLast ? 0u : (ty == tLast ? 1u : 2u);
  float dAxis = axis == 0u ? d.x : (axis == 1u ? d.y : d.z);
  uint face = axis * 2u + (dAxis > 0.0f ? 0u : 1u);
  return tLast < tStart ? VS_FACE_NONE : face;
}

// The hit record of a world ray's closest hit (vsTraceClosest's results): the entry face and the material are
// derived from the hit instance's re-based ray and the voxel, as every backend's walk saw them.
RayHit vsHitRecord(WorldRay ray, bool hit, float tHit, uint instanceHit, ivec3 voxel) {
  RayHit h;
  h.voxel = ivec4(0);
  h.t = ray.tMax;
  h.instance = 0u;
  h.material = 0u;
  h.hit = 0u;
  if (hit) {
    float tBase = vsInstanceBaseT(ray, instanceHit);
    vec3 lo = vec3(0.0f);
    vec3 ld = vec3(0.0f);
    vsInstanceRay(ray, instanceHit, tBase, lo, ld);
    vec3 invD = vec3(vsInverseAxis(ld.x), vsInverseAxis(ld.y), vsInverseAxis(ld.z));
    uint face = vsEntryFace(lo, ld, invD, voxel, vsLocalT(ray.tMin, tBase));
    h.voxel = ivec4(voxel, int(face));
    h.t = tHit;
    h.instance = instanceHit;
    h.material = vsVoxelMaterial(VS_READ_INSTANCE_OBJECT(instanceHit), voxel);
    h.hit = 1u;
  }
  return h;
}

// A caller's tMax cut where the ray o + t*d leaves the scene's bounds (the BVH root's box, grown by more than the
// rounding of this float slab test, and the exit t widened likewise, so no voxel the exact ray reaches lies
// past the cut). FLT_MAX and infinity are how callers write "unbounded": they, and every tMax beyond the scene,
// take the walk of a ray that ends with the scene, since culling pads grow with tMax and one near float's limit
// would swallow the world. A ray that never enters the bounds (or an empty scene) is cut to tMin: its segment
// in the scene is empty. NaN stays NaN (vsRayIsFinite refuses it).
float vsSceneEndT(vec3 o, vec3 d, float tMin, float tMax) {
  float cut = tMin;
  if (nodeCount > 0u) {
    BvhNode root = VS_READ_NODE(0u);
    vec3 reach = max(abs(root.boundsMin), abs(root.boundsMax));
    VS_PRECISE float scale = max(max(abs(o.x), abs(o.y)), abs(o.z)) + max(max(reach.x, reach.y), reach.z);
    float pad = scale * (1.0f / 1048576.0f);
    float t0 = tMin;
    float t1 = VS_T_INFINITY;
    float inv = 0.0f;
    bool inX = vsClipAxis(o.x, d.x, root.boundsMin.x - pad, root.boundsMax.x + pad, false, t0, t1, inv);
    bool inY = vsClipAxis(o.y, d.y, root.boundsMin.y - pad, root.boundsMax.y + pad, false, t0, t1, inv);
    bool inZ = vsClipAxis(o.z, d.z, root.boundsMin.z - pad, root.boundsMax.z + pad, false, t0, t1, inv);
    VS_PRECISE float widened = t1 + abs(t1) * (1.0f / 1048576.0f);
    // Selects, not min and max, whose choice between -0 and +0 differs between GLSL and C++.
    float end = widened > tMin ? widened : tMin;
    end = end < VS_T_INFINITY ? end : VS_T_INFINITY;
    cut = inX && inY && inZ && t0 <= t1 ? end : tMin;
  }
  return tMax > cut ? cut : tMax;
}

// The world ray of a caller's TraceRay.
WorldRay vsTraceRayToWorld(TraceRay r) {
  WorldRay ray;
  ray.eyeHigh = vec3(r.originHigh);
  ray.eyeLow = vec3(r.originLow);
  ray.start = vec3(0.0f);
  ray.d = vec3(r.direction);
  ray.tMin = r.originHigh.w;
  ray.tMax = vsSceneEndT(vsCullOrigin(ray), ray.d, ray.tMin, r.originLow.w);
  return ray;
}

// The closest-hit record of one ray.
RayHit vsClosestHit(WorldRay ray) {
  float tHit = ray.tMax;
  uint instanceHit = 0u;
  ivec3 voxel = ivec3(0);
  bool hit = vsRayIsFinite(ray) && vsTraceClosest(ray, tHit, instanceHit, voxel);
  return vsHitRecord(ray, hit, tHit, instanceHit, voxel);
}

// Whether one ray's segment holds any solid voxel.
bool vsAnyHit(WorldRay ray) { return vsRayIsFinite(ray) && vsTraceAny(ray); }
