// demo_frames.h: the demo scene at a test's size and the checks the frame-loop tests share (lifetimes,
// threads, embedding).
#ifndef VOXSHADOW_TEST_DEMO_FRAMES_H
#define VOXSHADOW_TEST_DEMO_FRAMES_H

#include <cstring>
#include <string>
#include <vector>

#include "compute/tracer.h"
#include "lighting/scene.h"

namespace vs::test {

// The demo world written under scratchDir(dir), its shadow layers at `resolution` texels a side and its camera
// stepped by `cameraStep` along x: two calls with other arguments give scenes whose frames differ.
Scene demoScene(const std::string& dir, int resolution, float cameraStep);

// Fails the current test with the first validation message when `tracer` is a Vulkan tracer that has any.
void expectNoValidationMessages(Tracer& tracer);

template <class T>
bool sameBytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

}  // namespace vs::test

#endif
