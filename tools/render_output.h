// render_output.h: a rendered frame as files (DESIGN.md §9): PNG, tonemapped sRGB; EXR, linear HDR with the
// G-buffer and each light's shadow term as further channels.
#ifndef VOXSHADOW_TOOLS_RENDER_OUTPUT_H
#define VOXSHADOW_TOOLS_RENDER_OUTPUT_H

#include <cstdint>
#include <filesystem>
#include <vector>

#include "lighting/renderer.h"

namespace vs {

// Linear HDR to display sRGB, 8 bits: a filmic curve (ACES, fitted) and the sRGB transfer function.
std::uint8_t tonemapToSrgb8(float linear);

// Writes the frame to `tmp` in the format of `out`'s extension (.png or .exr). Throws vs::Error(Runtime)
// naming `out` when the writer fails. Preconditions: frame is complete (color, gbuffer, shadowTerms).
void writeRenderedFrame(const std::filesystem::path& out, const std::filesystem::path& tmp, const RenderedFrame& frame);

// The EXR channel names: R, G, B, A, then position.{X,Y,Z}, normal.{X,Y,Z}, albedo.{R,G,B}, depth.Z,
// instance.id and shadow.<light> per light.
std::vector<std::string> renderExrChannels(const RenderedFrame& frame);

}  // namespace vs

#endif
