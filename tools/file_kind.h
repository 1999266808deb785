// file_kind.h: what a file's name and first bytes say it is. Outputs are matched by extension in any case
// (O.EXR is an EXR); inputs are checked by their first bytes before anything reads them whole, so that a
// file that is not what its name claims is refused for what it is, not for its size or a parser's confusion.
#ifndef VOXSHADOW_TOOLS_FILE_KIND_H
#define VOXSHADOW_TOOLS_FILE_KIND_H

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace vs {

struct SceneDesc;

// OpenVDB's magic number (openvdb::OPENVDB_MAGIC), the first 4 bytes of every .vdb file, little-endian.
inline constexpr std::uint32_t kVdbMagic = 0x56444220;

// Whether `p`'s extension is `ext` (".exr"), ignoring case.
bool hasExtension(const std::filesystem::path& p, std::string_view ext);

enum class InputKind { Vdb, Vox, Scene };

// What an input's extension claims (ignoring case): .json a scene, .vox a MagicaVoxel file, else a .vdb.
InputKind inputKindOf(const std::filesystem::path& p);

// Throws vs::Error(BadInput) "<where><file>: not a .vdb file (its first bytes are 00 00 ...; ...)" when the
// first bytes of `file` are not those of `kind` (OpenVDB's magic number; "VOX "; a JSON object, '{' after
// optional white space). `where` prefixes the message (a scene's field, "scene.json: assets.ball.file: ").
// Reads at most 4 KiB. A path that is not a regular file, or cannot be opened, is left to the loader, whose
// messages name those cases (and opening a FIFO could block).
void checkInputBytes(const std::filesystem::path& file, InputKind kind, const std::string& where = {});

// checkInputBytes on every asset of a parsed scene, naming the asset's field.
void checkSceneAssetBytes(const SceneDesc& scene);

}  // namespace vs

#endif
