// commands.h: the CLI's subcommands. Each adds itself to the app with its options and a callback that
// runs the command; callbacks throw vs::Error (or other exceptions) and main() maps them to exit codes.
#ifndef VOXSHADOW_TOOLS_COMMANDS_H
#define VOXSHADOW_TOOLS_COMMANDS_H

#include <filesystem>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

namespace vs {
class Tracer;
struct SceneDesc;
}

namespace vs::cli {

void registerInfo(CLI::App& app);  // voxshadow info FILE... [--json] | info --devices [--json]
void registerDemo(CLI::App& app);  // voxshadow demo [--out DIR]
void registerBake(CLI::App& app);  // voxshadow bake SCENE -o OUT.exr [--backend] [--device] [--preview] [--threads] [--stats]
                                   //   [--shard K/N | --shards N --parts DIR [--missing-shards]]
void registerMerge(CLI::App& app); // voxshadow merge PART... -o OUT.exr [--preview P.png]
void registerBench(CLI::App& app); // voxshadow bench [--threads N] [--resolution R] [--reps K] [--vulkan]
void registerConvert(CLI::App& app); // voxshadow convert IN.vox OUT.vdb [--frame F]
void registerRender(CLI::App& app);  // voxshadow render SCENE -o OUT.png|OUT.exr [--backend] [--shadows] [--debug] [--memory-budget]

struct BakeOptions {
  std::filesystem::path scene;
  std::filesystem::path output;                 // must end in .exr
  std::optional<std::filesystem::path> preview; // must end in .png
  std::string backend = "vulkan";               // "vulkan" | "cpu" (DESIGN.md §9)
  int threads = 0;                              // CPU backend: 0 = every hardware thread, at most kMaxThreads
  std::optional<std::uint64_t> memoryBudget;    // bytes; unset: the memory available now (memoryBudget())
  std::string device;                           // Vulkan backend: index (digits) or name part; empty = best
  bool stats = false;
  // Sharded bakes (tools/bake_shards.h): `shard` = (K, N) bakes shard K of N into the part file `output`
  // (.vspart); `shards` = N with `partsDir` bakes the shards whose parts in partsDir are missing or stale and
  // merges them into `output` (.exr), or with `missingShards` only prints those shards' numbers.
  std::optional<std::pair<int, int>> shard;
  std::optional<int> shards;
  std::optional<std::filesystem::path> partsDir;
  bool missingShards = false;
  // EVSM: also write each EVSM light's moment layers as extra channels (bake_output.h); refused when no light
  // uses EVSM, and with --shard (moments need whole layers: they are made when the parts are merged by
  // bake --shards).
  bool evsmMoments = false;
};

// The bake shared by `bake` and `demo`. Preconditions: none; bad paths or scenes throw vs::Error(BadInput)
// before any tracing, and a failure leaves no output file.
void runBake(const BakeOptions& options);

struct RenderCommandOptions {
  std::filesystem::path scene;
  std::filesystem::path output;  // .png or .exr
  std::string backend = "vulkan";
  std::string shadows = "maps";  // "maps" | "raytraced"
  std::string debug;             // "", "cascades", "shadow", "normals", "layer=N"
  int width = 0, height = 0;     // 0: the camera's
  int threads = 0;
  std::string device;
  std::optional<std::uint64_t> memoryBudget;  // bytes; unset: the memory available now (memoryBudget())
  bool stats = false;
};

// The render shared by `render` and `demo`. Preconditions: none; bad options, paths and scenes throw
// vs::Error(BadInput) before any tracing, and a failure leaves no output file.
void runRender(const RenderCommandOptions& options);

// A bake's outputs: the EXR, its sidecar and, when given, the preview. Refuses (vs::Error(BadInput)) an EXR
// path without the .exr extension or a preview without .png.
std::vector<std::filesystem::path> bakeOutputPaths(const std::filesystem::path& exr,
                                                   const std::optional<std::filesystem::path>& preview);

// Refuses (vs::Error(BadInput), before any work) outputs that would overwrite the scene file or one of its
// assets (refuseOutputsOverInputs), and checks each output's directory (checkOutputDirectory; the first output
// with maxFirstNameBytes).
void checkCommandOutputs(const SceneDesc& scene, const std::vector<std::filesystem::path>& outputs,
                         std::size_t maxFirstNameBytes = 255);

// The Vulkan backend on `device` (digits: an index; else part of a name; empty: the best). No usable device is
// vs::Error(Runtime) with the hint to use --backend cpu.
std::unique_ptr<Tracer> openVulkanBackend(const std::string& device, int hostThreads);

// Prints every Vulkan device (vs::listVulkanDevices order) with the limits the trace depends on, as text or
// one JSON array. Throws vs::Error(Runtime) when Vulkan cannot start; prints an empty list when it has no device.
void printVulkanDevices(bool asJson);

// Prints `info` of one file (.vdb, .vox or .json scene) to stdout. Throws vs::Error naming the file.
void printInfo(const std::filesystem::path& file);

// `info` of a .vox file as JSON, and as text. Preconditions: none; the reader's errors propagate.
nlohmann::json voxFileInfo(const std::filesystem::path& file);
void printVoxFile(const nlohmann::json& info);

}  // namespace vs::cli

#endif
