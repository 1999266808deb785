// Brickmap build, queries and edits against a plain reference map.
#include <cstring>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <tuple>

#include <gtest/gtest.h>

#include "voxel/brickmap.h"
#include "voxel/error.h"

namespace {

using Ref = std::map<std::tuple<int, int, int>, std::uint8_t>;
std::tuple<int, int, int> key(glm::ivec3 v) { return {v.x, v.y, v.z}; }

struct Snapshot {
  std::vector<std::vector<std::uint8_t>> arrays;
};

template <class T>
std::vector<std::uint8_t> bytesOf(std::span<const T> s) {
  std::vector<std::uint8_t> b(s.size_bytes());
  if (!b.empty()) std::memcpy(b.data(), s.data(), b.size());
  return b;
}

Snapshot snapshot(const vs::Brickmap& bm) {
  return {{bytesOf(bm.regionTable()), bytesOf(bm.regions()), bytesOf(bm.sectors()), bytesOf(bm.bricks()),
           bytesOf(bm.occupancyWords()), bytesOf(bm.payloadWords())}};
}

// Every changed (or appended) byte lies in a reported range; every range lies inside its array.
void checkDirty(const Snapshot& before, const Snapshot& after, const vs::EditResult& r) {
  for (const auto& d : r.dirty) {
    ASSERT_LE(d.byteOffset + d.byteSize, after.arrays[int(d.array)].size()) << "range outside array " << int(d.array);
  }
  if (r.rebuilt) return;
  for (int a = 0; a < 6; ++a) {
    const auto& o = before.arrays[a];
    const auto& n = after.arrays[a];
    ASSERT_GE(n.size(), o.size()) << "edits never shrink arrays";
    if (n.size() != o.size()) {
      ASSERT_TRUE(r.layoutChanged);
    }
    for (std::size_t i = 0; i < n.size(); ++i) {
      if (i < o.size() && o[i] == n[i]) continue;
      bool covered = false;
      for (const auto& d : r.dirty)
        if (int(d.array) == a && i >= d.byteOffset && i < d.byteOffset + d.byteSize) covered = true;
      if (!covered && a == 0) covered = r.layoutChanged;  // a rebuilt region table is reported whole
      ASSERT_TRUE(covered) << "array " << a << " byte " << i << " changed outside every dirty range";
    }
  }
}

void compareAll(const vs::Brickmap& bm, const Ref& ref) {
  ASSERT_EQ(bm.solidCount(), ref.size());
  Ref got;
  bm.forEachSolid([&](glm::ivec3 v, std::uint8_t m) { got[key(v)] = m; });
  ASSERT_EQ(got, ref);
  glm::ivec3 lo(INT32_MAX), hi(INT32_MIN);
  for (const auto& [k, m] : ref) {
    glm::ivec3 v(std::get<0>(k), std::get<1>(k), std::get<2>(k));
    lo = glm::min(lo, v);
    hi = glm::max(hi, v + 1);
    ASSERT_TRUE(bm.isSolid(v));
    ASSERT_EQ(bm.material(v), m);
  }
  vs::VoxelBox b = bm.bounds();
  if (ref.empty()) {
    ASSERT_TRUE(b.empty());
  } else {
    ASSERT_EQ(b.min, lo);
    ASSERT_EQ(b.max, hi);
  }
}

TEST(Brickmap, BuildMatchesInputWithDuplicatesKeepingLastMaterial) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> c(-300, 300);
  std::vector<vs::SolidVoxel> voxels;
  Ref ref;
  for (int i = 0; i < 20000; ++i) {
    glm::ivec3 v(c(rng) / 4, c(rng), c(rng) / 8);
    auto m = std::uint8_t(1 + rng() % 5);
    voxels.push_back({v, m});
    ref[key(v)] = m;
  }
  vs::Brickmap bm = vs::Brickmap::build(voxels);
  bm.checkConsistency();
  compareAll(bm, ref);
  EXPECT_FALSE(bm.isSolid(glm::ivec3(1000, 0, 0)));
  EXPECT_EQ(bm.material(glm::ivec3(-1000, 5, 0)), 0);
}

TEST(Brickmap, EmptyBuild) {
  vs::Brickmap bm = vs::Brickmap::build({});
  bm.checkConsistency();
  EXPECT_TRUE(bm.bounds().empty());
  EXPECT_EQ(bm.solidCount(), 0u);
  EXPECT_FALSE(bm.isSolid(glm::ivec3(0)));
}

TEST(Brickmap, HugeBoundsAreRefusedWithTheSize) {
  std::vector<vs::SolidVoxel> voxels{{glm::ivec3(0), 1}, {glm::ivec3((1 << 28) - 1, (1 << 28) - 1, 0), 1}};
  try {
    vs::Brickmap::build(voxels);
    FAIL() << "expected vs::Error";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput);
    EXPECT_NE(std::string(e.what()).find("slots"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("2097152x2097152x1"), std::string::npos) << e.what();
  }
}

// Three extents of 2^24 regions multiply past int64: the count saturates and the refusal names the extents.
TEST(Brickmap, BoundsWhoseSlotCountOverflowsAreRefused) {
  const int far = (1 << 30) - 1;
  std::vector<vs::SolidVoxel> voxels{{glm::ivec3(-far), 1}, {glm::ivec3(far), 1}};
  try {
    vs::Brickmap::build(voxels);
    FAIL() << "expected vs::Error";
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput);
    EXPECT_NE(std::string(e.what()).find("16777216x16777216x16777216 slots"), std::string::npos) << e.what();
  }
}

TEST(Brickmap, FullBricksOwnNoLineAndPayloadKinds) {
  vs::Brickmap bm;
  bm.fillBox({glm::ivec3(0), glm::ivec3(16, 8, 8)}, 4);
  bm.checkConsistency();
  ASSERT_EQ(bm.bricks().size(), 2u);
  for (const auto& b : bm.bricks()) {
    EXPECT_EQ(b.occupancy, vs::gpu::VS_FULL_BRICK);
    EXPECT_EQ(b.payload, vs::gpu::VS_UNIFORM_PAYLOAD | 4u);
  }
  EXPECT_EQ(bm.occupancyWords().size(), 0u);
  EXPECT_EQ(bm.payloadWords().size(), 0u);

  // A second material in brick 0 gives it a 128-word payload block; it stays full.
  auto r = bm.setVoxel(glm::ivec3(3, 2, 1), 9);
  bm.checkConsistency();
  EXPECT_EQ(bm.payloadWords().size(), 128u);
  EXPECT_TRUE(r.layoutChanged);
  EXPECT_EQ(bm.material(glm::ivec3(3, 2, 1)), 9);
  EXPECT_EQ(bm.material(glm::ivec3(3, 2, 2)), 4);
  // Clearing a voxel makes the brick partial: it gets an occupancy line.
  bm.clearVoxel(glm::ivec3(9, 1, 1));
  bm.checkConsistency();
  EXPECT_EQ(bm.occupancyWords().size(), 16u);
  EXPECT_FALSE(bm.isSolid(glm::ivec3(9, 1, 1)));
  EXPECT_TRUE(bm.isSolid(glm::ivec3(9, 1, 2)));
  // Refilling it returns the line to the free list and the brick is full again.
  bm.setVoxel(glm::ivec3(9, 1, 1), 4);
  bm.checkConsistency();
  int full = 0;
  for (const auto& b : bm.bricks()) full += b.occupancy == vs::gpu::VS_FULL_BRICK;
  EXPECT_EQ(full, 2);
  EXPECT_EQ(bm.solidCount(), 16u * 8u * 8u);
}

TEST(Brickmap, BoundsStayTightAfterClears) {
  vs::Brickmap bm;
  bm.fillBox({glm::ivec3(-20, 0, 0), glm::ivec3(20, 5, 3)}, 1);
  bm.clearBox({glm::ivec3(-20, 0, 0), glm::ivec3(-5, 5, 3)});
  bm.checkConsistency();
  EXPECT_EQ(bm.bounds().min, glm::ivec3(-5, 0, 0));
  EXPECT_EQ(bm.bounds().max, glm::ivec3(20, 5, 3));
  bm.clearBox({glm::ivec3(-100), glm::ivec3(100)});
  bm.checkConsistency();
  EXPECT_TRUE(bm.bounds().empty());
  EXPECT_EQ(bm.solidCount(), 0u);
}

TEST(Brickmap, RandomEditsMatchReference) {
  std::mt19937 rng(11);
  auto uni = [&](int lo, int hi) { return lo + int(rng() % unsigned(hi - lo + 1)); };
  std::vector<vs::SolidVoxel> initial;
  Ref ref;
  for (int i = 0; i < 3000; ++i) {
    glm::ivec3 v(uni(-60, 60), uni(-20, 40), uni(-60, 60));
    auto m = std::uint8_t(uni(1, 3));
    initial.push_back({v, m});
    ref[key(v)] = m;
  }
  vs::Brickmap bm = vs::Brickmap::build(initial);
  bm.checkConsistency();
  int layoutChanges = 0, tableGrowths = 0;
  for (int step = 0; step < 800; ++step) {
    int kind = uni(0, 3);
    // Mostly near the origin; sometimes far away (outside the current region bounds, negative too).
    int spread = uni(0, 20) == 0 ? 700 : 90;
    glm::ivec3 p(uni(-spread, spread), uni(-spread / 3, spread / 3), uni(-spread, spread));
    int maxSide = kind == 3 ? 24 : 10;
    glm::ivec3 size(uni(1, maxSide), uni(1, maxSide), uni(1, maxSide));
    auto m = std::uint8_t(uni(1, 4));
    vs::VoxelBox box{p, p + ((kind < 2) ? glm::ivec3(1) : size)};
    Ref before = ref;
    Snapshot s0 = snapshot(bm);
    glm::ivec3 dims0 = bm.regionDims();
    vs::EditResult r;
    switch (kind) {
      case 0: r = bm.setVoxel(p, m); break;
      case 1: r = bm.clearVoxel(p); break;
      case 2: r = bm.fillBox(box, m); break;
      default: r = bm.clearBox(box); break;
    }
    for (int z = box.min.z; z < box.max.z; ++z)
      for (int y = box.min.y; y < box.max.y; ++y)
        for (int x = box.min.x; x < box.max.x; ++x) {
          if (kind == 0 || kind == 2) ref[{x, y, z}] = m;
          else ref.erase({x, y, z});
        }
    ASSERT_NO_THROW(bm.checkConsistency()) << "step " << step;
    layoutChanges += r.layoutChanged;
    tableGrowths += bm.regionDims() != dims0;
    checkDirty(s0, snapshot(bm), r);
    // The dirty box covers every voxel whose state or material changed, and only the edit box.
    for (int z = box.min.z; z < box.max.z; ++z)
      for (int y = box.min.y; y < box.max.y; ++y)
        for (int x = box.min.x; x < box.max.x; ++x) {
          auto a = before.find({x, y, z});
          auto b = ref.find({x, y, z});
          bool changed = (a == before.end()) != (b == ref.end()) || (a != before.end() && a->second != b->second);
          if (changed) {
            ASSERT_FALSE(r.dirtyVoxels.empty());
            ASSERT_TRUE(x >= r.dirtyVoxels.min.x && x < r.dirtyVoxels.max.x && y >= r.dirtyVoxels.min.y &&
                        y < r.dirtyVoxels.max.y && z >= r.dirtyVoxels.min.z && z < r.dirtyVoxels.max.z)
                << "step " << step;
          }
        }
    if (!r.dirtyVoxels.empty()) {
      ASSERT_TRUE(glm::all(glm::greaterThanEqual(r.dirtyVoxels.min, box.min)));
      ASSERT_TRUE(glm::all(glm::lessThanEqual(r.dirtyVoxels.max, box.max)));
    }
    if (step % 40 == 0) compareAll(bm, ref);
    if (step % 400 == 399) {
      auto c = bm.compact();
      EXPECT_TRUE(c.rebuilt);
      bm.checkConsistency();
      compareAll(bm, ref);
    }
  }
  compareAll(bm, ref);
  EXPECT_GT(layoutChanges, 0);
  EXPECT_GT(tableGrowths, 0);
}

TEST(Brickmap, EditsOutsideSectorKeepOtherIndices) {
  vs::Brickmap bm;
  bm.fillBox({glm::ivec3(0), glm::ivec3(64, 8, 8)}, 1);  // two sectors
  auto bricks0 = std::vector<vs::gpu::Brick>(bm.bricks().begin(), bm.bricks().end());
  auto sectors0 = std::vector<vs::gpu::Sector>(bm.sectors().begin(), bm.sectors().end());
  // A new brick in the second sector moves only that sector's bricks.
  bm.setVoxel(glm::ivec3(40, 20, 0), 2);
  bm.checkConsistency();
  EXPECT_EQ(bm.sectors()[0].firstBrick, sectors0[0].firstBrick);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(std::memcmp(&bm.bricks()[std::size_t(i)], &bricks0[std::size_t(i)], sizeof(vs::gpu::Brick)), 0);
  EXPECT_TRUE(bm.isSolid(glm::ivec3(40, 20, 0)));
}

// Material 0 is empty everywhere else (queries, payload bytes, the palette), so an edit to 0 clears.
TEST(Brickmap, MaterialZeroClears) {
  vs::Brickmap bm;
  bm.fillBox({glm::ivec3(0), glm::ivec3(8, 8, 8)}, 3);
  bm.setVoxel(glm::ivec3(1, 2, 3), 0);
  bm.checkConsistency();
  EXPECT_FALSE(bm.isSolid(glm::ivec3(1, 2, 3)));
  EXPECT_EQ(bm.material(glm::ivec3(1, 2, 3)), 0);
  EXPECT_EQ(bm.solidCount(), 511u);
  bm.fillBox({glm::ivec3(0), glm::ivec3(8, 8, 4)}, 0);
  bm.checkConsistency();
  EXPECT_EQ(bm.solidCount(), 256u);
  EXPECT_FALSE(bm.isSolid(glm::ivec3(5, 5, 3)));
  EXPECT_TRUE(bm.isSolid(glm::ivec3(5, 5, 4)));
  EXPECT_EQ(bm.bounds().min, glm::ivec3(0, 0, 4));
  // On empty space it adds nothing.
  vs::Brickmap empty;
  empty.setVoxel(glm::ivec3(4), 0);
  empty.fillBox({glm::ivec3(0), glm::ivec3(3)}, 0);
  empty.checkConsistency();
  EXPECT_EQ(empty.solidCount(), 0u);
  EXPECT_TRUE(empty.bricks().empty());
}

std::string refusal(const std::function<void()>& edit) {
  try {
    edit();
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput);
    return e.what();
  }
  ADD_FAILURE() << "accepted";
  return "";
}

bool same(const Snapshot& a, const Snapshot& b) { return a.arrays == b.arrays; }

// v + 1 of the largest int wraps: such a voxel was a silent no-op while the smallest was refused.
TEST(Brickmap, VoxelsAtEitherEndOfIntAreRefusedAlike) {
  vs::Brickmap bm;
  bm.fillBox({glm::ivec3(0), glm::ivec3(10)}, 2);
  const Snapshot s0 = snapshot(bm);
  const int big = std::numeric_limits<int>::max(), small = std::numeric_limits<int>::min();
  struct Case {
    glm::ivec3 v;
    const char* text;
  } cases[] = {{{big, 0, 0}, "(2147483647, 0, 0)"},
               {{small, 0, 0}, "(-2147483648, 0, 0)"},
               {{0, 0, big}, "(0, 0, 2147483647)"},
               {{1 << 30, 1, 2}, "(1073741824, 1, 2)"}};
  for (const Case& c : cases) {
    for (int op = 0; op < 3; ++op) {
      SCOPED_TRACE(std::string(c.text) + " op " + std::to_string(op));
      std::string e = refusal([&] {
        if (op == 0) bm.setVoxel(c.v, 5);
        else if (op == 1) bm.setVoxel(c.v, 0);
        else bm.clearVoxel(c.v);
      });
      EXPECT_NE(e.find(std::string("brickmap: voxel ") + c.text + " is outside the editable range -1073741824..1073741823"),
                std::string::npos) << e;
      EXPECT_TRUE(same(s0, snapshot(bm)));
    }
  }
  // The last voxel inside the range is editable.
  vs::Brickmap edge;
  edge.setVoxel(glm::ivec3((1 << 30) - 1, -(1 << 30), 0), 7);
  edge.checkConsistency();
  EXPECT_EQ(edge.material(glm::ivec3((1 << 30) - 1, -(1 << 30), 0)), 7);
}

TEST(Brickmap, OversizeEditsAreRefusedUpFrontAndChangeNothing) {
  vs::Brickmap bm;
  bm.fillBox({glm::ivec3(0), glm::ivec3(20, 9, 9)}, 2);
  bm.setVoxel(glm::ivec3(3, 3, 3), 4);
  bm.clearVoxel(glm::ivec3(5, 5, 5));  // partial bricks, payload blocks and free lists all in use
  const Snapshot s0 = snapshot(bm);
  const std::uint64_t solid0 = bm.solidCount();
  std::string e = refusal([&] { bm.fillBox({glm::ivec3(0), glm::ivec3(4096)}, 1); });
  EXPECT_NE(e.find("brickmap: fill box [0,0,0]..[4096,4096,4096] is 4096 x 4096 x 4096 = 68719476736 voxels, "
                   "more than the limit of 67108864 voxels per edit"),
            std::string::npos) << e;
  EXPECT_TRUE(same(s0, snapshot(bm)));
  // One slab past the limit, and boxes whose sides alone pass it.
  e = refusal([&] { bm.fillBox({glm::ivec3(0), glm::ivec3(1024, 1024, 65)}, 1); });
  EXPECT_NE(e.find("1024 x 1024 x 65 = 68157440 voxels"), std::string::npos) << e;
  e = refusal([&] { bm.fillBox({glm::ivec3(-(1 << 30)), glm::ivec3(1 << 30)}, 1); });
  EXPECT_NE(e.find("2147483648 x 2147483648 x 2147483648 voxels, more than the limit"), std::string::npos) << e;
  EXPECT_TRUE(same(s0, snapshot(bm)));
  EXPECT_EQ(bm.solidCount(), solid0);
  bm.checkConsistency();

  // A clear is bounded by the part of its box inside the region table: small tables clear anything.
  bm.clearBox({glm::ivec3(-(1 << 30)), glm::ivec3(1 << 30)});
  bm.checkConsistency();
  EXPECT_EQ(bm.solidCount(), 0u);
  // A table of 41 x 1 x 1 regions holds 41 * 128^3 voxels, more than one edit may touch.
  std::vector<vs::SolidVoxel> far{{glm::ivec3(0), 1}, {glm::ivec3(128 * 40, 0, 0), 1}};
  vs::Brickmap wide = vs::Brickmap::build(far);
  const Snapshot w0 = snapshot(wide);
  e = refusal([&] { wide.clearBox({glm::ivec3(-(1 << 30)), glm::ivec3(1 << 30)}); });
  EXPECT_NE(e.find("covers 5248 x 128 x 128 = 85983232 voxels of the region table, more than the limit of 67108864"),
            std::string::npos) << e;
  EXPECT_TRUE(same(w0, snapshot(wide)));
  EXPECT_EQ(wide.solidCount(), 2u);
  wide.clearBox({glm::ivec3(0), glm::ivec3(128 * 20, 128, 128)});
  EXPECT_EQ(wide.solidCount(), 1u);
}

}  // namespace
