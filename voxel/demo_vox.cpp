// The demo's .vox asset: small enough to keep the demo fast, with enough of a scene graph to show placement.
#include "voxel/demo_vox.h"

namespace vs {

namespace {

VoxModel crate() {
  // Planks (1) with darker frame edges (2); hollow, so a shadow ray crosses two walls.
  VoxModel m;
  m.size = {5, 5, 5};
  for (int z = 0; z < 5; ++z)
    for (int y = 0; y < 5; ++y)
      for (int x = 0; x < 5; ++x) {
        int edges = (x == 0 || x == 4) + (y == 0 || y == 4) + (z == 0 || z == 4);
        if (edges == 0) continue;
        m.voxels.push_back({std::uint8_t(x), std::uint8_t(y), std::uint8_t(z), std::uint8_t(edges >= 2 ? 2 : 1)});
      }
  return m;
}

VoxModel signpost() {
  // A pole (3) at x = 1 with a board (4) across the top three layers.
  VoxModel m;
  m.size = {4, 1, 9};
  for (int z = 0; z < 9; ++z)
    for (int x = 0; x < 4; ++x)
      if (x == 1 || z >= 6) m.voxels.push_back({std::uint8_t(x), 0, std::uint8_t(z), std::uint8_t(z >= 6 ? 4 : 3)});
  return m;
}

}  // namespace

VoxWriteFile demoCratesVox() {
  VoxWriteFile f;
  f.models = {crate(), signpost()};
  std::array<std::uint32_t, 256> palette{};
  palette.fill(0xff808080u);
  palette[1] = 0xff3a78b0u;  // 0xAABBGGRR: warm wood
  palette[2] = 0xff1e3c5au;  // dark frame
  palette[3] = 0xff3c4650u;  // grey pole
  palette[4] = 0xff2828c8u;  // red board
  f.palette = palette;
  // Crates: two side by side (the second a quarter turn about z), a third resting on both, turned again;
  // the signpost beside them. Translations are MagicaVoxel's (Z up); each crate's pivot is (2 2 2).
  f.nodes = voxSceneGraph({{0, 4, {0, 0, 2}, "crate"},
                           {0, 17, {6, 0, 2}, "crate turned"},
                           {1, 17, {-5, 2, 4}, "signpost"}});
  // The top crate sits in a subgroup of its own, so the graph nests: group 1 -> transform -> group -> transform.
  using K = VoxWriteNode::Kind;
  const int base = int(f.nodes.size());
  VoxWriteNode outer{K::Transform, base, {{"_name", "top"}}, base + 1, 0, {{{"_t", "3 0 7"}}}, {}, {}};
  VoxWriteNode group{K::Group, base + 1, {}, -1, -1, {}, {base + 2}, {}};
  VoxWriteNode inner{K::Transform, base + 2, {}, base + 3, -1, {{{"_r", "24"}, {"_t", "0 0 0"}}}, {}, {}};
  VoxWriteNode shape{K::Shape, base + 3, {}, -1, -1, {}, {}, {{0, {}}}};
  f.nodes[1].children.push_back(base);
  for (VoxWriteNode n : {outer, group, inner, shape}) f.nodes.push_back(n);
  return f;
}

}  // namespace vs
