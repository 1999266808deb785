#include "tools/bake_output.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <memory>
#include <set>

#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "tools/atomic_file.h"
#include "tools/file_kind.h"
#include "voxel/error.h"

namespace vs {

namespace fs = std::filesystem;

void validateBakedViews(std::span<const BakedView> views) {
  if (views.empty()) throwBadInput("no shadow views to write (the scene has no shadowed light)");
  std::set<std::string> names;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const BakedView& v = views[i];
    std::string where = "view " + std::to_string(i) + " '" + v.name + "'";
    if (v.name.empty()) throwBadInput("view " + std::to_string(i) + ": empty name");
    if (!names.insert(v.name).second) throwBadInput(where + ": duplicate view name");
    if (v.encoding != "ndc_depth" && v.encoding != "linear_distance")
      throwBadInput(where + ": encoding must be ndc_depth or linear_distance, not '" + v.encoding + "'");
    if (v.depthPoint != "entry" && v.depthPoint != "voxel_center")
      throwBadInput(where + ": depthPoint must be entry or voxel_center, not '" + v.depthPoint + "'");
    if (v.width <= 0 || v.height <= 0) throwBadInput(where + ": size must be positive");
    if (v.texels.size() != std::size_t(v.width) * std::size_t(v.height))
      throwBadInput(where + ": " + std::to_string(v.texels.size()) + " texels for " + std::to_string(v.width) +
                    "x" + std::to_string(v.height));
    if (!v.moments.empty() && v.moments.size() != v.texels.size())
      throwBadInput(where + ": " + std::to_string(v.moments.size()) + " moment texels for " + std::to_string(v.texels.size()) +
                    " texels");
  }
}

fs::path sidecarPath(const fs::path& exr) {
  // Appended, never replacing the extension: "x/demo.exr" must not become the scene "x/demo.json".
  fs::path json = exr;
  json += ".json";
  return json;
}

nlohmann::json sidecarJson(std::span<const BakedView> views) {
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t i = 0; i < views.size(); ++i) {
    const BakedView& v = views[i];
    const float* m = glm::value_ptr(v.worldToClip);
    nlohmann::json j = {{"subimage", i},
                        {"name", v.name},
                        {"light", v.light},
                        {"encoding", v.encoding},
                        {"depthPoint", v.depthPoint},
                        {"range", v.range},
                        {"worldToClip", std::vector<float>(m, m + 16)},
                        {"eye", {v.eye.x, v.eye.y, v.eye.z}},
                        {"eyeToClip", std::vector<double>(glm::value_ptr(v.eyeToClip), glm::value_ptr(v.eyeToClip) + 16)},
                        {"width", v.width},
                        {"height", v.height}};
    if (v.position) j["position"] = {v.position->x, v.position->y, v.position->z};
    if (!v.moments.empty())
      j["evsm"] = {{"exponents", {v.evsmExponents.x, v.evsmExponents.y}},
                   {"blur", v.evsmBlur},
                   {"lightBleedReduction", v.lightBleedReduction},
                   {"channels", {"evsm.p", "evsm.p2", "evsm.n", "evsm.n2"}}};
    list.push_back(std::move(j));
  }
  return {{"version", 1}, {"views", std::move(list)}};
}

namespace {

// OpenEXR requires every part of a multi-part file to share one display window, so layers of different
// resolutions all get the smallest window holding each of them; each layer's data window starts at (0, 0)
// and is exactly its own size, and equals the display window when all layers have the same size.
OIIO::ImageSpec exrSpec(const BakedView& v, int displayWidth, int displayHeight) {
  const bool moments = !v.moments.empty();
  OIIO::ImageSpec spec(v.width, v.height, moments ? 5 : 1, OIIO::TypeDesc::FLOAT);
  spec.full_x = spec.full_y = 0;
  spec.full_width = displayWidth;
  spec.full_height = displayHeight;
  spec.channelnames = {"Z"};
  if (moments) {
    // The moments of the EVSM warps (lighting/shared/evsm.h): layer "evsm", in the order the shader reads them.
    spec.channelnames = {"Z", "evsm.p", "evsm.p2", "evsm.n", "evsm.n2"};
    spec.attribute("voxshadow:evsmExponents", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::VEC2),
                   glm::value_ptr(v.evsmExponents));
    spec.attribute("voxshadow:evsmBlur", v.evsmBlur);
    spec.attribute("voxshadow:lightBleedReduction", v.lightBleedReduction);
  }
  spec.attribute("compression", "zip");
  // No capture date: OpenImageIO stamps the writing time otherwise, and a bake's files must depend on its
  // inputs alone, so that a merge of shards baked elsewhere is the very file one machine would write.
  spec.attribute("DateTime", "");
  spec.attribute("oiio:subimagename", v.name);
  spec.attribute("voxshadow:light", v.light);
  spec.attribute("voxshadow:view", v.name);
  spec.attribute("voxshadow:worldToClip", OIIO::TypeMatrix44, glm::value_ptr(v.worldToClip));
  spec.attribute("voxshadow:eye", OIIO::TypeDesc(OIIO::TypeDesc::DOUBLE, OIIO::TypeDesc::VEC3, OIIO::TypeDesc::VECTOR),
                 glm::value_ptr(v.eye));
  spec.attribute("voxshadow:eyeToClip", OIIO::TypeDesc(OIIO::TypeDesc::DOUBLE, OIIO::TypeDesc::MATRIX44),
                 glm::value_ptr(v.eyeToClip));
  spec.attribute("voxshadow:encoding", v.encoding);
  spec.attribute("voxshadow:depthPoint", v.depthPoint);
  spec.attribute("voxshadow:range", v.range);
  if (v.position) spec.attribute("voxshadow:position", OIIO::TypeVector, glm::value_ptr(*v.position));
  return spec;
}

void writeExrFile(const fs::path& finalPath, const fs::path& tmp, std::span<const BakedView> views) {
  auto fail = [&](const std::string& what) {
    throwRuntime(finalPath.string() + ": " + what);
  };
  // The format comes from the final name; the temporary keeps the extension too, but say it explicitly.
  auto out = OIIO::ImageOutput::create("openexr");
  if (!out) fail("cannot create an EXR writer: " + OIIO::geterror());
  if (!out->supports("multiimage")) fail("this OpenImageIO's EXR writer cannot write several subimages");
  std::vector<OIIO::ImageSpec> specs;
  specs.reserve(views.size());
  int displayWidth = 0, displayHeight = 0;
  for (const BakedView& v : views) {
    displayWidth = std::max(displayWidth, v.width);
    displayHeight = std::max(displayHeight, v.height);
  }
  for (const BakedView& v : views) specs.push_back(exrSpec(v, displayWidth, displayHeight));
  if (!out->open(tmp.string(), int(specs.size()), specs.data())) fail("cannot open for writing: " + out->geterror());
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (i > 0 && !out->open(tmp.string(), specs[i], OIIO::ImageOutput::AppendSubimage))
      fail("cannot start subimage '" + views[i].name + "': " + out->geterror());
    const BakedView& v = views[i];
    bool written = false;
    if (v.moments.empty()) {
      written = out->write_image(OIIO::TypeDesc::FLOAT, v.texels.data());
    } else {
      // Depth and moments interleaved per texel, as the spec lists the channels.
      std::vector<float> pixels(v.texels.size() * 5);
      for (std::size_t k = 0; k < v.texels.size(); ++k) {
        pixels[k * 5] = v.texels[k];
        for (int c = 0; c < 4; ++c) pixels[k * 5 + 1 + std::size_t(c)] = v.moments[k][c];
      }
      written = out->write_image(OIIO::TypeDesc::FLOAT, pixels.data());
    }
    if (!written) fail("cannot write subimage '" + v.name + "': " + out->geterror());
  }
  if (!out->close()) fail("cannot finish the file: " + out->geterror());
}

void writeTextFile(const fs::path& finalPath, const fs::path& tmp, const std::string& text) {
  std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
  if (!f) throwRuntime(finalPath.string() + ": cannot open for writing");
  f << text;
  f.close();
  if (!f) throwRuntime(finalPath.string() + ": write failed");
}

// Display value 0..1 of one texel; NaN marks a texel a display cannot show honestly.
float displayValue(const BakedView& v, float texel) {
  if (!std::isfinite(texel)) return NAN;
  float scaled = v.encoding == "linear_distance" ? (v.range > 0.0f ? texel / v.range : texel) : texel;
  return std::clamp(scaled, 0.0f, 1.0f);
}

// The contact sheet as an image: a grid of cells, one per view, whose size shrinks with the view count so
// that the sheet never exceeds kSheetMax pixels a side (memory and PNG size stay bounded for any count).
OIIO::ImageBuf contactSheet(std::span<const BakedView> views) {
  constexpr int kSheetMax = 4096, kMaxCell = 256, kPad = 8, kLabel = 20, kMinLabelledCell = 64;
  const int n = int(views.size());
  const int columns = std::max(1, int(std::ceil(std::sqrt(double(n)))));
  const int rows = (n + columns - 1) / columns;
  // Labels need room; below kMinLabelledCell pixels a cell is too small to name its view legibly.
  int cell = std::min(kMaxCell, (kSheetMax - kPad) / columns - kPad);
  const bool labelled = cell >= kMinLabelledCell;
  const int label = labelled ? kLabel : 0;
  const int pad = cell >= kMinLabelledCell ? kPad : 1;
  cell = std::max(1, std::min(cell, (kSheetMax - pad) / rows - pad - label));
  const int sheetW = columns * (cell + pad) + pad;
  const int sheetH = rows * (cell + label + pad) + pad;
  if (sheetW > kSheetMax || sheetH > kSheetMax)
    throwBadInput("the preview cannot show " + std::to_string(n) + " views (at most " +
                  std::to_string((kSheetMax / 2) * (kSheetMax / 2)) + ")");
  OIIO::ImageBuf sheet(OIIO::ImageSpec(sheetW, sheetH, 3, OIIO::TypeDesc::UINT8));
  const float background[3] = {0.12f, 0.12f, 0.14f};
  OIIO::ImageBufAlgo::fill(sheet, background);

  bool labels = labelled;
  for (int i = 0; i < n; ++i) {
    const BakedView& v = views[std::size_t(i)];
    const int x0 = pad + (i % columns) * (cell + pad);
    const int y0 = pad + (i / columns) * (cell + label + pad);
    const double scale = std::min(1.0, double(cell) / double(std::max(v.width, v.height)));
    const int cw = std::max(1, int(std::lround(v.width * scale)));
    const int ch = std::max(1, int(std::lround(v.height * scale)));
    for (int cy = 0; cy < ch; ++cy) {
      // Box filter over the source texels under this cell pixel (64-bit products: 16384 * 16384 overflows int).
      const int sy0 = int(std::int64_t(cy) * v.height / ch);
      const int sy1 = std::max(sy0 + 1, int(std::int64_t(cy + 1) * v.height / ch));
      for (int cx = 0; cx < cw; ++cx) {
        const int sx0 = int(std::int64_t(cx) * v.width / cw);
        const int sx1 = std::max(sx0 + 1, int(std::int64_t(cx + 1) * v.width / cw));
        double sum = 0.0;
        int count = 0;
        bool bad = false;
        for (int sy = sy0; sy < sy1; ++sy)
          for (int sx = sx0; sx < sx1; ++sx) {
            float d = displayValue(v, v.texels[std::size_t(sy) * std::size_t(v.width) + std::size_t(sx)]);
            if (std::isnan(d)) bad = true; else { sum += d; ++count; }
          }
        float g = count ? float(sum / count) : 0.0f;
        float rgb[3] = {g, g, g};
        if (bad) { rgb[0] = 1.0f; rgb[1] = 0.0f; rgb[2] = 1.0f; }
        sheet.setpixel(x0 + cx, y0 + label + cy, rgb, 3);
      }
    }
    if (labels) {
      const float white[3] = {0.95f, 0.95f, 0.95f};
      // OpenImageIO's default font is often not installed; try it, then common system fonts. Labels are a
      // convenience: without any font the sheet is still a correct grid, in sidecar order.
      static const char* const kFonts[] = {"", "DejaVuSans", "LiberationSans-Regular", "FreeSans"};
      bool drawn = false;
      for (const char* font : kFonts) {
        if (OIIO::ImageBufAlgo::render_text(sheet, x0, y0 + label - 5, v.name, 14, font, white)) {
          drawn = true;
          break;
        }
        (void)sheet.geterror();
      }
      labels = drawn;
    }
  }
  return sheet;
}

void writeSheetFile(const fs::path& finalPath, const fs::path& tmp, const OIIO::ImageBuf& sheet) {
  if (!sheet.write(tmp.string(), OIIO::TypeDesc::UINT8, "png"))
    throwRuntime(finalPath.string() + ": cannot write the preview: " + sheet.geterror());
}

void checkExtension(const fs::path& out, const char* ext, const char* what) {
  if (!hasExtension(out, ext))
    throwBadInput(out.string() + ": the " + what + " must have the extension " + ext);
}

}  // namespace

void writeBakeOutputs(const fs::path& exr, const std::optional<fs::path>& preview, std::span<const BakedView> views) {
  validateBakedViews(views);
  checkExtension(exr, ".exr", "shadow file");
  checkOutputDirectory(exr, kMaxShadowFileNameBytes);
  std::vector<fs::path> outputs = {exr, sidecarPath(exr)};
  if (preview) {
    checkExtension(*preview, ".png", "preview");
    checkOutputDirectory(*preview);
    outputs.push_back(*preview);
  }
  writeAtomically(outputs, [&](std::size_t index, const fs::path& tmp) {
    if (index == 0) writeExrFile(exr, tmp, views);
    else if (index == 1) writeTextFile(outputs[1], tmp, sidecarJson(views).dump(2) + "\n");
    else writeSheetFile(outputs[2], tmp, contactSheet(views));
  });
}

void writeShadowExr(const fs::path& out, std::span<const BakedView> views) { writeBakeOutputs(out, std::nullopt, views); }

void writeContactSheetPng(const fs::path& out, std::span<const BakedView> views) {
  validateBakedViews(views);
  checkExtension(out, ".png", "preview");
  checkOutputDirectory(out);
  writeAtomically(std::span<const fs::path>(&out, 1),
                  [&](std::size_t, const fs::path& tmp) { writeSheetFile(out, tmp, contactSheet(views)); });
}

}  // namespace vs
