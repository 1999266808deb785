// city512: ground slab, 300 boxes and 50 spheres on a 512^3 grid (DESIGN.md §10).
#include "voxel/city512.h"

#include <random>

namespace vs {

std::vector<SolidVoxel> city512Voxels() {
  constexpr int n = kCity512Size;
  std::vector<std::uint64_t> bits(std::size_t(n) * n * n / 64, 0);
  auto set = [&](int x, int y, int z) {
    std::size_t i = std::size_t(x) + std::size_t(n) * (std::size_t(y) + std::size_t(n) * std::size_t(z));
    bits[i >> 6] |= std::uint64_t(1) << (i & 63);
  };
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < n; ++x) set(x, y, z);

  std::mt19937 rng(1);
  // Each draw is lo + rng() % (hi - lo + 1); separate statements keep the draw order fixed.
  auto draw = [&](int lo, int hi) { return lo + int(rng() % std::uint32_t(hi - lo + 1)); };
  for (int b = 0; b < 300; ++b) {
    int sx = draw(4, 40);
    int sy = draw(4, 40);
    int sz = draw(4, 40);
    int x0 = draw(0, n - sx);
    int y0 = draw(0, 256 - sy);
    int z0 = draw(0, n - sz);
    for (int z = z0; z < z0 + sz; ++z)
      for (int y = y0; y < y0 + sy; ++y)
        for (int x = x0; x < x0 + sx; ++x) set(x, y, z);
  }
  for (int s = 0; s < 50; ++s) {
    int r = draw(5, 30);
    int cx = draw(r, 511 - r);
    int cy = draw(r, 256);
    int cz = draw(r, 511 - r);
    for (int z = cz - r; z <= cz + r; ++z)
      for (int y = cy - r; y <= cy + r; ++y)
        for (int x = cx - r; x <= cx + r; ++x) {
          int dx = x - cx, dy = y - cy, dz = z - cz;
          if (dx * dx + dy * dy + dz * dz <= r * r && x >= 0 && y >= 0 && z >= 0 && x < n && y < n && z < n)
            set(x, y, z);
        }
  }

  std::vector<SolidVoxel> voxels;
  voxels.reserve(kCity512SolidVoxels);
  for (std::size_t w = 0; w < bits.size(); ++w) {
    for (std::uint64_t m = bits[w]; m; m &= m - 1) {
      std::size_t i = w * 64 + std::size_t(__builtin_ctzll(m));
      voxels.push_back({glm::ivec3(int(i % n), int((i / n) % n), int(i / (std::size_t(n) * n))), 1});
    }
  }
  return voxels;
}

}  // namespace vs
