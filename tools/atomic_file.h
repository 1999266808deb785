// atomic_file.h: write-to-temporary-then-rename, so that a failed write never leaves a partial output.
#ifndef VOXSHADOW_TOOLS_ATOMIC_FILE_H
#define VOXSHADOW_TOOLS_ATOMIC_FILE_H

#include <filesystem>
#include <functional>
#include <span>

namespace vs {

// A temporary path in the same directory as `out` (so the final rename stays on one file system), keeping
// `out`'s extension, because image writers pick the format from it. Unique within this process and run.
std::filesystem::path temporarySibling(const std::filesystem::path& out);

// Throws vs::Error(BadInput) naming the path when `out`'s directory does not exist, is not a directory or
// is not writable. Used before long work so that a bad output path fails early.
void checkOutputDirectory(const std::filesystem::path& out);

// Calls write(index, tmp) for every output with its own temporary path and, only when all of them
// succeeded, renames each temporary onto its output. Preconditions: outputs are distinct paths.
// On any failure (a write throws, a rename fails) every temporary is removed, so are the outputs already
// renamed by this call, and the exception propagates (file-system failures as vs::Error(Runtime)).
void writeAtomically(std::span<const std::filesystem::path> outputs,
                     const std::function<void(std::size_t index, const std::filesystem::path& tmp)>& write);

}  // namespace vs

#endif
