// traverse.h: the portable shadow-ray traversal, one ray through the instance BVH and each object's brickmap.
//
// This is a *body*: it is included where the scene arrays are in scope under these names:
//   regionTable (uint), regions (Region), sectors (Sector), bricks (Brick), occupancy (uint),
//   objects (ObjectRecord), instances (InstanceRecord), nodes (BvhNode), instanceIndices (uint), nodeCount (uint).
// GLSL declares them as storage buffers (and nodeCount as a push constant); C++ includes this body inside a
// struct whose members carry those names (compute/cpu/scene_arrays.h). The same arithmetic, in the same order,
// runs on both sides, so that GPU and CPU agree texel for texel (DESIGN.md §6).
//
// Robust stepping: cells are integer coordinates; the exit axis of a cell is the smallest exact t at which the
// ray crosses one of its faces; the coordinates of the other axes come from the exit point but are clamped
// to the cell and never move against the ray, so no voxel is skipped by an epsilon and every loop ends.

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

// log2 of the largest empty aligned cell that holds voxel v (7, 5, 3, 1 or 0), or -1 when v is solid.
// Precondition: v lies inside the object's voxel bounds.
int vsEmptyCellLog2(ObjectRecord obj, ivec3 v) {
  ivec3 r = (v >> VS_REGION_LOG2) - ivec3(obj.regionOrigin);
  uint slotIndex = obj.bases.x + uint(r.x + obj.regionDims.x * (r.y + obj.regionDims.y * r.z));
  uint slot = regionTable[slotIndex];
  if (slot == VS_EMPTY_SLOT) return VS_REGION_LOG2;
  Region region = regions[obj.bases.y + slot];
  uint sectorBit = vsChildBit(v, VS_SECTOR_LOG2);
  if (!vsTestBit(region.sectorMask, sectorBit)) return VS_SECTOR_LOG2;
  Sector sector = sectors[obj.bases.z + region.firstSector + vsRankBelow(region.sectorMask, sectorBit)];
  uint brickBit = vsChildBit(v, VS_BRICK_LOG2);
  if (!vsTestBit(sector.brickMask, brickBit)) return VS_BRICK_LOG2;
  Brick brick = bricks[obj.bases.w + sector.firstBrick + vsRankBelow(sector.brickMask, brickBit)];
  if (brick.occupancy == VS_FULL_BRICK) return -1;
  uint cellBit = vsChildBit(v, VS_CELL_LOG2);
  if (!vsTestBit(brick.cellMask, cellBit)) return VS_CELL_LOG2;
  uint voxelBit = cellBit * 8u + uint((v.x & 1) + 2 * (v.y & 1) + 4 * (v.z & 1));
  uint word = occupancy[obj.bases2.x + brick.occupancy * VS_OCCUPANCY_WORDS + (voxelBit >> 5u)];
  return ((word >> (voxelBit & 31u)) & 1u) != 0u ? -1 : 0;
}

// Closest solid voxel of one object along o + t*d (brick space; t is the caller's parameter, kept through
// the affine map), for t in [tMin, tMax]. On a hit returns true with tHit the entry t and voxel its coordinate.
bool vsTraceObject(uint objectIndex, vec3 o, vec3 d, float tMin, float tMax, VS_INOUT(float) tHit,
                   VS_INOUT(ivec3) voxel) {
  ObjectRecord obj = objects[objectIndex];
  ivec3 vmin = ivec3(obj.voxelMin);
  ivec3 vmax = ivec3(obj.voxelMax);
  if (vmax.x <= vmin.x || vmax.y <= vmin.y || vmax.z <= vmin.z) return false;

  VS_PRECISE vec3 invD = vec3(0.0f);
  VS_PRECISE float t0 = tMin;
  VS_PRECISE float t1 = tMax;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0f) {
      if (o[a] < float(vmin[a]) || o[a] >= float(vmax[a])) return false;
    } else {
      invD[a] = 1.0f / d[a];
      VS_PRECISE float tLo = (float(vmin[a]) - o[a]) * invD[a];
      VS_PRECISE float tHi = (float(vmax[a]) - o[a]) * invD[a];
      t0 = max(t0, min(tLo, tHi));
      t1 = min(t1, max(tLo, tHi));
    }
  }
  if (t0 > t1) return false;

  VS_PRECISE vec3 entry = o + d * t0;
  ivec3 v = ivec3(clamp(floor(entry), vec3(vmin), vec3(vmax - ivec3(1))));
  VS_PRECISE float tEnter = t0;
  // Every step moves at least one voxel along its exit axis and never back on any axis.
  int maxSteps = (vmax.x - vmin.x) + (vmax.y - vmin.y) + (vmax.z - vmin.z) + 3;
  for (int step = 0; step < maxSteps; ++step) {
    int log2Size = vsEmptyCellLog2(obj, v);
    if (log2Size < 0) {
      tHit = tEnter;
      voxel = v;
      return true;
    }
    int size = 1 << log2Size;
    ivec3 cellMin = v & ivec3(~(size - 1));

    VS_PRECISE float tExit = VS_T_INFINITY;
    int exitAxis = -1;
    for (int a = 0; a < 3; ++a) {
      if (d[a] != 0.0f) {
        int bound = d[a] > 0.0f ? cellMin[a] + size : cellMin[a];
        VS_PRECISE float ta = (float(bound) - o[a]) * invD[a];
        if (ta < tExit) {
          tExit = ta;
          exitAxis = a;
        }
      }
    }
    if (exitAxis < 0 || tExit >= t1) return false;
    tExit = max(tExit, tEnter);

    VS_PRECISE vec3 p = o + d * tExit;
    ivec3 next = v;
    for (int a = 0; a < 3; ++a) {
      if (a == exitAxis) {
        next[a] = d[a] > 0.0f ? cellMin[a] + size : cellMin[a] - 1;
      } else if (d[a] != 0.0f) {
        float lo = float(cellMin[a]);
        float hi = float(cellMin[a] + size - 1);
        int c = int(clamp(floor(p[a]), lo, hi));
        next[a] = d[a] > 0.0f ? max(c, v[a]) : min(c, v[a]);
      }
    }
    if (next[exitAxis] < vmin[exitAxis] || next[exitAxis] >= vmax[exitAxis]) return false;
    v = next;
    tEnter = tExit;
  }
  return false;
}

vec3 vsApplyAffine(Affine m, vec3 p) {
  VS_PRECISE float x = m.row0.x * p.x + m.row0.y * p.y + m.row0.z * p.z + m.row0.w;
  VS_PRECISE float y = m.row1.x * p.x + m.row1.y * p.y + m.row1.z * p.z + m.row1.w;
  VS_PRECISE float z = m.row2.x * p.x + m.row2.y * p.y + m.row2.z * p.z + m.row2.w;
  return vec3(x, y, z);
}

vec3 vsApplyLinear(Affine m, vec3 v) {
  VS_PRECISE float x = m.row0.x * v.x + m.row0.y * v.y + m.row0.z * v.z;
  VS_PRECISE float y = m.row1.x * v.x + m.row1.y * v.y + m.row1.z * v.z;
  VS_PRECISE float z = m.row2.x * v.x + m.row2.y * v.y + m.row2.z * v.z;
  return vec3(x, y, z);
}

// Slab test of o + t*d against a box; returns the entry t, or VS_T_INFINITY when [tMin, tMax] misses it.
float vsBoxEntry(vec3 bmin, vec3 bmax, vec3 o, vec3 d, float tMin, float tMax) {
  VS_PRECISE float t0 = tMin;
  VS_PRECISE float t1 = tMax;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0f) {
      if (o[a] < bmin[a] || o[a] > bmax[a]) return VS_T_INFINITY;
    } else {
      VS_PRECISE float inv = 1.0f / d[a];
      VS_PRECISE float tLo = (bmin[a] - o[a]) * inv;
      VS_PRECISE float tHi = (bmax[a] - o[a]) * inv;
      t0 = max(t0, min(tLo, tHi));
      t1 = min(t1, max(tLo, tHi));
    }
  }
  return t0 <= t1 ? t0 : VS_T_INFINITY;
}

// Closest hit of the world ray o + t*d, t in [tMin, tMax], over every instance. On a hit, tHit is the entry t,
// instanceHit the instance index and voxel the hit voxel in that object's brick space.
bool vsTraceClosest(vec3 o, vec3 d, float tMin, float tMax, VS_INOUT(float) tHit, VS_INOUT(uint) instanceHit,
                    VS_INOUT(ivec3) voxel) {
  if (nodeCount == 0u) return false;
  bool hit = false;
  float tBest = tMax;
  uint stack[VS_BVH_STACK_SIZE];
  int top = 0;
  stack[top++] = 0u;
  // A full tree has 2n-1 nodes: each is visited at most once per ray.
  uint budget = nodeCount;
  while (top > 0 && budget > 0u) {
    --budget;
    uint nodeIndex = stack[--top];
    BvhNode node = nodes[nodeIndex];
    if (vsBoxEntry(node.boundsMin, node.boundsMax, o, d, tMin, tBest) == VS_T_INFINITY) continue;
    if (node.count == 0u) {
      if (top + 2 <= VS_BVH_STACK_SIZE) {
        stack[top++] = node.rightOrFirst;
        stack[top++] = nodeIndex + 1u;
      }
      continue;
    }
    for (uint i = 0u; i < node.count; ++i) {
      uint instanceIndex = instanceIndices[node.rightOrFirst + i];
      InstanceRecord inst = instances[instanceIndex];
      vec3 lo = vsApplyAffine(inst.worldToBrick, o);
      vec3 ld = vsApplyLinear(inst.worldToBrick, d);
      float t = VS_T_INFINITY;
      ivec3 v = ivec3(0);
      if (vsTraceObject(inst.info.x, lo, ld, tMin, tBest, t, v)) {
        if (!hit || t < tBest || (t == tBest && instanceIndex < instanceHit)) {
          tBest = t;
          instanceHit = instanceIndex;
          voxel = v;
        }
        hit = true;
      }
    }
  }
  if (hit) tHit = tBest;
  return hit;
}

vec4 vsMulPoint(mat4 m, vec4 p) {
  VS_PRECISE vec4 r = m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3] * p.w;
  return r;
}

// The ray of one texel of a view: origin, direction and parameter range (DESIGN.md §2, §6).
// Directional (NDC-depth) views: o on the near plane, d reaching the far plane at t = 1, so t is the NDC depth.
// Linear-distance views: o at the light, |d| = 1, t in [0, range] is the distance.
void vsViewRay(TraceView view, ivec2 texel, VS_OUT(vec3) o, VS_OUT(vec3) d, VS_OUT(float) tMax) {
  VS_PRECISE float nx = (float(texel.x) + 0.5f) / float(view.info.x) * 2.0f - 1.0f;
  VS_PRECISE float ny = (float(texel.y) + 0.5f) / float(view.info.y) * 2.0f - 1.0f;
  vec4 farH = vsMulPoint(view.invViewProj, vec4(nx, ny, 1.0f, 1.0f));
  VS_PRECISE vec3 farP = vec3(farH.x / farH.w, farH.y / farH.w, farH.z / farH.w);
  if (view.info.z == VS_ENCODING_NDC_DEPTH) {
    vec4 nearH = vsMulPoint(view.invViewProj, vec4(nx, ny, 0.0f, 1.0f));
    VS_PRECISE vec3 nearP = vec3(nearH.x / nearH.w, nearH.y / nearH.w, nearH.z / nearH.w);
    o = nearP;
    d = farP - nearP;
    tMax = 1.0f;
  } else {
    o = vec3(view.origin);
    VS_PRECISE vec3 toFar = farP - o;
    VS_PRECISE float len = sqrt(toFar.x * toFar.x + toFar.y * toFar.y + toFar.z * toFar.z);
    d = toFar / len;
    tMax = view.origin.w;
  }
}

// The texel value of one ray (DESIGN.md §2): the hit's t (entry point) or that of the hit voxel's centre,
// and the miss value (t range end) when nothing is hit.
float vsShadowTexel(TraceView view, ivec2 texel) {
  vec3 o = vec3(0.0f);
  vec3 d = vec3(0.0f);
  float tMax = 0.0f;
  vsViewRay(view, texel, o, d, tMax);
  float tHit = tMax;
  uint instanceHit = 0u;
  ivec3 voxel = ivec3(0);
  if (!vsTraceClosest(o, d, 0.0f, tMax, tHit, instanceHit, voxel)) return tMax;
  if (view.info.w == VS_DEPTH_POINT_VOXEL_CENTER) {
    vec3 c = vsApplyAffine(instances[instanceHit].brickToWorld, vec3(voxel) + vec3(0.5f));
    VS_PRECISE vec3 rel = c - o;
    if (view.info.z == VS_ENCODING_NDC_DEPTH) {
      VS_PRECISE float dd = d.x * d.x + d.y * d.y + d.z * d.z;
      VS_PRECISE float t = (rel.x * d.x + rel.y * d.y + rel.z * d.z) / dd;
      return clamp(t, 0.0f, 1.0f);
    }
    VS_PRECISE float dist = sqrt(rel.x * rel.x + rel.y * rel.y + rel.z * rel.z);
    return min(dist, tMax);
  }
  return tHit;
}
