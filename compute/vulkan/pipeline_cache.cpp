// pipeline_cache.cpp: loading and atomically saving the on-disk pipeline cache.
#include "compute/vulkan/pipeline_cache.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include <unistd.h>

namespace vs {
namespace {

// VkPipelineCacheHeaderVersionOne: length, version, vendorID, deviceID, then the 16-byte UUID.
constexpr std::size_t kHeaderBytes = 16 + VK_UUID_SIZE;
// Drivers' caches of one pipeline's few variants are kilobytes to a few megabytes; a larger file is not ours.
constexpr std::uintmax_t kMaxCacheBytes = 256ull << 20;

std::string hex(const std::uint8_t* bytes, std::size_t n) {
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (std::size_t i = 0; i < n; ++i) {
    s += digits[bytes[i] >> 4];
    s += digits[bytes[i] & 15];
  }
  return s;
}

}  // namespace

std::filesystem::path defaultPipelineCacheDir() {
  if (const char* d = std::getenv("VOXSHADOW_CACHE_DIR"); d && *d) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::filesystem::path(x) / "voxshadow";
  if (const char* h = std::getenv("HOME"); h && *h) return std::filesystem::path(h) / ".cache" / "voxshadow";
  return {};
}

DiskPipelineCache::DiskPipelineCache(VulkanContext& context, const std::filesystem::path& dir) : context_(context) {
  if (context.hostPipelineCache() != VK_NULL_HANDLE) return;  // the host's cache: the host keeps it
  const VulkanDeviceInfo& info = context.info();
  if (!dir.empty()) {
    char version[16];
    std::snprintf(version, sizeof version, "%08x", info.driverVersion);
    file_ = dir / ("pipelines-" + hex(info.pipelineCacheUuid.data(), VK_UUID_SIZE) + "-" + version + ".bin");
  }
  std::vector<char> data;
  if (!file_.empty()) {
    // Only a regular file is read (a FIFO would block the open forever, a directory cannot be read), and only
    // up to a size no driver's cache reaches: anything else is ignored here and reported when saving.
    std::error_code ec;
    std::filesystem::file_status st = std::filesystem::status(file_, ec);
    if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
      lastError_ = file_.string() + ": is not a regular file; the pipeline cache is not used";
      unusable_ = true;
    } else if (std::filesystem::is_regular_file(st)) {
      const std::uintmax_t bytes = std::filesystem::file_size(file_, ec);
      if (!ec && bytes <= kMaxCacheBytes) {
        std::ifstream in(file_, std::ios::binary);
        if (in) data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      }
    }
  }
  // Only hand the driver data it wrote itself; a header mismatch means another device or a damaged file.
  // A header-only file is valid: some drivers (lavapipe) keep no pipeline binaries at all.
  bool valid = data.size() >= kHeaderBytes &&
               std::memcmp(data.data() + 16, info.pipelineCacheUuid.data(), VK_UUID_SIZE) == 0;
  auto ci = vk::make<VkPipelineCacheCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO);
  if (valid) {
    ci.initialDataSize = data.size();
    ci.pInitialData = data.data();
  }
  VkPipelineCache cache = VK_NULL_HANDLE;
  VkResult r = context.functions().vkCreatePipelineCache(context.device(), &ci, context.functions().allocator, &cache);
  if (r != VK_SUCCESS && valid) {
    ci.initialDataSize = 0;
    ci.pInitialData = nullptr;
    valid = false;
    r = context.functions().vkCreatePipelineCache(context.device(), &ci, context.functions().allocator, &cache);
  }
  vk::check(r, "vkCreatePipelineCache");
  cache_ = vk::UniquePipelineCache(context.functions(), context.device(), cache);
  warm_ = valid && data.size() > kHeaderBytes;
  empty_ = valid && data.size() <= kHeaderBytes;
}

bool DiskPipelineCache::save() {
  if (!cache_) return true;  // the host's cache is the host's to keep
  if (file_.empty()) {
    lastError_ = "no cache directory (set VOXSHADOW_CACHE_DIR, XDG_CACHE_HOME or HOME)";
    return false;
  }
  if (unusable_) return false;  // lastError_ says why
  std::size_t size = 0;
  vk::check(context_.functions().vkGetPipelineCacheData(context_.device(), cache_.get(), &size, nullptr), "vkGetPipelineCacheData");
  std::vector<char> data(size);
  vk::check(context_.functions().vkGetPipelineCacheData(context_.device(), cache_.get(), &size, data.data()), "vkGetPipelineCacheData");
  data.resize(size);
  std::error_code ec;
  std::filesystem::create_directories(file_.parent_path(), ec);
  if (ec) {
    lastError_ = file_.parent_path().string() + ": " + ec.message();
    return false;
  }
  // A unique temporary name, so concurrent runs never interleave writes; rename replaces atomically.
  std::filesystem::path tmp = file_;
  tmp += ".tmp" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    out.close();
    if (!out) {
      lastError_ = tmp.string() + ": cannot write pipeline cache";
      std::filesystem::remove(tmp, ec);
      return false;
    }
  }
  std::filesystem::rename(tmp, file_, ec);
  if (ec) {
    lastError_ = file_.string() + ": " + ec.message();
    std::filesystem::remove(tmp, ec);
    return false;
  }
  return true;
}

}  // namespace vs
