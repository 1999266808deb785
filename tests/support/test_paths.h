// test_paths.h: where tests find the third-party assets, scratch space and the CLI.
#ifndef VOXSHADOW_TEST_PATHS_H
#define VOXSHADOW_TEST_PATHS_H

#include <filesystem>
#include <string>

namespace vs::test {

// ../shared/assets beside the source tree (or $VOXSHADOW_ASSETS). Fails the calling test with a clear
// message when the folder is missing: never skips.
std::filesystem::path sharedAssets();

// A fresh, empty scratch directory for one test (under the build tree's temp area).
std::filesystem::path scratchDir(const std::string& name);

// The voxshadow CLI built beside the tests.
std::string cliPath();

// Runs a shell command, returns its exit status; stdout+stderr captured into `output`.
int runCommand(const std::string& command, std::string& output);

}  // namespace vs::test

#endif
