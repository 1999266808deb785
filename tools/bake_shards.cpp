#include "tools/bake_shards.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>

#include <glm/gtc/type_ptr.hpp>

#include "lighting/scene_file.h"
#include "tools/atomic_file.h"
#include "tools/sha256.h"
#include "voxel/error.h"

#ifndef VOXSHADOW_VERSION
#error "VOXSHADOW_VERSION must be defined by the build"
#endif

namespace vs {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little, "part files store texels as the host's little-endian floats");

namespace {

constexpr char kMagic[16] = {'v', 'o', 'x', 's', 'h', 'a', 'd', 'o', 'w', '-', 'p', 'a', 'r', 't', '1', '\n'};
constexpr int kPartFormatVersion = 1;
constexpr std::size_t kDigestBytes = 32;
// A manifest lists one small array per tile: 16,384² layers of 128-texel tiles, a few hundred of them, stay far
// below this; anything larger is a damaged length field, not a manifest.
constexpr std::uint64_t kMaxManifestBytes = 1ull << 30;
// A ray's own cost (set-up, the instance BVH, a miss) in units of the walk through one caster box it passes:
// with 8, the shards of the demo scene (3 shards, CPU) trace within 20% of each other's time.
constexpr std::uint64_t kRayBaseCost = 8;

// The texel rectangle of `box` projected into `view`, clamped to the layer; the whole layer when a corner lies
// on or behind a perspective view's eye plane (its projection is unbounded there).
std::optional<ShardTile> projectedRect(const LightView& view, const Aabb& box) {
  const int w = view.trace.info.x, h = view.trace.info.y;
  double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 corner((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y,
                            (c & 4) ? box.max.z : box.min.z);
    const glm::dvec4 clip = view.eyeToClip * glm::dvec4(corner - view.eye, 1.0);
    if (!(clip.w > 1e-9)) return ShardTile{0, 0, 0, w, h};
    for (int a = 0; a < 2; ++a) {
      const double ndc = clip[a] / clip.w;
      lo[a] = std::min(lo[a], ndc);
      hi[a] = std::max(hi[a], ndc);
    }
  }
  auto texel = [](double ndc, int size) { return (ndc * 0.5 + 0.5) * double(size); };
  const double x0 = std::clamp(std::floor(texel(lo[0], w)), 0.0, double(w));
  const double x1 = std::clamp(std::ceil(texel(hi[0], w)), 0.0, double(w));
  const double y0 = std::clamp(std::floor(texel(lo[1], h)), 0.0, double(h));
  const double y1 = std::clamp(std::ceil(texel(hi[1], h)), 0.0, double(h));
  if (!(x1 > x0 && y1 > y0)) return std::nullopt;
  return ShardTile{0, int(x0), int(y0), int(x1), int(y1)};
}

int tilesAcross(int size) { return (size + kShardTileTexels - 1) / kShardTileTexels; }

// The checks a tile of a part must pass: on the tile grid of its view, inside it, and of the full tile size
// there (clipped only at the layer's edges).
bool onTileGrid(const ShardTile& t, int width, int height) {
  if (t.x0 < 0 || t.y0 < 0 || t.x0 % kShardTileTexels != 0 || t.y0 % kShardTileTexels != 0) return false;
  if (t.x0 >= width || t.y0 >= height) return false;
  return t.x1 == std::min(width, t.x0 + kShardTileTexels) && t.y1 == std::min(height, t.y0 + kShardTileTexels);
}

}  // namespace

ShardPlan planShards(std::span<const LightView> views, std::span<const Aabb> casterBoxes, int shards) {
  if (shards < 1 || shards > kMaxShards)
    throwBadInput("shards: must be between 1 and " + std::to_string(kMaxShards) + ", not " + std::to_string(shards));
  ShardPlan plan;
  plan.shards = shards;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const int w = views[v].trace.info.x, h = views[v].trace.info.y;
    const int across = tilesAcross(w), down = tilesAcross(h);
    // Boxes over each tile of this layer, counted per tile through each box's covered tile range.
    std::vector<std::uint32_t> over(std::size_t(across) * std::size_t(down), 0);
    for (const Aabb& box : casterBoxes) {
      if (box.empty()) continue;
      std::optional<ShardTile> r = projectedRect(views[v], box);
      if (!r) continue;
      for (int ty = r->y0 / kShardTileTexels; ty < tilesAcross(r->y1); ++ty)
        for (int tx = r->x0 / kShardTileTexels; tx < tilesAcross(r->x1); ++tx) ++over[std::size_t(ty) * across + tx];
    }
    for (int ty = 0; ty < down; ++ty)
      for (int tx = 0; tx < across; ++tx) {
        ShardTile t{int(v), tx * kShardTileTexels, ty * kShardTileTexels, std::min(w, (tx + 1) * kShardTileTexels),
                    std::min(h, (ty + 1) * kShardTileTexels)};
        plan.costs.push_back(t.texels() * (kRayBaseCost + std::uint64_t(over[std::size_t(ty) * across + tx])));
        plan.tiles.push_back(t);
      }
  }
  // Tile i goes to the shard whose cost interval holds the middle of its own: floor((2 P_i + c_i) N / 2C), with
  // P_i the cost before it. This never decreases along the order, so each shard is one contiguous run.
  unsigned __int128 total = 0;
  for (std::uint64_t c : plan.costs) total += c;
  plan.first.assign(std::size_t(shards) + 1, plan.tiles.size());
  plan.first[0] = 0;
  unsigned __int128 before = 0;
  int current = 0;
  for (std::size_t i = 0; i < plan.tiles.size(); ++i) {
    const unsigned __int128 middle2 = 2 * before + plan.costs[i];
    int shard = total == 0 ? 0 : int(std::min<unsigned __int128>(shards - 1, middle2 * unsigned(shards) / (2 * total)));
    while (current < shard) plan.first[++current] = i;
    before += plan.costs[i];
  }
  return plan;
}

std::string toolVersionString() { return std::string("voxshadow ") + VOXSHADOW_VERSION; }

BakeInputs hashBakeInputs(const SceneDesc& desc) {
  BakeInputs in;
  in.tool = toolVersionString();
  in.sceneSha256 = sha256File(desc.file);
  for (const AssetDesc& a : desc.assets) in.assets.push_back({a.name, sha256File(a.file), a.file});
  return in;
}

std::string partFileName(int shard, int shards) {
  return "shard-" + std::to_string(shard) + "-of-" + std::to_string(shards) + ".vspart";
}

namespace {

nlohmann::json bakeIdentity(const BakeInputs& inputs, int shards) {
  nlohmann::json assets = nlohmann::json::array();
  for (const BakeInputs::Asset& a : inputs.assets) assets.push_back({{"name", a.name}, {"sha256", a.sha256}});
  return {{"tool", inputs.tool},
          {"scene", {{"sha256", inputs.sceneSha256}}},
          {"assets", std::move(assets)},
          {"options", inputs.options},
          {"shards", shards},
          {"tileTexels", kShardTileTexels}};
}

}  // namespace

nlohmann::json partManifest(const BakeInputs& inputs, const ShardPlan& plan, int shard,
                            std::span<const BakedView> views, const nlohmann::json& producer) {
  nlohmann::json bake = bakeIdentity(inputs, plan.shards);
  bake["views"] = sidecarJson(views)["views"];
  nlohmann::json tiles = nlohmann::json::array();
  for (const ShardTile& t : plan.shardTiles(shard)) tiles.push_back({t.view, t.x0, t.y0, t.x1, t.y1});
  return {{"format", "voxshadow-part"}, {"version", kPartFormatVersion}, {"bake", std::move(bake)},
          {"shard", shard},             {"tiles", std::move(tiles)},     {"producer", producer}};
}

void writeBakePart(const fs::path& out, const nlohmann::json& manifest, std::span<const float> texels) {
  std::uint64_t expected = 0;
  for (const nlohmann::json& t : manifest.at("tiles"))
    expected += std::uint64_t(t[3].get<int>() - t[1].get<int>()) * std::uint64_t(t[4].get<int>() - t[2].get<int>());
  if (expected != texels.size())
    throwBadInput(out.string() + ": " + std::to_string(texels.size()) + " texels for tiles of " + std::to_string(expected));
  const std::string text = manifest.dump();
  writeAtomically(std::span<const fs::path>(&out, 1), [&](std::size_t, const fs::path& tmp) {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throwRuntime(out.string() + ": cannot open for writing");
    Sha256 hash;
    auto put = [&](const void* data, std::size_t size) {
      f.write(static_cast<const char*>(data), std::streamsize(size));
      hash.update(data, size);
    };
    put(kMagic, sizeof(kMagic));
    const std::uint64_t lengths[2] = {text.size(), texels.size_bytes()};
    put(lengths, sizeof(lengths));
    put(text.data(), text.size());
    put(texels.data(), texels.size_bytes());
    const auto digest = hash.digest();
    f.write(reinterpret_cast<const char*>(digest.data()), std::streamsize(digest.size()));
    f.close();
    if (!f) throwRuntime(out.string() + ": write failed");
  });
}

namespace {

// The sidecar's view entry back as a BakedView (texels empty); `where` names it in messages.
BakedView viewFromJson(const nlohmann::json& j, const std::string& where) {
  BakedView v;
  try {
    v.name = j.at("name").get<std::string>();
    v.light = j.at("light").get<std::string>();
    v.encoding = j.at("encoding").get<std::string>();
    v.depthPoint = j.at("depthPoint").get<std::string>();
    v.range = j.at("range").get<float>();
    const auto m = j.at("worldToClip").get<std::vector<float>>();
    const auto eye = j.at("eye").get<std::vector<double>>();
    const auto eyeToClip = j.at("eyeToClip").get<std::vector<double>>();
    if (m.size() != 16 || eye.size() != 3 || eyeToClip.size() != 16)
      throwBadInput(where + ": worldToClip, eye and eyeToClip need 16, 3 and 16 numbers");
    std::memcpy(glm::value_ptr(v.worldToClip), m.data(), sizeof(float) * 16);
    v.eye = glm::dvec3(eye[0], eye[1], eye[2]);
    std::memcpy(glm::value_ptr(v.eyeToClip), eyeToClip.data(), sizeof(double) * 16);
    if (j.contains("position")) {
      const auto p = j.at("position").get<std::vector<float>>();
      if (p.size() != 3) throwBadInput(where + ".position: needs 3 numbers");
      v.position = glm::vec3(p[0], p[1], p[2]);
    }
    v.width = j.at("width").get<int>();
    v.height = j.at("height").get<int>();
  } catch (const nlohmann::json::exception& e) {
    throwBadInput(where + ": " + e.what());
  }
  if (v.width <= 0 || v.height <= 0 || v.width > 65536 || v.height > 65536)
    throwBadInput(where + ": size " + std::to_string(v.width) + "x" + std::to_string(v.height) + " out of range");
  return v;
}

std::uint64_t readU64(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}

}  // namespace

BakePart readBakePart(const fs::path& file) {
  const std::string name = file.string();
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throwBadInput(name + ": no such part file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throwBadInput(name + ": cannot open the part file");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throwBadInput(name + ": read failed");
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throwBadInput(name + ": not a voxshadow part file (it does not start with \"voxshadow-part1\")");
  const std::size_t headerBytes = sizeof(kMagic) + 2 * sizeof(std::uint64_t);
  if (bytes.size() < headerBytes) throwBadInput(name + ": truncated (" + std::to_string(bytes.size()) + " bytes)");
  const std::uint64_t manifestBytes = readU64(bytes.data() + sizeof(kMagic));
  const std::uint64_t payload = readU64(bytes.data() + sizeof(kMagic) + sizeof(std::uint64_t));
  if (manifestBytes > kMaxManifestBytes || payload > (1ull << 50) || payload % sizeof(float) != 0)
    throwBadInput(name + ": damaged (its header gives a manifest of " + std::to_string(manifestBytes) + " bytes and " +
                  std::to_string(payload) + " bytes of texels)");
  const std::uint64_t expected = headerBytes + manifestBytes + payload + kDigestBytes;
  if (bytes.size() < expected)
    throwBadInput(name + ": truncated (" + std::to_string(bytes.size()) + " of its " + std::to_string(expected) + " bytes)");
  if (bytes.size() > expected)
    throwBadInput(name + ": damaged (" + std::to_string(bytes.size() - expected) + " bytes after its end)");
  {
    Sha256 hash;
    hash.update(bytes.data(), bytes.size() - kDigestBytes);
    const auto digest = hash.digest();
    if (std::memcmp(digest.data(), bytes.data() + bytes.size() - kDigestBytes, kDigestBytes) != 0)
      throwBadInput(name + ": damaged: its sha256 does not match its content");
  }
  BakePart part;
  part.file = file;
  try {
    part.manifest = nlohmann::json::parse(bytes.begin() + headerBytes, bytes.begin() + headerBytes + manifestBytes);
  } catch (const nlohmann::json::exception& e) {
    throwBadInput(name + ": manifest: " + e.what());
  }
  const nlohmann::json& m = part.manifest;
  auto field = [&](const nlohmann::json& parent, const char* key, const std::string& path) -> const nlohmann::json& {
    if (!parent.is_object() || !parent.contains(key)) throwBadInput(name + ": manifest: " + path + " is missing");
    return parent.at(key);
  };
  if (field(m, "format", "format") != "voxshadow-part") throwBadInput(name + ": manifest: format is not voxshadow-part");
  if (field(m, "version", "version") != kPartFormatVersion)
    throwBadInput(name + ": manifest: version " + m.at("version").dump() + " (this voxshadow reads version " +
                  std::to_string(kPartFormatVersion) + ")");
  const nlohmann::json& bake = field(m, "bake", "bake");
  const nlohmann::json& shards = field(bake, "shards", "bake.shards");
  const nlohmann::json& shard = field(m, "shard", "shard");
  if (!shards.is_number_integer() || shards.get<std::int64_t>() < 1 || shards.get<std::int64_t>() > kMaxShards)
    throwBadInput(name + ": manifest: bake.shards must be an integer 1.." + std::to_string(kMaxShards));
  part.shards = shards.get<int>();
  if (!shard.is_number_integer() || shard.get<std::int64_t>() < 0 || shard.get<std::int64_t>() >= part.shards)
    throwBadInput(name + ": manifest: shard must be an integer 0.." + std::to_string(part.shards - 1));
  part.shard = shard.get<int>();
  if (!field(bake, "tool", "bake.tool").is_string()) throwBadInput(name + ": manifest: bake.tool must be a string");
  if (!field(field(bake, "scene", "bake.scene"), "sha256", "bake.scene.sha256").is_string())
    throwBadInput(name + ": manifest: bake.scene.sha256 must be a string");
  if (!field(bake, "assets", "bake.assets").is_array()) throwBadInput(name + ": manifest: bake.assets must be an array");
  if (!field(bake, "options", "bake.options").is_object())
    throwBadInput(name + ": manifest: bake.options must be an object");
  if (field(bake, "tileTexels", "bake.tileTexels") != kShardTileTexels)
    throwBadInput(name + ": manifest: bake.tileTexels is " + bake.at("tileTexels").dump() + ", not " +
                  std::to_string(kShardTileTexels));
  const nlohmann::json& views = field(bake, "views", "bake.views");
  if (!views.is_array() || views.empty()) throwBadInput(name + ": manifest: bake.views must be a non-empty array");
  for (std::size_t i = 0; i < views.size(); ++i)
    part.views.push_back(viewFromJson(views[i], name + ": manifest: bake.views[" + std::to_string(i) + "]"));
  const nlohmann::json& tiles = field(m, "tiles", "tiles");
  if (!tiles.is_array()) throwBadInput(name + ": manifest: tiles must be an array");
  std::uint64_t texels = 0;
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    const std::string where = name + ": manifest: tiles[" + std::to_string(i) + "]";
    const nlohmann::json& t = tiles[i];
    if (!t.is_array() || t.size() != 5 || !std::all_of(t.begin(), t.end(), [](const nlohmann::json& n) { return n.is_number_integer(); }))
      throwBadInput(where + ": must be [view, x0, y0, x1, y1]");
    const std::int64_t view = t[0].get<std::int64_t>();
    if (view < 0 || view >= std::int64_t(part.views.size())) throwBadInput(where + ": no view " + t[0].dump());
    ShardTile tile{int(view), 0, 0, 0, 0};
    for (int k = 1; k < 5; ++k) {
      const std::int64_t c = t[k].get<std::int64_t>();
      if (c < 0 || c > 65536) throwBadInput(where + ": coordinate " + t[k].dump() + " out of range");
    }
    tile.x0 = t[1].get<int>();
    tile.y0 = t[2].get<int>();
    tile.x1 = t[3].get<int>();
    tile.y1 = t[4].get<int>();
    if (!onTileGrid(tile, part.views[tile.view].width, part.views[tile.view].height))
      throwBadInput(where + ": " + t.dump() + " is not a tile of the " + std::to_string(kShardTileTexels) +
                    "-texel grid of view '" + part.views[tile.view].name + "'");
    texels += tile.texels();
    part.tiles.push_back(tile);
  }
  if (payload != texels * sizeof(float))
    throwBadInput(name + ": " + std::to_string(payload) + " bytes of texels for tiles of " + std::to_string(texels) +
                  " texels");
  part.texels.resize(texels);
  std::memcpy(part.texels.data(), bytes.data() + headerBytes + manifestBytes, payload);
  return part;
}

bool partUpToDate(const fs::path& file, const BakeInputs& inputs, int shard, int shards, std::string* why) {
  auto no = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  std::error_code ec;
  if (!fs::exists(file, ec)) return no("missing");
  BakePart part;
  try {
    part = readBakePart(file);
  } catch (const std::exception& e) {
    return no(e.what());
  }
  if (part.shard != shard || part.shards != shards)
    return no("holds shard " + std::to_string(part.shard) + " of " + std::to_string(part.shards));
  nlohmann::json identity = part.manifest.at("bake");
  identity.erase("views");
  if (identity != bakeIdentity(inputs, shards)) return no("made from other inputs or by another version");
  return true;
}

namespace {

// The first input in which two bakes differ, in words.
std::string identityDifference(const nlohmann::json& a, const nlohmann::json& b) {
  auto value = [](const nlohmann::json& j, const char* key) { return j.contains(key) ? j.at(key).dump() : "nothing"; };
  if (a.at("tool") != b.at("tool"))
    return "made by " + a.at("tool").get<std::string>() + ", the other parts by " + b.at("tool").get<std::string>();
  if (a.at("shards") != b.at("shards"))
    return "a part of " + a.at("shards").dump() + " shards, the other parts of " + b.at("shards").dump();
  if (a.at("scene") != b.at("scene"))
    return "from another scene file (sha256 " + value(a.at("scene"), "sha256") + ", the other parts " +
           value(b.at("scene"), "sha256") + ")";
  if (a.at("assets") != b.at("assets")) {
    const nlohmann::json &x = a.at("assets"), &y = b.at("assets");
    for (std::size_t i = 0; i < std::max(x.size(), y.size()); ++i)
      if (i >= x.size() || i >= y.size() || x[i] != y[i])
        return "from other assets (asset " + std::to_string(i) + ": " + (i < x.size() ? x[i].dump() : "none") +
               ", the other parts " + (i < y.size() ? y[i].dump() : "none") + ")";
  }
  if (a.at("options") != b.at("options"))
    return "baked with other options (" + a.at("options").dump() + ", the other parts " + b.at("options").dump() + ")";
  return "its views differ from the other parts' (same inputs, other views: a damaged or hand-made part)";
}

}  // namespace

std::vector<BakedView> mergeBakeParts(std::span<const fs::path> parts) {
  if (parts.empty()) throwBadInput("merge: no part files given");
  std::vector<BakePart> read;
  read.reserve(parts.size());
  for (const fs::path& p : parts) read.push_back(readBakePart(p));

  // The bake most parts belong to is the reference; the first part's on a tie.
  std::map<std::string, int> votes;
  for (const BakePart& p : read) ++votes[p.manifest.at("bake").dump()];
  std::size_t reference = 0;
  for (std::size_t i = 0; i < read.size(); ++i)
    if (votes[read[i].manifest.at("bake").dump()] > votes[read[reference].manifest.at("bake").dump()]) reference = i;
  const nlohmann::json& bake = read[reference].manifest.at("bake");
  for (const BakePart& p : read)
    if (p.manifest.at("bake") != bake)
      throwBadInput(p.file.string() + ": not a part of the same bake as " + read[reference].file.string() + ": " +
                    identityDifference(p.manifest.at("bake"), bake));

  const int shards = read[reference].shards;
  std::vector<const BakePart*> byShard(std::size_t(shards), nullptr);
  for (const BakePart& p : read) {
    if (byShard[p.shard])
      throwBadInput(p.file.string() + ": shard " + std::to_string(p.shard) + " of " + std::to_string(shards) +
                    " given twice (also " + byShard[p.shard]->file.string() + ")");
    byShard[p.shard] = &p;
  }
  std::string missing;
  int missingCount = 0, firstMissing = -1;
  for (int k = 0; k < shards; ++k)
    if (!byShard[k]) {
      missing += (missingCount++ ? ", " : "") + std::to_string(k);
      if (firstMissing < 0) firstMissing = k;
    }
  if (missingCount)
    throwBadInput("merge: shard" + std::string(missingCount > 1 ? "s " : " ") + missing + " of " + std::to_string(shards) +
                  " missing: no part given for " + (missingCount > 1 ? "them" : "it") + " (a part such as " +
                  partFileName(firstMissing, shards) + ")");

  std::vector<BakedView> views = read[reference].views;
  // The layers are allocated only when the parts' texels (which their files hold) cover them: a manifest
  // cannot make the merge allocate what the parts do not carry. More texels than the views is an overlap,
  // which the tile-by-tile check below names.
  std::uint64_t viewTexels = 0, partTexels = 0;
  for (const BakedView& v : views) viewTexels += std::uint64_t(v.width) * std::uint64_t(v.height);
  for (const BakePart* p : byShard) partTexels += p->texels.size();
  if (partTexels < viewTexels)
    throwBadInput("merge: the parts hold " + std::to_string(partTexels) + " texels of their views' " +
                  std::to_string(viewTexels) + ": their tiles leave texels out");
  std::vector<std::vector<const BakePart*>> owner(views.size());
  for (std::size_t v = 0; v < views.size(); ++v) {
    views[v].texels.assign(std::size_t(views[v].width) * std::size_t(views[v].height), 0.0f);
    owner[v].assign(std::size_t(tilesAcross(views[v].width)) * std::size_t(tilesAcross(views[v].height)), nullptr);
  }
  for (const BakePart* p : byShard) {
    std::size_t offset = 0;
    for (const ShardTile& t : p->tiles) {
      BakedView& v = views[t.view];
      const BakePart*& cell = owner[t.view][std::size_t(t.y0 / kShardTileTexels) * tilesAcross(v.width) + t.x0 / kShardTileTexels];
      if (cell)
        throwBadInput(p->file.string() + ": tile (" + std::to_string(t.x0) + ", " + std::to_string(t.y0) + ") of view '" +
                      v.name + "' is also in " + cell->file.string());
      cell = p;
      const int w = t.x1 - t.x0;
      for (int y = t.y0; y < t.y1; ++y, offset += std::size_t(w))
        std::memcpy(&v.texels[std::size_t(y) * v.width + t.x0], &p->texels[offset], std::size_t(w) * sizeof(float));
    }
  }
  for (std::size_t v = 0; v < views.size(); ++v)
    for (std::size_t c = 0; c < owner[v].size(); ++c)
      if (!owner[v][c]) {
        const int across = tilesAcross(views[v].width);
        throwBadInput("merge: no part holds tile (" + std::to_string(int(c % across) * kShardTileTexels) + ", " +
                      std::to_string(int(c / across) * kShardTileTexels) + ") of view '" + views[v].name +
                      "': the parts' tiles leave texels out");
      }
  return views;
}

}  // namespace vs
