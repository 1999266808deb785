// Fuzz target: the part files of sharded bakes (tools/bake_shards.h), read and merged. The first byte picks
// the form: odd, the input is the file as it is (magic, lengths, checksum); even, the input is a manifest, a
// NUL and the texel bytes, framed here with their true lengths and sha256, so that the fuzzer reaches the
// manifest's checks and the merge instead of stopping at the checksum. A refusal is vs::Error; any other
// exception, crash or sanitizer report is a defect.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>

#include "fuzz/scratch.h"
#include "tools/bake_shards.h"
#include "tools/sha256.h"
#include "voxel/error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::filesystem::path file = vs::fuzz::scratchDir() / "input.vspart";
  if (data[0] & 1) {
    vs::fuzz::writeInput(file, data + 1, size - 1);
  } else {
    const std::uint8_t* body = data + 1;
    const std::size_t bodySize = size - 1;
    const void* nul = std::memchr(body, 0, bodySize);
    const std::size_t manifest = nul ? std::size_t(static_cast<const std::uint8_t*>(nul) - body) : bodySize;
    const std::size_t texels = nul ? bodySize - manifest - 1 : 0;
    std::string bytes("voxshadow-part1\n");
    const std::uint64_t lengths[2] = {manifest, texels};
    bytes.append(reinterpret_cast<const char*>(lengths), sizeof(lengths));
    bytes.append(reinterpret_cast<const char*>(body), manifest);
    if (nul) bytes.append(reinterpret_cast<const char*>(body) + manifest + 1, texels);
    vs::Sha256 hash;
    hash.update(bytes.data(), bytes.size());
    const auto digest = hash.digest();
    bytes.append(reinterpret_cast<const char*>(digest.data()), digest.size());
    vs::fuzz::writeInput(file, reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  try {
    const vs::BakePart part = vs::readBakePart(file);
    (void)part;
    const std::filesystem::path parts[1] = {file};
    const std::vector<vs::BakedView> views = vs::mergeBakeParts(parts);
    vs::validateBakedViews(views);
  } catch (const vs::Error&) {
  }
  return 0;
}
