// voxshadow merge: the part files of a sharded bake -> the bake's EXR, sidecar and preview, exactly as one
// machine's bake writes them (tools/bake_shards.h).
#include <cstdio>

#include "tools/atomic_file.h"
#include "tools/bake_output.h"
#include "tools/bake_shards.h"
#include "tools/commands.h"
#include "tools/resources.h"
#include "voxel/error.h"

namespace vs::cli {

namespace {

struct MergeOptions {
  std::vector<std::filesystem::path> parts;
  std::filesystem::path output;
  std::optional<std::filesystem::path> preview;
  std::optional<std::uint64_t> memoryBudget;
};

void runMerge(const MergeOptions& options) {
  const std::vector<std::filesystem::path> outputs = bakeOutputPaths(options.output, options.preview);
  refuseOutputsOverInputs(outputs, options.parts, std::vector<std::string>(options.parts.size(), "part"));
  for (std::size_t i = 0; i < outputs.size(); ++i) checkOutputDirectory(outputs[i], i == 0 ? kMaxShadowFileNameBytes : 255);
  // The parts are read whole and the layers assembled beside them: twice the parts' bytes at the peak.
  std::uint64_t partBytes = 0;
  for (const auto& p : options.parts) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(p, ec);
    if (!ec) partBytes += size;
  }
  checkMemoryNeed(3 * partBytes, memoryBudget(options.memoryBudget, 1),
                  "merge: " + std::to_string(options.parts.size()) + " parts need", "merge on a machine with more memory");
  std::vector<BakedView> views = mergeBakeParts(options.parts);
  writeBakeOutputs(options.output, options.preview, views);
  std::printf("merged %zu part%s (%zu view%s) into %s\n", options.parts.size(), options.parts.size() == 1 ? "" : "s",
              views.size(), views.size() == 1 ? "" : "s", options.output.c_str());
  if (options.preview) std::printf("preview: %s\n", options.preview->c_str());
}

}  // namespace

void registerMerge(CLI::App& app) {
  auto options = std::make_shared<MergeOptions>();
  CLI::App* sub = app.add_subcommand(
      "merge", "Merge the part files of a sharded bake (bake --shard K/N) into the EXR and sidecar one bake writes");
  sub->add_option("PARTS", options->parts, "Every part file of the bake, one per shard")->required();
  sub->add_option("-o,--output", options->output, "Output .exr (its directory must exist)")->required();
  sub->add_option("--preview", options->preview, "Also write a PNG contact sheet of the layers");
  sub->add_option_function<std::string>(
         "--memory-budget",
         [options](const std::string& text) { options->memoryBudget = parseByteSize(text, "--memory-budget"); },
         "Most host memory the merge may plan to use, e.g. 8G, 512M (default: the memory available now)")
      ->type_name("SIZE");
  sub->callback([options] { runMerge(*options); });
}

}  // namespace vs::cli
