// voxshadow info FILE.vox: the models, the scene graph's instances and what the brickmaps cost.
#include <cstdio>

#include "tools/commands.h"
#include "voxel/vox_scene.h"

namespace vs::cli {

namespace {

using nlohmann::json;

json vec3Json(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

}  // namespace

json voxFileInfo(const std::filesystem::path& file) {
  VoxInfo info = inspectVox(file.string());
  json models = json::array();
  std::uint64_t totalStructure = 0, totalVoxels = 0;
  for (std::size_t i = 0; i < info.models.size(); ++i) {
    const VoxModelInfo& m = info.models[i];
    const BrickmapMemory& b = m.brickmapMemory;
    json mj = {{"index", i},
               {"size", {m.size.x, m.size.y, m.size.z}},
               {"voxels", m.voxelCount},
               {"paletteEntriesUsed", m.paletteEntriesUsed},
               {"instances", m.instanceCount},
               {"sharedWith", m.sharedWith < 0 ? json(nullptr) : json(m.sharedWith)},
               {"brickmap",
                {{"regionTableBytes", b.regionTableBytes}, {"regionBytes", b.regionBytes},
                 {"sectorBytes", b.sectorBytes}, {"brickBytes", b.brickBytes}, {"occupancyBytes", b.occupancyBytes},
                 {"payloadBytes", b.payloadBytes}, {"occupancyStructureBytes", b.occupancyStructureBytes()},
                 {"bytesPerSolidVoxel", m.voxelCount ? double(b.occupancyStructureBytes()) / double(m.voxelCount) : 0.0}}}};
    if (m.sharedWith < 0) totalStructure += b.occupancyStructureBytes() + b.payloadBytes;
    totalVoxels += m.voxelCount;
    models.push_back(std::move(mj));
  }
  json instances = json::array();
  for (const VoxInstanceInfo& i : info.instances)
    instances.push_back({{"model", i.model},
                         {"name", i.name},
                         {"shapeNode", i.shapeNode},
                         {"worldBox", {{"min", vec3Json(i.boxMin)}, {"max", vec3Json(i.boxMax)}}}});
  json materials = json::array();
  for (const VoxMaterial& m : info.materials) {
    json props = json::object();
    for (const auto& [k, v] : m.props) props[k] = v;
    materials.push_back({{"id", m.id}, {"type", m.type()}, {"properties", std::move(props)}});
  }
  json layers = json::array();
  for (const VoxLayer& l : info.layers) layers.push_back({{"id", l.id}, {"name", l.name}, {"hidden", l.hidden}});
  return {{"file", file.string()},
          {"kind", "vox"},
          {"version", info.version},
          {"palette", info.hasPaletteChunk ? "RGBA chunk" : "MagicaVoxel default"},
          {"sceneGraph", info.hasSceneGraph},
          {"pack", info.packModels < 0 ? json(nullptr) : json(info.packModels)},
          {"animation", info.packFrames ? json{{"kind", "PACK frames"}, {"frames", info.models.size()}, {"frameShown", info.frame}}
                                        : json(nullptr)},
          {"models", std::move(models)},
          {"instances", std::move(instances)},
          {"materials", std::move(materials)},
          {"layers", std::move(layers)},
          {"voxels", totalVoxels},
          {"brickmapBytes", totalStructure},
          {"notes", info.notes}};
}

void printVoxFile(const json& j) {
  const json& models = j["models"];
  std::string animation;
  if (const json& a = j["animation"]; a.is_object())
    animation = " (PACK animation frames 0.." + std::to_string(a["frames"].get<std::size_t>() - 1) + ", frame " +
                std::to_string(a["frameShown"].get<int>()) + " shown)";
  std::printf("%s: MagicaVoxel version %d, %zu model%s%s, %zu instance%s, palette: %s\n",
              j["file"].get<std::string>().c_str(), j["version"].get<int>(), models.size(), models.size() == 1 ? "" : "s",
              animation.c_str(), j["instances"].size(), j["instances"].size() == 1 ? "" : "s",
              j["palette"].get<std::string>().c_str());
  for (const json& m : models) {
    const json& s = m["size"];
    const json& b = m["brickmap"];
    std::printf("  model %d: %d x %d x %d, %llu voxels, %d palette entries, %d instance%s", m["index"].get<int>(),
                s[0].get<int>(), s[1].get<int>(), s[2].get<int>(), m["voxels"].get<unsigned long long>(),
                m["paletteEntriesUsed"].get<int>(), m["instances"].get<int>(), m["instances"].get<int>() == 1 ? "" : "s");
    if (!m["sharedWith"].is_null()) std::printf(", identical to model %d (shared)", m["sharedWith"].get<int>());
    std::printf(", brickmap %llu B structure + %llu B payload\n",
                b["occupancyStructureBytes"].get<unsigned long long>(), b["payloadBytes"].get<unsigned long long>());
  }
  for (std::size_t i = 0; i < j["instances"].size(); ++i) {
    const json& in = j["instances"][i];
    const json &mn = in["worldBox"]["min"], &mx = in["worldBox"]["max"];
    std::printf("  instance %zu: model %d%s%s, world box [%g, %g, %g] .. [%g, %g, %g]\n", i, in["model"].get<int>(),
                in["name"].get<std::string>().empty() ? "" : " ", in["name"].get<std::string>().c_str(),
                mn[0].get<double>(), mn[1].get<double>(), mn[2].get<double>(), mx[0].get<double>(),
                mx[1].get<double>(), mx[2].get<double>());
  }
  for (const json& m : j["materials"])
    if (m["type"] != "diffuse") std::printf("  material %d: %s\n", m["id"].get<int>(), m["type"].get<std::string>().c_str());
  std::printf("  %llu voxels, brickmaps %llu B (shared models counted once)\n", j["voxels"].get<unsigned long long>(),
              j["brickmapBytes"].get<unsigned long long>());
  for (const json& n : j["notes"]) std::printf("  note: %s\n", n.get<std::string>().c_str());
}

}  // namespace vs::cli
