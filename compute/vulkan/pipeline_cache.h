// pipeline_cache.h: a Vulkan pipeline cache kept on disk, so a second run skips the shader JIT.
#ifndef VOXSHADOW_PIPELINE_CACHE_H
#define VOXSHADOW_PIPELINE_CACHE_H

#include <filesystem>
#include <string>

#include "compute/vulkan/vulkan_context.h"

namespace vs {

// $VOXSHADOW_CACHE_DIR, else $XDG_CACHE_HOME/voxshadow, else $HOME/.cache/voxshadow (empty when none is set).
std::filesystem::path defaultPipelineCacheDir();

// One cache file per device and driver: <dir>/pipelines-<pipelineCacheUUID>-<driverVersion>.bin.
class DiskPipelineCache {
 public:
  // Loads the file when present, a regular file of sane size, and made by this device and driver; a
  // missing, foreign, corrupt or non-regular file (FIFO, directory) gives an empty cache (never an error;
  // the non-regular one is reported by save() and lastError()). On a host's device that gave its own
  // pipeline cache (VulkanHostDevice::pipelineCache) that cache is used and no file is read or written.
  // Precondition: context outlives this object.
  DiskPipelineCache(VulkanContext& context, const std::filesystem::path& dir);

  VkPipelineCache get() const { return cache_ ? cache_.get() : context_.hostPipelineCache(); }
  // True when a cache file for this device with pipeline data in it was loaded.
  bool warm() const { return warm_; }
  // True when the loaded file was valid but held a header only (drivers such as lavapipe cache nothing).
  bool empty() const { return empty_; }
  const std::filesystem::path& file() const { return file_; }
  // Writes the cache atomically (temporary file, then rename). Returns false and keeps the reason in
  // lastError() when the directory cannot be written; a cache is an optimisation, never a failure.
  bool save();
  const std::string& lastError() const { return lastError_; }

 private:
  VulkanContext& context_;
  std::filesystem::path file_;
  vk::UniquePipelineCache cache_;
  bool warm_ = false;
  bool empty_ = false;
  bool unusable_ = false;  // the cache path is not a regular file: neither read nor written
  std::string lastError_;
};

}  // namespace vs

#endif
