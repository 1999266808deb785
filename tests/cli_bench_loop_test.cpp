// bench --loop: the scripted game loop on both backends (small frames and shadow layers), its `loop ...` lines,
// its CSV, its plot, and the options it refuses before any work.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "support/test_paths.h"

namespace fs = std::filesystem;

namespace {

using vs::test::contains;
using vs::test::quote;
int cli(const std::string& args, std::string& out) { return vs::test::runCli(args, out); }

// 320x180 frames and shadow layers an eighth of the demo's side keep a run of both backends to seconds.
const std::string kQuick = "bench --loop --frames 3 --full-every 3 --size 320x180 --shadow-divisor 8";
const char* const kPhases[] = {"still", "pan", "actor", "dig", "sun"};

struct LoopLine {
  int frames = 0;
  double medianMs = 0.0, p99Ms = 0.0, fullMedianMs = 0.0, share = 0.0;
  unsigned long long texels = 0, rays = 0, uploaded = 0, readback = 0;
};

// (backend, phase) -> its line; every line that starts with "loop " must parse.
std::map<std::pair<std::string, std::string>, LoopLine> loopLines(const std::string& out) {
  static const std::regex line(
      R"(loop (cpu|vulkan) (still|pan|actor|dig|sun) frames=(\d+) median_ms=([0-9.]+) p99_ms=([0-9.]+) )"
      R"(full_median_ms=([0-9.]+) texels=(\d+) texel_share=([0-9.]+) rays=(\d+) uploaded=(\d+) readback=(\d+))");
  std::map<std::pair<std::string, std::string>, LoopLine> lines;
  std::istringstream in(out);
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("loop ", 0) != 0) continue;
    std::smatch m;
    if (!std::regex_match(l, m, line)) {
      ADD_FAILURE() << "unparsed: " << l;
      continue;
    }
    LoopLine v;
    v.frames = std::stoi(m[3]);
    v.medianMs = std::stod(m[4]);
    v.p99Ms = std::stod(m[5]);
    v.fullMedianMs = std::stod(m[6]);
    v.texels = std::stoull(m[7]);
    v.share = std::stod(m[8]);
    v.rays = std::stoull(m[9]);
    v.uploaded = std::stoull(m[10]);
    v.readback = std::stoull(m[11]);
    EXPECT_TRUE(lines.insert({{m[1], m[2]}, v}).second) << "twice: " << l;
  }
  return lines;
}

std::vector<std::vector<std::string>> readCsv(const fs::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(file);
  for (std::string l; std::getline(in, l);) {
    std::vector<std::string> cells;
    std::istringstream cs(l);
    for (std::string c; std::getline(cs, c, ',');) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

TEST(CliBenchLoop, BothBackendsReportEveryPhaseAndWriteEveryFrame) {
  const fs::path dir = vs::test::scratchDir("cli_bench_loop");
  const fs::path csv = dir / "x.csv";
  std::string out;
  ASSERT_EQ(cli(kQuick + " --vulkan --csv " + quote(csv), out), 0) << out;

  const auto lines = loopLines(out);
  ASSERT_EQ(lines.size(), 10u) << out;
  for (const char* backend : {"cpu", "vulkan"})
    for (const char* phase : kPhases) {
      ASSERT_TRUE(lines.count({backend, phase})) << backend << " " << phase << "\n" << out;
      const LoopLine& l = lines.at({backend, phase});
      EXPECT_EQ(l.frames, 3) << backend << " " << phase;
      EXPECT_GT(l.medianMs, 0.0) << backend << " " << phase;
      EXPECT_GE(l.p99Ms, l.medianMs) << backend << " " << phase;
      EXPECT_GT(l.fullMedianMs, 0.0) << backend << " " << phase;
      EXPECT_LE(l.share, 100.0) << backend << " " << phase;
      EXPECT_GE(l.rays, l.texels) << backend << " " << phase;
      if (std::string(backend) == "cpu") {
        EXPECT_EQ(l.uploaded, 0u) << phase;  // the CPU backend moves nothing to a device
        EXPECT_EQ(l.readback, 0u) << phase;
      }
      if (std::string(phase) == "still") {
        // Nothing changed: nothing traced, nothing moved.
        EXPECT_EQ(l.texels, 0u) << backend;
        EXPECT_EQ(l.rays, 0u) << backend;
        EXPECT_EQ(l.uploaded, 0u) << backend;
        EXPECT_EQ(l.readback, 0u) << backend;
      } else {
        // The last pan frame moves a whole texel; the actor, the edits and the sun change what the sun sees.
        EXPECT_GT(l.texels, 0u) << backend << " " << phase;
      }
    }
  // The sun's cascades are most of the layer texels, and they all follow the sun.
  EXPECT_GT(lines.at({"cpu", "sun"}).share, 50.0);
  if (const char* v = std::getenv("VOXSHADOW_VALIDATION"); v && std::string(v) == "1") {
    EXPECT_TRUE(contains(out, "vulkan: validation messages: 0")) << out;
  }

  const auto rows = readCsv(csv);
  ASSERT_FALSE(rows.empty());
  const std::vector<std::string> header = {"backend", "phase", "frame", "kind", "ms", "scene_ms", "shadow_ms",
                                           "gbuffer_ms", "visibility_ms", "lighting_ms", "texels", "primary",
                                           "visibility", "pixels_shaded", "uploaded", "readback", "dispatches"};
  EXPECT_EQ(rows[0], header);
  // Per backend and phase: frames 0, 1, 2 incremental, then frame 2 again forced full.
  ASSERT_EQ(rows.size(), 1u + 2u * 5u * 4u);
  std::set<std::string> seen;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const auto& r = rows[i];
    ASSERT_EQ(r.size(), header.size()) << "row " << i;
    const std::size_t k = (i - 1) % 4;
    const std::string backend = (i - 1) < 20 ? "cpu" : "vulkan";
    const std::string phase = kPhases[((i - 1) / 4) % 5];
    EXPECT_EQ(r[0], backend) << "row " << i;
    EXPECT_EQ(r[1], phase) << "row " << i;
    EXPECT_EQ(r[2], std::to_string(k < 3 ? k : 2)) << "row " << i;
    EXPECT_EQ(r[3], k < 3 ? "incremental" : "full") << "row " << i;
    EXPECT_GT(std::stod(r[4]), 0.0) << "row " << i;
    if (k == 3) {
      EXPECT_GT(std::stoull(r[10]), 0u) << "row " << i;         // a full frame traces every layer
      EXPECT_EQ(r[11], std::to_string(320 * 180)) << "row " << i;  // and every primary ray
      EXPECT_EQ(r[13], std::to_string(320 * 180)) << "row " << i;  // and shades every pixel
    }
    if (phase == "still" && k < 3) {
      EXPECT_EQ(r[10], "0") << "row " << i;
      EXPECT_EQ(r[11], "0") << "row " << i;
      EXPECT_EQ(r[12], "0") << "row " << i;
    }
    seen.insert(r[0] + r[1] + r[2] + r[3]);
  }
  EXPECT_EQ(seen.size(), 40u);
  EXPECT_TRUE(vs::test::leftovers(dir, ".x.csv").empty());
  fs::remove_all(dir);
}

TEST(CliBenchLoop, PlotsTheCsvOrNamesThePackageToInstall) {
  const fs::path dir = vs::test::scratchDir("cli_bench_loop_plot");
  const fs::path csv = dir / "p.csv", png = dir / "p.png";
  std::string out;
  std::string probe;
  const bool matplotlib =
      vs::test::runCommand("/usr/bin/python3 -c 'import matplotlib' || python3 -c 'import matplotlib'", probe) == 0;
  const int rc = cli(kQuick + " --csv " + quote(csv) + " --plot " + quote(png), out);
  if (matplotlib) {
    ASSERT_EQ(rc, 0) << out;
    std::ifstream in(png, std::ios::binary);
    char signature[8] = {};
    in.read(signature, 8);
    EXPECT_EQ(std::string(signature + 1, 3), "PNG") << out;
    EXPECT_TRUE(fs::exists(csv));
  } else {
    // Refused before any work: a clear runtime failure naming the Debian package, nothing written.
    EXPECT_EQ(rc, 1) << out;
    EXPECT_TRUE(contains(out, "python3-matplotlib")) << out;
    EXPECT_FALSE(fs::exists(csv));
    EXPECT_FALSE(fs::exists(png));
  }
  fs::remove_all(dir);
}

TEST(CliBenchLoop, BadOptionsExitTwoBeforeAnyWork) {
  const fs::path dir = vs::test::scratchDir("cli_bench_loop_bad");
  const fs::path csv = dir / "bad.csv";
  const std::string to = " --csv " + quote(csv);
  struct Case {
    std::string args, message;
  };
  const std::vector<Case> cases = {
      {"bench --loop --frames 0" + to, "--frames: must be between 1 and 100000, not 0"},
      {"bench --loop --frames 100001" + to, "--frames: must be between 1 and 100000"},
      {"bench --loop --frames x" + to, "--frames"},
      {"bench --loop --full-every 0" + to, "--full-every: must be between 1 and 100000, not 0"},
      {"bench --loop --frame" + to, "excludes"},
      {"bench --loop --reps 3" + to, "excludes"},
      {"bench --frames 3" + to, "requires --loop"},
      {"bench --loop --plot " + quote(dir / "p.jpg") + to, "must end in .png"},
      {"bench --loop --plot " + quote(dir / "bad.png") + " --csv " + quote(dir / "bad.png"), "bad.png"},
      {"bench --loop --csv " + quote(dir / "missing" / "bad.csv"), "does not exist"},
      {"bench --loop --size 320" + to, "--size 320: must be WxH"},
  };
  for (const Case& c : cases) {
    std::string out;
    EXPECT_EQ(cli(c.args, out), 2) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, c.message)) << c.args << "\n" << out;
    EXPECT_FALSE(fs::exists(csv)) << c.args;
    EXPECT_FALSE(fs::exists(dir / "bad.png")) << c.args;
  }
  fs::remove_all(dir);
}

}  // namespace
