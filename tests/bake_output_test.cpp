// The baked EXR, its sidecar and the contact sheet: content read back exactly, failures leave nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <sys/wait.h>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <OpenImageIO/imageio.h>

#include "support/test_paths.h"
#include "tools/atomic_file.h"
#include "tools/bake_output.h"
#include "voxel/error.h"

namespace fs = std::filesystem;

namespace {

vs::BakedView makeView(std::string light, std::string name, std::string encoding, std::string depthPoint,
                       float range, std::optional<glm::vec3> position, glm::mat4 worldToClip, int w, int h,
                       float seed) {
  vs::BakedView v;
  v.light = std::move(light);
  v.name = std::move(name);
  v.encoding = std::move(encoding);
  v.depthPoint = std::move(depthPoint);
  v.range = range;
  v.position = position;
  v.worldToClip = worldToClip;
  // Values no float holds, so that a reader that rounds them to float shows.
  v.eye = glm::dvec3(1.0 / 3.0 + seed, 1e4 + 1.0 / 7.0, -2.0 / 3.0);
  v.eyeToClip = glm::dmat4(glm::dmat4(worldToClip) * (1.0 + 1.0 / 3.0 * 1e-9));
  v.width = w;
  v.height = h;
  v.texels.resize(std::size_t(w) * std::size_t(h));
  // Distinct, non-round values per texel so that any reordering (rows flipped, subimages swapped) shows.
  for (std::size_t i = 0; i < v.texels.size(); ++i) v.texels[i] = seed + float(i) * 0.001953125f + 1.0f / 3.0f;
  return v;
}

std::vector<vs::BakedView> threeViews() {
  glm::mat4 ortho = glm::orthoRH_ZO(-10.0f, 10.0f, -5.0f, 5.0f, 0.5f, 100.0f) *
                    glm::lookAt(glm::vec3(4, 20, 3), glm::vec3(0), glm::vec3(0, 0, 1));
  glm::mat4 spot = glm::perspectiveRH_ZO(glm::radians(60.0f), 1.0f, 0.1f, 40.0f) *
                   glm::lookAt(glm::vec3(0, 10, 0), glm::vec3(0, 0, 0.01f), glm::vec3(0, 1, 0));
  glm::mat4 face = glm::perspectiveRH_ZO(glm::radians(90.0f), 1.0f, 0.05f, 20.0f) *
                   glm::lookAt(glm::vec3(5, 3, 5), glm::vec3(6, 3, 5), glm::vec3(0, -1, 0));
  std::vector<vs::BakedView> views;
  views.push_back(makeView("sun", "sun.cascade0", "ndc_depth", "entry", 1.0f, std::nullopt, ortho, 16, 8, 0.0f));
  views.push_back(makeView("lamp", "lamp", "linear_distance", "voxel_center", 40.0f, glm::vec3(0, 10, 0), spot, 12,
                           12, 1.0f));
  views.push_back(makeView("torch", "torch.face+x", "linear_distance", "entry", 20.0f, glm::vec3(5, 3, 5), face, 8,
                           8, 2.0f));
  return views;
}

std::vector<std::string> dirEntries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}



}  // namespace

TEST(BakeOutput, ExrRoundTripsEveryTexelAndAttribute) {
  fs::path dir = vs::test::scratchDir("bake_output_roundtrip");
  fs::path exr = dir / "shadows.exr";
  auto views = threeViews();
  vs::writeShadowExr(exr, views);
  ASSERT_TRUE(fs::is_regular_file(exr));
  ASSERT_TRUE(fs::is_regular_file(dir / "shadows.exr.json"));
  EXPECT_EQ(dirEntries(dir).size(), 2u) << "temporaries left behind";

  auto in = OIIO::ImageInput::open(exr.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  int subimages = 0;
  while (in->seek_subimage(subimages, 0)) ++subimages;
  ASSERT_EQ(subimages, 3);
  for (int s = 0; s < 3; ++s) {
    const vs::BakedView& v = views[std::size_t(s)];
    SCOPED_TRACE(v.name);
    ASSERT_TRUE(in->seek_subimage(s, 0));
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.get_string_attribute("oiio:subimagename"), v.name);
    ASSERT_EQ(spec.nchannels, 1);
    EXPECT_EQ(spec.channelnames[0], "Z");
    EXPECT_EQ(spec.format, OIIO::TypeDesc::FLOAT);
    EXPECT_EQ(spec.width, v.width);
    EXPECT_EQ(spec.height, v.height);
    EXPECT_EQ(spec.x, 0);
    EXPECT_EQ(spec.y, 0);
    EXPECT_EQ(spec.full_x, 0);
    EXPECT_EQ(spec.full_y, 0);
    // OpenEXR's parts share one display window: the largest view (16 x 12 here).
    EXPECT_EQ(spec.full_width, 16);
    EXPECT_EQ(spec.full_height, 12);

    std::vector<float> pixels(std::size_t(spec.width) * std::size_t(spec.height));
    ASSERT_TRUE(in->read_image(s, 0, 0, 1, OIIO::TypeDesc::FLOAT, pixels.data())) << in->geterror();
    for (std::size_t i = 0; i < pixels.size(); ++i) ASSERT_EQ(pixels[i], v.texels[i]) << "texel " << i;

    EXPECT_EQ(spec.get_string_attribute("voxshadow:light"), v.light);
    EXPECT_EQ(spec.get_string_attribute("voxshadow:view"), v.name);
    EXPECT_EQ(spec.get_string_attribute("voxshadow:encoding"), v.encoding);
    EXPECT_EQ(spec.get_string_attribute("voxshadow:depthPoint"), v.depthPoint);
    const OIIO::ParamValue* range = spec.find_attribute("voxshadow:range", OIIO::TypeFloat);
    ASSERT_NE(range, nullptr);
    EXPECT_EQ(range->get_float(), v.range);
    const OIIO::ParamValue* matrix = spec.find_attribute("voxshadow:worldToClip", OIIO::TypeMatrix44);
    ASSERT_NE(matrix, nullptr);
    const float* m = static_cast<const float*>(matrix->data());
    const float* expected = glm::value_ptr(v.worldToClip);
    for (int k = 0; k < 16; ++k) EXPECT_EQ(m[k], expected[k]) << "matrix element " << k;
    // The eye and the eye-relative matrix keep every bit of their doubles.
    const OIIO::ParamValue* eye = spec.find_attribute("voxshadow:eye");
    ASSERT_NE(eye, nullptr);
    ASSERT_EQ(eye->type().basetype, OIIO::TypeDesc::DOUBLE);
    ASSERT_EQ(eye->type().numelements() * eye->type().aggregate, 3u);
    const double* e = static_cast<const double*>(eye->data());
    for (int k = 0; k < 3; ++k) EXPECT_EQ(e[k], v.eye[k]) << "eye component " << k;
    const OIIO::ParamValue* eyeToClip = spec.find_attribute("voxshadow:eyeToClip");
    ASSERT_NE(eyeToClip, nullptr);
    ASSERT_EQ(eyeToClip->type().basetype, OIIO::TypeDesc::DOUBLE);
    ASSERT_EQ(eyeToClip->type().numelements() * eyeToClip->type().aggregate, 16u);
    const double* em = static_cast<const double*>(eyeToClip->data());
    for (int k = 0; k < 16; ++k) EXPECT_EQ(em[k], glm::value_ptr(v.eyeToClip)[k]) << "eyeToClip element " << k;
    const OIIO::ParamValue* position = spec.find_attribute("voxshadow:position");
    if (v.position) {
      ASSERT_NE(position, nullptr);
      ASSERT_EQ(position->type().basetype, OIIO::TypeDesc::FLOAT);
      ASSERT_EQ(position->type().numelements() * position->type().aggregate, 3u);
      const float* p = static_cast<const float*>(position->data());
      EXPECT_EQ(p[0], v.position->x);
      EXPECT_EQ(p[1], v.position->y);
      EXPECT_EQ(p[2], v.position->z);
    } else {
      EXPECT_EQ(position, nullptr);
    }
  }
  in->close();

  std::ifstream sidecar(dir / "shadows.exr.json");
  nlohmann::json j = nlohmann::json::parse(sidecar);
  EXPECT_EQ(j.at("version"), 1);
  ASSERT_EQ(j.at("views").size(), 3u);
  for (std::size_t s = 0; s < 3; ++s) {
    const auto& jv = j["views"][s];
    const vs::BakedView& v = views[s];
    EXPECT_EQ(jv.at("subimage"), s);
    EXPECT_EQ(jv.at("name"), v.name);
    EXPECT_EQ(jv.at("light"), v.light);
    EXPECT_EQ(jv.at("encoding"), v.encoding);
    EXPECT_EQ(jv.at("depthPoint"), v.depthPoint);
    EXPECT_EQ(jv.at("range").get<float>(), v.range);
    EXPECT_EQ(jv.at("width"), v.width);
    EXPECT_EQ(jv.at("height"), v.height);
    auto m = jv.at("worldToClip").get<std::vector<float>>();
    ASSERT_EQ(m.size(), 16u);
    for (int k = 0; k < 16; ++k) EXPECT_EQ(m[std::size_t(k)], glm::value_ptr(v.worldToClip)[k]);
    EXPECT_EQ(jv.at("eye").get<std::vector<double>>(), (std::vector<double>{v.eye.x, v.eye.y, v.eye.z}));
    auto em = jv.at("eyeToClip").get<std::vector<double>>();
    ASSERT_EQ(em.size(), 16u);
    for (int k = 0; k < 16; ++k) EXPECT_EQ(em[std::size_t(k)], glm::value_ptr(v.eyeToClip)[k]);
    EXPECT_EQ(jv.contains("position"), v.position.has_value());
    if (v.position) {
      EXPECT_EQ(jv["position"].get<std::vector<float>>(),
                (std::vector<float>{v.position->x, v.position->y, v.position->z}));
    }
  }
}

TEST(BakeOutput, OiiotoolListsTheAttributes) {
  fs::path dir = vs::test::scratchDir("bake_output_oiiotool");
  fs::path exr = dir / "shadows.exr";
  vs::writeShadowExr(exr, threeViews());
  std::string out;
  ASSERT_EQ(vs::test::runCommand("oiiotool --info -v -a '" + exr.string() + "'", out), 0) << out;
  for (const char* needle : {"voxshadow:light", "voxshadow:view", "voxshadow:worldToClip", "voxshadow:eye",
                             "voxshadow:eyeToClip", "voxshadow:encoding",
                             "voxshadow:depthPoint", "voxshadow:range", "voxshadow:position", "sun.cascade0",
                             "lamp", "torch.face+x", "linear_distance", "voxel_center"}) {
    EXPECT_NE(out.find(needle), std::string::npos) << needle << " missing from:\n" << out;
  }
}

TEST(BakeOutput, UnwritableDirectoryLeavesNothing) {
  fs::path scratch = vs::test::scratchDir("bake_output_unwritable");
  fs::path dir = vs::test::unwritableDir(scratch);
  auto views = threeViews();
  try {
    vs::writeShadowExr(dir / "vs_shadows.exr", views);
    ADD_FAILURE() << "writing into " << dir << " succeeded";
  } catch (const vs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("vs_shadows.exr"), std::string::npos) << e.what();
  }
  EXPECT_THROW(vs::writeContactSheetPng(dir / "vs_sheet.png", views), vs::Error);
  EXPECT_TRUE(vs::test::leftovers(dir, "vs_s").empty());
  fs::permissions(scratch, fs::perms::owner_all);
  // A directory that does not exist at all.
  EXPECT_THROW(vs::writeShadowExr(scratch / "missing" / "shadows.exr", views), vs::Error);
  EXPECT_FALSE(fs::exists(scratch / "missing"));
  EXPECT_TRUE(dirEntries(scratch).empty());
}

TEST(BakeOutput, FailureMidWriteLeavesNothing) {
  fs::path dir = vs::test::scratchDir("bake_output_midwrite");
  // An earlier good bake must survive a failed one untouched only if the failure precedes the renames;
  // here the outputs did not exist before, so after the failure nothing may exist.
  const std::array<fs::path, 2> outputs = {dir / "a.exr", dir / "a.exr.json"};
  std::vector<fs::path> temps;
  EXPECT_THROW(vs::writeAtomically(outputs,
                                   [&](std::size_t index, const fs::path& tmp) {
                                     temps.push_back(tmp);
                                     std::ofstream(tmp) << "partial";
                                     EXPECT_EQ(tmp.parent_path(), dir);
                                     if (index == 1) vs::throwRuntime("simulated failure");
                                   }),
               vs::Error);
  ASSERT_EQ(temps.size(), 2u);
  EXPECT_TRUE(dirEntries(dir).empty());

  // A view that breaks the preconditions after a good one: nothing is written.
  auto views = threeViews();
  views[2].texels.pop_back();
  EXPECT_THROW(vs::writeShadowExr(dir / "b.exr", views), vs::Error);
  views = threeViews();
  views[1].name = views[0].name;
  EXPECT_THROW(vs::writeShadowExr(dir / "b.exr", views), vs::Error);
  EXPECT_THROW(vs::writeShadowExr(dir / "b.png", threeViews()), vs::Error);
  EXPECT_TRUE(dirEntries(dir).empty());

  // The EXR writer itself failing (its temporary path is a directory) leaves neither file behind.
  std::vector<fs::path> sidecarTemps;
  EXPECT_THROW(vs::writeAtomically(outputs,
                                   [&](std::size_t index, const fs::path& tmp) {
                                     if (index == 1) {
                                       std::ofstream(tmp) << "{}";
                                       sidecarTemps.push_back(tmp);
                                       return;
                                     }
                                     fs::create_directory(tmp);
                                   }),
               vs::Error);
  // The writer "produced no file" (a directory): the temporary directory is removed too.
  EXPECT_TRUE(dirEntries(dir).empty());
}

TEST(BakeOutput, ContactSheetIsAnImageOfTheViews) {
  fs::path dir = vs::test::scratchDir("bake_output_sheet");
  fs::path png = dir / "sheet.png";
  auto views = threeViews();
  // Make the first view half near (0.25) and half miss (1.0) so the normalisation is visible.
  for (int y = 0; y < views[0].height; ++y)
    for (int x = 0; x < views[0].width; ++x)
      views[0].texels[std::size_t(y * views[0].width + x)] = x < views[0].width / 2 ? 0.25f : 1.0f;
  vs::writeContactSheetPng(png, views);
  EXPECT_EQ(dirEntries(dir).size(), 1u);
  auto in = OIIO::ImageInput::open(png.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.nchannels, 3);
  EXPECT_GE(spec.width, 2 * 16);
  std::vector<float> rgb(std::size_t(spec.width) * std::size_t(spec.height) * 3);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, rgb.data()));
  // Both display levels of the first view appear: 0.25 grey and white.
  bool sawQuarter = false, sawWhite = false;
  for (std::size_t i = 0; i + 2 < rgb.size(); i += 3) {
    if (std::abs(rgb[i] - 0.25f) < 0.01f && rgb[i] == rgb[i + 1] && rgb[i] == rgb[i + 2]) sawQuarter = true;
    if (rgb[i] == 1.0f && rgb[i + 1] == 1.0f && rgb[i + 2] == 1.0f) sawWhite = true;
  }
  EXPECT_TRUE(sawQuarter);
  EXPECT_TRUE(sawWhite);
}

TEST(BakeOutput, SameSizeViewsHaveDataWindowEqualToDisplayWindow) {
  fs::path dir = vs::test::scratchDir("bake_output_same_size");
  auto views = threeViews();
  for (auto& v : views) {
    v.width = 8;
    v.height = 8;
    v.texels.assign(64, 0.5f);
  }
  vs::writeShadowExr(dir / "s.exr", views);
  auto in = OIIO::ImageInput::open((dir / "s.exr").string());
  ASSERT_TRUE(in);
  for (int s = 0; in->seek_subimage(s, 0); ++s) {
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.x, spec.full_x);
    EXPECT_EQ(spec.y, spec.full_y);
    EXPECT_EQ(spec.width, spec.full_width);
    EXPECT_EQ(spec.height, spec.full_height);
  }
}

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

}  // namespace

int failRenamesOntoPng(const char* from, const char* to) {
  if (std::string(to).ends_with(".png")) {
    errno = EIO;
    return -1;
  }
  return ::rename(from, to);
}

// A rename failing halfway through the commit (the third output cannot be replaced) puts the outputs already
// replaced back as they were: a bake's outputs change together or not at all.
TEST(BakeOutput, AFailedCommitRestoresEveryPreviousOutput) {
  fs::path dir = vs::test::scratchDir("bake_output_rollback");
  const std::array<fs::path, 3> outputs = {dir / "y.exr", dir / "y.exr.json", dir / "y.png"};
  auto writeNew = [](std::size_t i, const fs::path& tmp) { writeText(tmp, "new " + std::to_string(i)); };
  writeText(outputs[0], "old exr");
  writeText(outputs[1], "old json");
  writeText(outputs[2], "old png");
  vs::RenameFunction previous = vs::exchangeCommitRenameForTesting(&failRenamesOntoPng);
  EXPECT_THROW(vs::writeAtomically(outputs, writeNew), vs::Error);
  EXPECT_EQ(slurp(outputs[0]), "old exr");
  EXPECT_EQ(slurp(outputs[1]), "old json");
  EXPECT_EQ(slurp(outputs[2]), "old png");
  EXPECT_EQ(dirEntries(dir).size(), 3u) << "temporaries or backups left behind";
  // Outputs that did not exist before are removed again.
  fs::remove(outputs[0]);
  EXPECT_THROW(vs::writeAtomically(outputs, writeNew), vs::Error);
  EXPECT_FALSE(fs::exists(outputs[0]));
  EXPECT_EQ(slurp(outputs[1]), "old json");
  EXPECT_EQ(dirEntries(dir).size(), 2u);
  vs::exchangeCommitRenameForTesting(previous);

  // A directory in place of an output is refused before anything is replaced.
  fs::create_directory(outputs[0]);
  EXPECT_THROW(vs::writeAtomically(outputs, writeNew), vs::Error);
  EXPECT_TRUE(fs::is_directory(outputs[0]));
  EXPECT_EQ(slurp(outputs[1]), "old json");
  EXPECT_EQ(dirEntries(dir).size(), 3u);

  // And a commit that can complete replaces all of them.
  fs::remove(outputs[0]);
  vs::writeAtomically(outputs, writeNew);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(slurp(outputs[i]), "new " + std::to_string(i));
  EXPECT_EQ(dirEntries(dir).size(), 3u);
}

// The case as a user meets it: an immutable preview (chattr +i) cannot be replaced, so the bake fails and the
// previous EXR and sidecar stay. Needs root and a file system with the immutable flag; where chattr refuses,
// the test says so and fails, since the rollback above would then be the only evidence.
TEST(BakeOutput, AnImmutablePreviewKeepsThePreviousBake) {
  fs::path dir = vs::test::scratchDir("bake_output_immutable");
  auto views = threeViews();
  vs::writeBakeOutputs(dir / "y.exr", dir / "y.png", views);
  const std::string exr = slurp(dir / "y.exr"), json = slurp(dir / "y.exr.json"), png = slurp(dir / "y.png");
  std::string out;
  ASSERT_EQ(vs::test::runCommand("chattr +i " + vs::test::quote(dir / "y.png"), out), 0)
      << "chattr +i is not available here (" << out << "); run as root on a file system with the immutable flag";
  views[0].texels[0] = 0.125f;
  views[1].name = "renamed";
  EXPECT_THROW(vs::writeBakeOutputs(dir / "y.exr", dir / "y.png", views), vs::Error);
  vs::test::runCommand("chattr -i " + vs::test::quote(dir / "y.png"), out);
  EXPECT_EQ(slurp(dir / "y.exr"), exr);
  EXPECT_EQ(slurp(dir / "y.exr.json"), json);
  EXPECT_EQ(slurp(dir / "y.png"), png);
  EXPECT_EQ(dirEntries(dir).size(), 3u);
}

TEST(BakeOutput, TemporariesAreRecognisableAndFitTheNameLimit) {
  const fs::path out = "/somewhere/" + std::string(250, 'x') + ".exr";
  const fs::path tmp = vs::temporarySibling(out);
  EXPECT_LE(tmp.filename().string().size(), 255u);
  EXPECT_EQ(tmp.extension(), ".exr");
  EXPECT_EQ(tmp.parent_path(), out.parent_path());
  EXPECT_EQ(vs::temporaryWriterPid(tmp.filename().string()), long(::getpid()));
  EXPECT_EQ(vs::temporaryWriterPid(vs::temporarySibling("a/b.png", ".bak").filename().string()), long(::getpid()));
  for (const char* notOurs : {"shadows.exr", ".shadows.exr", ".x.voxshadow-12.exr", ".x.voxshadow--3.exr",
                              ".x.voxshadow-12-4.exr.json", "x.voxshadow-12-4.exr"})
    EXPECT_FALSE(vs::temporaryWriterPid(notOurs)) << notOurs;
}

TEST(BakeOutput, StaleTemporariesOfDeadWritersAreRemoved) {
  fs::path dir = vs::test::scratchDir("bake_output_stale");
  // A pid that is certainly not running: a child that has exited and been reaped.
  pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  const std::string dead = std::to_string(child), alive = std::to_string(::getppid());
  // Built by appending: GCC 12 warns falsely on chains of string operator+.
  auto temp = [](const char* name, const std::string& pid, const char* tail) {
    return std::string(".").append(name).append(".voxshadow-").append(pid).append(tail);
  };
  for (const std::string& name : {temp("y.exr", dead, "-0.exr"), temp("y.exr.json", dead, "-1.json"),
                                  temp("y.png", dead, "-7.bak"), temp("y.exr", alive, "-0.exr"), std::string("y.exr"),
                                  std::string("notes.voxshadow-1-1.txt")})
    writeText(dir / name, "x");
  EXPECT_EQ(vs::removeStaleTemporaries(dir), 3u);
  std::vector<std::string> left = dirEntries(dir);
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{temp("y.exr", alive, "-0.exr"), "notes.voxshadow-1-1.txt", "y.exr"}));
  // checkOutputDirectory, which every bake calls first, does the same.
  writeText(dir / temp("z.exr", dead, "-3.exr"), "x");
  vs::checkOutputDirectory(dir / "z.exr");
  EXPECT_FALSE(fs::exists(dir / temp("z.exr", dead, "-3.exr")));
}

TEST(BakeOutput, ContactSheetOfThousandsOfViewsIsBounded) {
  fs::path dir = vs::test::scratchDir("bake_output_many");
  std::vector<vs::BakedView> views;
  glm::mat4 m(1.0f);
  for (int i = 0; i < 3000; ++i)
    views.push_back(makeView(std::string("l").append(std::to_string(i)), std::string("l").append(std::to_string(i)),
                             "ndc_depth", "entry", 1.0f, std::nullopt, m,
                             i % 7 == 0 ? 64 : 16, 16, float(i % 5) * 0.1f));
  vs::writeContactSheetPng(dir / "many.png", views);
  auto in = OIIO::ImageInput::open((dir / "many.png").string());
  ASSERT_TRUE(in);
  EXPECT_LE(in->spec().width, 4096);
  EXPECT_LE(in->spec().height, 4096);
  EXPECT_GT(in->spec().width, 1000) << "the cells shrank more than they needed to";
}
