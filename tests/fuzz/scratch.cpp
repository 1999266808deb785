#include "fuzz/scratch.h"

#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include <unistd.h>

namespace vs::fuzz {

namespace {

std::filesystem::path* dir = nullptr;

void removeScratch() {
  std::error_code ec;
  if (dir) std::filesystem::remove_all(*dir, ec);
}

}  // namespace

const std::filesystem::path& scratchDir() {
  if (!dir) {
    dir = new std::filesystem::path(std::filesystem::temp_directory_path() /
                                    ("voxshadow-fuzz-" + std::to_string(getpid())));
    std::filesystem::create_directories(*dir);
    std::atexit(removeScratch);
  }
  return *dir;
}

void writeInput(const std::filesystem::path& file, const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(file.c_str(), "wb");
  if (!f) throw std::runtime_error("cannot write " + file.string());
  const bool ok = size == 0 || std::fwrite(data, 1, size, f) == size;
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error("cannot write " + file.string());
}

}  // namespace vs::fuzz
