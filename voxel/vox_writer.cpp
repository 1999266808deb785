// encodeVox: chunk by chunk, little-endian, MAIN's children sized after they are written.
#include "voxel/vox_writer.h"

#include <fstream>

#include "voxel/error.h"

namespace vs {

namespace {

class Out {
 public:
  std::vector<std::uint8_t> bytes;

  void u32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes.push_back(std::uint8_t(v >> (8 * i)));
  }
  void i32(std::int32_t v) { u32(std::uint32_t(v)); }
  void tag(const char* id) { bytes.insert(bytes.end(), id, id + 4); }
  void string(const std::string& s) {
    i32(std::int32_t(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
  }
  void dict(const VoxDict& d) {
    i32(std::int32_t(d.size()));
    for (const auto& [k, v] : d) string(k), string(v);
  }
  // Starts a chunk without children; returns where its content size goes.
  std::size_t begin(const char* id) {
    tag(id);
    std::size_t at = bytes.size();
    u32(0);
    u32(0);
    return at;
  }
  void end(std::size_t at) { patch(at, std::uint32_t(bytes.size() - at - 8)); }
  void patch(std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
  }
};

}  // namespace

std::vector<std::uint8_t> encodeVox(const VoxWriteFile& file) {
  Out o;
  o.tag("VOX ");
  o.i32(file.version);
  o.tag("MAIN");
  o.u32(0);
  const std::size_t mainChildren = o.bytes.size();
  o.u32(0);
  if (file.pack) {
    std::size_t at = o.begin("PACK");
    o.i32(*file.pack);
    o.end(at);
  }
  for (const VoxModel& m : file.models) {
    std::size_t at = o.begin("SIZE");
    o.i32(m.size.x), o.i32(m.size.y), o.i32(m.size.z);
    o.end(at);
    at = o.begin("XYZI");
    o.i32(std::int32_t(m.voxels.size()));
    for (const VoxVoxel& v : m.voxels) o.bytes.insert(o.bytes.end(), {v.x, v.y, v.z, v.colorIndex});
    o.end(at);
  }
  for (const VoxWriteNode& n : file.nodes) {
    using K = VoxWriteNode::Kind;
    std::size_t at = o.begin(n.kind == K::Transform ? "nTRN" : n.kind == K::Group ? "nGRP" : "nSHP");
    o.i32(n.id);
    o.dict(n.attributes);
    if (n.kind == K::Transform) {
      o.i32(n.child);
      o.i32(-1);
      o.i32(n.layer);
      if (n.frames.empty()) {
        o.i32(1);
        o.dict({});
      } else {
        o.i32(std::int32_t(n.frames.size()));
        for (const VoxDict& f : n.frames) o.dict(f);
      }
    } else if (n.kind == K::Group) {
      o.i32(std::int32_t(n.children.size()));
      for (int c : n.children) o.i32(c);
    } else {
      o.i32(std::int32_t(n.models.size()));
      for (const auto& [model, d] : n.models) o.i32(model), o.dict(d);
    }
    o.end(at);
  }
  for (const VoxLayer& l : file.layers) {
    std::size_t at = o.begin("LAYR");
    o.i32(l.id);
    VoxDict d;
    if (!l.name.empty()) d["_name"] = l.name;
    if (l.hidden) d["_hidden"] = "1";
    o.dict(d);
    o.i32(-1);
    o.end(at);
  }
  if (file.palette) {
    std::size_t at = o.begin("RGBA");
    for (int i = 1; i <= 256; ++i) o.u32(i < 256 ? (*file.palette)[std::size_t(i)] : 0u);
    o.end(at);
  }
  for (const VoxMaterial& m : file.materials) {
    std::size_t at = o.begin("MATL");
    o.i32(m.id);
    o.dict(m.props);
    o.end(at);
  }
  o.patch(mainChildren, std::uint32_t(o.bytes.size() - mainChildren - 4));
  return o.bytes;
}

std::vector<VoxWriteNode> voxSceneGraph(const std::vector<VoxPlaced>& placed) {
  using K = VoxWriteNode::Kind;
  std::vector<VoxWriteNode> nodes;
  VoxWriteNode root;
  root.kind = K::Transform;
  root.id = 0;
  root.child = 1;
  nodes.push_back(root);
  VoxWriteNode group;
  group.kind = K::Group;
  group.id = 1;
  nodes.push_back(group);
  int next = 2;
  for (const VoxPlaced& p : placed) {
    VoxWriteNode t;
    t.kind = K::Transform;
    t.id = next;
    t.child = next + 1;
    t.layer = 0;
    if (!p.name.empty()) t.attributes["_name"] = p.name;
    t.frames.push_back({{"_r", std::to_string(p.rotation)},
                        {"_t", std::to_string(p.translation[0]) + " " + std::to_string(p.translation[1]) + " " +
                                   std::to_string(p.translation[2])}});
    VoxWriteNode s;
    s.kind = K::Shape;
    s.id = next + 1;
    s.models.push_back({p.model, {}});
    nodes[1].children.push_back(next);
    nodes.push_back(t);
    nodes.push_back(s);
    next += 2;
  }
  return nodes;
}

void writeVoxFile(const std::filesystem::path& path, const VoxWriteFile& file) {
  std::vector<std::uint8_t> bytes = encodeVox(file);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  out.close();
  if (!out) throwRuntime(path.string() + ": cannot write");
}

}  // namespace vs
