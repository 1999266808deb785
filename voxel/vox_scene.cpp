// .vox files to objects and placements; identical models share one object.
#include "voxel/vox_scene.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <unordered_map>

#include <glm/gtc/matrix_transform.hpp>

#include "voxel/error.h"

namespace vs {

glm::dmat4 voxZupToYup() {
  glm::dmat4 m(0.0);
  m[0] = {1, 0, 0, 0};   // x stays x
  m[1] = {0, 0, -1, 0};  // y (MagicaVoxel's depth) becomes -z
  m[2] = {0, 1, 0, 0};   // z (up) becomes y
  m[3] = {0, 0, 0, 1};
  return m;
}

glm::dmat4 voxPlacementMatrix(glm::ivec3 size, const VoxTransform& t, double voxelSize) {
  glm::dmat4 rt(1.0);
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) rt[c][r] = double(t.rotation[c][r]);
  rt[3] = glm::dvec4(glm::dvec3(t.translation), 1.0);
  const glm::dvec3 pivot(size.x / 2, size.y / 2, size.z / 2);  // integer division: floor for sizes >= 1
  return glm::scale(glm::dmat4(1.0), glm::dvec3(voxelSize)) * voxZupToYup() * rt *
         glm::translate(glm::dmat4(1.0), -pivot);
}

std::vector<glm::vec3> voxLinearPalette(const std::array<std::uint32_t, 256>& palette) {
  std::vector<glm::vec3> out(256, glm::vec3(0.0f));
  for (std::size_t i = 1; i < 256; ++i) {
    std::uint32_t c = palette[i];
    out[i] = {srgbToLinear(std::uint8_t(c)), srgbToLinear(std::uint8_t(c >> 8)), srgbToLinear(std::uint8_t(c >> 16))};
  }
  return out;
}

namespace {

// A model's voxels in a canonical order (by coordinate, the last duplicate kept), packed x | y << 8 | z << 16 |
// colour << 24, so that identical models compare equal whatever order their files list voxels in.
std::vector<std::uint32_t> canonicalVoxels(const VoxModel& m) {
  std::vector<std::uint32_t> v;
  v.reserve(m.voxels.size());
  for (const VoxVoxel& x : m.voxels)
    v.push_back(std::uint32_t(x.x) | std::uint32_t(x.y) << 8 | std::uint32_t(x.z) << 16 | std::uint32_t(x.colorIndex) << 24);
  std::stable_sort(v.begin(), v.end(), [](std::uint32_t a, std::uint32_t b) { return (a & 0xffffff) < (b & 0xffffff); });
  std::vector<std::uint32_t> out;
  out.reserve(v.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    if (i + 1 == v.size() || (v[i] & 0xffffff) != (v[i + 1] & 0xffffff)) out.push_back(v[i]);
  return out;
}

struct ModelTable {
  std::vector<std::vector<std::uint32_t>> canonical;
  std::vector<int> sharedWith;  // first identical model, or -1

  explicit ModelTable(const VoxFile& file) {
    std::unordered_map<std::uint64_t, std::vector<int>> byHash;
    for (std::size_t i = 0; i < file.models.size(); ++i) {
      canonical.push_back(canonicalVoxels(file.models[i]));
      const glm::ivec3 s = file.models[i].size;
      std::uint64_t h = 1469598103934665603ull;
      auto mix = [&h](std::uint64_t x) { h = (h ^ x) * 1099511628211ull; };
      mix(std::uint64_t(s.x)), mix(std::uint64_t(s.y)), mix(std::uint64_t(s.z));
      for (std::uint32_t v : canonical.back()) mix(v);
      int shared = -1;
      for (int j : byHash[h])
        if (file.models[std::size_t(j)].size == s && canonical[std::size_t(j)] == canonical.back()) shared = j;
      sharedWith.push_back(shared);
      if (shared < 0) byHash[h].push_back(int(i));
    }
  }
  int representative(int model) const { return sharedWith[std::size_t(model)] < 0 ? model : sharedWith[std::size_t(model)]; }
};

Brickmap buildModelBrickmap(const std::vector<std::uint32_t>& voxels) {
  std::vector<SolidVoxel> solid;
  solid.reserve(voxels.size());
  for (std::uint32_t v : voxels)
    solid.push_back({glm::ivec3(int(v & 0xff), int((v >> 8) & 0xff), int((v >> 16) & 0xff)), std::uint8_t(v >> 24)});
  return Brickmap::build(solid);
}

}  // namespace

VoxAsset buildVoxAsset(const VoxFile& file, const VoxAssetOptions& options) {
  if (!(options.voxelSize > 0.0) || !std::isfinite(options.voxelSize)) {
    char size[32];
    std::snprintf(size, sizeof size, "%g", options.voxelSize);
    throwBadInput(file.file + ": voxel size must be a finite number greater than 0, not " + size);
  }
  VoxAsset asset;
  asset.notes = file.notes;
  std::vector<VoxInstance> chosen;
  const std::string& want = options.model;
  if (want.empty()) {
    chosen = file.instances;
  } else if (std::all_of(want.begin(), want.end(), [](unsigned char c) { return std::isdigit(c); })) {
    if (want.size() > 9 || std::stoul(want) >= file.models.size())
      throwBadInput(file.file + ": model " + want + " is out of range (the file has " +
                    std::to_string(file.models.size()) + " model" + (file.models.size() == 1 ? "" : "s") + ")");
    chosen.push_back({int(std::stoul(want)), VoxTransform{}, "", -1, -1});
    asset.notes.push_back("model " + want + " taken alone, unrotated, pivot at the origin");
  } else {
    std::string names;
    int matches = 0;
    for (const VoxInstance& inst : file.instances) {
      if (!inst.name.empty() && names.find("'" + inst.name + "'") == std::string::npos)
        names += (names.empty() ? "" : ", ") + ("'" + inst.name + "'");
      if (inst.name == want && matches++ == 0) chosen.push_back(inst);
    }
    if (chosen.empty())
      throwBadInput(file.file + ": no visible shape named '" + want + "' (names: " + (names.empty() ? "none" : names) + ")");
    asset.notes.push_back("shape '" + want + "' taken (model " + std::to_string(chosen[0].model) + ")" +
                          (matches > 1 ? ", the first of " + std::to_string(matches) + " with that name" : ""));
  }

  ModelTable table(file);
  std::vector<glm::vec3> palette = voxLinearPalette(file.palette);
  std::unordered_map<int, std::size_t> objectOf;  // representative model -> object
  int sharedUses = 0;
  for (const VoxInstance& inst : chosen) {
    const int rep = table.representative(inst.model);
    auto [it, inserted] = objectOf.try_emplace(rep, asset.objects.size());
    if (inserted) {
      VoxelObject obj;
      obj.file = file.file;
      obj.gridName = "model " + std::to_string(rep);
      obj.gridIndex = rep;
      obj.gridType = "vox";
      obj.gridClass = "MagicaVoxel model";
      obj.rule = "vox: every XYZI voxel, material = palette index";
      obj.palette = palette;
      const glm::ivec3 size = file.models[std::size_t(rep)].size;
      obj.brickToObject = voxPlacementMatrix(size, VoxTransform{}, options.voxelSize);
      obj.brickmap = buildModelBrickmap(table.canonical[std::size_t(rep)]);
      asset.objects.push_back(std::move(obj));
    } else {
      ++sharedUses;
    }
    asset.placements.push_back({it->second, inst.model, inst.name,
                                voxPlacementMatrix(file.models[std::size_t(inst.model)].size, inst.transform,
                                                   options.voxelSize)});
  }
  if (sharedUses > 0)
    asset.notes.push_back(std::to_string(asset.placements.size()) + " placements share " +
                          std::to_string(asset.objects.size()) + " object" + (asset.objects.size() == 1 ? "" : "s"));
  return asset;
}

VoxAsset loadVox(const std::string& path, const VoxAssetOptions& options) {
  VoxReadOptions read;
  read.frame = options.frame;
  return buildVoxAsset(readVoxFile(path, read), options);
}

VoxInfo inspectVox(const std::string& path, const VoxReadOptions& options) {
  VoxFile file = readVoxFile(path, options);
  VoxInfo info;
  info.version = file.version;
  info.hasPaletteChunk = file.hasPaletteChunk;
  info.hasSceneGraph = file.hasSceneGraph;
  info.packModels = file.packModels;
  info.packFrames = file.packFrames;
  info.frame = file.frame;
  info.materials = file.materials;
  info.layers = file.layers;
  info.notes = file.notes;
  ModelTable table(file);
  for (std::size_t i = 0; i < file.models.size(); ++i) {
    VoxModelInfo m;
    m.size = file.models[i].size;
    m.voxelCount = table.canonical[i].size();
    bool used[256] = {};
    for (std::uint32_t v : table.canonical[i]) used[v >> 24] = true;
    m.paletteEntriesUsed = int(std::count(std::begin(used), std::end(used), true));
    m.sharedWith = table.sharedWith[i];
    m.brickmapMemory = buildModelBrickmap(table.canonical[i]).memory();
    info.models.push_back(m);
  }
  for (const VoxInstance& inst : file.instances) {
    ++info.models[std::size_t(inst.model)].instanceCount;
    VoxInstanceInfo ii;
    ii.model = inst.model;
    ii.name = inst.name;
    ii.shapeNode = inst.shapeNode;
    const glm::ivec3 s = file.models[std::size_t(inst.model)].size;
    glm::dmat4 m = voxPlacementMatrix(s, inst.transform, 1.0);
    glm::dvec3 a(m * glm::dvec4(0, 0, 0, 1)), b(m * glm::dvec4(glm::dvec3(s), 1));
    ii.boxMin = glm::min(a, b);
    ii.boxMax = glm::max(a, b);
    info.instances.push_back(ii);
  }
  return info;
}

}  // namespace vs
