#include "support/test_paths.h"

#include <array>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <sys/wait.h>

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
  auto dir = std::filesystem::temp_directory_path() / "voxshadow-tests" / name;
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

}  // namespace vs::test
