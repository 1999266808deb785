// lane_walk.h: the arithmetic that moves a walk from one voxel to the next, written once for every backend.
//
// A *body* in the lane vocabulary of compute/shared/lanes.h: compute/shared/traverse.h includes it with one
// lane (the shader, and the C++ reference in compute/cpu/scene_arrays.h), and compute/cpu/lane_tracer.cpp
// with the 8 and 16 lanes of compute/cpu/lanes_avx2.h and lanes_avx512.h. Every lane performs the same IEEE
// operations in the same order in each of them, so the voxel at which a walk stops and its t are the same
// bit for bit. The code is straight-line: a branch is taken only where every lane's result is the same
// either way (vsLaneAny before a settle whose absence changes nothing).
//
// The includer provides, besides the vocabulary:
//   LInt vsReadBoxCodeLanes(LBool mask, LInt index)  the box table's entry `index` where mask is set (any
//                                                    value elsewhere; index 0 is always readable);
//   VS_SETTLE_ALWAYS  true to settle every coordinate (cheaper than deciding for a shader, whose lanes pay
//                     for any branch one of them takes), false to settle only near a plane (vsNearPlane);
//   VS_DIV            correctly rounded division, from compute/shared/lanes.h (which every includer has
//                     included, the SIMD ones through compute/cpu/scene_arrays.h).
// Canonical order and robust stepping: see traverse.h.

// Whether a ray along one axis (origin o, inverse direction invD) has crossed the plane `coord` at parameter
// t; a plane at exactly t counts as crossed when `tieCrossed` (its axis comes before the exit axis in the
// canonical order, or at the start of a walk).
// The per-axis helpers take scalars: indexing a vector by a loop variable makes some shader compilers
// (llvmpipe) keep the whole walk state in per-lane scratch memory.
LBool vsPlaneCrossed(LFloat o, LFloat invD, LInt coord, LFloat t, LBool tieCrossed) {
  VS_PRECISE LFloat tp = (LFloat(coord) - o) * invD;
  return tp < t || (tp == t && tieCrossed);
}

// The coordinate along one axis (d != 0) of the canonical walk's voxel at parameter t, given an estimate c
// from the point o + d*t that lies in [lo, hi] and is off by at most one voxel. Precondition: the voxel's
// coordinate lies in [lo, hi].
LInt vsSettleCoord(LFloat o, LFloat d, LFloat invD, LInt c, LInt lo, LInt hi, LFloat t, LBool tieCrossed) {
  // The two planes around c decide.
  LBool up = d > 0.0f;
  LBool lowCrossed = vsPlaneCrossed(o, invD, c, t, tieCrossed);
  LBool highCrossed = vsPlaneCrossed(o, invD, c + 1, t, tieCrossed);
  LBool back = vsSelect(up, c > lo && !lowCrossed, c < hi && !highCrossed);  // c is past the voxel
  LBool ahead = vsSelect(up, c < hi && highCrossed, c > lo && lowCrossed);   // c falls short of it
  LInt step = vsSelect(up, LInt(1), LInt(-1));
  return vsSelect(back, c - step, vsSelect(ahead, c + step, c));
}

// Whether floor(x), x = o + d*t along one axis, could disagree with the plane comparisons of vsPlaneCrossed: only
// when x lies within a hair of an integer plane. The rounding errors of x and of a plane's t amount to less than
// 2^-21 of `scale` = 1 + |o| + |d*t| in position; the band is 32 times that, so outside it floor(x) is the
// canonical coordinate and the settle can be skipped.
LBool vsNearPlane(LFloat x, LFloat scale) {
  return abs(x - floor(x + 0.5f)) <= scale * (1.0f / 65536.0f);
}

// The t at which a ray along one axis leaves [boxMin, boxEnd) through the face it runs toward (d != 0).
LFloat vsAxisExit(LFloat o, LFloat d, LFloat invD, LInt boxMin, LInt boxEnd) {
  LInt bound = vsSelect(d > 0.0f, boxEnd, boxMin);
  VS_PRECISE LFloat ta = (LFloat(bound) - o) * invD;
  return ta;
}

// The coordinate along one axis (not the exit axis: `isExit` false) of the voxel after the box, left at tExit:
// the canonical coordinate at tExit, between the current voxel v and the box's far face (the ray never moves
// back). floor(o + d*tExit) is within one voxel of it, and vsSettleCoord settles it where it could differ.
LInt vsAxisNext(LFloat o, LFloat d, LFloat invD, LInt v, LInt boxMin, LInt boxEnd, LFloat tExit, LBool tieCrossed,
                LBool isExit) {
  VS_PRECISE LFloat p = o + d * tExit;
  LBool up = d > 0.0f;
  LInt from = vsSelect(up, v, boxMin);
  LInt to = vsSelect(up, boxEnd - 1, v);
  LInt c = clamp(LInt(clamp(floor(p), LFloat(boxMin), LFloat(boxEnd - 1))), from, to);
  LBool moves = d != 0.0f;
  LBool settle = moves && !isExit && (VS_SETTLE_ALWAYS || vsNearPlane(p, 1.0f + abs(o) + abs(d * tExit)));
  if (VS_SETTLE_ALWAYS || vsLaneAny(settle))
    c = vsSelect(settle, vsSettleCoord(o, d, invD, c, from, to, tExit, tieCrossed), c);
  return vsSelect(moves, c, v);
}

// One walk through one object in lane form: the brick-space ray, the object's voxel bounds, the box table's
// strides, and the walk's voxel.
struct BoxWalk {
  LFloat ox, oy, oz;  // ray origin in brick space
  LFloat dx, dy, dz;  // ray direction in brick space (t is the caller's parameter)
  LFloat ix, iy, iz;  // 1 / d per axis, 0 where d is 0
  LFloat t1;          // end of the ray's span inside the object
  LInt minX, minY, minZ, maxX, maxY, maxZ;  // the object's voxels [min, max)
  // Index of the box code of brick (0, 0, 0) (it may lie outside the table), and the code index steps along
  // y and z.
  LInt table, rowStride, sliceStride;
  LInt vx, vy, vz;  // current voxel
  LFloat tEnter;    // t at which the ray enters it (the hit's depth)
  LInt stepsLeft;   // hard bound: every step moves at least one voxel along its exit axis, never back
  LBool hit;        // set when the walk ends on a solid voxel
};

// The voxel after the empty box [boxMin, boxEnd) (voxel coordinates, end exclusive) that holds the walk's
// voxel: (nx, ny, nz) and the t at which the ray enters it, tNext. False when the ray leaves the object's voxels
// or its span (t1) first. Any empty box around the voxel leads to the same voxels.
LBool vsBoxExit(VS_IN(BoxWalk) w, LInt minX, LInt minY, LInt minZ, LInt endX, LInt endY, LInt endZ, VS_OUT(LInt) nx,
                VS_OUT(LInt) ny, VS_OUT(LInt) nz, VS_OUT(LFloat) tNext) {
  // The nearest face, the highest axis on ties (canonical order); an axis the ray runs parallel to has none.
  LFloat tx = vsSelect(w.dx != 0.0f, vsAxisExit(w.ox, w.dx, w.ix, minX, endX), LFloat(VS_T_INFINITY));
  LFloat ty = vsSelect(w.dy != 0.0f, vsAxisExit(w.oy, w.dy, w.iy, minY, endY), LFloat(VS_T_INFINITY));
  LFloat tz = vsSelect(w.dz != 0.0f, vsAxisExit(w.oz, w.dz, w.iz, minZ, endZ), LFloat(VS_T_INFINITY));
  VS_PRECISE LFloat tExit = min(min(tx, ty), tz);
  LInt exitAxis = vsSelect(tz == tExit, LInt(2), vsSelect(ty == tExit, LInt(1), LInt(0)));
  LBool inSpan = tExit < w.t1;  // false past the span, or with no face at all
  tExit = max(tExit, w.tEnter);

  // Past the box's face on the exit axis; the canonical coordinate on the others, where planes at tExit
  // count as crossed on the axes above the exit axis.
  LInt ex = vsSelect(w.dx > 0.0f, endX, minX - 1);
  LInt ey = vsSelect(w.dy > 0.0f, endY, minY - 1);
  LInt ez = vsSelect(w.dz > 0.0f, endZ, minZ - 1);
  LBool exitX = exitAxis == 0, exitY = exitAxis == 1, exitZ = exitAxis == 2;
  nx = vsSelect(exitX, ex, vsAxisNext(w.ox, w.dx, w.ix, w.vx, minX, endX, tExit, LBool(false), exitX));
  ny = vsSelect(exitY, ey, vsAxisNext(w.oy, w.dy, w.iy, w.vy, minY, endY, tExit, exitX, exitY));
  nz = vsSelect(exitZ, ez, vsAxisNext(w.oz, w.dz, w.iz, w.vz, minZ, endZ, tExit, !exitZ, exitZ));
  tNext = tExit;
  LInt exitCoord = vsSelect(exitX, ex, vsSelect(exitY, ey, ez));
  LInt exitMin = vsSelect(exitX, w.minX, vsSelect(exitY, w.minY, w.minZ));
  LInt exitMax = vsSelect(exitX, w.maxX, vsSelect(exitY, w.maxY, w.maxZ));
  return inSpan && exitCoord >= exitMin && exitCoord < exitMax;
}

// One step of the walk over a box table, for the lanes in `walking`: per object, one code per brick (VS_BOX_*
// in trace_view.h; built by compute/box_table.cpp), laid out like the object's region table with 16^3 bricks
// per region; a partial brick's code is the table index of its occupancy words, and its cells are empty
// exactly where their occupancy byte is 0. One read per step instead of the chain from the region table
// down, and boxes far larger than aligned cells; the canonical order makes the result that of the hierarchy
// walk (vsObjectWalkStep) bit for bit. Returns the lanes that walk on (on the next voxel); a lane that stops
// sets w.hit when it stopped on a solid voxel (w.vx, w.vy, w.vz and w.tEnter hold the hit).
LBool vsBoxWalkStep(VS_INOUT(BoxWalk) w, LBool walking) {
  LInt code = vsReadBoxCodeLanes(walking, w.table + (w.vx >> VS_BRICK_LOG2) + w.rowStride * (w.vy >> VS_BRICK_LOG2) +
                                              w.sliceStride * (w.vz >> VS_BRICK_LOG2));
  LBool partial = code >= 0;
  LInt cellBit = ((w.vx >> VS_CELL_LOG2) & 3) + 4 * ((w.vy >> VS_CELL_LOG2) & 3) + 16 * ((w.vz >> VS_CELL_LOG2) & 3);
  LInt voxelBit = cellBit * 8 + ((w.vx & 1) + 2 * (w.vy & 1) + 4 * (w.vz & 1));
  LInt word = vsReadBoxCodeLanes(walking && partial, vsSelect(partial, code + (voxelBit >> 5), LInt(0)));
  LBool solid = code == VS_BOX_FULL || (partial && ((word >> (voxelBit & 31)) & 1) != 0);
  LBool cellEmpty = ((word >> ((cellBit & 3) * 8)) & 255) == 0;
  LInt box = vsSelect(partial || code == VS_BOX_FULL, LInt(0), -1 - code);
  LInt log2 = vsSelect(partial, vsSelect(cellEmpty, LInt(VS_CELL_LOG2), LInt(0)), box >> VS_BOX_LOG2_SHIFT);
  LInt cx = w.vx >> log2, cy = w.vy >> log2, cz = w.vz >> log2;
  LInt belowX = box & VS_BOX_EXTENT_MASK, aboveX = (box >> VS_BOX_EXTENT_BITS) & VS_BOX_EXTENT_MASK;
  LInt belowY = (box >> (2 * VS_BOX_EXTENT_BITS)) & VS_BOX_EXTENT_MASK;
  LInt aboveY = (box >> (3 * VS_BOX_EXTENT_BITS)) & VS_BOX_EXTENT_MASK;
  LInt belowZ = (box >> (4 * VS_BOX_EXTENT_BITS)) & VS_BOX_EXTENT_MASK;
  LInt aboveZ = (box >> (5 * VS_BOX_EXTENT_BITS)) & VS_BOX_EXTENT_MASK;
  LInt nx = w.vx, ny = w.vy, nz = w.vz;
  LFloat tNext = w.tEnter;
  LBool stays = vsBoxExit(w, (cx - belowX) << log2, (cy - belowY) << log2, (cz - belowZ) << log2,
                          (cx + aboveX + 1) << log2, (cy + aboveY + 1) << log2, (cz + aboveZ + 1) << log2, nx, ny,
                          nz, tNext);
  // Every step, the solid one included, counts against the bound.
  LBool stops = w.stepsLeft <= 0 || solid || !stays;
  w.hit = vsSelect(walking && stops, w.stepsLeft > 0 && solid, w.hit);
  LBool goesOn = walking && !stops;
  w.vx = vsSelect(goesOn, nx, w.vx);
  w.vy = vsSelect(goesOn, ny, w.vy);
  w.vz = vsSelect(goesOn, nz, w.vz);
  w.tEnter = vsSelect(goesOn, tNext, w.tEnter);
  w.stepsLeft = vsSelect(goesOn, w.stepsLeft - 1, w.stepsLeft);
  return goesOn;
}

// ---- Ray set-up: from a world ray to a walk's first voxel (DESIGN.md §6, exact rays). ----
// Records (instance boxes, transforms, anchors, objects) are the same for every lane and come as arguments.

// A world ray, kept eye-relative (DESIGN.md §6): the points eyeHigh + eyeLow + start + d*t, t in [tMin, tMax].
// The eye is two floats (their sum holds it to about 48 bits), so that a ray keeps its precision however far
// from the world origin its eye lies; start (a directional view's near-plane point) is relative to the eye.
struct WorldRay {
  LVec3 eyeHigh;
  LVec3 eyeLow;
  LVec3 start;
  LVec3 d;
  LFloat tMin;
  LFloat tMax;
};

// |v| by component (GLM's vector abs stays an out-of-line call in the large CPU drivers).
VS_ALWAYS_INLINE LVec3 vsAbs3(LVec3 v) { return LVec3(abs(v.x), abs(v.y), abs(v.z)); }

// Whether every component of a ray is finite. Comparisons, not isnan/isinf, so that GLSL and C++ read it
// alike: a NaN fails every comparison. A non-finite ray (a degenerate view matrix) is a miss, so that no
// tracer turns it into a voxel coordinate.
VS_ALWAYS_INLINE LBool vsIsFinite3(LVec3 v) {
  LVec3 a = vsAbs3(v);
  return a.x <= VS_T_INFINITY && a.y <= VS_T_INFINITY && a.z <= VS_T_INFINITY;
}
VS_ALWAYS_INLINE LBool vsRayIsFinite(VS_IN(WorldRay) ray) {
  return vsIsFinite3(ray.eyeHigh) && vsIsFinite3(ray.eyeLow) && vsIsFinite3(ray.start) && vsIsFinite3(ray.d) &&
         abs(ray.tMin) <= VS_T_INFINITY && abs(ray.tMax) <= VS_T_INFINITY;
}

// 1 / d, or 0 where the ray runs parallel to the axis (d == 0): the walk's inverse direction.
VS_ALWAYS_INLINE LFloat vsInverseAxis(LFloat d) { return vsSelect(d == 0.0f, LFloat(0.0f), VS_DIV(LFloat(1.0f), d)); }

// One axis of a slab test against [lo, hi]: narrows [t0, t1] to where the ray lies between the two planes and
// gives 1/d (0 where d is 0). A ray parallel to the planes is kept when lo <= o and o < hi (o <= hi when
// `hiExclusive` is false).
VS_ALWAYS_INLINE LBool vsClipAxis(LFloat o, LFloat d, LFloat lo, LFloat hi, bool hiExclusive, VS_INOUT(LFloat) t0,
                 VS_INOUT(LFloat) t1, VS_INOUT(LFloat) invD) {
  LBool parallel = d == 0.0f;
  invD = vsInverseAxis(d);
  VS_PRECISE LFloat tLo = (lo - o) * invD;
  VS_PRECISE LFloat tHi = (hi - o) * invD;
  t0 = vsSelect(parallel, t0, max(t0, min(tLo, tHi)));
  t1 = vsSelect(parallel, t1, min(t1, max(tLo, tHi)));
  return !parallel || !(o < lo || vsSelect(LBool(hiExclusive), o >= hi, o > hi));
}

// Slab test of o + t*d against a box; returns the entry t, or VS_T_INFINITY when [tMin, tMax] misses it.
VS_ALWAYS_INLINE LFloat vsBoxEntry(LVec3 bmin, LVec3 bmax, LVec3 o, LVec3 d, LFloat tMin, LFloat tMax) {
  LFloat t0 = tMin;
  LFloat t1 = tMax;
  LFloat inv = 0.0f;
  LBool inX = vsClipAxis(o.x, d.x, bmin.x, bmax.x, false, t0, t1, inv);
  LBool inY = vsClipAxis(o.y, d.y, bmin.y, bmax.y, false, t0, t1, inv);
  LBool inZ = vsClipAxis(o.z, d.z, bmin.z, bmax.z, false, t0, t1, inv);
  return vsSelect(inX && inY && inZ && t0 <= t1, t0, LFloat(VS_T_INFINITY));
}

// The ray's start in float, for culling against world boxes only (vsCullPad bounds its error).
VS_ALWAYS_INLINE LVec3 vsCullOrigin(VS_IN(WorldRay) ray) {
  VS_PRECISE LVec3 o = ray.eyeHigh + ray.start;
  return o;
}

// How far a world box is grown for the culling tests of one ray: more than the rounding of vsCullOrigin and
// of the slab test's arithmetic (a few ulps of the largest magnitude involved), so that culling never drops an
// instance the exact ray enters; a culling test that keeps too much costs a walk, never a result.
VS_ALWAYS_INLINE LFloat vsCullPad(VS_IN(WorldRay) ray) {
  LVec3 o = vsAbs3(ray.eyeHigh) + vsAbs3(ray.start);
  VS_PRECISE LVec3 reach = vsAbs3(ray.d) * max(abs(ray.tMin), abs(ray.tMax));
  VS_PRECISE LFloat scale = max(max(o.x, o.y), o.z) + max(max(reach.x, reach.y), reach.z);
  return scale * (1.0f / 1048576.0f);
}

// Where a ray enters a world box [bmin, bmax] grown by vsCullPad, or VS_T_INFINITY when it misses it.
VS_ALWAYS_INLINE LFloat vsInstanceBoxEntry(VS_IN(WorldRay) ray, vec3 bmin, vec3 bmax) {
  LFloat pad = vsCullPad(ray);
  return vsBoxEntry(LVec3(bmin) - LVec3(pad), LVec3(bmax) + LVec3(pad), vsCullOrigin(ray), ray.d, ray.tMin,
                    ray.tMax);
}

// x with its 12 most significant bits kept (the rest cleared, toward zero): the product of two such values, or
// of one and a remainder x - vsKeepHighBits(x), is exact in float.
LFloat vsKeepHighBits(LFloat x) { return vsMaskFloatBits(x, 0xfffff000u); }
LVec3 vsKeepHighBits3(LVec3 x) { return LVec3(vsKeepHighBits(x.x), vsKeepHighBits(x.y), vsKeepHighBits(x.z)); }

// a + b = s + e exactly (Knuth's two-sum; no fused or reordered operations).
void vsTwoSum(LVec3 a, LVec3 b, VS_OUT(LVec3) s, VS_OUT(LVec3) e) {
  VS_PRECISE LVec3 sum = a + b;
  VS_PRECISE LVec3 bVirtual = sum - a;
  VS_PRECISE LVec3 err = (a - (sum - bVirtual)) + (b - bVirtual);
  s = sum;
  e = err;
}

// The t at which a ray's walk through an instance is re-based, from its vsInstanceEntry: the entry, or tMin when
// it misses the box, cut toward zero to 16 significant bits. The cut moves the base back by less than 2^-15 of
// t (at most 2^11 voxels within limits::kMaxRayVoxels), and keeps exact inputs exact: a ray with short
// coordinates gets a short re-based origin and the very t it got before re-basing. It depends on the ray and
// the instance alone, never on a backend's state.
LFloat vsBaseT(VS_IN(WorldRay) ray, LFloat entry) {
  LFloat t = vsSelect(entry == VS_T_INFINITY, ray.tMin, entry);
  return vsMaskFloatBits(t, 0xffffff00u);
}

// The ray's point at tBase relative to `anchor`, rounded once: d * tBase is split into four exact products
// (each factor cut into 12-bit halves), and the eye, the start and those products are summed with every
// rounding error carried, so the result is as precise as its own magnitude (near the instance) allows, not as
// the eye's distance from the world origin or from the instance does.
LVec3 vsRebasedPoint(VS_IN(WorldRay) ray, LFloat tBase, vec3 anchor) {
  LVec3 dHigh = vsKeepHighBits3(ray.d);
  VS_PRECISE LVec3 dLow = ray.d - dHigh;
  LFloat tHigh = vsKeepHighBits(tBase);
  VS_PRECISE LFloat tLow = tBase - tHigh;
  VS_PRECISE LVec3 pHighHigh = dHigh * tHigh;
  VS_PRECISE LVec3 pHighLow = dHigh * tLow;
  VS_PRECISE LVec3 pLowHigh = dLow * tHigh;
  VS_PRECISE LVec3 pLowLow = dLow * tLow;
  LVec3 s = LVec3(0.0f);
  LVec3 e1 = LVec3(0.0f);
  LVec3 e2 = LVec3(0.0f);
  LVec3 e3 = LVec3(0.0f);
  LVec3 e4 = LVec3(0.0f);
  LVec3 e5 = LVec3(0.0f);
  vsTwoSum(ray.eyeHigh, -LVec3(anchor), s, e1);
  vsTwoSum(s, pHighHigh, s, e2);
  vsTwoSum(s, ray.start, s, e3);
  vsTwoSum(s, pHighLow, s, e4);
  vsTwoSum(s, pLowHigh, s, e5);
  VS_PRECISE LVec3 small = (((e1 + e2) + (e3 + e4)) + (e5 + pLowLow)) + ray.eyeLow;
  VS_PRECISE LVec3 rel = s + small;
  return rel;
}

LVec3 vsApplyAffine(Affine m, LVec3 p) {
  VS_PRECISE LFloat x = m.row0.x * p.x + m.row0.y * p.y + m.row0.z * p.z + m.row0.w;
  VS_PRECISE LFloat y = m.row1.x * p.x + m.row1.y * p.y + m.row1.z * p.z + m.row1.w;
  VS_PRECISE LFloat z = m.row2.x * p.x + m.row2.y * p.y + m.row2.z * p.z + m.row2.w;
  return LVec3(x, y, z);
}
LVec3 vsApplyLinear(Affine m, LVec3 v) {
  VS_PRECISE LFloat x = m.row0.x * v.x + m.row0.y * v.y + m.row0.z * v.z;
  VS_PRECISE LFloat y = m.row1.x * v.x + m.row1.y * v.y + m.row1.z * v.z;
  VS_PRECISE LFloat z = m.row2.x * v.x + m.row2.y * v.y + m.row2.z * v.z;
  return LVec3(x, y, z);
}

// The brick-space ray of an instance (its world-to-brick map and anchor), re-based at tBase: brick-space t is
// the world t less tBase.
void vsInstanceRayOf(VS_IN(WorldRay) ray, Affine worldToBrick, vec3 anchor, LFloat tBase, VS_OUT(LVec3) lo,
                     VS_OUT(LVec3) ld) {
  lo = vsApplyAffine(worldToBrick, vsRebasedPoint(ray, tBase, anchor));
  ld = vsApplyLinear(worldToBrick, ray.d);
}

// A world t in an instance's re-based t.
LFloat vsLocalT(LFloat t, LFloat tBase) {
  VS_PRECISE LFloat local = t - tBase;
  return local;
}

// Clips o + t*d, t in [tMin, tMax], to the object's voxel bounds and places the walk on its first voxel (every
// plane at the entry t counts as crossed: the voxel the ray runs into). Returns the lanes whose rays enter the
// bounds (none where the object is empty); w's box-table fields are left 0.
LBool vsBoxWalkBegin(ObjectRecord obj, LVec3 o, LVec3 d, LFloat tMin, LFloat tMax, VS_OUT(BoxWalk) w) {
  ivec3 vmin = ivec3(obj.voxelMin);
  ivec3 vmax = ivec3(obj.voxelMax);
  if (vmax.x <= vmin.x || vmax.y <= vmin.y || vmax.z <= vmin.z) return LBool(false);
  LFloat t0 = tMin;
  LFloat t1 = tMax;
  LFloat ix = 0.0f;
  LFloat iy = 0.0f;
  LFloat iz = 0.0f;
  // All three axes, then one test: no branch per axis for SIMD lanes to diverge on.
  LBool inX = vsClipAxis(o.x, d.x, LFloat(float(vmin.x)), LFloat(float(vmax.x)), true, t0, t1, ix);
  LBool inY = vsClipAxis(o.y, d.y, LFloat(float(vmin.y)), LFloat(float(vmax.y)), true, t0, t1, iy);
  LBool inZ = vsClipAxis(o.z, d.z, LFloat(float(vmin.z)), LFloat(float(vmax.z)), true, t0, t1, iz);
  LBool enters = inX && inY && inZ && !(t0 > t1);
  // A lane that misses never reaches the integer conversions (in scalar code, where they could overflow).
  if (!vsLaneAny(enters)) return enters;
  VS_PRECISE LFloat ex = o.x + d.x * t0;
  VS_PRECISE LFloat ey = o.y + d.y * t0;
  VS_PRECISE LFloat ez = o.z + d.z * t0;
  LInt cx = LInt(clamp(floor(ex), LFloat(float(vmin.x)), LFloat(float(vmax.x - 1))));
  LInt cy = LInt(clamp(floor(ey), LFloat(float(vmin.y)), LFloat(float(vmax.y - 1))));
  LInt cz = LInt(clamp(floor(ez), LFloat(float(vmin.z)), LFloat(float(vmax.z - 1))));
  w.ox = o.x;
  w.oy = o.y;
  w.oz = o.z;
  w.dx = d.x;
  w.dy = d.y;
  w.dz = d.z;
  w.ix = ix;
  w.iy = iy;
  w.iz = iz;
  w.t1 = t1;
  w.minX = LInt(vmin.x);
  w.minY = LInt(vmin.y);
  w.minZ = LInt(vmin.z);
  w.maxX = LInt(vmax.x);
  w.maxY = LInt(vmax.y);
  w.maxZ = LInt(vmax.z);
  w.table = LInt(0);
  w.rowStride = LInt(0);
  w.sliceStride = LInt(0);
  w.vx = vsSelect(d.x != 0.0f, vsSettleCoord(o.x, d.x, ix, cx, LInt(vmin.x), LInt(vmax.x - 1), t0, LBool(true)), cx);
  w.vy = vsSelect(d.y != 0.0f, vsSettleCoord(o.y, d.y, iy, cy, LInt(vmin.y), LInt(vmax.y - 1), t0, LBool(true)), cy);
  w.vz = vsSelect(d.z != 0.0f, vsSettleCoord(o.z, d.z, iz, cz, LInt(vmin.z), LInt(vmax.z - 1), t0, LBool(true)), cz);
  w.tEnter = t0;
  w.stepsLeft = LInt((vmax.x - vmin.x) + (vmax.y - vmin.y) + (vmax.z - vmin.z) + 3);
  w.hit = LBool(false);
  return enters;
}
