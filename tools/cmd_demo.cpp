// voxshadow demo: writes the built-in demo world (real .vdb files and a scene), describes it, bakes it and
// renders it.
#include <cstdio>

#include "tools/commands.h"
#include "voxel/demo_world.h"
#include "voxel/error.h"

namespace vs::cli {

namespace {

namespace fs = std::filesystem;

void runDemo(const fs::path& dir, const std::string& backend) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throwBadInput(dir.string() + ": cannot create the demo directory: " + ec.message());
  std::vector<std::string> written = writeDemoWorld(dir);
  if (written.empty()) throwRuntime(dir.string() + ": the demo world wrote no files");
  const fs::path scene = written.back();  // the scene comes last
  std::printf("demo world written to %s\n", dir.c_str());
  for (std::size_t i = 0; i + 1 < written.size(); ++i) printInfo(written[i]);
  printInfo(scene);

  BakeOptions bake;
  bake.scene = scene;
  bake.backend = backend;
  bake.output = dir / "demo_shadows.exr";
  bake.preview = dir / "demo_shadows.png";
  runBake(bake);

  RenderCommandOptions render;
  render.scene = scene;
  render.backend = backend;
  render.output = dir / "demo.png";
  runRender(render);
}

}  // namespace

void registerDemo(CLI::App& app) {
  struct Options {
    fs::path dir = "voxshadow-demo";
    std::string backend = BakeOptions{}.backend;
  };
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("demo", "Write the demo world (.vdb assets + demo.json), describe it, bake its shadow maps and render it (demo.png)");
  sub->add_option("--out", options->dir, "Directory to write into (created if missing)")->capture_default_str();
  sub->add_option("--backend", options->backend, "Trace backend")
      ->check(CLI::IsMember({"cpu", "vulkan"}))
      ->capture_default_str();
  sub->callback([options] { runDemo(options->dir, options->backend); });
}

}  // namespace vs::cli
