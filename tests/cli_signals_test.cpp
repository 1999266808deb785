// A bake killed at random moments (SIGINT, SIGTERM, SIGKILL) leaves the previous outputs whole, and no
// temporary survives: the killed process removes its own on every catchable terminating signal and dies by
// it, the next run removes those of a process killed by SIGKILL; a signal ignored at start-up stays ignored.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/resource.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "support/test_paths.h"
#include "tools/atomic_file.h"

namespace fs = std::filesystem;

namespace {

std::string readFile(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

// Two point lights at 512^2 and a sun at 1024^2 over the fog sphere: a bake whose trace and write phases
// both take a noticeable share of a second, so that random kills land in each.
void writeScene(const fs::path& scene, double sunX) {
  std::ofstream(scene) << R"({ "version": 1,
  "assets": { "ball": { "file": ")" << (vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string() << R"(" } },
  "instances": [ { "asset": "ball" }, { "asset": "ball", "translate": [1.2, 0.3, 0] } ],
  "lights": [ { "name": "sun", "type": "directional", "direction": [)" << sunX << R"(, -1, -0.3],
                "shadow": { "resolution": 1024 } },
              { "name": "a", "type": "point", "position": [0, 2, 1], "range": 9, "shadow": { "resolution": 512 } },
              { "name": "b", "type": "point", "position": [1, 2, -1], "range": 9, "shadow": { "resolution": 512 } } ] })";
}

struct Outputs {
  std::string exr, sidecar, preview;
  bool operator==(const Outputs&) const = default;
};

// The EXR's bytes with the write time (OpenEXR's "capDate" attribute, which OpenImageIO sets) blanked, so that
// two bakes of one scene compare equal.
std::string withoutWriteTime(std::string exr) {
  const std::string name("capDate\0string\0", 15);
  for (std::size_t at = exr.find(name); at != std::string::npos; at = exr.find(name, at + 1))
    for (std::size_t i = at + name.size(); i < std::min(exr.size(), at + name.size() + 4 + 19); ++i) exr[i] = '\0';
  return exr;
}

Outputs readOutputs(const fs::path& dir) {
  return {withoutWriteTime(readFile(dir / "out.exr")), readFile(dir / "out.exr.json"), readFile(dir / "out.png")};
}

// Starts `voxshadow bake scene -o dir/out.exr --preview dir/out.png --backend cpu`, output discarded.
pid_t startBake(const fs::path& scene, const fs::path& dir) {
  const std::string cli = vs::test::cliPath(), sceneArg = scene.string(), exr = (dir / "out.exr").string(),
                    png = (dir / "out.png").string();
  pid_t pid = ::fork();
  if (pid == 0) {
    int devnull = ::open("/dev/null", O_WRONLY);
    ::dup2(devnull, 1);
    ::dup2(devnull, 2);
    ::execl(cli.c_str(), cli.c_str(), "bake", sceneArg.c_str(), "-o", exr.c_str(), "--preview", png.c_str(),
            "--backend", "cpu", "--threads", "2", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

// Waits until the process has installed its handler for `sig` (bit sig-1 of SigCgt in /proc/<pid>/status;
// SIGINT's means it has finished loading its libraries and entered main), or has ended. The random kills then
// fall into the work itself, however long the start takes on a loaded machine. The handlers go in one by one,
// so a test that looks at one signal waits for that one.
void waitUntilHandling(pid_t pid, int sig = SIGINT) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    std::ifstream status("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    bool zombie = false, handling = false;
    while (std::getline(status, line)) {
      if (line.rfind("State:", 0) == 0) zombie = line.find('Z') != std::string::npos;
      if (line.rfind("SigCgt:", 0) == 0) handling = (std::stoull(line.substr(7), nullptr, 16) >> (sig - 1)) & 1u;
    }
    if (zombie || handling || !status.eof()) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

int waitStatus(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

std::vector<std::string> temporaries(const fs::path& dir) {
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir))
    if (vs::temporaryWriterPid(e.path().filename().string())) found.push_back(e.path().filename().string());
  return found;
}

}  // namespace

TEST(CliSignals, KilledBakesLeaveWholeOutputsAndNoTemporaries) {
  fs::path dir = vs::test::scratchDir("signals");
  fs::path sceneA = dir / "a.json", sceneB = dir / "b.json";
  writeScene(sceneA, -0.4);
  writeScene(sceneB, 0.4);

  // The two possible complete states, and how long a bake works once started.
  pid_t pid = startBake(sceneB, dir);
  waitUntilHandling(pid);
  auto t0 = std::chrono::steady_clock::now();
  int status = waitStatus(pid);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  const Outputs b = readOutputs(dir);
  ASSERT_EQ(WEXITSTATUS(waitStatus(startBake(sceneA, dir))), 0);
  const Outputs a = readOutputs(dir);
  ASSERT_FALSE(a.exr == b.exr || a.sidecar == b.sidecar || a.preview == b.preview);
  ASSERT_EQ(WEXITSTATUS(waitStatus(startBake(sceneA, dir))), 0);
  ASSERT_TRUE(readOutputs(dir) == a) << "a bake's outputs are not reproducible; the test cannot tell them apart";

  std::mt19937 rng(20261201);
  std::uniform_real_distribution<double> when(0.0, seconds);
  int interruptedExits = 0, killedDuringWork = 0;
  // 15 rounds, 5 of each signal: each costs two bakes, and the suite has a time budget.
  for (int round = 0; round < 15; ++round) {
    const int sig = round % 3 == 0 ? SIGINT : round % 3 == 1 ? SIGKILL : SIGTERM;
    SCOPED_TRACE("round " + std::to_string(round) + ", signal " + std::to_string(sig));
    // Each round starts from A's outputs (the previous round ends with them) and interrupts a bake of B.
    pid = startBake(sceneB, dir);
    waitUntilHandling(pid);
    const double delay = when(rng);
    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
    ::kill(pid, sig);
    status = waitStatus(pid);
    const bool finished = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (!finished) ++killedDuringWork;
    if (sig == SIGKILL) {
      EXPECT_TRUE(finished || (WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL));
    } else {
      // The handler removes the temporaries and ends the process by the same signal.
      const bool handled = WIFSIGNALED(status) && WTERMSIG(status) == sig;
      EXPECT_TRUE(finished || handled) << "status " << status << " after " << delay << " s of " << seconds;
      if (handled) ++interruptedExits;
      EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
    }
    const Outputs now = readOutputs(dir);
    EXPECT_TRUE(now == a || now == b) << "outputs of two bakes mixed, or one of them partial";
    if (finished) {
      EXPECT_TRUE(now == b);
    }
    // The next run into the directory removes what a SIGKILL left, whether it then completes or not.
    ASSERT_EQ(WEXITSTATUS(waitStatus(startBake(sceneA, dir))), 0);
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
    EXPECT_TRUE(readOutputs(dir) == a);
  }
  // The kills must really have landed while work was going on, not only after it.
  std::printf("15 rounds: %d ended by their signal during work, %d of them by the handler\n", killedDuringWork,
              interruptedExits);
  EXPECT_GE(killedDuringWork, 8);
  EXPECT_GE(interruptedExits, 5);
}

namespace {

// One 1024^2 sun layer over the fog sphere and a preview: a short bake whose write still takes a while.
void writeSmallScene(const fs::path& scene) {
  std::ofstream(scene) << R"({ "version": 1,
  "assets": { "ball": { "file": ")" << (vs::test::sharedAssets() / "vdb" / "oiio_fog_sphere.vdb").string() << R"(" } },
  "instances": [ { "asset": "ball" } ],
  "lights": [ { "name": "sun", "type": "directional", "direction": [-0.4, -1, -0.3], "shadow": { "resolution": 1024 } } ] })";
}

// Starts the CPU bake of `scene` into dir/out.exr (+ dir/out.png) with `ignored` set to SIG_IGN (0: none), as
// a shell does for a job started with `&`. No core files: some of the signals dump core by default.
pid_t startBakeIgnoring(const fs::path& scene, const fs::path& dir, int ignored) {
  const std::string cli = vs::test::cliPath(), sceneArg = scene.string(), exr = (dir / "out.exr").string(),
                    png = (dir / "out.png").string();
  pid_t pid = ::fork();
  if (pid == 0) {
    int devnull = ::open("/dev/null", O_WRONLY);
    ::dup2(devnull, 1);
    ::dup2(devnull, 2);
    struct rlimit noCore {0, 0};
    ::setrlimit(RLIMIT_CORE, &noCore);
    if (ignored != 0) ::signal(ignored, SIG_IGN);
    ::execl(cli.c_str(), cli.c_str(), "bake", sceneArg.c_str(), "-o", exr.c_str(), "--preview", png.c_str(),
            "--backend", "cpu", "--threads", "2", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

// The signal masks of /proc/<pid>/status (SigCgt: caught, SigIgn: ignored).
std::uint64_t signalMask(pid_t pid, const std::string& field) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind(field + ":", 0) == 0) return std::stoull(line.substr(field.size() + 1), nullptr, 16);
  return 0;
}

bool maskHas(std::uint64_t mask, int sig) { return (mask >> (sig - 1)) & 1u; }

// Waits until a temporary with content exists in dir (a write is under way) or the process has ended;
// true in the first case.
bool waitForWrite(pid_t pid, const fs::path& dir) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (vs::temporaryWriterPid(e.path().filename().string()) && e.file_size(ec) > 0 && !ec) return true;
    siginfo_t info{};
    if (::waitid(P_PID, id_t(pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == pid) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return false;
}

}  // namespace

TEST(CliSignals, EveryTerminatingSignalDuringAWriteRemovesTheTemporariesAndEndsByThatSignal) {
  fs::path dir = vs::test::scratchDir("signals_every");
  fs::path scene = dir / "scene.json";
  writeSmallScene(scene);
  const std::vector<int> expected = vs::cleanupSignals();
  const int signals[] = {SIGHUP,  SIGINT,  SIGQUIT, SIGABRT,   SIGTERM, SIGPIPE, SIGALRM, SIGUSR1, SIGUSR2,
                         SIGXCPU, SIGXFSZ, SIGVTALRM, SIGPROF, SIGIO,   SIGPWR,  SIGRTMIN};
  for (int sig : signals) {
    SCOPED_TRACE(std::string("signal ") + std::to_string(sig) + " (" + ::strsignal(sig) + ")");
    EXPECT_NE(std::find(expected.begin(), expected.end(), sig), expected.end());
    bool landed = false;
    // A run may finish before the poll sees its write; a few tries make the signal land in one.
    for (int attempt = 0; attempt < 4 && !landed; ++attempt) {
      pid_t pid = startBakeIgnoring(scene, dir, 0);
      waitUntilHandling(pid, sig);
      EXPECT_TRUE(maskHas(signalMask(pid, "SigCgt"), sig)) << "no handler installed";
      landed = waitForWrite(pid, dir);
      if (landed) ::kill(pid, sig);
      const int status = waitStatus(pid);
      if (landed) {
        EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "status " << status;
        EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
        EXPECT_FALSE(fs::exists(dir / "out.exr")) << "an output of the interrupted bake was committed";
      } else {
        ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
      }
      fs::remove(dir / "out.exr");
      fs::remove(dir / "out.exr.json");
      fs::remove(dir / "out.png");
    }
    EXPECT_TRUE(landed) << "no run was caught writing";
  }
}

TEST(CliSignals, ASignalIgnoredAtStartUpStaysIgnored) {
  fs::path dir = vs::test::scratchDir("signals_ignored");
  fs::path scene = dir / "scene.json";
  writeSmallScene(scene);
  for (int sig : {SIGINT, SIGHUP}) {
    SCOPED_TRACE(std::string("signal ") + std::to_string(sig));
    pid_t pid = startBakeIgnoring(scene, dir, sig);
    // Handling: SIGTERM's handler is in place (SIGINT, the usual mark, is the ignored one here).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!maskHas(signalMask(pid, "SigCgt"), SIGTERM) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_FALSE(maskHas(signalMask(pid, "SigCgt"), sig)) << "a handler replaced SIG_IGN";
    EXPECT_TRUE(maskHas(signalMask(pid, "SigIgn"), sig));
    // A Ctrl-C (or a hang-up) meant for another job, in the middle of the write: the bake carries on.
    const bool writing = waitForWrite(pid, dir);
    ::kill(pid, sig);
    const int status = waitStatus(pid);
    EXPECT_TRUE(writing) << "the bake ended before its write was seen";
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
    EXPECT_TRUE(fs::is_regular_file(dir / "out.exr"));
    EXPECT_TRUE(fs::is_regular_file(dir / "out.png"));
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
  }
}
