// voxshadow: the command-line front end. Exit status 0 success, 1 runtime failure, 2 bad usage or bad input.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <exception>
#include <iostream>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "tools/atomic_file.h"
#include "tools/commands.h"
#include "voxel/error.h"
#include "voxel/voxel_object.h"

namespace {

int fail(int status, const std::string& message) {
  std::cout.flush();
  std::cerr << "voxshadow: " << message << "\n";
  return status;
}

// Edits (insertions, deletions, substitutions, swaps of neighbours) between two words: how far a typo is.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The first word that is not an option names the command (the top level takes no option with a value).
// CLI11 would take an unknown one for a stray argument and only say that a subcommand is required.
std::optional<std::string> unknownCommand(const CLI::App& app, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (!word.empty() && word[0] == '-') {
      if (word == "--") return std::nullopt;
      continue;
    }
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands({})) names.push_back(sub->get_name());
    if (std::find(names.begin(), names.end(), word) != names.end()) return std::nullopt;
    std::string best;
    std::size_t bestDistance = 3;  // more than two edits away is another word, not a typo
    for (const std::string& name : names) {
      std::string lower = word;
      for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
      const std::size_t d = editDistance(lower, name);
      if (d < bestDistance && d < name.size()) {
        bestDistance = d;
        best = name;
      }
    }
    std::string message = "unknown command '" + word + "'";
    if (!best.empty()) return message + "; did you mean '" + best + "'?";
    std::string list;
    for (const std::string& name : names) list += (list.empty() ? "" : ", ") + name;
    return message + " (the commands are " + list + "; run with --help for usage)";
  }
  return std::nullopt;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"voxshadow: ray-traced shadows for voxel scenes (OpenVDB assets, CPU and Vulkan backends)"};
  app.name("voxshadow");
  app.set_version_flag("--version", std::string("voxshadow ") + VOXSHADOW_VERSION);
  app.require_subcommand(1);
  // Before anything can write a temporary: a command ended by a signal removes its temporaries first.
  vs::installSignalCleanup();
  // Before any other thread works: .vdb checks must never fork a process whose threads may hold locks.
  try {
    vs::startVdbCheckingProcess();
  } catch (const vs::Error&) {
    // Checks fork per file instead; a fork that fails there is reported with the file it was for.
  }
  vs::cli::registerInfo(app);
  vs::cli::registerDemo(app);
  vs::cli::registerBake(app);
  vs::cli::registerMerge(app);
  vs::cli::registerRender(app);
  vs::cli::registerBench(app);
  vs::cli::registerConvert(app);
  if (std::optional<std::string> unknown = unknownCommand(app, argc, argv)) return fail(2, *unknown);
  try {
    // Subcommand callbacks run inside parse(), so their exceptions arrive here too.
    app.parse(argc, argv);
    return 0;
  } catch (const CLI::ParseError& e) {
    // Help and version requests are ParseErrors with exit code 0; CLI11 prints them (for the chosen
    // subcommand where there is one).
    if (e.get_exit_code() == 0) return app.exit(e);
    return fail(2, std::string(e.what()) + " (run with --help for usage)");
  } catch (const vs::Error& e) {
    return fail(e.kind() == vs::ErrorKind::BadInput ? 2 : 1, e.what());
  } catch (const std::bad_alloc&) {
    return fail(1, "out of memory");
  } catch (const std::exception& e) {
    return fail(1, e.what());
  }
}
