// Inputs that are not what they claim, several files to one `info`, outputs named in upper case, mistyped
// commands, out-of-range bench options, and build.sh building only the targets asked for.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <openvdb/version.h>

#include "support/test_paths.h"
#include "tools/file_kind.h"

namespace fs = std::filesystem;

namespace {

using vs::test::contains;
using vs::test::quote;
int cli(const std::string& args, std::string& out) { return vs::test::runCli(args, out); }

void writeFile(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

fs::path fogSphere() { return vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb"; }

std::string sceneOver(const fs::path& asset) {
  return R"({ "version": 1, "assets": { "ball": { "file": ")" + asset.string() + R"(" } },
  "instances": [ { "asset": "ball" } ],
  "camera": { "position": [3, 3, 3], "target": [0, 0, 0], "far": 20 },
  "lights": [ { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3],
                "shadow": { "resolution": 32, "cascades": 1 } } ] })";
}

// A sparse file of `bytes` zeros: no disk space, but a size no reader may take in whole.
fs::path sparseFile(const fs::path& p, std::uintmax_t bytes) {
  writeFile(p, "");
  fs::resize_file(p, bytes);
  return p;
}

}  // namespace

TEST(CliInputs, TheVdbMagicNumberIsOpenVdbs) { EXPECT_EQ(vs::kVdbMagic, std::uint32_t(openvdb::OPENVDB_MAGIC)); }

// A 10 GB sparse file of zeros named .vdb, .vox or .json is refused for its first bytes, at once.
TEST(CliInputs, FirstBytesAreCheckedBeforeTheSize) {
  fs::path dir = vs::test::scratchDir("inputs_magic");
  const std::uintmax_t tenGB = 10ull << 30;
  std::string out;
  EXPECT_EQ(cli("info " + quote(sparseFile(dir / "zeros.vdb", tenGB)), out), 2) << out;
  EXPECT_TRUE(contains(out, "zeros.vdb: not a .vdb file (its first bytes are 00 00 00 00 00 00 00 00;")) << out;
  EXPECT_FALSE(contains(out, "too large")) << out;
  EXPECT_EQ(cli("info " + quote(sparseFile(dir / "zeros.vox", tenGB)), out), 2) << out;
  EXPECT_TRUE(contains(out, "zeros.vox: not a MagicaVoxel .vox file (its first bytes are 00 00")) << out;
  EXPECT_FALSE(contains(out, "larger than 1 GiB")) << out;
  EXPECT_EQ(cli("info " + quote(sparseFile(dir / "zeros.json", tenGB)), out), 2) << out;
  EXPECT_TRUE(contains(out, "zeros.json: not a JSON scene file (its first bytes are 00 00")) << out;
  EXPECT_FALSE(contains(out, "bytes; a scene file may have at most")) << out;
  // A PNG renamed: its own first bytes are shown.
  writeFile(dir / "image.vdb", "\x89PNG\r\n\x1a\n and more");
  EXPECT_EQ(cli("info " + quote(dir / "image.vdb"), out), 2) << out;
  EXPECT_TRUE(contains(out, "image.vdb: not a .vdb file (its first bytes are 89 50 4e 47 0d 0a 1a 0a;")) << out;
  // Bake and render check the scene file and each asset the same way, naming the asset's field.
  writeFile(dir / "scene.json", sceneOver(dir / "zeros.vdb"));
  EXPECT_EQ(cli("info " + quote(dir / "scene.json"), out), 2) << out;
  EXPECT_TRUE(contains(out, "scene.json: assets.ball.file: " + (dir / "zeros.vdb").string() + ": not a .vdb file")) << out;
  for (const char* command : {"bake", "render"}) {
    SCOPED_TRACE(command);
    EXPECT_EQ(cli(std::string(command) + " " + quote(dir / "scene.json") + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2)
        << out;
    EXPECT_TRUE(contains(out, "scene.json: assets.ball.file: " + (dir / "zeros.vdb").string() + ": not a .vdb file")) << out;
    EXPECT_EQ(cli(std::string(command) + " " + quote(dir / "zeros.json") + " -o " + quote(dir / "o.exr") + " --backend cpu", out), 2)
        << out;
    EXPECT_TRUE(contains(out, "zeros.json: not a JSON scene file")) << out;
  }
  EXPECT_EQ(cli("convert " + quote(dir / "zeros.vox") + " " + quote(dir / "o.vdb"), out), 2) << out;
  EXPECT_TRUE(contains(out, "zeros.vox: not a MagicaVoxel .vox file")) << out;
  EXPECT_FALSE(fs::exists(dir / "o.exr"));
  EXPECT_FALSE(fs::exists(dir / "o.vdb"));
  // Real files still pass, scenes with leading white space too.
  writeFile(dir / "spaced.json", "\n  \t" + sceneOver(fogSphere()));
  EXPECT_EQ(cli("info " + quote(fogSphere()) + " " + quote(dir / "spaced.json"), out), 0) << out;
}

TEST(CliInputs, InfoReportsEveryFileAndFailsAtTheEnd) {
  fs::path dir = vs::test::scratchDir("inputs_info_many");
  writeFile(dir / "bad.vdb", "not a vdb");
  const fs::path missing = dir / "missing.vdb";
  std::string out;
  EXPECT_EQ(cli("info " + quote(fogSphere()) + " " + quote(dir / "bad.vdb") + " " + quote(missing) + " " +
                    quote(vs::test::sharedAssets() / "vdb" / "gaffer_levelset_sphere.vdb"),
                out),
            2) << out;
  EXPECT_TRUE(contains(out, "oiio_fog_sphere.vdb: 1 grid")) << out;
  EXPECT_TRUE(contains(out, "gaffer_levelset_sphere.vdb: ")) << out;  // the file after the bad ones
  EXPECT_TRUE(contains(out, "voxshadow: " + (dir / "bad.vdb").string() + ": not a .vdb file")) << out;
  EXPECT_TRUE(contains(out, "voxshadow: " + missing.string() + ": no such file")) << out;
  EXPECT_TRUE(contains(out, "info: 2 of 4 files could not be described")) << out;
  // In order: the good file's report comes before the error of the file after it.
  EXPECT_LT(out.find("oiio_fog_sphere.vdb: 1 grid"), out.find("bad.vdb: not a .vdb file")) << out;
  EXPECT_LT(out.find("bad.vdb: not a .vdb file"), out.find("gaffer_levelset_sphere.vdb: ")) << out;
  // --json: one document, with an entry per file.
  EXPECT_EQ(vs::test::runCommand(vs::test::cliPath() + " info --json " + quote(fogSphere()) + " " + quote(dir / "bad.vdb") +
                                     " 2>/dev/null",
                                 out),
            2) << out;
  EXPECT_TRUE(contains(out, "\"kind\": \"vdb\"")) << out;
  EXPECT_TRUE(contains(out, "\"error\": \"" + (dir / "bad.vdb").string() + ": not a .vdb file")) << out;
  // One file alone: its own error and exit status, nothing more.
  EXPECT_EQ(cli("info " + quote(missing), out), 2) << out;
  EXPECT_FALSE(contains(out, "could not be described")) << out;
}

TEST(CliInputs, OutputExtensionsMatchInAnyCase) {
  fs::path dir = vs::test::scratchDir("inputs_upper_case");
  writeFile(dir / "scene.json", sceneOver(fogSphere()));
  std::string out;
  EXPECT_EQ(cli("bake " + quote(dir / "scene.json") + " -o " + quote(dir / "O.EXR") + " --preview " + quote(dir / "P.Png") +
                    " --backend cpu", out),
            0) << out;
  EXPECT_EQ(cli("render " + quote(dir / "scene.json") + " -o " + quote(dir / "R.EXR") + " --backend cpu --width 32 --height 24", out),
            0) << out;
  EXPECT_EQ(cli("render " + quote(dir / "scene.json") + " -o " + quote(dir / "R.PNG") + " --backend cpu --width 32 --height 24", out),
            0) << out;
  for (const char* name : {"O.EXR", "P.Png", "R.EXR", "R.PNG"}) {
    SCOPED_TRACE(name);
    auto in = OIIO::ImageInput::open((dir / name).string());
    ASSERT_TRUE(in) << OIIO::geterror();
    const std::string format = in->format_name();
    EXPECT_EQ(format, std::string(name).find("EXR") != std::string::npos ? "openexr" : "png");
  }
  EXPECT_TRUE(fs::is_regular_file(dir / "O.EXR.json"));
  auto in = OIIO::ImageInput::open((dir / "R.EXR").string());
  ASSERT_TRUE(in);
  EXPECT_GT(in->spec().nchannels, 4) << "an upper-case .EXR render is the linear EXR with the G-buffer";
  EXPECT_EQ(cli("bake " + quote(dir / "scene.json") + " -o " + quote(dir / "O.TIF") + " --backend cpu", out), 2) << out;
  EXPECT_TRUE(contains(out, "O.TIF: the output must be an .exr file")) << out;
}

TEST(CliInputs, AMistypedCommandIsNamedWithTheNearestOne) {
  std::string out;
  EXPECT_EQ(cli("bakee scene.json", out), 2) << out;
  EXPECT_TRUE(contains(out, "unknown command 'bakee'; did you mean 'bake'?")) << out;
  EXPECT_FALSE(contains(out, "A subcommand is required")) << out;
  EXPECT_EQ(cli("rendr scene.json -o x.png", out), 2) << out;
  EXPECT_TRUE(contains(out, "did you mean 'render'?")) << out;
  EXPECT_EQ(cli("inof x.vdb", out), 2) << out;
  EXPECT_TRUE(contains(out, "did you mean 'info'?")) << out;
  EXPECT_EQ(cli("frobnicate", out), 2) << out;
  EXPECT_TRUE(contains(out, "unknown command 'frobnicate' (the commands are info, demo, bake")) << out;
  // Known commands and top-level flags are untouched.
  EXPECT_EQ(cli("--version", out), 0) << out;
  EXPECT_EQ(cli("info --help", out), 0) << out;
  EXPECT_EQ(cli("", out), 2) << out;
}

TEST(CliInputs, BenchRangeErrorsNameTheOption) {
  std::string out;
  EXPECT_EQ(cli("bench --resolution 8", out), 2) << out;
  EXPECT_TRUE(contains(out, "--resolution: must be between 16 and 16384, not 8")) << out;
  EXPECT_EQ(cli("bench --resolution 20000", out), 2) << out;
  EXPECT_TRUE(contains(out, "--resolution: must be between 16 and 16384, not 20000")) << out;
  EXPECT_EQ(cli("bench --reps 0", out), 2) << out;
  EXPECT_TRUE(contains(out, "--reps: must be between 1 and 1000, not 0")) << out;
  EXPECT_FALSE(contains(out, "--resolution")) << out;
  EXPECT_EQ(cli("bench --frame --reps 5000", out), 2) << out;
  EXPECT_TRUE(contains(out, "--reps: must be between 1 and 1000, not 5000")) << out;
  EXPECT_EQ(cli("bench --embree --reps 0", out), 2) << out;
  EXPECT_TRUE(contains(out, "--reps: must be between 1 and 1000, not 0")) << out;
  EXPECT_EQ(cli("bench --embree --resolution 8", out), 2) << out;
  EXPECT_TRUE(contains(out, "--resolution: must be between 16 and 16384, not 8")) << out;
  EXPECT_EQ(cli("bench --embree --frame", out), 2) << out;
  EXPECT_TRUE(contains(out, "--embree")) << out;
}

// build.sh passes the targets it is given to CMake (run-demo.sh: only the CLI), and builds everything
// without any (run-tests.sh). A stand-in cmake on PATH records what it was asked.
TEST(CliInputs, BuildScriptBuildsOnlyTheTargetsAskedFor) {
  fs::path dir = vs::test::scratchDir("inputs_build_sh");
  const fs::path bin = dir / "bin", log = dir / "cmake.log";
  fs::create_directories(bin);
  writeFile(bin / "cmake", "#!/bin/sh\necho \"$*\" >> '" + log.string() + "'\n");
  fs::permissions(bin / "cmake", fs::perms::owner_all);
  const fs::path root = VOXSHADOW_SOURCE_DIR;
  const std::string env = "PATH=" + quote(bin) + ":\"$PATH\" VOXSHADOW_BUILD_DIR=" + quote(dir / "b") + " ";
  auto builds = [&](const std::string& args) {
    fs::remove(log);
    std::string out;
    EXPECT_EQ(vs::test::runCommand(env + "bash " + quote(root / "tools" / "build.sh") + args, out), 0) << out;
    std::ifstream in(log);
    std::string configure, build;
    std::getline(in, configure);
    std::getline(in, build);
    return build;
  };
  const std::string demo = builds(" voxshadow");
  EXPECT_TRUE(contains(demo, "--build " + (dir / "b").string())) << demo;
  EXPECT_TRUE(contains(demo, "--target voxshadow")) << demo;
  const std::string all = builds("");
  EXPECT_TRUE(contains(all, "--build")) << all;
  EXPECT_FALSE(contains(all, "--target")) << all;
  // run-demo.sh asks for the CLI alone.
  std::ifstream demoScript(root / "tools" / "run-demo.sh");
  const std::string text((std::istreambuf_iterator<char>(demoScript)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(contains(text, "tools/build.sh\" voxshadow\n")) << text;
}
