// voxshadow: the command-line front end. Exit status 0 success, 1 runtime failure, 2 bad usage or bad input.
#include <cstdio>
#include <exception>
#include <iostream>
#include <new>

#include <CLI/CLI.hpp>

#include "tools/atomic_file.h"
#include "tools/commands.h"
#include "voxel/error.h"

namespace {

int fail(int status, const std::string& message) {
  std::cout.flush();
  std::cerr << "voxshadow: " << message << "\n";
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"voxshadow: ray-traced shadows for voxel scenes (OpenVDB assets, CPU and Vulkan backends)"};
  app.name("voxshadow");
  app.set_version_flag("--version", std::string("voxshadow ") + VOXSHADOW_VERSION);
  app.require_subcommand(1);
  // Before anything can write a temporary: an interrupted command removes its temporaries and exits 130/143.
  vs::installSignalCleanup();
  vs::cli::registerInfo(app);
  vs::cli::registerDemo(app);
  vs::cli::registerBake(app);
  vs::cli::registerRender(app);
  vs::cli::registerBench(app);
  vs::cli::registerConvert(app);
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
