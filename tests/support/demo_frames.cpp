// demo_frames.cpp
#include "support/demo_frames.h"

#include <gtest/gtest.h>

#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/scene_file.h"
#include "support/test_paths.h"
#include "voxel/demo_world.h"

namespace vs::test {

Scene demoScene(const std::string& dir, int resolution, float cameraStep) {
  const std::vector<std::string> written = writeDemoWorld(scratchDir(dir));
  SceneDesc desc = parseSceneFile(written.back());
  for (LightDesc& l : desc.lights)
    if (l.shadow) l.shadow->resolution = resolution;
  desc.camera->position.x += cameraStep;
  desc.camera->target.x += cameraStep;
  return Scene::load(std::move(desc));
}

void expectNoValidationMessages(Tracer& tracer) {
  if (VulkanTracer* v = tracer.vulkan()) {
    EXPECT_TRUE(v->validationMessages().empty()) << v->validationMessages().front();
  }
}

}  // namespace vs::test
