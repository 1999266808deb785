// lanes_avx2.h: the lane vocabulary of compute/shared/lanes.h over eight AVX2 lanes.
//
// Included by compute/cpu/lane_tracer.cpp inside a namespace of its own and a region compiled for AVX2 (no
// FMA: every operation rounds as the scalar and GLSL code does). Each operation is the IEEE operation of the
// scalar vocabulary on every lane: comparisons are ordered (false on NaN) except !=, min and max keep glm's
// operand order, floor rounds toward -inf, LInt(f) truncates, shifts of negative ints are arithmetic.

constexpr int kLanes = 8;

struct LInt;

struct LBool {
  __m256i m;  // all ones where set
  LBool() = default;
  LBool(bool b) : m(_mm256_set1_epi32(b ? -1 : 0)) {}
  explicit LBool(__m256i x) : m(x) {}
};

struct LFloat {
  __m256 v;
  LFloat() = default;
  LFloat(float x) : v(_mm256_set1_ps(x)) {}
  explicit LFloat(__m256 x) : v(x) {}
  explicit LFloat(const LInt& i);
};

struct LInt {
  __m256i v;
  LInt() = default;
  LInt(int x) : v(_mm256_set1_epi32(x)) {}
  explicit LInt(__m256i x) : v(x) {}
  explicit LInt(const LFloat& f) : v(_mm256_cvttps_epi32(f.v)) {}
};

inline LFloat::LFloat(const LInt& i) : v(_mm256_cvtepi32_ps(i.v)) {}

inline LBool operator&&(const LBool& a, const LBool& b) { return LBool(_mm256_and_si256(a.m, b.m)); }
inline LBool operator||(const LBool& a, const LBool& b) { return LBool(_mm256_or_si256(a.m, b.m)); }
inline LBool operator!(const LBool& a) { return LBool(_mm256_xor_si256(a.m, _mm256_set1_epi32(-1))); }

inline LFloat operator+(const LFloat& a, const LFloat& b) { return LFloat(_mm256_add_ps(a.v, b.v)); }
inline LFloat operator-(const LFloat& a, const LFloat& b) { return LFloat(_mm256_sub_ps(a.v, b.v)); }
inline LFloat operator*(const LFloat& a, const LFloat& b) { return LFloat(_mm256_mul_ps(a.v, b.v)); }
inline LFloat operator/(const LFloat& a, const LFloat& b) { return LFloat(_mm256_div_ps(a.v, b.v)); }
inline LFloat operator-(const LFloat& a) { return LFloat(_mm256_xor_ps(a.v, _mm256_set1_ps(-0.0f))); }
// x with only the bits of `mask` kept.
inline LFloat vsMaskFloatBits(const LFloat& x, std::uint32_t mask) {
  return LFloat(_mm256_and_ps(x.v, _mm256_castsi256_ps(_mm256_set1_epi32(int(mask)))));
}
inline LBool floatCompare(__m256 r) { return LBool(_mm256_castps_si256(r)); }
inline LBool operator<(const LFloat& a, const LFloat& b) { return floatCompare(_mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ)); }
inline LBool operator<=(const LFloat& a, const LFloat& b) { return floatCompare(_mm256_cmp_ps(a.v, b.v, _CMP_LE_OQ)); }
inline LBool operator>(const LFloat& a, const LFloat& b) { return floatCompare(_mm256_cmp_ps(a.v, b.v, _CMP_GT_OQ)); }
inline LBool operator>=(const LFloat& a, const LFloat& b) { return floatCompare(_mm256_cmp_ps(a.v, b.v, _CMP_GE_OQ)); }
inline LBool operator==(const LFloat& a, const LFloat& b) { return floatCompare(_mm256_cmp_ps(a.v, b.v, _CMP_EQ_OQ)); }
inline LBool operator!=(const LFloat& a, const LFloat& b) { return floatCompare(_mm256_cmp_ps(a.v, b.v, _CMP_NEQ_UQ)); }

inline LInt operator+(const LInt& a, const LInt& b) { return LInt(_mm256_add_epi32(a.v, b.v)); }
inline LInt operator-(const LInt& a, const LInt& b) { return LInt(_mm256_sub_epi32(a.v, b.v)); }
inline LInt operator*(const LInt& a, const LInt& b) { return LInt(_mm256_mullo_epi32(a.v, b.v)); }
inline LInt operator&(const LInt& a, const LInt& b) { return LInt(_mm256_and_si256(a.v, b.v)); }
inline LInt operator>>(const LInt& a, int n) { return LInt(_mm256_sra_epi32(a.v, _mm_cvtsi32_si128(n))); }
inline LInt operator<<(const LInt& a, int n) { return LInt(_mm256_sll_epi32(a.v, _mm_cvtsi32_si128(n))); }
inline LInt operator>>(const LInt& a, const LInt& n) { return LInt(_mm256_srav_epi32(a.v, n.v)); }
inline LInt operator<<(const LInt& a, const LInt& n) { return LInt(_mm256_sllv_epi32(a.v, n.v)); }
inline LBool operator==(const LInt& a, const LInt& b) { return LBool(_mm256_cmpeq_epi32(a.v, b.v)); }
inline LBool operator!=(const LInt& a, const LInt& b) { return !(a == b); }
inline LBool operator>(const LInt& a, const LInt& b) { return LBool(_mm256_cmpgt_epi32(a.v, b.v)); }
inline LBool operator<(const LInt& a, const LInt& b) { return b > a; }
inline LBool operator>=(const LInt& a, const LInt& b) { return !(b > a); }
inline LBool operator<=(const LInt& a, const LInt& b) { return !(a > b); }

inline LInt vsSelect(const LBool& c, const LInt& a, const LInt& b) { return LInt(_mm256_blendv_epi8(b.v, a.v, c.m)); }
inline LFloat vsSelect(const LBool& c, const LFloat& a, const LFloat& b) {
  return LFloat(_mm256_blendv_ps(b.v, a.v, _mm256_castsi256_ps(c.m)));
}
inline LBool vsSelect(const LBool& c, const LBool& a, const LBool& b) {
  return LBool(_mm256_blendv_epi8(b.m, a.m, c.m));
}
inline bool vsLaneAny(const LBool& b) { return !_mm256_testz_si256(b.m, b.m); }

// glm: min(x, y) = y < x ? y : x and max(x, y) = x < y ? y : x; minps(a, b) = a < b ? a : b.
inline LFloat min(const LFloat& x, const LFloat& y) { return LFloat(_mm256_min_ps(y.v, x.v)); }
inline LFloat max(const LFloat& x, const LFloat& y) { return LFloat(_mm256_max_ps(y.v, x.v)); }
inline LFloat clamp(const LFloat& x, const LFloat& lo, const LFloat& hi) { return min(max(x, lo), hi); }
inline LInt min(const LInt& x, const LInt& y) { return LInt(_mm256_min_epi32(x.v, y.v)); }
inline LInt max(const LInt& x, const LInt& y) { return LInt(_mm256_max_epi32(x.v, y.v)); }
inline LInt clamp(const LInt& x, const LInt& lo, const LInt& hi) { return min(max(x, lo), hi); }
inline LFloat floor(const LFloat& x) { return LFloat(_mm256_round_ps(x.v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)); }
inline LFloat abs(const LFloat& x) {
  return LFloat(_mm256_and_ps(x.v, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff))));
}

// Lane access for the drivers.
inline void setLane(LFloat& x, int i, float value) { reinterpret_cast<float*>(&x.v)[i] = value; }
inline void setLane(LInt& x, int i, int value) { reinterpret_cast<int*>(&x.v)[i] = value; }
inline void setLane(LBool& x, int i, bool value) { reinterpret_cast<int*>(&x.m)[i] = value ? -1 : 0; }
inline float laneOf(const LFloat& x, int i) { return reinterpret_cast<const float*>(&x.v)[i]; }
inline int laneOf(const LInt& x, int i) { return reinterpret_cast<const int*>(&x.v)[i]; }
inline unsigned laneBits(const LBool& b) { return unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(b.m))); }

// table[index] where mask is set, 0 elsewhere.
inline LInt gatherLanes(const std::int32_t* table, const LBool& mask, const LInt& index) {
  return LInt(_mm256_mask_i32gather_epi32(_mm256_setzero_si256(), table, index.v, mask.m, 4));
}
