#include "tools/atomic_file.h"

#include <atomic>
#include <cctype>
#include <cerrno>
#include <climits>
#include <csignal>
#include <cstring>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include "voxel/error.h"

namespace vs {

namespace fs = std::filesystem;

namespace {

constexpr const char* kTag = ".voxshadow-";
constexpr std::size_t kNameMax = 255;

// The temporaries a signal handler must remove. A handler may only touch lock-free atomics and
// async-signal-safe calls, so paths live in fixed slots: state 0 free, 1 being filled, 2 registered.
struct Slot {
  std::atomic<int> state{0};
  char path[PATH_MAX];
};
constexpr int kSlotCount = 64;
Slot g_slots[kSlotCount];
// While > 0 a commit is renaming: a signal then only records itself, and the commit ends the process once
// all outputs are in place, so that they never change halfway.
std::atomic<int> g_committing{0};
std::atomic<int> g_pendingSignal{0};
std::atomic<RenameFunction> g_commitRename{&::rename};

void removeRegisteredTemporaries() {
  for (Slot& s : g_slots)
    if (s.state.load(std::memory_order_acquire) == 2) ::unlink(s.path);
}

// The process that installed the handlers. A child forked from it (the .vdb check) inherits them but not the
// temporaries: its signal must not remove files its parent is still writing.
std::atomic<pid_t> g_owner{0};

// Dies by `sig` itself, so that a parent (a shell, make, a supervisor) sees the signal and not an exit status:
// a shell that sees its foreground job die by SIGINT stops its own script too.
[[noreturn]] void exitForSignal(int sig) {
  if (::getpid() == g_owner.load()) removeRegisteredTemporaries();
  struct sigaction dfl;
  std::memset(&dfl, 0, sizeof dfl);
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  ::raise(sig);
  // Inside the handler the signal is blocked: unblocking delivers it, with the default action.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, sig);
  ::pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
  ::_exit(128 + sig);  // reached only if the default action did not end the process
}

extern "C" void onTerminatingSignal(int sig) {
  if (g_committing.load() > 0) {
    g_pendingSignal.store(sig);
    return;
  }
  exitForSignal(sig);
}

// Registers a temporary for removal on a signal for as long as it lives. Create it before the file.
class Registration {
 public:
  explicit Registration(const fs::path& p) {
    const std::string& s = p.native();
    if (s.size() >= PATH_MAX) throwRuntime(s + ": path too long");
    for (int i = 0; i < kSlotCount; ++i) {
      int expected = 0;
      if (g_slots[i].state.compare_exchange_strong(expected, 1)) {
        std::memcpy(g_slots[i].path, s.c_str(), s.size() + 1);
        g_slots[i].state.store(2, std::memory_order_release);
        slot_ = i;
        return;
      }
    }
    throwRuntime(s + ": more than " + std::to_string(kSlotCount) + " temporary files open at once");
  }
  ~Registration() {
    if (slot_ >= 0) g_slots[slot_].state.store(0, std::memory_order_release);
  }
  Registration(const Registration&) = delete;
  Registration& operator=(const Registration&) = delete;

 private:
  int slot_ = -1;
};

// Holds signals off for the duration of a commit; the destructor ends the process for a signal that came in.
class CommitGuard {
 public:
  CommitGuard() { g_committing.fetch_add(1); }
  ~CommitGuard() {
    if (g_committing.fetch_sub(1) == 1) {
      int sig = g_pendingSignal.exchange(0);
      if (sig != 0) exitForSignal(sig);
    }
  }
};

bool processAlive(long pid) {
  if (pid <= 0 || pid > INT_MAX) return false;
  if (::kill(pid_t(pid), 0) == 0) return true;
  return errno != ESRCH;  // EPERM: it runs, as another user
}

std::string describeKind(const fs::file_status& st) {
  switch (st.type()) {
    case fs::file_type::directory: return "a directory";
    case fs::file_type::fifo: return "a FIFO";
    case fs::file_type::socket: return "a socket";
    case fs::file_type::block: return "a block device";
    case fs::file_type::character: return "a character device";
    default: return "not a regular file";
  }
}

}  // namespace

fs::path temporarySibling(const fs::path& out, const std::string& ext) {
  static std::atomic<unsigned> counter{0};
  const std::string suffix = kTag + std::to_string(::getpid()) + "-" + std::to_string(counter.fetch_add(1)) +
                             (ext.empty() ? out.extension().string() : ext);
  std::string base = out.filename().string();
  // The leading dot keeps the temporary out of casual listings.
  if (1 + base.size() + suffix.size() > kNameMax)
    base.resize(kNameMax > 1 + suffix.size() ? kNameMax - 1 - suffix.size() : 0);
  return out.parent_path() / ("." + base + suffix);
}

std::optional<long> temporaryWriterPid(const std::string& name) {
  if (name.empty() || name[0] != '.') return std::nullopt;
  std::size_t tag = name.rfind(kTag);
  if (tag == std::string::npos || tag == 0) return std::nullopt;
  std::size_t p = tag + std::strlen(kTag), pidStart = p;
  while (p < name.size() && std::isdigit(static_cast<unsigned char>(name[p]))) ++p;
  if (p == pidStart || p - pidStart > 10 || p >= name.size() || name[p] != '-') return std::nullopt;
  const long pid = std::stol(name.substr(pidStart, p - pidStart));
  std::size_t n = ++p;
  while (p < name.size() && std::isdigit(static_cast<unsigned char>(name[p]))) ++p;
  if (p == n) return std::nullopt;
  // What follows the counter is the extension: a dot and no further dot.
  if (p < name.size() && (name[p] != '.' || name.find('.', p + 1) != std::string::npos)) return std::nullopt;
  return pid;
}

std::size_t removeStaleTemporaries(const fs::path& dir) {
  std::size_t removed = 0;
  std::error_code ec;
  fs::directory_iterator it(dir.empty() ? fs::path(".") : dir, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::optional<long> pid = temporaryWriterPid(name);
    if (!pid || *pid == long(::getpid()) || processAlive(*pid)) continue;
    std::error_code rm;
    if (it->is_regular_file(rm) && fs::remove(it->path(), rm)) ++removed;
  }
  return removed;
}

void checkOutputDirectory(const fs::path& out, std::size_t maxNameBytes) {
  fs::path dir = out.parent_path();
  if (dir.empty()) dir = ".";
  const std::string name = out.filename().string();
  if (name.empty()) throwBadInput(out.string() + ": names a directory, not a file");
  if (name.size() > maxNameBytes)
    throwBadInput(out.string() + ": the file name is " + std::to_string(name.size()) + " bytes long; at most " +
                  std::to_string(maxNameBytes) + " are allowed here (file names are limited to 255 bytes, " +
                  "including what a derived output adds)");
  std::error_code ec;
  fs::file_status dirStatus = fs::status(dir, ec);
  if (!fs::exists(dirStatus)) throwBadInput(out.string() + ": output directory " + dir.string() + " does not exist");
  if (!fs::is_directory(dirStatus)) throwBadInput(out.string() + ": " + dir.string() + " is not a directory");
  fs::file_status outStatus = fs::status(out, ec);
  if (fs::exists(outStatus) && !fs::is_regular_file(outStatus))
    throwBadInput(out.string() + ": is " + describeKind(outStatus) + "; an output must be a regular file");
  // Permission bits do not tell the whole story (root, ACLs, read-only mounts, pseudo file systems):
  // creating a file is the only reliable test.
  const fs::path probe = temporarySibling(out);
  Registration registration(probe);
  int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    int err = errno;
    throwBadInput(out.string() + ": output directory " + dir.string() + " is not writable (" +
                  std::strerror(err) + ")");
  }
  ::close(fd);
  ::unlink(probe.c_str());
  removeStaleTemporaries(dir);
}

void refuseOutputsOverInputs(std::span<const fs::path> outputs, std::span<const fs::path> inputs,
                             std::span<const std::string> inputWhat) {
  auto same = [](const fs::path& a, const fs::path& b) {
    std::error_code ec1, ec2;
    fs::path ca = fs::weakly_canonical(a, ec1), cb = fs::weakly_canonical(b, ec2);
    if (!ec1 && !ec2 && ca == cb) return true;
    std::error_code ec;
    return fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec);
  };
  for (std::size_t o = 0; o < outputs.size(); ++o) {
    for (std::size_t i = 0; i < inputs.size(); ++i)
      if (same(outputs[o], inputs[i]))
        throwBadInput(outputs[o].string() + ": would overwrite the input " +
                      (i < inputWhat.size() ? inputWhat[i] + " " : std::string()) + inputs[i].string() +
                      "; choose another output path");
    for (std::size_t p = 0; p < o; ++p)
      if (same(outputs[o], outputs[p]))
        throwBadInput(outputs[o].string() + ": is the same file as the output " + outputs[p].string());
  }
}

void writeAtomically(std::span<const fs::path> outputs,
                     const std::function<void(std::size_t, const fs::path&)>& write) {
  std::vector<fs::path> temps, backups(outputs.size());
  std::vector<std::unique_ptr<Registration>> registrations;
  auto removeAll = [&] {
    std::error_code ignored;
    for (const auto& t : temps) fs::remove(t, ignored);
    for (const auto& b : backups)
      if (!b.empty()) fs::remove(b, ignored);
  };
  try {
    for (std::size_t i = 0; i < outputs.size(); ++i) {
      temps.push_back(temporarySibling(outputs[i]));
      registrations.push_back(std::make_unique<Registration>(temps.back()));
      write(i, temps.back());
      std::error_code ec;
      if (!fs::is_regular_file(temps.back(), ec)) throwRuntime(outputs[i].string() + ": the writer produced no file");
    }
  } catch (...) {
    removeAll();
    throw;
  }

  CommitGuard commit;
  // Keep every previous output first, so that a rename failing halfway can put them all back.
  std::vector<bool> existed(outputs.size(), false);
  try {
    for (std::size_t i = 0; i < outputs.size(); ++i) {
      struct stat st;
      if (::lstat(outputs[i].c_str(), &st) != 0) continue;
      if (S_ISDIR(st.st_mode)) throwRuntime(outputs[i].string() + ": is a directory; it cannot be replaced by a file");
      existed[i] = true;
      backups[i] = temporarySibling(outputs[i], ".bak");
      registrations.push_back(std::make_unique<Registration>(backups[i]));
      // A hard link keeps the old output in place until its replacement arrives; where the file system has
      // none, the old output moves aside instead (and comes back on failure).
      if (::link(outputs[i].c_str(), backups[i].c_str()) != 0 && ::rename(outputs[i].c_str(), backups[i].c_str()) != 0) {
        int err = errno;
        backups[i].clear();
        throwRuntime(outputs[i].string() + ": cannot be replaced (" + std::strerror(err) + ")");
      }
    }
  } catch (...) {
    // Nothing was renamed onto an output yet; a moved-aside output goes back.
    for (std::size_t i = 0; i < outputs.size(); ++i)
      if (!backups[i].empty() && ::access(outputs[i].c_str(), F_OK) != 0) ::rename(backups[i].c_str(), outputs[i].c_str());
    removeAll();
    throw;
  }
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    if (g_commitRename.load()(temps[i].c_str(), outputs[i].c_str()) == 0) continue;
    int err = errno;
    // Every output with a backup gets it back (those moved aside too); new ones replaced so far go.
    for (std::size_t j = 0; j < outputs.size(); ++j) {
      if (existed[j] && !backups[j].empty()) ::rename(backups[j].c_str(), outputs[j].c_str());
      else if (j < i) ::unlink(outputs[j].c_str());
    }
    removeAll();
    throwRuntime(outputs[i].string() + ": cannot rename the temporary file into place (" + std::strerror(err) + ")");
  }
  std::error_code ignored;
  for (const auto& b : backups)
    if (!b.empty()) fs::remove(b, ignored);
}

RenameFunction exchangeCommitRenameForTesting(RenameFunction rename) { return g_commitRename.exchange(rename); }

std::vector<int> cleanupSignals() {
  // Every signal whose default action ends the process and that a handler can catch, except the faults a
  // bug raises (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS): those belong to debuggers and sanitizers, and
  // the next run removes what a crashed writer left (removeStaleTemporaries).
  std::vector<int> signals = {SIGHUP,  SIGINT,  SIGQUIT, SIGABRT,   SIGTERM, SIGPIPE, SIGALRM, SIGUSR1,
                              SIGUSR2, SIGXCPU, SIGXFSZ, SIGVTALRM, SIGPROF, SIGIO,   SIGPWR};
#ifdef SIGSTKFLT
  signals.push_back(SIGSTKFLT);
#endif
  for (int sig = SIGRTMIN; sig <= SIGRTMAX; ++sig) signals.push_back(sig);
  return signals;
}

void installSignalCleanup() {
  g_owner.store(::getpid());
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = onTerminatingSignal;
  sigemptyset(&sa.sa_mask);
  for (int sig : cleanupSignals()) {
    struct sigaction old;
    if (::sigaction(sig, nullptr, &old) != 0) continue;
    // A signal ignored at start-up stays ignored: `voxshadow ... &` in a script has SIGINT ignored, and must
    // not die on a Ctrl-C meant for the foreground job. A handler someone else installed stays too.
    if (old.sa_handler != SIG_DFL || (old.sa_flags & SA_SIGINFO)) continue;
    ::sigaction(sig, &sa, nullptr);
  }
}

}  // namespace vs
