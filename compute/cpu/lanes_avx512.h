// lanes_avx512.h: the lane vocabulary of compute/shared/lanes.h over sixteen AVX-512 lanes.
//
// Included by compute/cpu/lane_tracer.cpp inside a namespace of its own and a region compiled for AVX-512F.
// The same IEEE operations as lanes_avx2.h, lane for lane (see there); masks are __mmask16 registers. The
// build keeps -ffp-contract=off, so no multiply and add are fused although the instruction set has FMA.

constexpr int kLanes = 16;

struct LInt;

struct LBool {
  __mmask16 m;  // bit i: lane i is set
  LBool() = default;
  LBool(bool b) : m(b ? __mmask16(0xffff) : __mmask16(0)) {}
  explicit LBool(__mmask16 x) : m(x) {}
};

struct LFloat {
  __m512 v;
  LFloat() = default;
  LFloat(float x) : v(_mm512_set1_ps(x)) {}
  explicit LFloat(__m512 x) : v(x) {}
  explicit LFloat(const LInt& i);
};

struct LInt {
  __m512i v;
  LInt() = default;
  LInt(int x) : v(_mm512_set1_epi32(x)) {}
  explicit LInt(__m512i x) : v(x) {}
  explicit LInt(const LFloat& f) : v(_mm512_cvttps_epi32(f.v)) {}
};

inline LFloat::LFloat(const LInt& i) : v(_mm512_cvtepi32_ps(i.v)) {}

inline LBool operator&&(const LBool& a, const LBool& b) { return LBool(__mmask16(a.m & b.m)); }
inline LBool operator||(const LBool& a, const LBool& b) { return LBool(__mmask16(a.m | b.m)); }
inline LBool operator!(const LBool& a) { return LBool(__mmask16(~a.m)); }

inline LFloat operator+(const LFloat& a, const LFloat& b) { return LFloat(_mm512_add_ps(a.v, b.v)); }
inline LFloat operator-(const LFloat& a, const LFloat& b) { return LFloat(_mm512_sub_ps(a.v, b.v)); }
inline LFloat operator*(const LFloat& a, const LFloat& b) { return LFloat(_mm512_mul_ps(a.v, b.v)); }
inline LFloat operator/(const LFloat& a, const LFloat& b) { return LFloat(_mm512_div_ps(a.v, b.v)); }
inline LFloat operator-(const LFloat& a) {
  return LFloat(_mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(a.v), _mm512_set1_epi32(int(0x80000000u)))));
}
// x with only the bits of `mask` kept.
inline LFloat vsMaskFloatBits(const LFloat& x, std::uint32_t mask) {
  return LFloat(_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(x.v), _mm512_set1_epi32(int(mask)))));
}
inline LBool operator<(const LFloat& a, const LFloat& b) { return LBool(_mm512_cmp_ps_mask(a.v, b.v, _CMP_LT_OQ)); }
inline LBool operator<=(const LFloat& a, const LFloat& b) { return LBool(_mm512_cmp_ps_mask(a.v, b.v, _CMP_LE_OQ)); }
inline LBool operator>(const LFloat& a, const LFloat& b) { return LBool(_mm512_cmp_ps_mask(a.v, b.v, _CMP_GT_OQ)); }
inline LBool operator>=(const LFloat& a, const LFloat& b) { return LBool(_mm512_cmp_ps_mask(a.v, b.v, _CMP_GE_OQ)); }
inline LBool operator==(const LFloat& a, const LFloat& b) { return LBool(_mm512_cmp_ps_mask(a.v, b.v, _CMP_EQ_OQ)); }
inline LBool operator!=(const LFloat& a, const LFloat& b) { return LBool(_mm512_cmp_ps_mask(a.v, b.v, _CMP_NEQ_UQ)); }

inline LInt operator+(const LInt& a, const LInt& b) { return LInt(_mm512_add_epi32(a.v, b.v)); }
inline LInt operator-(const LInt& a, const LInt& b) { return LInt(_mm512_sub_epi32(a.v, b.v)); }
inline LInt operator*(const LInt& a, const LInt& b) { return LInt(_mm512_mullo_epi32(a.v, b.v)); }
inline LInt operator&(const LInt& a, const LInt& b) { return LInt(_mm512_and_si512(a.v, b.v)); }
inline LInt operator>>(const LInt& a, int n) { return LInt(_mm512_sra_epi32(a.v, _mm_cvtsi32_si128(n))); }
inline LInt operator<<(const LInt& a, int n) { return LInt(_mm512_sll_epi32(a.v, _mm_cvtsi32_si128(n))); }
inline LInt operator>>(const LInt& a, const LInt& n) { return LInt(_mm512_srav_epi32(a.v, n.v)); }
inline LInt operator<<(const LInt& a, const LInt& n) { return LInt(_mm512_sllv_epi32(a.v, n.v)); }
inline LBool operator==(const LInt& a, const LInt& b) { return LBool(_mm512_cmpeq_epi32_mask(a.v, b.v)); }
inline LBool operator!=(const LInt& a, const LInt& b) { return LBool(_mm512_cmpneq_epi32_mask(a.v, b.v)); }
inline LBool operator>(const LInt& a, const LInt& b) { return LBool(_mm512_cmpgt_epi32_mask(a.v, b.v)); }
inline LBool operator<(const LInt& a, const LInt& b) { return LBool(_mm512_cmplt_epi32_mask(a.v, b.v)); }
inline LBool operator>=(const LInt& a, const LInt& b) { return LBool(_mm512_cmpge_epi32_mask(a.v, b.v)); }
inline LBool operator<=(const LInt& a, const LInt& b) { return LBool(_mm512_cmple_epi32_mask(a.v, b.v)); }

// _mm512_mask_blend(k, x, y) takes y where k is set.
inline LInt vsSelect(const LBool& c, const LInt& a, const LInt& b) {
  return LInt(_mm512_mask_blend_epi32(c.m, b.v, a.v));
}
inline LFloat vsSelect(const LBool& c, const LFloat& a, const LFloat& b) {
  return LFloat(_mm512_mask_blend_ps(c.m, b.v, a.v));
}
inline LBool vsSelect(const LBool& c, const LBool& a, const LBool& b) {
  return LBool(__mmask16((c.m & a.m) | (~c.m & b.m)));
}
inline bool vsLaneAny(const LBool& b) { return b.m != 0; }

// glm: min(x, y) = y < x ? y : x and max(x, y) = x < y ? y : x; minps(a, b) = a < b ? a : b.
inline LFloat min(const LFloat& x, const LFloat& y) { return LFloat(_mm512_min_ps(y.v, x.v)); }
inline LFloat max(const LFloat& x, const LFloat& y) { return LFloat(_mm512_max_ps(y.v, x.v)); }
inline LFloat clamp(const LFloat& x, const LFloat& lo, const LFloat& hi) { return min(max(x, lo), hi); }
inline LInt min(const LInt& x, const LInt& y) { return LInt(_mm512_min_epi32(x.v, y.v)); }
inline LInt max(const LInt& x, const LInt& y) { return LInt(_mm512_max_epi32(x.v, y.v)); }
inline LInt clamp(const LInt& x, const LInt& lo, const LInt& hi) { return min(max(x, lo), hi); }
inline LFloat floor(const LFloat& x) {
  return LFloat(_mm512_roundscale_ps(x.v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
}
inline LFloat abs(const LFloat& x) {
  return LFloat(_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(x.v), _mm512_set1_epi32(0x7fffffff))));
}

// Lane access for the drivers.
inline void setLane(LFloat& x, int i, float value) { reinterpret_cast<float*>(&x.v)[i] = value; }
inline void setLane(LInt& x, int i, int value) { reinterpret_cast<int*>(&x.v)[i] = value; }
inline void setLane(LBool& x, int i, bool value) {
  x.m = __mmask16(value ? (x.m | (1u << i)) : (x.m & ~(1u << i)));
}
inline float laneOf(const LFloat& x, int i) { return reinterpret_cast<const float*>(&x.v)[i]; }
inline int laneOf(const LInt& x, int i) { return reinterpret_cast<const int*>(&x.v)[i]; }
inline unsigned laneBits(const LBool& b) { return unsigned(b.m); }

// table[index] where mask is set, 0 elsewhere.
inline LInt gatherLanes(const std::int32_t* table, const LBool& mask, const LInt& index) {
  return LInt(_mm512_mask_i32gather_epi32(_mm512_setzero_si512(), mask.m, index.v, table, 4));
}
