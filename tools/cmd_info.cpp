// voxshadow info: what a .vdb file or a scene holds, and what voxshadow makes of it.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <new>

#include <nlohmann/json.hpp>

#include "lighting/scene.h"
#include "tools/commands.h"
#include "tools/file_kind.h"
#include "voxel/error.h"
#include "voxel/vdb_info.h"

namespace vs::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json vec3Json(const glm::vec3& v) { return {v.x, v.y, v.z}; }

json memoryJson(const BrickmapMemory& m, std::uint64_t solid) {
  const std::size_t total = m.occupancyStructureBytes();
  return {{"regionTableBytes", m.regionTableBytes}, {"regionBytes", m.regionBytes}, {"sectorBytes", m.sectorBytes},
          {"brickBytes", m.brickBytes},           {"occupancyBytes", m.occupancyBytes}, {"payloadBytes", m.payloadBytes},
          {"occupancyStructureBytes", total},
          {"bytesPerSolidVoxel", solid ? double(total) / double(solid) : 0.0}};
}

std::string bytes(std::uint64_t n) {
  char buf[64];
  if (n >= (1ull << 20)) std::snprintf(buf, sizeof buf, "%.2f MiB", double(n) / double(1ull << 20));
  else if (n >= (1ull << 10)) std::snprintf(buf, sizeof buf, "%.1f KiB", double(n) / 1024.0);
  else std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(n));
  return buf;
}

void printMemory(const json& m, const char* indent) {
  std::printf("%sbrickmap: region table %s, regions %s, sectors %s, bricks %s, occupancy %s (structure %s, "
              "%.3f B/solid voxel), payload %s\n",
              indent, bytes(m["regionTableBytes"]).c_str(), bytes(m["regionBytes"]).c_str(),
              bytes(m["sectorBytes"]).c_str(), bytes(m["brickBytes"]).c_str(), bytes(m["occupancyBytes"]).c_str(),
              bytes(m["occupancyStructureBytes"]).c_str(), m["bytesPerSolidVoxel"].get<double>(),
              bytes(m["payloadBytes"]).c_str());
}

json vdbInfo(const fs::path& file) {
  std::vector<GridInfo> grids = inspectVdb(file.string());
  json list = json::array();
  for (const GridInfo& g : grids) {
    json gj = {{"name", g.name},
               {"index", g.index},
               {"type", g.valueType},
               {"class", g.gridClass},
               {"voxelSize", {g.voxelSize.x, g.voxelSize.y, g.voxelSize.z}},
               {"activeVoxels", g.activeVoxelCount},
               {"openvdbTreeBytes", g.openvdbTreeBytes},
               {"solidRule", g.hasSolidRule ? json(g.rule) : json(nullptr)}};
    if (g.activeVoxelCount > 0)
      gj["indexBounds"] = {{"min", {g.indexMin.x, g.indexMin.y, g.indexMin.z}},
                           {"max", {g.indexMax.x, g.indexMax.y, g.indexMax.z}}};
    else
      gj["indexBounds"] = nullptr;
    if (g.hasSolidRule && g.error.empty()) {
      gj["solidVoxels"] = g.solidVoxelCount;
      gj["brickmap"] = memoryJson(g.brickmapMemory, g.solidVoxelCount);
    }
    if (!g.error.empty()) gj["error"] = g.error;
    list.push_back(std::move(gj));
  }
  return {{"file", file.string()}, {"kind", "vdb"}, {"grids", std::move(list)}};
}

void printVdb(const json& j) {
  const json& grids = j["grids"];
  std::printf("%s: %zu grid%s\n", j["file"].get<std::string>().c_str(), grids.size(), grids.size() == 1 ? "" : "s");
  for (const json& g : grids) {
    const json& vs = g["voxelSize"];
    std::printf("  [%d] '%s': %s, %s, voxel size %g x %g x %g, %llu active voxels\n", g["index"].get<int>(),
                g["name"].get<std::string>().c_str(), g["type"].get<std::string>().c_str(),
                g["class"].get<std::string>().c_str(), vs[0].get<double>(), vs[1].get<double>(), vs[2].get<double>(),
                g["activeVoxels"].get<unsigned long long>());
    if (!g["indexBounds"].is_null()) {
      const json &mn = g["indexBounds"]["min"], &mx = g["indexBounds"]["max"];
      std::printf("      index bounds [%d, %d, %d] .. [%d, %d, %d]\n", mn[0].get<int>(), mn[1].get<int>(),
                  mn[2].get<int>(), mx[0].get<int>(), mx[1].get<int>(), mx[2].get<int>());
    }
    if (g["solidRule"].is_null()) {
      std::printf("      no solid rule for this grid type\n");
    } else {
      std::printf("      solid rule: %s\n", g["solidRule"].get<std::string>().c_str());
    }
    if (g.contains("error")) std::printf("      cannot build a brickmap: %s\n", g["error"].get<std::string>().c_str());
    if (g.contains("brickmap")) {
      std::printf("      solid voxels: %llu\n", g["solidVoxels"].get<unsigned long long>());
      printMemory(g["brickmap"], "      ");
    }
    std::printf("      OpenVDB tree: %s\n", bytes(g["openvdbTreeBytes"].get<std::uint64_t>()).c_str());
  }
}

json sceneInfo(const fs::path& file) {
  SceneDesc parsed = parseSceneFile(file);
  checkSceneAssetBytes(parsed);
  Scene scene = Scene::load(std::move(parsed));
  const SceneDesc& desc = scene.desc();
  const SceneData& data = scene.data();
  json j = {{"file", file.string()}, {"kind", "scene"}};
  json assets = json::array();
  for (std::size_t i = 0; i < desc.assets.size(); ++i) {
    const Scene::ObjectRange range = scene.assetObjects()[i];
    if (desc.assets[i].vox) {
      json objects = json::array();
      std::uint64_t solid = 0;
      for (std::size_t k = range.first; k < range.first + range.count; ++k) {
        const VoxelObject& o = scene.objects()[k];
        solid += o.brickmap.solidCount();
        objects.push_back({{"model", o.gridIndex}, {"solidVoxels", o.brickmap.solidCount()},
                           {"brickmap", memoryJson(o.brickmap.memory(), o.brickmap.solidCount())}});
      }
      assets.push_back({{"name", desc.assets[i].name}, {"file", desc.assets[i].file.string()}, {"kind", "vox"},
                        {"voxelSize", desc.assets[i].voxelSize}, {"solidVoxels", solid},
                        {"objects", std::move(objects)}, {"notes", scene.assetNotes(i)}});
      continue;
    }
    const VoxelObject& o = scene.objects()[range.first];
    assets.push_back({{"name", desc.assets[i].name},
                      {"file", desc.assets[i].file.string()},
                      {"grid", o.gridName},
                      {"gridIndex", o.gridIndex},
                      {"rule", o.rule},
                      {"solidVoxels", o.brickmap.solidCount()},
                      {"brickmap", memoryJson(o.brickmap.memory(), o.brickmap.solidCount())}});
  }
  j["assets"] = std::move(assets);
  j["instances"] = scene.instances().size();
  // The scene keeps no build timing: rebuild from its instance boxes, which is exactly the build it ran.
  auto t0 = std::chrono::steady_clock::now();
  Bvh rebuilt = Bvh::build(data.instanceBounds);
  double buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  j["bvh"] = {{"nodes", data.bvh.nodes().size()}, {"sahCost", data.bvh.sahCost()}, {"buildMs", buildMs},
              {"rebuiltNodes", rebuilt.nodes().size()}};
  if (data.worldBounds.empty()) j["worldBounds"] = nullptr;
  else j["worldBounds"] = {{"min", vec3Json(data.worldBounds.min)}, {"max", vec3Json(data.worldBounds.max)}};
  std::vector<LightView> views = scene.lightViews();
  json lights = json::array();
  for (std::size_t li = 0; li < desc.lights.size(); ++li) {
    const LightDesc& l = desc.lights[li];
    json lj = {{"name", l.name}, {"type", lightTypeName(l.type)}, {"shadow", l.shadow.has_value()}};
    if (l.shadow) {
      lj["resolution"] = l.shadow->resolution;
      lj["filter"] = shadowFilterName(l.shadow->filter);
    }
    json vj = json::array();
    for (const LightView& v : views) {
      if (v.lightIndex != int(li)) continue;
      vj.push_back({{"name", v.name},
                    {"resolution", v.resolution},
                    {"encoding", v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE ? "linear_distance" : "ndc_depth"},
                    {"range", v.range}});
    }
    lj["views"] = std::move(vj);
    lights.push_back(std::move(lj));
  }
  j["lights"] = std::move(lights);
  return j;
}

void printScene(const json& j) {
  std::printf("%s: scene\n", j["file"].get<std::string>().c_str());
  for (const json& a : j["assets"]) {
    if (a.value("kind", "") == "vox") {
      std::printf("  asset %s: %s, %zu object%s, voxel size %g, %llu solid voxels\n", a["name"].get<std::string>().c_str(),
                  a["file"].get<std::string>().c_str(), a["objects"].size(), a["objects"].size() == 1 ? "" : "s",
                  a["voxelSize"].get<double>(), a["solidVoxels"].get<unsigned long long>());
      for (const json& n : a["notes"]) std::printf("    note: %s\n", n.get<std::string>().c_str());
      continue;
    }
    std::printf("  asset %s: %s grid '%s' (#%d), %s, %llu solid voxels\n", a["name"].get<std::string>().c_str(),
                a["file"].get<std::string>().c_str(), a["grid"].get<std::string>().c_str(), a["gridIndex"].get<int>(),
                a["rule"].get<std::string>().c_str(), a["solidVoxels"].get<unsigned long long>());
    printMemory(a["brickmap"], "    ");
  }
  const json& b = j["bvh"];
  std::printf("  instances: %zu\n", j["instances"].get<std::size_t>());
  std::printf("  bvh: %zu nodes, SAH cost %.3f, build %.3f ms\n", b["nodes"].get<std::size_t>(),
              b["sahCost"].get<double>(), b["buildMs"].get<double>());
  if (!j["worldBounds"].is_null()) {
    auto mn = j["worldBounds"]["min"], mx = j["worldBounds"]["max"];
    std::printf("  world bounds: [%g, %g, %g] .. [%g, %g, %g]\n", mn[0].get<double>(), mn[1].get<double>(),
                mn[2].get<double>(), mx[0].get<double>(), mx[1].get<double>(), mx[2].get<double>());
  } else {
    std::printf("  world bounds: empty (no solid voxel)\n");
  }
  for (const json& l : j["lights"]) {
    std::printf("  light %s (%s)", l["name"].get<std::string>().c_str(), l["type"].get<std::string>().c_str());
    if (!l["shadow"].get<bool>()) {
      std::printf(": no shadow\n");
      continue;
    }
    std::printf(": shadow %d, filter %s\n", l["resolution"].get<int>(), l["filter"].get<std::string>().c_str());
    for (const json& v : l["views"])
      std::printf("    view %s: %dx%d %s, miss %g\n", v["name"].get<std::string>().c_str(), v["resolution"].get<int>(),
                  v["resolution"].get<int>(), v["encoding"].get<std::string>().c_str(), v["range"].get<double>());
  }
}

json fileInfo(const fs::path& file) {
  // The first bytes before anything else: a file that is not what its name says is refused for that, not
  // for its size (a sparse 10 GB file of zeros named .vdb) or for what a reader makes of it.
  const InputKind kind = inputKindOf(file);
  checkInputBytes(file, kind);
  if (kind == InputKind::Scene) return sceneInfo(file);
  if (kind == InputKind::Vox) return voxFileInfo(file);
  return vdbInfo(file);
}

void printFile(const json& j) {
  if (j["kind"] == "scene") printScene(j);
  else if (j["kind"] == "vox") printVoxFile(j);
  else printVdb(j);
}

}  // namespace

void printInfo(const fs::path& file) { printFile(fileInfo(file)); }

void registerInfo(CLI::App& app) {
  struct Options {
    std::vector<std::string> files;
    bool json = false;
    bool devices = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("info", "Describe .vdb and .vox files (grids or models, solid voxels, brickmap memory) and scenes");
  sub->add_option("FILE", options->files, ".vdb, .vox or .json scene files");
  sub->add_flag("--json", options->json, "Print one JSON document instead of text");
  sub->add_flag("--devices", options->devices,
                "List the Vulkan devices (index, name, type, driver, limits the trace uses) for bake --device");
  sub->callback([options] {
    if (options->devices) {
      if (!options->files.empty()) throwBadInput("info: --devices takes no FILE");
      printVulkanDevices(options->json);
      return;
    }
    if (options->files.empty()) throwBadInput("info: FILE is required (or --devices)");
    // Every file is reported: a bad one is an error line (and, with --json, an entry with its error), and the
    // files after it are still described; the exit status says that one failed.
    json all = json::array();
    std::size_t failed = 0;
    bool badInput = false;
    for (const std::string& f : options->files) {
      std::string error;
      if (options->files.size() == 1) {
        // One file: its error is the command's error, exit status and all.
        json j = fileInfo(f);
        if (options->json) all.push_back(std::move(j));
        else printFile(j);
        continue;
      }
      try {
        json j = fileInfo(f);
        if (options->json) all.push_back(std::move(j));
        else printFile(j);
        continue;
      } catch (const Error& e) {
        error = e.what();
        badInput = badInput || e.kind() == ErrorKind::BadInput;
      } catch (const std::bad_alloc&) {
        error = "out of memory";
      } catch (const std::exception& e) {
        error = e.what();
      }
      if (error.find(f) == std::string::npos) error = f + ": " + error;
      ++failed;
      std::fflush(stdout);
      std::cout.flush();
      std::fprintf(stderr, "voxshadow: %s\n", error.c_str());
      if (options->json) all.push_back({{"file", f}, {"error", error}});
    }
    if (options->json) std::cout << all.dump(2) << "\n";
    if (failed == 0) return;
    const std::string summary = "info: " + std::to_string(failed) + " of " + std::to_string(options->files.size()) +
                                " file" + (options->files.size() == 1 ? "" : "s") + " could not be described";
    if (badInput) throwBadInput(summary);
    throwRuntime(summary);
  });
}

}  // namespace vs::cli
