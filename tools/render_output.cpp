// render_output.cpp: PNG and EXR of a rendered frame, through OpenImageIO.
#include "tools/render_output.h"

#include <algorithm>
#include <cmath>

#include <OpenImageIO/imageio.h>

#include "tools/file_kind.h"
#include "voxel/error.h"

namespace vs {

std::uint8_t tonemapToSrgb8(float linear) {
  // 0.6: the exposure the fitted curve was made for (it maps the ACES reference's scene white there).
  const float x = 0.6f * std::max(0.0f, std::isfinite(linear) ? linear : 0.0f);
  const float filmic = std::clamp((x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f), 0.0f, 1.0f);
  const float srgb = filmic <= 0.0031308f ? 12.92f * filmic : 1.055f * std::pow(filmic, 1.0f / 2.4f) - 0.055f;
  return std::uint8_t(std::lround(std::clamp(srgb, 0.0f, 1.0f) * 255.0f));
}

std::vector<std::string> renderExrChannels(const RenderedFrame& frame) {
  std::vector<std::string> names = {"R", "G", "B", "A", "position.X", "position.Y", "position.Z", "normal.X",
                                    "normal.Y", "normal.Z", "albedo.R", "albedo.G", "albedo.B", "depth.Z", "instance.id"};
  for (const std::string& light : frame.lightNames) names.push_back("shadow." + light);
  return names;
}

void writeRenderedFrame(const std::filesystem::path& out, const std::filesystem::path& tmp, const RenderedFrame& frame) {
  auto fail = [&](const std::string& why) { throwRuntime(out.string() + ": " + why); };
  const std::size_t pixels = std::size_t(frame.width) * std::size_t(frame.height);
  const bool exr = hasExtension(out, ".exr");
  std::unique_ptr<OIIO::ImageOutput> writer = OIIO::ImageOutput::create(exr ? "openexr" : "png");
  if (!writer) fail("no image writer: " + OIIO::geterror());
  if (!exr) {
    OIIO::ImageSpec spec(frame.width, frame.height, 3, OIIO::TypeDesc::UINT8);
    std::vector<std::uint8_t> rgb(pixels * 3);
    for (std::size_t i = 0; i < pixels; ++i)
      for (int c = 0; c < 3; ++c) rgb[i * 3 + std::size_t(c)] = tonemapToSrgb8(frame.color[i][c]);
    if (!writer->open(tmp.string(), spec)) fail("cannot open for writing: " + writer->geterror());
    if (!writer->write_image(OIIO::TypeDesc::UINT8, rgb.data())) fail("cannot write: " + writer->geterror());
    if (!writer->close()) fail("cannot finish the file: " + writer->geterror());
    return;
  }
  const std::vector<std::string> names = renderExrChannels(frame);
  const std::size_t channels = names.size(), lights = frame.lightNames.size();
  OIIO::ImageSpec spec(frame.width, frame.height, int(channels), OIIO::TypeDesc::FLOAT);
  spec.channelnames = names;
  spec.alpha_channel = 3;
  spec.attribute("compression", "zip");
  std::vector<float> data(pixels * channels);
  for (std::size_t i = 0; i < pixels; ++i) {
    float* d = &data[i * channels];
    const gpu::GBufferTexel& g = frame.gbuffer.texels[i];
    for (int c = 0; c < 4; ++c) d[c] = frame.color[i][c];
    for (int c = 0; c < 3; ++c) {
      d[4 + c] = g.position[c];
      d[7 + c] = g.normal[c];
      d[10 + c] = g.albedo[c];
    }
    d[13] = g.position.w;
    d[14] = g.info.w != 0u ? float(g.info.x) : -1.0f;
    for (std::size_t l = 0; l < lights; ++l) d[15 + l] = frame.shadowTerms[i * lights + l];
  }
  if (!writer->open(tmp.string(), spec)) fail("cannot open for writing: " + writer->geterror());
  if (!writer->write_image(OIIO::TypeDesc::FLOAT, data.data())) fail("cannot write: " + writer->geterror());
  if (!writer->close()) fail("cannot finish the file: " + writer->geterror());
}

}  // namespace vs
