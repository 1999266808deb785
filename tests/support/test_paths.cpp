#include "support/test_paths.h"

#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include <gtest/gtest.h>
#include <stdexcept>
#include <sys/wait.h>
#include <unistd.h>

namespace vs::test {

std::filesystem::path sharedAssets() {
  std::filesystem::path dir;
  if (const char* env = std::getenv("VOXSHADOW_ASSETS")) {
    dir = env;
  } else {
    dir = std::filesystem::path(VOXSHADOW_SOURCE_DIR) / ".." / "shared" / "assets";
  }
  if (!std::filesystem::is_directory(dir / "vdb")) {
    throw std::runtime_error("third-party assets not found at " + dir.string() +
                             " (expected ../shared/assets beside the source tree, or set VOXSHADOW_ASSETS)");
  }
  return std::filesystem::canonical(dir);
}

std::filesystem::path scratchDir(const std::string& name) {
  // ctest runs test cases of one executable in parallel processes: the process id keeps them apart.
  auto dir = std::filesystem::temp_directory_path() / "voxshadow-tests" / (name + "-" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string cliPath() { return VOXSHADOW_CLI; }

int runCommand(const std::string& command, std::string& output) {
  output.clear();
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) throw std::runtime_error("popen failed for: " + command);
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe)) output += buffer.data();
  int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string quote(const std::filesystem::path& p) {
  // Appending keeps GCC 12's -Wrestrict false positive on chained string operator+ away.
  std::string q(1, '\'');
  q += p.string();
  q += '\'';
  return q;
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

int runCli(const std::string& args, std::string& output) { return runCommand(cliPath() + " " + args, output); }

std::filesystem::path unwritableDir(const std::filesystem::path& scratch) {
  namespace fs = std::filesystem;
  fs::permissions(scratch, fs::perms::owner_read | fs::perms::owner_exec);
  const fs::path probe = scratch / "probe";
  if (!std::ofstream(probe)) return scratch;
  fs::remove(probe);
  fs::permissions(scratch, fs::perms::owner_all);
  const fs::path sys = "/sys";
  if (fs::is_directory(sys) && !std::ofstream(sys / "voxshadow-probe")) return sys;
  ADD_FAILURE() << "no directory refuses new files to this process";
  return scratch;
}

std::vector<std::string> leftovers(const std::filesystem::path& dir, const std::string& stem) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    std::string n = e.path().filename().string();
    if (n.find(stem) != std::string::npos) names.push_back(n);
  }
  return names;
}

}  // namespace vs::test
