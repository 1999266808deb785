#include "tools/atomic_file.h"

#include <atomic>
#include <string>
#include <system_error>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>
#include <vector>

#include "voxel/error.h"

namespace vs {

namespace fs = std::filesystem;

fs::path temporarySibling(const fs::path& out) {
  static std::atomic<unsigned> counter{0};
  // A leading dot keeps the temporary out of casual listings; the pid and counter keep concurrent writers
  // (several processes or threads baking into one directory) from colliding.
  std::string name(1, '.');
  name += out.stem().string();
  name += ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(counter.fetch_add(1));
  name += out.extension().string();
  return out.parent_path() / name;
}

void checkOutputDirectory(const fs::path& out) {
  fs::path dir = out.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::exists(dir, ec)) throwBadInput(out.string() + ": output directory " + dir.string() + " does not exist");
  if (!fs::is_directory(dir, ec)) throwBadInput(out.string() + ": " + dir.string() + " is not a directory");
  if (fs::is_directory(out, ec)) throwBadInput(out.string() + ": is a directory");
  // Permission bits do not tell the whole story (root, ACLs, read-only mounts, pseudo file systems):
  // creating a file is the only reliable test.
  const fs::path probe = temporarySibling(out);
  int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    int err = errno;
    throwBadInput(out.string() + ": output directory " + dir.string() + " is not writable (" +
                  std::strerror(err) + ")");
  }
  ::close(fd);
  ::unlink(probe.c_str());
}

void writeAtomically(std::span<const fs::path> outputs,
                     const std::function<void(std::size_t, const fs::path&)>& write) {
  std::vector<fs::path> temps;
  std::vector<fs::path> renamed;
  auto cleanup = [&] {
    std::error_code ignored;
    for (const auto& t : temps) fs::remove(t, ignored);
    for (const auto& r : renamed) fs::remove(r, ignored);
  };
  try {
    for (std::size_t i = 0; i < outputs.size(); ++i) {
      temps.push_back(temporarySibling(outputs[i]));
      write(i, temps.back());
      if (!fs::is_regular_file(temps.back()))
        throwRuntime(outputs[i].string() + ": the writer produced no file");
    }
    for (std::size_t i = 0; i < outputs.size(); ++i) {
      std::error_code ec;
      fs::rename(temps[i], outputs[i], ec);
      if (ec) throwRuntime(outputs[i].string() + ": cannot rename the temporary file into place: " + ec.message());
      renamed.push_back(outputs[i]);
    }
  } catch (...) {
    cleanup();
    throw;
  }
}

}  // namespace vs
