// test_paths.h: where tests find the third-party assets, scratch space and the CLI.
#ifndef VOXSHADOW_TEST_PATHS_H
#define VOXSHADOW_TEST_PATHS_H

#include <filesystem>
#include <string>
#include <vector>

namespace vs::test {

// ../shared/assets beside the source tree (or $VOXSHADOW_ASSETS). Fails the calling test with a clear
// message when the folder is missing: never skips.
std::filesystem::path sharedAssets();

// A fresh, empty scratch directory for one test process (under the system temp directory).
std::filesystem::path scratchDir(const std::string& name);

// The voxshadow CLI built beside the tests.
std::string cliPath();

// Runs a shell command, returns its exit status; stdout+stderr captured into `output`.
int runCommand(const std::string& command, std::string& output);

// A path in single quotes for a shell command line (test paths hold no quotes).
std::string quote(const std::filesystem::path& p);

// Whether `haystack` contains `needle`.
bool contains(const std::string& haystack, const std::string& needle);

// Runs the CLI with `args` (a shell-quoted argument string); returns its exit status.
int runCli(const std::string& args, std::string& output);

// A directory in which this process cannot create files: `scratch` made read-only, or, for root (whom
// permission bits do not bind), sysfs's top directory. Adds a test failure when neither refuses files.
std::filesystem::path unwritableDir(const std::filesystem::path& scratch);

// Entries of dir whose names contain stem (an output or its temporaries).
std::vector<std::string> leftovers(const std::filesystem::path& dir, const std::string& stem);

}  // namespace vs::test

#endif
