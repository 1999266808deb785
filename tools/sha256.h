// sha256.h: SHA-256 (FIPS 180-4), to name the exact inputs of a bake in its part files: two shards are parts of
// one bake only when they saw byte-identical scene and asset files.
#ifndef VOXSHADOW_TOOLS_SHA256_H
#define VOXSHADOW_TOOLS_SHA256_H

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

namespace vs {

// Incremental hashing: update() any number of times, then digest() once.
class Sha256 {
 public:
  Sha256();
  void update(std::span<const std::uint8_t> bytes);
  void update(const void* data, std::size_t size) {
    update(std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(data), size));
  }
  // The 32-byte digest. Precondition: called once; the object is spent afterwards.
  std::array<std::uint8_t, 32> digest();

 private:
  void compress(const std::uint8_t* block);
  std::array<std::uint32_t, 8> state_;
  std::array<std::uint8_t, 64> buffer_{};
  std::size_t buffered_ = 0;
  std::uint64_t totalBytes_ = 0;
};

// Lower-case hexadecimal of a digest.
std::string toHex(std::span<const std::uint8_t> bytes);

// The hex digest of a byte string.
std::string sha256Hex(std::span<const std::uint8_t> bytes);

// The hex digest of a file's bytes, read in chunks. Throws vs::Error(BadInput) naming the file when it cannot
// be opened or read.
std::string sha256File(const std::filesystem::path& file);

}  // namespace vs

#endif
