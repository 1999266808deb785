// bake_shards.h: a bake split into shards that run anywhere (one machine, a Slurm job array) and merge into
// exactly the file one machine would have written (README "Baking on a cluster").
//
// The work of a bake is its layers' texels, cut into tiles of kShardTileTexels a side on each layer's own
// texel grid, in one canonical order: layer by layer (the bake's order), rows of tiles top to bottom, tiles
// left to right. Each tile has a cost estimate; shard K of N takes a contiguous run of that order whose cost
// is about 1/N of the whole. A shard writes a part file: a manifest naming the exact inputs (sha256 of the
// scene file and of every asset), the tool's version, N, K and its tiles, then the tiles' texels. A merge
// checks that the parts belong to one bake and hold every tile once, and writes the bake's EXR and sidecar.
#ifndef VOXSHADOW_TOOLS_BAKE_SHARDS_H
#define VOXSHADOW_TOOLS_BAKE_SHARDS_H

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bvh/bvh.h"
#include "lighting/light_views.h"
#include "tools/bake_output.h"

namespace vs {

struct SceneDesc;

// Tiles are this many texels a side (clipped at a layer's right and bottom edges): small enough that N shards
// of one large layer balance, large enough that a shard's manifest stays small (a 16384² layer: 16,384 tiles).
inline constexpr int kShardTileTexels = 128;
// The most shards one bake splits into: beyond this, shards of the largest bakes would hold a tile or two.
inline constexpr int kMaxShards = 4096;

// One tile of one layer: texels [x0, x1) x [y0, y1) of views[view].
struct ShardTile {
  int view = 0;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::uint64_t texels() const { return std::uint64_t(x1 - x0) * std::uint64_t(y1 - y0); }
  bool operator==(const ShardTile&) const = default;
};

// Every tile of a bake in the canonical order, with its cost and shard.
struct ShardPlan {
  int shards = 1;
  std::vector<ShardTile> tiles;
  std::vector<std::uint64_t> costs;  // per tile
  std::vector<std::size_t> first;    // shards + 1 entries: shard k holds tiles [first[k], first[k + 1])
  std::span<const ShardTile> shardTiles(int k) const {
    return std::span<const ShardTile>(tiles).subspan(first[k], first[k + 1] - first[k]);
  }
};

// The plan of `views` in `shards` shards. A tile's cost is its texel count times (8 + the number of caster
// boxes whose projection into the layer overlaps it): a ray that passes many instances' boxes costs more to
// walk. A box that reaches behind a perspective view's eye counts for the whole layer. The estimate only
// balances the shards; any plan merges into the same file. Integer and double arithmetic only, so every
// machine that runs the same version plans the same split. Preconditions: 1 <= shards <= kMaxShards (else
// vs::Error(BadInput)); views non-empty with positive sizes.
ShardPlan planShards(std::span<const LightView> views, std::span<const Aabb> casterBoxes, int shards);

// What makes two shards parts of one bake: the tool, the bytes of the scene and of every asset, and the
// options that change texels (none of bake's options does today: the backend, threads and device only change
// how fast the same texels come; a future one that changes texels belongs here).
struct BakeInputs {
  std::string tool;        // "voxshadow <version>"
  std::string sceneSha256;
  struct Asset {
    std::string name, sha256;
    std::filesystem::path file;  // where this machine read it (not part of the identity)
  };
  std::vector<Asset> assets;
  nlohmann::json options = nlohmann::json::object();
};

// The tool string of this build ("voxshadow 0.1.0").
std::string toolVersionString();

// Hashes the scene file and every asset of `desc` (as parseSceneFile returns it). Throws vs::Error(BadInput)
// naming a file that cannot be read.
BakeInputs hashBakeInputs(const SceneDesc& desc);

// A part file's content. Layout on disk: the 16-byte magic "voxshadow-part1\n", the manifest's length and the
// texels' length in bytes (two uint64, little-endian), the manifest (UTF-8 JSON), the tiles' texels (float32,
// little-endian, tile by tile in the manifest's order, each row by row), and the sha256 of everything before
// it (32 bytes). The lengths tell a truncated file from a damaged one.
// The manifest: {"format": "voxshadow-part", "version": 1, "bake": {"tool", "scene": {"sha256"},
// "assets": [{"name", "sha256"}], "options", "shards", "tileTexels", "views": [the sidecar's view entries]},
// "shard": K, "tiles": [[view, x0, y0, x1, y1], ...], "producer": {"scene", "assets", "backend", "host"}}.
// "bake" is equal, byte for byte, in every part of one bake; "producer" is for people only.
struct BakePart {
  std::filesystem::path file;
  nlohmann::json manifest;
  int shard = 0, shards = 1;
  std::vector<BakedView> views;  // from the manifest; texels empty
  std::vector<ShardTile> tiles;
  std::vector<float> texels;     // the tiles' texels in order
};

// The manifest of shard `shard` of `plan` for a bake of `inputs` with `views` (their texels are not used).
nlohmann::json partManifest(const BakeInputs& inputs, const ShardPlan& plan, int shard,
                            std::span<const BakedView> views, const nlohmann::json& producer);

// The part's file name in a parts directory: "shard-<K>-of-<N>.vspart".
std::string partFileName(int shard, int shards);

// Writes a part (writeAtomically: a failure leaves no file and an older part as it was). Preconditions:
// texels holds exactly the manifest's tiles' texels (else vs::Error(BadInput)).
void writeBakePart(const std::filesystem::path& out, const nlohmann::json& manifest, std::span<const float> texels);

// Reads and checks a part: magic, lengths, checksum, the manifest's fields (types, ranges, tiles on the tile
// grid inside their views). Throws vs::Error(BadInput) naming the file and what is wrong ("not a voxshadow part
// file", "truncated", "damaged: its sha256 does not match its content", a manifest field).
BakePart readBakePart(const std::filesystem::path& file);

// Whether `file` holds an intact part of shard K of N of a bake of `inputs` (same tool, scene, assets,
// options), so that a rerun can keep it. Never throws: a missing, unreadable or foreign file is simply not
// up to date; `why` (when given) says why not.
bool partUpToDate(const std::filesystem::path& file, const BakeInputs& inputs, int shard, int shards,
                  std::string* why = nullptr);

// Checks that `parts` are the parts of one bake, each shard once and every texel of every layer in exactly one
// tile, and assembles the bake's layers in its order. The reference bake is the one most parts belong to (the
// first part's on a tie). Throws vs::Error(BadInput) naming the part: unreadable or damaged, of another bake
// (and which input differs: tool version, scene, an asset, options, shard count), a shard given twice, a
// shard missing, tiles that overlap or leave texels out.
std::vector<BakedView> mergeBakeParts(std::span<const std::filesystem::path> parts);

}  // namespace vs

#endif
