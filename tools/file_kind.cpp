#include "tools/file_kind.h"

#include <cctype>
#include <cstdio>
#include <fstream>

#include "lighting/scene_file.h"
#include "voxel/error.h"

namespace vs {

namespace fs = std::filesystem;

bool hasExtension(const fs::path& p, std::string_view ext) {
  const std::string e = p.extension().string();
  if (e.size() != ext.size()) return false;
  for (std::size_t i = 0; i < e.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(e[i])) != std::tolower(static_cast<unsigned char>(ext[i]))) return false;
  return true;
}

InputKind inputKindOf(const fs::path& p) {
  if (hasExtension(p, ".json")) return InputKind::Scene;
  if (hasExtension(p, ".vox")) return InputKind::Vox;
  return InputKind::Vdb;
}

namespace {

std::string hexBytes(const std::string& bytes, std::size_t count) {
  std::string s;
  char buf[4];
  for (std::size_t i = 0; i < bytes.size() && i < count; ++i) {
    std::snprintf(buf, sizeof buf, "%02x", static_cast<unsigned char>(bytes[i]));
    if (!s.empty()) s += ' ';
    s += buf;
  }
  return s;
}

bool isJsonSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

}  // namespace

void checkInputBytes(const fs::path& file, InputKind kind, const std::string& where) {
  std::error_code ec;
  if (!fs::is_regular_file(fs::status(file, ec))) return;
  std::ifstream in(file, std::ios::binary);
  if (!in) return;
  std::string head(4096, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));

  const char* what = kind == InputKind::Vdb ? "a .vdb file" : kind == InputKind::Vox ? "a MagicaVoxel .vox file" : "a JSON scene file";
  const std::string prefix = where + file.string() + ": ";
  if (head.empty()) throwBadInput(prefix + "is empty, not " + what);
  std::string expected;
  bool ok = false;
  if (kind == InputKind::Vdb) {
    const char magic[4] = {char(kVdbMagic & 0xff), char(kVdbMagic >> 8 & 0xff), char(kVdbMagic >> 16 & 0xff),
                           char(kVdbMagic >> 24 & 0xff)};
    ok = head.size() >= 4 && head.compare(0, 4, magic, 4) == 0;
    expected = "an OpenVDB file starts with its magic number, 20 42 44 56";
  } else if (kind == InputKind::Vox) {
    ok = head.size() >= 4 && head.compare(0, 4, "VOX ") == 0;
    expected = "a .vox file starts with \"VOX \", 56 4f 58 20";
  } else {
    std::size_t i = head.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // a UTF-8 byte order mark
    while (i < head.size() && isJsonSpace(head[i])) ++i;
    // Only white space so far: the parser reads on and says what it finds.
    ok = i == head.size() || head[i] == '{';
    expected = "a scene is a JSON object, starting with '{'";
  }
  if (!ok) throwBadInput(prefix + "not " + what + " (its first bytes are " + hexBytes(head, 8) + "; " + expected + ")");
}

void checkSceneAssetBytes(const SceneDesc& scene) {
  for (const AssetDesc& a : scene.assets)
    checkInputBytes(a.file, a.vox ? InputKind::Vox : InputKind::Vdb,
                    scene.file.string() + ": assets." + a.name + ".file: ");
}

}  // namespace vs
