// The .vox reader: a bounds-checked walk over the chunk tree, then the scene graph resolved for one frame.
#include "voxel/vox_reader.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include "voxel/error.h"

namespace vs {

std::string VoxMaterial::type() const {
  auto it = props.find("_type");
  if (it == props.end() || it->second.empty()) return "diffuse";
  return it->second[0] == '_' ? it->second.substr(1) : it->second;
}

VoxTransform VoxTransform::then(const VoxTransform& child) const {
  return {rotation * child.rotation, rotation * child.translation + translation};
}

bool decodeVoxRotation(int packed, glm::imat3x3& out) {
  const int c0 = packed & 3, c1 = (packed >> 2) & 3;
  if (c0 == 3 || c1 == 3 || c0 == c1) return false;
  const int col[3] = {c0, c1, 3 - c0 - c1};
  glm::imat3x3 m(0);
  for (int row = 0; row < 3; ++row) m[col[row]][row] = (packed >> (4 + row)) & 1 ? -1 : 1;  // GLM: m[column][row]
  out = m;
  return true;
}

const std::array<std::uint32_t, 256>& voxDefaultPalette() {
  static const std::array<std::uint32_t, 256> palette = [] {
    std::array<std::uint32_t, 256> p{};
    auto rgb = [](std::uint32_t r, std::uint32_t g, std::uint32_t b) { return 0xff000000u | b << 16 | g << 8 | r; };
    // Indices 1..215: the 6-level colour cube from white down, blue varying fastest, black left out.
    for (int k = 0; k < 215; ++k) {
      auto level = [](int i) { return std::uint32_t(0xff - 0x33 * i); };
      p[std::size_t(1 + k)] = rgb(level(k / 36), level((k / 6) % 6), level(k % 6));
    }
    // Indices 216..255: ten-step ramps of red, green, blue and grey between the cube's levels.
    const std::uint32_t ramp[10] = {0xee, 0xdd, 0xbb, 0xaa, 0x88, 0x77, 0x55, 0x44, 0x22, 0x11};
    for (int i = 0; i < 10; ++i) {
      p[std::size_t(216 + i)] = rgb(ramp[i], 0, 0);
      p[std::size_t(226 + i)] = rgb(0, ramp[i], 0);
      p[std::size_t(236 + i)] = rgb(0, 0, ramp[i]);
      p[std::size_t(246 + i)] = rgb(ramp[i], ramp[i], ramp[i]);
    }
    return p;
  }();
  return palette;
}

float srgbToLinear(std::uint8_t c) {
  const double s = c / 255.0;
  return float(s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4));
}

namespace {

std::string chunkName(const std::uint8_t* id) {
  std::string s(reinterpret_cast<const char*>(id), 4);
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e) c = '?';
  return s;
}

using Dict = std::map<std::string, std::string>;

// Reads one chunk's content; every read is checked against the content's end.
class Cursor {
 public:
  Cursor(const std::uint8_t* data, std::size_t begin, std::size_t end, std::string label)
      : data_(data), at_(begin), end_(end), label_(std::move(label)) {}

  [[noreturn]] void fail(const std::string& what) const { throwBadInput(label_ + ": " + what); }
  const std::string& label() const { return label_; }
  std::size_t remaining() const { return end_ - at_; }

  std::int32_t i32(const char* what) {
    if (remaining() < 4) fail(std::string("truncated: no room for ") + what);
    std::uint32_t v = std::uint32_t(data_[at_]) | std::uint32_t(data_[at_ + 1]) << 8 |
                      std::uint32_t(data_[at_ + 2]) << 16 | std::uint32_t(data_[at_ + 3]) << 24;
    at_ += 4;
    return std::int32_t(v);
  }

  // A count of items of at least `minItemBytes` each that must fit in what is left.
  std::size_t count(const char* what, std::size_t minItemBytes) {
    std::int32_t n = i32(what);
    if (n < 0) fail(std::string(what) + " " + std::to_string(n) + " is negative");
    if (std::size_t(n) > remaining() / minItemBytes)
      fail(std::string(what) + " " + std::to_string(n) + " is larger than the chunk (" + std::to_string(remaining()) +
           " bytes left)");
    return std::size_t(n);
  }

  const std::uint8_t* bytes(std::size_t n, const char* what) {
    if (remaining() < n) fail(std::string("truncated: no room for ") + what);
    const std::uint8_t* p = data_ + at_;
    at_ += n;
    return p;
  }

  std::string string(const char* what) {
    std::size_t n = count(what, 1);
    const std::uint8_t* p = bytes(n, what);
    return std::string(reinterpret_cast<const char*>(p), n);
  }

  Dict dict(const char* what) {
    std::size_t n = count(what, 8);  // a pair is two length-prefixed strings
    Dict d;
    for (std::size_t i = 0; i < n; ++i) {
      std::string k = string("dictionary key");
      d[k] = string("dictionary value");
    }
    return d;
  }

 private:
  const std::uint8_t* data_;
  std::size_t at_, end_;
  std::string label_;
};

std::optional<long long> parseInt(const std::string& s) {
  long long v = 0;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || p != s.data() + s.size()) return std::nullopt;
  return v;
}

bool flag(const Dict& d, const char* key) {
  auto it = d.find(key);
  return it != d.end() && it->second == "1";
}

std::string value(const Dict& d, const char* key) {
  auto it = d.find(key);
  return it == d.end() ? std::string() : it->second;
}

enum class NodeType { Transform, Group, Shape };

struct Keyframe {
  long long frame = 0;
  VoxTransform transform;  // Transform nodes
  int model = -1;          // Shape nodes
};

struct Node {
  NodeType type = NodeType::Transform;
  std::string label;  // "nTRN chunk at byte N" for messages
  std::string name;
  bool hidden = false;
  int layer = -1;
  std::vector<int> children;  // Transform: exactly one; Group: any number
  std::vector<Keyframe> frames;
};

int frameIndexOf(const Cursor& c, const Dict& d) {
  std::string f = value(d, "_f");
  if (f.empty()) return 0;
  auto v = parseInt(f);
  if (!v || *v < 0 || *v > kVoxMaxFrame)
    c.fail("frame index \"" + f + "\" is not an integer in 0.." + std::to_string(kVoxMaxFrame));
  return int(*v);
}

VoxTransform frameTransform(const Cursor& c, const Dict& d) {
  VoxTransform t;
  std::string r = value(d, "_r");
  if (!r.empty()) {
    auto v = parseInt(r);
    if (!v || *v < 0 || *v > 127 || !decodeVoxRotation(int(*v), t.rotation))
      c.fail("rotation \"" + r + "\" is not a valid packed rotation byte");
  }
  std::string s = value(d, "_t");
  if (!s.empty()) {
    long long xyz[3];
    std::size_t at = 0;
    for (int i = 0; i < 3; ++i) {
      while (at < s.size() && s[at] == ' ') ++at;
      std::size_t end = s.find(' ', at);
      if (end == std::string::npos) end = s.size();
      auto v = parseInt(s.substr(at, end - at));
      // Translations stay far inside int32 so that sums over a deep graph cannot overflow.
      if (!v || std::llabs(*v) > (1 << 20)) c.fail("translation \"" + s + "\" is not three integers within ±2^20");
      xyz[i] = *v;
      at = end;
    }
    while (at < s.size() && s[at] == ' ') ++at;
    if (at != s.size()) c.fail("translation \"" + s + "\" is not three integers");
    t.translation = glm::ivec3(int(xyz[0]), int(xyz[1]), int(xyz[2]));
  }
  return t;
}

// The keyframe a node shows at `frame`: the last one at or before it, else the earliest.
const Keyframe& pick(const std::vector<Keyframe>& frames, int frame) {
  const Keyframe* best = nullptr;
  const Keyframe* earliest = &frames.front();
  for (const Keyframe& k : frames) {
    if (k.frame < earliest->frame) earliest = &k;
    if (k.frame <= frame && (!best || k.frame >= best->frame)) best = &k;
  }
  return best ? *best : *earliest;
}

class SceneResolver {
 public:
  SceneResolver(VoxFile& out, const std::map<int, Node>& nodes, const std::string& name, int frame)
      : out_(out), nodes_(nodes), name_(name), frame_(frame) {
    for (const VoxLayer& l : out.layers)
      if (l.hidden) hiddenLayers_[l.id] = l.name;
  }

  void run() {
    auto root = nodes_.find(0);
    if (root == nodes_.end()) throwBadInput(name_ + ": scene graph has no root node 0");
    visit(0, -1, VoxTransform{}, std::string(), -1, true, 0);
    for (const auto& [id, skipped] : skippedNodes_)
      out_.notes.push_back("hidden node " + std::to_string(id) + (skipped.first.empty() ? "" : " '" + skipped.first + "'") +
                           " skipped (" + std::to_string(skipped.second) + " shape" + (skipped.second == 1 ? "" : "s") + ")");
    for (const auto& [id, count] : skippedLayers_)
      out_.notes.push_back("hidden layer " + std::to_string(id) +
                           (hiddenLayers_[id].empty() ? "" : " '" + hiddenLayers_[id] + "'") + " skipped (" +
                           std::to_string(count) + " shape" + (count == 1 ? "" : "s") + ")");
  }

 private:
  // Hidden subtrees are still walked, so that a file is refused or accepted whatever is hidden.
  void visit(int id, int parent, const VoxTransform& above, const std::string& name, int layer, bool visible,
             int depth) {
    if (depth > kVoxMaxSceneDepth)
      throwBadInput(name_ + ": scene graph deeper than " + std::to_string(kVoxMaxSceneDepth) + " nodes (at node " +
                    std::to_string(id) + ")");
    auto it = nodes_.find(id);
    const std::string from = parent < 0 ? std::string("the root") : nodes_.at(parent).label + " (node " + std::to_string(parent) + ")";
    if (it == nodes_.end())
      throwBadInput(name_ + ": " + from + ": child node " + std::to_string(id) + " does not exist");
    int& state = state_[id];
    if (state == 1)
      throwBadInput(name_ + ": " + from + ": child node " + std::to_string(id) + " is its own ancestor (a cycle)");
    // Shared subtrees are MagicaVoxel's instancing and are walked once per path; the visit cap bounds the
    // blow-up a hostile file can build from them.
    if (++visits_ > kMaxVisits)
      throwBadInput(name_ + ": scene graph expands to more than " + std::to_string(kMaxVisits) + " node visits");
    state = 1;
    const Node& node = it->second;
    switch (node.type) {
      case NodeType::Transform: {
        VoxTransform here = above.then(pick(node.frames, frame_).transform);
        int nodeLayer = node.layer >= 0 ? node.layer : layer;
        bool show = visible;
        if (visible && node.hidden) {
          show = false;
          hiddenRoot_ = id;
          skippedNodes_[id] = {node.name, 0};
        } else if (visible && node.layer >= 0 && hiddenLayers_.count(node.layer)) {
          show = false;
          hiddenRoot_ = -1;
          hiddenLayer_ = node.layer;
          skippedLayers_[node.layer] += 0;
        }
        visit(node.children[0], id, here, node.name.empty() ? name : node.name, nodeLayer, show, depth + 1);
        break;
      }
      case NodeType::Group:
        for (int child : node.children) visit(child, id, above, name, layer, visible, depth + 1);
        break;
      case NodeType::Shape: {
        int model = pick(node.frames, frame_).model;
        for (const Keyframe& k : node.frames)
          if (k.model < 0 || std::size_t(k.model) >= out_.models.size())
            throwBadInput(name_ + ": " + node.label + " (node " + std::to_string(id) + "): model " +
                          std::to_string(k.model) + " does not exist (the file has " +
                          std::to_string(out_.models.size()) + ")");
        if (visible) {
          if (out_.instances.size() >= kVoxMaxInstances)
            throwBadInput(name_ + ": more than " + std::to_string(kVoxMaxInstances) + " shape instances");
          out_.instances.push_back({model, above, node.name.empty() ? name : node.name, id, layer});
        } else if (hiddenRoot_ >= 0) {
          ++skippedNodes_[hiddenRoot_].second;
        } else {
          ++skippedLayers_[hiddenLayer_];
        }
        break;
      }
    }
    state_[id] = 0;
  }

  static constexpr std::size_t kMaxVisits = std::size_t(1) << 22;
  VoxFile& out_;
  std::size_t visits_ = 0;
  const std::map<int, Node>& nodes_;
  const std::string& name_;
  int frame_;
  std::map<int, int> state_;
  std::map<int, std::string> hiddenLayers_;
  std::map<int, std::pair<std::string, int>> skippedNodes_;
  std::map<int, int> skippedLayers_;
  int hiddenRoot_ = -1, hiddenLayer_ = -1;
};

}  // namespace

VoxFile readVox(std::span<const std::uint8_t> bytes, const std::string& name, const VoxReadOptions& options) {
  VoxFile out;
  out.file = name;
  const std::uint8_t* data = bytes.data();
  const std::size_t size = bytes.size();
  if (size < 8 || std::memcmp(data, "VOX ", 4) != 0)
    throwBadInput(name + ": not a MagicaVoxel .vox file (it does not start with \"VOX \")");
  Cursor head(data, 4, 8, name + ": header");
  out.version = head.i32("the version");
  if (out.version < 150 || out.version > 200)
    throwBadInput(name + ": unsupported .vox version " + std::to_string(out.version) + " (this build reads 150 to 200)");
  if (options.frame < 0 || options.frame > kVoxMaxFrame)
    throwBadInput(name + ": frame " + std::to_string(options.frame) + " is outside 0.." + std::to_string(kVoxMaxFrame));
  out.frame = options.frame;

  // MAIN's children span the rest of the file; every other chunk's children are skipped with it.
  auto header = [&](std::size_t at, std::size_t end, std::size_t& contentBegin, std::size_t& contentEnd,
                    std::size_t& next) {
    if (end - at < 12)
      throwBadInput(name + ": chunk at byte " + std::to_string(at) + ": truncated header (" +
                    std::to_string(end - at) + " of 12 bytes)");
    std::string id = chunkName(data + at);
    Cursor c(data, at + 4, at + 12, name + ": " + id + " chunk at byte " + std::to_string(at));
    std::int32_t content = c.i32("the content size"), children = c.i32("the children size");
    if (content < 0 || children < 0) c.fail("negative size");
    if (std::uint64_t(content) + std::uint64_t(children) > end - at - 12)
      c.fail("truncated: declares " + std::to_string(content) + " + " + std::to_string(children) + " bytes, " +
             std::to_string(end - at - 12) + " are left");
    contentBegin = at + 12;
    contentEnd = contentBegin + std::size_t(content);
    next = contentEnd + std::size_t(children);
    return id;
  };

  std::size_t mainBegin, mainEnd, mainNext;
  std::string mainId = header(8, size, mainBegin, mainEnd, mainNext);
  if (mainId != "MAIN") throwBadInput(name + ": " + mainId + " chunk at byte 8: expected the MAIN chunk");

  std::map<int, Node> nodes;
  std::map<std::string, int> skipped;
  glm::ivec3 pendingSize(0);
  bool hasPendingSize = false;
  std::string pendingLabel;  // "SIZE chunk at byte N", without the file name that messages start with
  std::string packLabel;
  for (std::size_t at = mainEnd; at < mainNext;) {
    std::size_t begin, end, next;
    std::string id = header(at, mainNext, begin, end, next);
    Cursor c(data, begin, end, name + ": " + id + " chunk at byte " + std::to_string(at));
    if (id == "SIZE") {
      if (hasPendingSize) c.fail("a second SIZE without an XYZI chunk after the first (" + pendingLabel + ")");
      glm::ivec3 s(0);
      for (int i = 0; i < 3; ++i) s[i] = c.i32("the model size");
      for (int i = 0; i < 3; ++i)
        if (s[i] < 1 || s[i] > kVoxMaxModelSize)
          c.fail("model size " + std::to_string(s.x) + " x " + std::to_string(s.y) + " x " + std::to_string(s.z) +
                 " is outside 1.." + std::to_string(kVoxMaxModelSize) + " per axis");
      pendingSize = s;
      hasPendingSize = true;
      pendingLabel = id + " chunk at byte " + std::to_string(at);
    } else if (id == "XYZI") {
      if (!hasPendingSize) c.fail("XYZI without a SIZE chunk before it");
      VoxModel m;
      m.size = pendingSize;
      hasPendingSize = false;
      std::size_t n = c.count("the voxel count", 4);
      const std::uint8_t* p = c.bytes(n * 4, "the voxels");
      m.voxels.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        VoxVoxel v{p[4 * i], p[4 * i + 1], p[4 * i + 2], p[4 * i + 3]};
        if (v.x >= m.size.x || v.y >= m.size.y || v.z >= m.size.z)
          c.fail("voxel " + std::to_string(i) + " at (" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " +
                 std::to_string(v.z) + ") is outside the model size " + std::to_string(m.size.x) + " x " +
                 std::to_string(m.size.y) + " x " + std::to_string(m.size.z));
        if (v.colorIndex == 0) c.fail("voxel " + std::to_string(i) + " has colour index 0 (reserved for empty)");
        m.voxels[i] = v;
      }
      out.models.push_back(std::move(m));
    } else if (id == "RGBA") {
      const std::uint8_t* p = c.bytes(1024, "the 256 palette entries");
      // File entry i is colour index i + 1; the last entry has no index.
      for (int i = 0; i < 255; ++i)
        out.palette[std::size_t(i + 1)] = std::uint32_t(p[4 * i]) | std::uint32_t(p[4 * i + 1]) << 8 |
                                         std::uint32_t(p[4 * i + 2]) << 16 | std::uint32_t(p[4 * i + 3]) << 24;
      out.hasPaletteChunk = true;
    } else if (id == "nTRN" || id == "nGRP" || id == "nSHP") {
      Node node;
      node.label = id + " chunk at byte " + std::to_string(at);
      int nodeId = c.i32("the node id");
      if (nodeId < 0) c.fail("node id " + std::to_string(nodeId) + " is negative");
      if (nodes.count(nodeId)) c.fail("node id " + std::to_string(nodeId) + " is used twice");
      Dict attrs = c.dict("the attribute count");
      node.name = value(attrs, "_name");
      node.hidden = flag(attrs, "_hidden");
      if (id == "nTRN") {
        node.type = NodeType::Transform;
        node.children.push_back(c.i32("the child node id"));
        c.i32("the reserved id");
        node.layer = c.i32("the layer id");
        std::size_t frames = c.count("the frame count", 4);
        if (frames == 0) c.fail("a transform node needs at least one frame");
        for (std::size_t f = 0; f < frames; ++f) {
          Dict fd = c.dict("the frame attribute count");
          node.frames.push_back({frameIndexOf(c, fd), frameTransform(c, fd), -1});
        }
      } else if (id == "nGRP") {
        node.type = NodeType::Group;
        std::size_t n = c.count("the child count", 4);
        node.children.reserve(n);
        for (std::size_t i = 0; i < n; ++i) node.children.push_back(c.i32("a child node id"));
      } else {
        node.type = NodeType::Shape;
        std::size_t n = c.count("the model count", 8);
        if (n == 0) c.fail("a shape node needs at least one model");
        for (std::size_t i = 0; i < n; ++i) {
          int model = c.i32("a model id");
          Dict md = c.dict("the model attribute count");
          node.frames.push_back({frameIndexOf(c, md), VoxTransform{}, model});
        }
      }
      nodes.emplace(nodeId, std::move(node));
    } else if (id == "PACK") {
      if (out.packModels >= 0) c.fail("a second PACK chunk (the first is the " + packLabel + ")");
      std::int32_t n = c.i32("the model count");
      if (n < 1) c.fail("model count " + std::to_string(n) + " is not positive");
      out.packModels = n;
      packLabel = id + " chunk at byte " + std::to_string(at);
    } else if (id == "LAYR") {
      VoxLayer layer;
      layer.id = c.i32("the layer id");
      Dict attrs = c.dict("the attribute count");
      layer.name = value(attrs, "_name");
      layer.hidden = flag(attrs, "_hidden");
      out.layers.push_back(std::move(layer));
    } else if (id == "MATL") {
      VoxMaterial m;
      m.id = c.i32("the material id");
      m.props = c.dict("the property count");
      out.materials.push_back(std::move(m));
    } else {
      // MATT, rOBJ, rCAM, NOTE, IMAP and anything newer: not needed for geometry.
      ++skipped[id];
    }
    at = next;
  }
  if (hasPendingSize) throwBadInput(name + ": " + pendingLabel + ": no XYZI chunk follows it");
  if (!out.hasPaletteChunk) {
    out.palette = voxDefaultPalette();
    out.notes.push_back("no RGBA chunk: MagicaVoxel's default palette");
  }

  if (!nodes.empty()) {
    out.hasSceneGraph = true;
    SceneResolver(out, nodes, name, options.frame).run();
    // The scene graph places the models itself (and animates them by keyframes); PACK adds nothing.
    if (out.packModels >= 0) ++skipped["PACK"];
  } else if (out.packModels >= 0) {
    // Files from before the scene graph store an animation as a PACK chunk and one model per frame; drawn
    // together the frames would lie on top of each other.
    out.packFrames = true;
    const std::size_t frames = out.models.size();
    if (frames == 0) throwBadInput(name + ": " + packLabel + ": declares " + std::to_string(out.packModels) + " models, the file has none");
    if (std::size_t(options.frame) >= frames)
      throwBadInput(name + ": frame " + std::to_string(options.frame) + " is beyond the " + std::to_string(frames) +
                    " frame" + (frames == 1 ? "" : "s") + " of its PACK animation (0.." + std::to_string(frames - 1) + ")");
    out.instances.push_back({options.frame, VoxTransform{}, "", -1, -1});
    std::string note = frames == 1 ? std::string("PACK animation: 1 model, frame 0 shown")
                                   : "PACK animation: the " + std::to_string(frames) + " models are frames 0.." +
                                         std::to_string(frames - 1) + ", frame " + std::to_string(options.frame) + " shown";
    if (std::size_t(out.packModels) != frames)
      note += " (the PACK chunk declares " + std::to_string(out.packModels) + " models; the file's count is used)";
    out.notes.push_back(note);
  } else {
    for (std::size_t i = 0; i < out.models.size(); ++i) out.instances.push_back({int(i), VoxTransform{}, "", -1, -1});
  }

  std::string emissive, glass;
  for (const VoxMaterial& m : out.materials) {
    std::string t = m.type();
    if (t == "emit") emissive += (emissive.empty() ? "" : ", ") + std::to_string(m.id);
    if (t == "glass") glass += (glass.empty() ? "" : ", ") + std::to_string(m.id);
  }
  if (!emissive.empty()) out.notes.push_back("emissive materials (palette " + emissive + ") kept as metadata, rendered as solid");
  if (!glass.empty()) out.notes.push_back("glass materials (palette " + glass + ") kept as metadata, rendered as solid");
  if (!skipped.empty()) {
    std::string s;
    for (const auto& [id, n] : skipped) s += (s.empty() ? "" : ", ") + id + " x" + std::to_string(n);
    out.notes.push_back("chunks skipped: " + s);
  }
  return out;
}

VoxFile readVoxFile(const std::string& path, const VoxReadOptions& options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throwBadInput(path + ": no such file");
  std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throwBadInput(path + ": cannot read its size (" + ec.message() + ")");
  // Models are bounded by their chunks, so a file's voxels never exceed its bytes; a cap on the bytes
  // bounds the whole load.
  if (size > (std::uintmax_t(1) << 30)) throwBadInput(path + ": larger than 1 GiB, not read");
  std::ifstream in(path, std::ios::binary);
  if (!in) throwBadInput(path + ": cannot open for reading");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size));
  if (in.gcount() != std::streamsize(size)) throwBadInput(path + ": cannot read (short read)");
  return readVox(bytes, path, options);
}

}  // namespace vs
