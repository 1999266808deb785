// voxshadow convert IN.vox OUT.vdb: one Int32 palette grid per model, readable by OpenVDB's own tools.
#include <algorithm>
#include <cctype>
#include <cstdio>

#include <glm/gtc/matrix_transform.hpp>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "tools/atomic_file.h"
#include "tools/commands.h"
#include "tools/file_kind.h"
#include "voxel/error.h"
#include "voxel/vox_scene.h"

namespace vs::cli {

namespace {

namespace fs = std::filesystem;

std::string lowerExtension(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

// The palette as the grid's metadata: 255 sRGB "rrggbb" words for colour indices 1..255, the file's own
// 8-bit values, so that loading the grid gives the same linear palette as loading the .vox.
std::string paletteMetadata(const std::array<std::uint32_t, 256>& palette) {
  std::string s;
  char buf[8];
  for (std::size_t i = 1; i < 256; ++i) {
    std::snprintf(buf, sizeof buf, "%06x", unsigned((palette[i] & 0xff) << 16 | (palette[i] & 0xff00) | (palette[i] >> 16 & 0xff)));
    if (i > 1) s += ' ';
    s += buf;
  }
  return s;
}

openvdb::math::Transform::Ptr gridTransform(const glm::dmat4& brickToAsset) {
  // A VDB index is a voxel's centre; brick space puts voxel v at [v, v + 1).
  glm::dmat4 m = brickToAsset * glm::translate(glm::dmat4(1.0), glm::dvec3(0.5));
  openvdb::Mat4d o;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) o(i, j) = m[i][j];  // GLM m[col][row] holds OpenVDB's row-vector m(row, col)
  return openvdb::math::Transform::createLinearTransform(o);
}

void runConvert(const fs::path& in, const fs::path& out, int frame) {
  if (lowerExtension(in) != ".vox") throwBadInput("convert: " + in.string() + ": the input must be a .vox file");
  if (lowerExtension(out) != ".vdb") throwBadInput("convert: " + out.string() + ": the output must end in .vdb");
  const fs::path outputs[] = {out}, inputs[] = {in};
  const std::string inputWhat[] = {"file"};
  refuseOutputsOverInputs(outputs, inputs, inputWhat);
  checkOutputDirectory(out);
  checkInputBytes(in, InputKind::Vox);
  VoxReadOptions read;
  read.frame = frame;
  VoxFile vox = readVoxFile(in.string(), read);

  openvdb::initialize();
  openvdb::GridPtrVec grids;
  const std::string palette = paletteMetadata(vox.palette);
  std::vector<std::string> lines;
  // OpenVDB writes a file's grids ordered by name: zero-padded numbers keep that order the models' order,
  // so that grid index i (a scene's "grid": i) is model i.
  const int digits = int(std::to_string(vox.models.empty() ? 0 : vox.models.size() - 1).size());
  auto gridName = [digits](std::size_t i) {
    std::string n = std::to_string(i);
    return "model" + std::string(std::size_t(digits) - n.size(), '0') + n;
  };
  for (std::size_t i = 0; i < vox.models.size(); ++i) {
    const VoxModel& model = vox.models[i];
    const VoxInstance* first = nullptr;
    int count = 0;
    for (const VoxInstance& inst : vox.instances)
      if (inst.model == int(i) && count++ == 0) first = &inst;
    auto grid = openvdb::Int32Grid::create(0);
    grid->setName(gridName(i));
    grid->setGridClass(openvdb::GRID_UNKNOWN);
    grid->setTransform(gridTransform(voxPlacementMatrix(model.size, first ? first->transform : VoxTransform{}, 1.0)));
    auto acc = grid->getAccessor();
    for (const VoxVoxel& v : model.voxels) acc.setValue(openvdb::Coord(v.x, v.y, v.z), v.colorIndex);
    grid->insertMeta("voxshadow:palette", openvdb::StringMetadata(palette));
    grid->insertMeta("voxshadow:source", openvdb::StringMetadata(in.filename().string()));
    grid->insertMeta("voxshadow:model", openvdb::Int32Metadata(int(i)));
    grid->insertMeta("voxshadow:instances", openvdb::Int32Metadata(count));
    if (first && !first->name.empty()) grid->insertMeta("voxshadow:name", openvdb::StringMetadata(first->name));
    std::string line = "  grid " + std::to_string(i) + " '" + gridName(i) + "': " +
                       std::to_string(model.size.x) + " x " + std::to_string(model.size.y) + " x " +
                       std::to_string(model.size.z) + ", " + std::to_string(grid->activeVoxelCount()) + " voxels, ";
    // Every frame of a PACK animation sits at the origin, so each grid gets the model's own transform.
    if (vox.packFrames) line += "frame " + std::to_string(i) + " of the PACK animation" + (count ? " (the frame chosen)" : "");
    else if (count == 0) line += "not placed by the scene graph: transform of the model alone";
    else if (count == 1) line += "transform of its instance";
    else line += "transform of the first of its " + std::to_string(count) + " instances";
    lines.push_back(line);
    grids.push_back(grid);
  }
  writeAtomically(outputs, [&](std::size_t, const fs::path& tmp) {
    try {
      openvdb::io::File file(tmp.string());
      file.write(grids);
      file.close();
    } catch (const std::exception& e) {
      throwRuntime(out.string() + ": cannot write (" + e.what() + ")");
    }
  });
  std::printf("%s -> %s: %zu grid%s\n", in.c_str(), out.c_str(), grids.size(), grids.size() == 1 ? "" : "s");
  for (const std::string& l : lines) std::printf("%s\n", l.c_str());
  for (const std::string& n : vox.notes) std::printf("  note: %s\n", n.c_str());
}

}  // namespace

void registerConvert(CLI::App& app) {
  struct Options {
    fs::path in, out;
    int frame = 0;
  };
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("convert", "Convert a MagicaVoxel .vox file to a .vdb file (one Int32 palette grid per model)");
  sub->add_option("IN", options->in, "Input .vox file")->required();
  sub->add_option("OUT", options->out, "Output .vdb file")->required();
  // Checked as text before CLI11 converts it, so that every bad value gets the same message (CLI11's own
  // checks print the range of a double or only "Could not convert").
  const std::string range = "must be a whole number from 0 to " + std::to_string(kVoxMaxFrame);
  sub->add_option("--frame", options->frame,
                  "Animation frame: the scene graph's transforms at it, or the PACK animation frame marked as chosen")
      ->check(CLI::Validator(
          [range](std::string& s) {
            if (s.empty() || s.size() > 7 || !std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); }) ||
                std::stoi(s) > kVoxMaxFrame)
              return range;
            return std::string();
          },
          "0.." + std::to_string(kVoxMaxFrame)))
      ->capture_default_str();
  sub->callback([options] { runConvert(options->in, options->out, options->frame); });
}

}  // namespace vs::cli
