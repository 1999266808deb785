// Fuzz target: the scene-file parser (lighting/scene_file.h) on arbitrary text. A refusal is vs::Error; any
// other exception, crash or sanitizer report is a defect.
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

#include "fuzz/scratch.h"
#include "lighting/scene_file.h"
#include "voxel/error.h"

namespace {

// The parser requires every asset file to exist; these names (those the seed scenes use) exist, so inputs
// get past the asset table to instances and lights. Their content is never read.
const std::filesystem::path& sceneFile() {
  static const std::filesystem::path file = [] {
    const std::filesystem::path& dir = vs::fuzz::scratchDir();
    for (const char* name : {"a.vdb", "b.vdb", "ball.vdb", "castle.vdb", "ground.vdb"}) std::ofstream(dir / name);
    return dir / "scene.json";
  }();
  return file;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    vs::SceneDesc scene = vs::parseSceneJson(text, sceneFile());
    (void)scene;
  } catch (const vs::Error&) {
  }
  return 0;
}
