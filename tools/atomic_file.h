// atomic_file.h: outputs written to temporaries and committed together, so that a failure or a signal never
// leaves a partial output, and a command's outputs change together or not at all (DESIGN.md §2).
#ifndef VOXSHADOW_TOOLS_ATOMIC_FILE_H
#define VOXSHADOW_TOOLS_ATOMIC_FILE_H

#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace vs {

// A temporary path in the same directory as `out` (so the final rename stays on one file system), keeping
// `out`'s extension, because image writers pick the format from it. Its name is
// ".<out's name>.voxshadow-<pid>-<n><ext>" (out's name shortened where needed, so that the whole name fits
// the file system's 255-byte limit): recognisable as ours, with the writer's pid, unique within this process.
// `ext` replaces out's extension when given (backups use ".bak").
std::filesystem::path temporarySibling(const std::filesystem::path& out, const std::string& ext = {});

// The writer pid of a temporary named by temporarySibling, or nothing when `name` (a file name, no directory)
// is not one.
std::optional<long> temporaryWriterPid(const std::string& name);

// Removes the temporaries of writers that no longer run (a process killed by SIGKILL cannot remove its own)
// from `dir`. Only names temporarySibling makes are touched, and never those of a live process.
// Returns how many were removed. Never throws: a directory that cannot be listed is left as it is.
std::size_t removeStaleTemporaries(const std::filesystem::path& dir);

// Throws vs::Error(BadInput) naming the path when `out`'s directory does not exist, is not a directory or is
// not writable, when `out` itself is a directory or not a regular file, or when its name is longer than
// `maxNameBytes` (255, the usual limit, minus what a derived output such as a sidecar adds). Also removes the
// stale temporaries of that directory. Used before long work so that a bad output path fails early.
void checkOutputDirectory(const std::filesystem::path& out, std::size_t maxNameBytes = 255);

// Throws vs::Error(BadInput) when one of `outputs` is, after symlinks and hard links, the same file as one of
// `inputs` ("<output>: would overwrite the input <what> <input>"; `inputWhat` says what each input is, e.g.
// "scene", "asset 'castle'") or as another output. Inputs that do not exist are skipped.
void refuseOutputsOverInputs(std::span<const std::filesystem::path> outputs,
                             std::span<const std::filesystem::path> inputs,
                             std::span<const std::string> inputWhat);

// Calls write(index, tmp) for every output with its own temporary path and, only when all of them
// succeeded, commits them together: every existing output is first kept as a hard-linked backup, then each
// temporary is renamed onto its output; if a rename fails, the outputs already replaced get their backups
// back (or are removed when they did not exist before). Preconditions: outputs are distinct paths. On any
// failure every temporary and backup is removed, the previous outputs are as they were, and the exception
// propagates (file-system failures as vs::Error(Runtime) naming the file).
// A terminating signal while temporaries exist removes them (installSignalCleanup); one during the commit
// is held until the commit is complete.
void writeAtomically(std::span<const std::filesystem::path> outputs,
                     const std::function<void(std::size_t index, const std::filesystem::path& tmp)>& write);

// The rename the commit uses (::rename by default); returns the previous one. Only for tests that need a
// rename to fail halfway through a commit, which no file system arranges on request.
using RenameFunction = int (*)(const char* from, const char* to);
RenameFunction exchangeCommitRenameForTesting(RenameFunction rename);

// The signals installSignalCleanup handles: every catchable signal whose default action ends the process
// (SIGHUP, SIGINT, SIGQUIT, SIGABRT, SIGTERM, SIGPIPE, SIGALRM, SIGUSR1, SIGUSR2, SIGXCPU, SIGXFSZ, SIGVTALRM,
// SIGPROF, SIGIO, SIGPWR, SIGSTKFLT, the real-time signals) but the faults of a bug (SIGSEGV, SIGBUS, SIGFPE,
// SIGILL, SIGTRAP, SIGSYS).
std::vector<int> cleanupSignals();

// Installs handlers for cleanupSignals() that remove every temporary writeAtomically (or
// checkOutputDirectory's probe) has open, then end the process by the same signal with its default action
// (a shell reports 128 + signal: 130 for SIGINT, 143 for SIGTERM). A signal that is ignored, or already
// handled, when this runs is left as it is. Call once, early in main().
void installSignalCleanup();

}  // namespace vs

#endif
