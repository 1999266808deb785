// lane_vec3.h: LVec3 of the lane vocabulary (compute/shared/lanes.h) over any LFloat of compute/cpu/lanes_*.h:
// three lanes' worth of x, y and z, each operation the componentwise operation glm's vec3 performs.
// Included after a lanes_*.h, inside its namespace.

struct LVec3 {
  LFloat x, y, z;
  LVec3() = default;
  LVec3(const LFloat& a, const LFloat& b, const LFloat& c) : x(a), y(b), z(c) {}
  explicit LVec3(const LFloat& s) : x(s), y(s), z(s) {}
  explicit LVec3(float s) : x(s), y(s), z(s) {}
  explicit LVec3(const glm::vec3& v) : x(v.x), y(v.y), z(v.z) {}
};

inline LVec3 operator+(const LVec3& a, const LVec3& b) { return LVec3(a.x + b.x, a.y + b.y, a.z + b.z); }
inline LVec3 operator-(const LVec3& a, const LVec3& b) { return LVec3(a.x - b.x, a.y - b.y, a.z - b.z); }
inline LVec3 operator*(const LVec3& a, const LVec3& b) { return LVec3(a.x * b.x, a.y * b.y, a.z * b.z); }
inline LVec3 operator*(const LVec3& a, const LFloat& s) { return LVec3(a.x * s, a.y * s, a.z * s); }
// -v flips the sign bits, as glm's negation (0 - v would turn -0 into +0).
inline LVec3 operator-(const LVec3& a) { return LVec3(-a.x, -a.y, -a.z); }
inline LVec3 abs(const LVec3& a) { return LVec3(abs(a.x), abs(a.y), abs(a.z)); }
