// Solid rules over OpenVDB grids (DESIGN.md §3) and guarded .vdb reading.
#include "voxel/vdb_rules.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <cstdint>
#include <limits>
#include <filesystem>
#include <mutex>
#include <unordered_map>

#include <csignal>
#include <cstdio>
#include <istream>
#include <new>
#include <stdexcept>
#include <streambuf>
#include <type_traits>

#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <glm/gtc/matrix_transform.hpp>

#include <openvdb/io/Archive.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/util/logging.h>

#include "voxel/error.h"
#include "voxel/valid_range.h"
#include "voxel/vox_reader.h"

namespace vs {

void ensureOpenVdbInitialized() {
  static std::once_flag once;
  std::call_once(once, [] {
    openvdb::initialize();
#ifdef OPENVDB_USE_LOG4CPLUS
    // OpenVDB's own warnings carry terminal colour codes; a log file or a pipe gets them plain.
    openvdb::logging::initialize(::isatty(2) != 0);
#endif
  });
}

namespace {
// Damaged files put raw bytes into OpenVDB's messages: keep them printable.
std::string printable(std::string s) {
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e) c = '?';
  return s;
}
}  // namespace

namespace {

// An input stream over bytes held in memory (read-only, seekable), so that a checking child process and the
// loading process read the very same bytes.
class MemoryBuf : public std::streambuf {
 public:
  MemoryBuf(const char* data, std::size_t size) {
    char* p = const_cast<char*>(data);  // never written: the get area only
    setg(p, p, p + size);
  }

 protected:
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) override {
    const off_type size = egptr() - eback();
    if (!(which & std::ios_base::in) || off < -size || off > size) return pos_type(off_type(-1));
    const off_type base = dir == std::ios_base::beg ? 0 : dir == std::ios_base::cur ? gptr() - eback() : size;
    const off_type target = base + off;
    if (target < 0 || target > size) return pos_type(off_type(-1));
    setg(eback(), eback() + target, egptr());
    return pos_type(target);
  }
  pos_type seekpos(pos_type pos, std::ios_base::openmode which) override {
    return seekoff(off_type(pos), std::ios_base::beg, which);
  }
};

// Where a reading stands, for the error message when the reader dies: written by the reading process into
// memory shared with its parent.
struct ReadProgress {
  int grid = -1;           // index (file order) of the grid being read; -1: header and file metadata
  char name[128] = {};     // its name, cut to fit
  int done = 0;            // 1: every grid was read; 2: the reader refused the file with an exception
  char refusal[8192] = {}; // done == 2: the error message, cut to fit
  std::uint64_t taken = 0; // the checking process: serial number of the last request it took
};

// A value OpenVDB copied from the file without checking it, invalid for its type. The message names the grid
// and the value, not the file.
class DamagedValue : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The error message for the exception being handled (called inside a catch block).
std::string refusalOf(const std::string& path) {
  try {
    throw;
  } catch (const DamagedValue& e) {
    return path + ": damaged VDB file: " + e.what();
  } catch (const openvdb::Exception& e) {
    return path + ": not a readable VDB file (" + printable(e.what()) + ")";
  } catch (const std::bad_alloc&) {
    return path + ": damaged VDB file (asks for more memory than is available)";
  } catch (const std::ios_base::failure&) {
    return path + ": truncated or damaged VDB file (it ends before the data it announces)";
  } catch (const std::exception& e) {
    return path + ": not a readable VDB file (" + printable(e.what()) + ")";
  } catch (...) {
    return path + ": not a readable VDB file";
  }
}

// OpenVDB reads the bools of a tree (grid background, tile values, a root tile's active flag) and bool
// metadata by copying bytes from the file into them, unchecked: a damaged file can leave a bool whose byte is
// neither 0 nor 1, and loading such a bool is undefined behaviour (UBSan reports it; an optimised build may
// take it for true and false at once). These read each such byte as a byte once the grid is read, and refuse
// the grid if one is neither 0 nor 1, before voxshadow loads any of them. Refusing, rather than reading the
// byte as true: no VDB writer stores another byte, so the file is damaged, and OpenVDB's own code (its
// reader's copies, its tree operations) would go on loading the value.
unsigned byteOf(const bool& b) {
  unsigned char c;
  std::memcpy(&c, &b, 1);
  return c;
}

std::string coordText(const openvdb::Coord& c) {
  return "(" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")";
}

[[noreturn]] void refuseBool(const std::string& label, const std::string& what, unsigned byte) {
  throw DamagedValue(label + " has " + what + " stored as the byte " + std::to_string(byte) +
                     ", not a bool (0 or 1)");
}

// A root tile's active flag lives beside its value in a node of the root's table, which OpenVDB reaches only
// by loading the flag (isValueOn); the root's value iterators hold the table iterator (protected).
template <class RootT>
class RootTileFlags : public RootT::ValueAllCIter {
 public:
  explicit RootTileFlags(const typename RootT::ValueAllCIter& it) : RootT::ValueAllCIter(it) {}
  const bool& activeFlag() const { return this->mIter->second.tile.active; }
};

// The tile values of an internal node and of the internal nodes below it (the leaf nodes of bool trees hold
// their values as bits). The node's table, not OpenVDB's value iterators: a bool tree's top internal node
// alone has 32,768 entries, and the iterators cost more than the reading.
template <class NodeT>
void checkTileBytes(const NodeT& node, const std::string& label) {
  if constexpr (NodeT::LEVEL > 0) {
    const auto* table = node.getTable();
    const auto& children = node.getChildMask();
    for (openvdb::Index i = 0; i < NodeT::NUM_VALUES; ++i)
      if (children.isOff(i))
        if (unsigned b = byteOf(table[i].getValue()); b > 1)
          refuseBool(label, "a tile value at " + coordText(node.offsetToGlobalCoord(i)), b);
    for (auto child = node.cbeginChildOn(); child; ++child) checkTileBytes(*child, label);
  }
}

template <class GridT>
void checkStoredBools(const GridT& grid, const std::string& label) {
  using TreeT = typename GridT::TreeType;
  using RootT = typename TreeT::RootNodeType;
  const TreeT& tree = grid.tree();
  constexpr bool boolValues = std::is_same_v<typename TreeT::ValueType, bool>;
  if constexpr (boolValues)
    if (unsigned b = byteOf(tree.background()); b > 1) refuseBool(label, "a background value", b);
  for (RootTileFlags<RootT> it(tree.root().cbeginValueAll()); it; it.next()) {
    if (unsigned b = byteOf(it.activeFlag()); b > 1)
      refuseBool(label, "a tile at " + coordText(it.getCoord()) + " whose active flag is", b);
    if constexpr (boolValues)
      if (unsigned b = byteOf(it.getValue()); b > 1) refuseBool(label, "a tile value at " + coordText(it.getCoord()), b);
  }
  if constexpr (boolValues)
    for (auto child = tree.root().cbeginChildOn(); child; ++child) checkTileBytes(*child, label);
  for (auto m = grid.beginMeta(); m != grid.endMeta(); ++m) {
    if (m->second && m->second->typeName() == openvdb::BoolMetadata::staticTypeName()) {
      const auto& meta = static_cast<const openvdb::BoolMetadata&>(*m->second);
      if (unsigned b = byteOf(meta.value()); b > 1)
        refuseBool(label, "the metadata '" + printable(m->first) + "'", b);
    }
  }
}

// Throws DamagedValue for a grid holding a bool that is neither 0 nor 1 (see byteOf).
void checkStoredBools(const openvdb::GridBase& grid, const std::string& label) {
  grid.apply<openvdb::GridTypes>([&](const auto& typed) { checkStoredBools(typed, label); });
}

// The reading io::Stream(is, delayLoad=false) does (OpenVDB 10, Stream.cc), step by step, so that the grid
// being read can be reported. io::Stream reads grids in file order (io::File lists them sorted by name).
// Without delayed loading every grid is read fully from the stream; with it, Stream would first copy the
// whole input into a temporary file (openvdb_temp_*) that it does not remove when reading fails.
class GridReader : public openvdb::io::Archive {
 public:
  // `keep` (the checking child's): every grid is also kept there from before it is read, so that neither
  // an exception nor the end of reading destroys a tree (Tree::clear runs a TBB parallel_for, which would
  // start worker threads in the child).
  openvdb::GridPtrVec read(std::istream& is, ReadProgress* progress, openvdb::GridPtrVec* keep) {
    readHeader(is);
    openvdb::io::StreamMetadata::Ptr streamMetadata(new openvdb::io::StreamMetadata);
    openvdb::io::setStreamMetadataPtr(is, streamMetadata, /*transfer=*/false);
    openvdb::io::setVersion(is, libraryVersion(), fileVersion());
    openvdb::io::setDataCompression(is, compression());
    openvdb::MetaMap meta;
    meta.readMeta(is);
    const std::int32_t count = readGridCount(is);
    openvdb::GridPtrVec grids;
    std::vector<openvdb::io::GridDescriptor> descriptors;
    NamedGridMap named;
    for (std::int32_t i = 0; i < count; ++i) {
      openvdb::io::GridDescriptor gd;
      gd.read(is);
      if (progress) {
        const std::string name = openvdb::io::GridDescriptor::nameAsString(gd.uniqueName());
        progress->grid = int(i);
        std::snprintf(progress->name, sizeof progress->name, "%s", name.c_str());
      }
      if (!openvdb::GridBase::isRegistered(gd.gridType()))
        OPENVDB_THROW(openvdb::TypeError, "can't read grid \"" << openvdb::io::GridDescriptor::nameAsString(gd.uniqueName())
                                              << "\" because grid type " << gd.gridType() << " is unknown");
      openvdb::GridBase::Ptr grid = openvdb::GridBase::createGrid(gd.gridType());
      if (grid) grid->setSaveFloatAsHalf(gd.saveFloatAsHalf());
      if (keep) keep->push_back(grid);
      Archive::readGrid(grid, gd, is);
      if (grid) checkStoredBools(*grid, "grid " + std::to_string(i) + " '" +
                                  printable(openvdb::io::GridDescriptor::nameAsString(gd.uniqueName())) + "'");
      descriptors.push_back(gd);
      grids.push_back(grid);
      named[gd.uniqueName()] = grid;
    }
    // Grids that share a tree with another (instances) get it now.
    for (const openvdb::io::GridDescriptor& gd : descriptors) connectInstance(gd, named);
    if (progress) progress->grid = count;
    return grids;
  }
};

// Reads the grids from the bytes; OpenVDB's exceptions (and the stream's, see below) pass through.
openvdb::GridPtrVec parseGrids(const std::string& bytes, ReadProgress* progress = nullptr,
                               openvdb::GridPtrVec* keep = nullptr) {
  MemoryBuf buf(bytes.data(), bytes.size());
  std::istream in(&buf);
  // OpenVDB does not check every read: at the end of a truncated or lying file it would go on reading
  // nothing (looping for minutes over a count it read as garbage, or sizing a string from an unset length).
  // A stream that throws on the first failed read turns all of these into one error.
  in.exceptions(std::ios::failbit | std::ios::badbit);
  return GridReader().read(in, progress, keep);
}

std::string signalName(int sig) {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGABRT: return "SIGABRT";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGKILL: return "SIGKILL";
    default: return "signal " + std::to_string(sig);
  }
}

}  // namespace

}  // namespace vs

// Sanitizer run-time hooks, present only in sanitized builds (weak: null otherwise).
extern "C" void __sanitizer_set_report_fd(void* fd) __attribute__((weak));
extern "C" void __sanitizer_set_death_callback(void (*callback)(void)) __attribute__((weak));

namespace vs {

namespace {

// Puts a freshly forked checking child in its state. Die with the parent (PR_SET_PDEATHSIG: with the thread
// that forked it, unless `dieWithParentThread` is false); default actions for the signals
// the parent handles (its handlers remove the parent's temporaries), none blocked, so that an interrupt of
// the process group ends the child too. Quiet: OpenVDB's warnings come again from the parent's own reading,
// and the C library's or a sanitizer's report of the reader's failure would only repeat the error the parent
// gives.
void prepareCheckingChild(pid_t parent, bool dieWithParentThread = true) {
  if (dieWithParentThread) ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (::getppid() != parent) ::_exit(3);
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE, SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGALRM})
    std::signal(sig, SIG_DFL);
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  int devnull = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (devnull >= 0) {
    ::dup2(devnull, 1);
    ::dup2(devnull, 2);
  }
  if (__sanitizer_set_report_fd) __sanitizer_set_report_fd(reinterpret_cast<void*>(std::intptr_t(2)));
  if (__sanitizer_set_death_callback) __sanitizer_set_death_callback(nullptr);
}

// Parses the bytes in the child and records the verdict in `progress` (done = 1 or 2). Every grid is kept in
// `keep`, never freed (see GridReader::read).
void checkBytes(const std::string& bytes, const std::string& path, ReadProgress* progress, openvdb::GridPtrVec* keep) {
  try {
    (void)parseGrids(bytes, progress, keep);
    progress->done = 1;
  } catch (...) {
    // Refused with an exception: the parent throws the same message and need not read the file at all
    // (OpenVDB leaks the nodes it read when it throws: in the child, they go with it).
    try {
      std::snprintf(progress->refusal, sizeof progress->refusal, "%s", refusalOf(path).c_str());
    } catch (...) {
      std::snprintf(progress->refusal, sizeof progress->refusal, "%s: not a readable VDB file", path.c_str());
    }
    progress->done = 2;
  }
}

// The child process: parses every grid, then ends without returning into the caller (no unwinding into
// the parent's frames, no atexit handlers, no flushing of the parent's buffered output).
[[noreturn]] void checkInChild(const std::string& bytes, const std::string& path, ReadProgress* progress, pid_t parent) {
  prepareCheckingChild(parent);
  checkBytes(bytes, path, progress, new openvdb::GridPtrVec);
  ::_exit(0);
}

// The verdict of a checking child on one file, once the child has ended (`waited` and `status` from waitpid)
// or, for the persistent child, died while reading it. Returns when the child read the file to its end.
void verdictOf(const std::string& path, ReadProgress* progress, pid_t waited, int status) {
  // waitpid fails (ECHILD) where SIGCHLD is ignored or another waiter reaped the child: the shared flag,
  // set by the child only after its reading ended normally, decides then.
  const bool ended = waited < 0 || (WIFEXITED(status) && WEXITSTATUS(status) == 0);
  if (ended && progress->done == 1) return;
  if (ended && progress->done == 2) {
    progress->refusal[sizeof progress->refusal - 1] = 0;
    throwBadInput(progress->refusal);
  }
  progress->name[sizeof progress->name - 1] = 0;
  std::string where = progress->grid < 0 ? std::string("the file header and metadata")
                                          : "grid " + std::to_string(progress->grid) + " '" + printable(progress->name) + "'";
  std::string how;
  if (waited < 0) how = "it ended abnormally";
  else if (WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) how = "killed by SIGKILL, out of memory?";
  else if (WIFSIGNALED(status)) how = "it crashed with " + signalName(WTERMSIG(status));
  else how = "it exited with status " + std::to_string(WEXITSTATUS(status));
  throwBadInput(path + ": damaged VDB file: OpenVDB's reader failed on " + where + " (" + how +
                " in a checking process); the file was not loaded");
}

pid_t waitForChild(pid_t child, int* status) {
  pid_t waited;
  do waited = ::waitpid(child, status, 0);
  while (waited < 0 && errno == EINTR);
  return waited;
}

ReadProgress* mapProgress(const std::string& path) {
  void* shared = ::mmap(nullptr, sizeof(ReadProgress), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (shared == MAP_FAILED) throwRuntime(path + ": cannot map memory to check the file (" + std::strerror(errno) + ")");
  return new (shared) ReadProgress;
}

// Parses the bytes in a child process first; throws vs::Error(BadInput) naming the file and the grid being
// read when the child dies (a crash inside OpenVDB on damaged data, or the kernel killing it for memory),
// and with the child's message when OpenVDB refused the file with an exception there.
void checkInChildProcess(const std::string& bytes, const std::string& path) {
  ReadProgress* progress = mapProgress(path);
  struct Unmap {
    void* p;
    ~Unmap() { ::munmap(p, sizeof(ReadProgress)); }
  } unmap{progress};
  const pid_t parent = ::getpid();
  const pid_t child = ::fork();
  if (child < 0) throwRuntime(path + ": cannot start a process to check the file (" + std::strerror(errno) + ")");
  if (child == 0) checkInChild(bytes, path, progress, parent);
  int status = 0;
  const pid_t waited = waitForChild(child, &status);
  verdictOf(path, progress, waited, status);
}

// --- The checking process (setPersistentCheckingProcess) ---
//
// One process, forked before the caller's other threads work, serves check after check over a socket pair:
// the parent sends a request (header, path, bytes), the checking process forks a reader for it, which parses
// the bytes as checkInChild does and records its verdict in the shared ReadProgress, waits for the reader and
// answers with the reader's wait status. The checking process itself never parses a file, starts no thread
// and holds nothing between requests, so every fork it makes is a fork of a one-thread process (a fork of a
// multithreaded process may copy a lock that another thread held: the reader then waits forever, as with
// the allocator of clang 14's AddressSanitizer, which has no fork handlers) and it never needs replacing
// unless something kills it.

struct CheckRequest {
  std::uint64_t serial;
  std::uint64_t pathSize;
  std::uint64_t byteCount;
};

// The checking process's answer: the reader's waitpid result and status, or the errno of a fork that failed.
struct CheckAnswer {
  std::int32_t waited;
  std::int32_t status;
  std::int32_t forkError;  // 0: a reader ran
};

bool readFully(int fd, void* data, std::size_t size) {
  char* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = ::read(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= std::size_t(n);
  }
  return true;
}

// MSG_NOSIGNAL: a child that died leaves EPIPE, not a SIGPIPE that would end the parent.
bool sendFully(int fd, const void* data, std::size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::send(fd, p, size, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= std::size_t(n);
  }
  return true;
}

[[noreturn]] void serveChecks(int fd, ReadProgress* progress, pid_t parent) {
  // Above the standard streams, which prepareCheckingChild points at /dev/null (a parent that closed them
  // can get the socket there).
  if (fd < 3) fd = ::fcntl(fd, F_DUPFD, 3);
  if (fd < 0) ::_exit(4);
  // Not tied to the thread that started it (a TBB worker that ran a check may end long before the process):
  // the end of its socket, when the parent ends, ends it; its readers die with it.
  prepareCheckingChild(parent, /*dieWithParentThread=*/false);
  // Nothing else the parent had open stays open for the process's whole life (a pipe's write end would keep
  // its reader from seeing the end).
  ::syscall(SYS_close_range, 3u, unsigned(fd) - 1, 0u);
  ::syscall(SYS_close_range, unsigned(fd) + 1, ~0u, 0u);
  std::signal(SIGCHLD, SIG_DFL);  // a parent that ignores it would have the readers reaped unseen
  const pid_t self = ::getpid();
  std::string path, bytes;
  for (;;) {
    CheckRequest request{};
    if (!readFully(fd, &request, sizeof request)) ::_exit(0);  // the parent closed its end, or ended
    try {
      path.resize(request.pathSize);
      bytes.resize(request.byteCount);
    } catch (...) {
      ::_exit(4);  // no memory for the request: the parent starts another checking process and asks again
    }
    if (!readFully(fd, path.data(), path.size()) || !readFully(fd, bytes.data(), bytes.size())) ::_exit(0);
    progress->taken = request.serial;
    CheckAnswer answer{-1, 0, 0};
    const pid_t reader = ::fork();
    if (reader == 0) {
      ::close(fd);
      checkInChild(bytes, path, progress, self);
    }
    if (reader > 0) {
      int status = 0;
      answer.waited = std::int32_t(waitForChild(reader, &status));
      answer.status = std::int32_t(status);
    } else {
      answer.forkError = errno;  // no reader: the parent refuses the file with the fork's failure
    }
    // The file's bytes are not kept between requests: a large file would otherwise stay resident here.
    std::string().swap(bytes);
    if (!sendFully(fd, &answer, sizeof answer)) ::_exit(0);
  }
}

class PersistentChecker {
 public:
  ~PersistentChecker() {
    // At exit: the child sees the end of its socket and ends; a check still running on another thread keeps
    // it (the process is ending anyway).
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (lock.owns_lock() && owner_ == ::getpid()) stop();
  }

  // Starts the checking process now, when none is running. `what` names the cause in an error.
  void start(const std::string& what) {
    std::lock_guard<std::mutex> lock(mutex_);
    startLocked(what);
  }

  void check(const std::string& bytes, const std::string& path) {
    std::lock_guard<std::mutex> lock(mutex_);
    // A checking process can have died (killed): it is replaced, once per file, without blaming the file.
    for (int attempt = 0;; ++attempt) {
      startLocked(path);
      const std::uint64_t serial = ++serial_;
      progress_->grid = -1;
      progress_->name[0] = 0;
      progress_->done = 0;
      progress_->refusal[0] = 0;
      const CheckRequest request{serial, path.size(), bytes.size()};
      CheckAnswer answer{};
      const bool answered = sendFully(fd_, &request, sizeof request) && sendFully(fd_, path.data(), path.size()) &&
                            sendFully(fd_, bytes.data(), bytes.size()) && readFully(fd_, &answer, sizeof answer);
      if (answered && progress_->taken == serial) {
        if (answer.forkError != 0)
          throwRuntime(path + ": cannot start a process to check the file (" + std::strerror(answer.forkError) + ")");
        verdictOf(path, progress_, answer.waited, answer.status);
        return;
      }
      // The checking process itself ended (killed): it parses nothing, so the file is not to blame; a new one
      // checks it once more.
      stop();
      if (attempt > 0) throwRuntime(path + ": the process checking VDB files ended twice while checking the file");
    }
  }

  // Ends the child (when this process started it) and waits for it.
  void shutdown() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (owner_ == ::getpid()) stop();
  }

 private:
  void stop() {
    int status = 0;
    (void)stop(&status);
  }

  void startLocked(const std::string& what) {
    if (owner_ != ::getpid()) {
      // A fork of the process that started the checking process: the socket and the shared record are
      // that process's.
      if (fd_ >= 0) ::close(fd_);
      fd_ = -1;
      child_ = -1;
      progress_ = nullptr;
      owner_ = ::getpid();
    }
    if (!progress_) progress_ = mapProgress(what);
    if (child_ < 0) spawn(what);
  }

  void spawn(const std::string& path) {
    int fds[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0)
      throwRuntime(path + ": cannot start a process to check the file (" + std::strerror(errno) + ")");
    const pid_t parent = ::getpid();
    const pid_t child = ::fork();
    if (child < 0) {
      const int error = errno;
      ::close(fds[0]);
      ::close(fds[1]);
      throwRuntime(path + ": cannot start a process to check the file (" + std::strerror(error) + ")");
    }
    if (child == 0) {
      ::close(fds[0]);
      serveChecks(fds[1], progress_, parent);
    }
    ::close(fds[1]);
    fd_ = fds[0];
    child_ = child;
  }

  // Closes the socket (a child waiting for a request ends) and reaps the child; waitpid's result.
  pid_t stop(int* status) {
    if (child_ < 0) return -1;
    ::close(fd_);
    const pid_t waited = waitForChild(child_, status);
    fd_ = -1;
    child_ = -1;
    return waited;
  }

  std::mutex mutex_;
  ReadProgress* progress_ = nullptr;  // shared with every child, never unmapped
  pid_t child_ = -1;
  int fd_ = -1;
  std::uint64_t serial_ = 0;
  pid_t owner_ = ::getpid();
};

std::atomic<bool> persistentChecks{false};

PersistentChecker& persistentChecker() {
  static PersistentChecker checker;
  return checker;
}

std::string readWholeFile(const std::string& path) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throwBadInput(path + ": cannot open for reading (" + std::strerror(errno) + ")");
  struct Close {
    int fd;
    ~Close() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) throwBadInput(path + ": is not a regular file (a FIFO or a device)");
  std::string bytes;
  bytes.resize(std::size_t(st.st_size) + 1);  // one more, to see the end without a second pass
  std::size_t got = 0;
  for (;;) {
    if (got == bytes.size()) bytes.resize(bytes.size() + (bytes.size() >> 1) + 4096);  // it grew
    const ssize_t n = ::read(fd, bytes.data() + got, bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throwBadInput(path + ": cannot read (" + std::strerror(errno) + ")");
    if (n == 0) break;
    got += std::size_t(n);
  }
  bytes.resize(got);
  return bytes;
}

}  // namespace

void setPersistentCheckingProcess(bool on) {
  if (on) {
    // Its readers inherit OpenVDB's registries from it.
    ensureOpenVdbInitialized();
    persistentChecker().start("the VDB checking process");
  }
  persistentChecks.store(on);
  if (!on) persistentChecker().shutdown();
}

void startVdbCheckingProcess() { setPersistentCheckingProcess(true); }

openvdb::GridPtrVec readVdbGrids(const std::string& path, bool checkInChild) {
  ensureOpenVdbInitialized();
  std::error_code ec;
  std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) throwBadInput(path + ": no such file");
  if (std::filesystem::is_directory(st)) throwBadInput(path + ": is a directory, not a .vdb file");
  if (!std::filesystem::is_regular_file(st)) throwBadInput(path + ": is not a regular file (a FIFO or a device)");
  std::string bytes;
  try {
    bytes = readWholeFile(path);
  } catch (const std::bad_alloc&) {
    throwRuntime(path + ": too large to read into memory");
  }
  if (checkInChild && persistentChecks.load()) persistentChecker().check(bytes, path);
  else if (checkInChild) checkInChildProcess(bytes, path);
  try {
    return parseGrids(bytes);
  } catch (...) {
    throwBadInput(refusalOf(path));
  }
}

namespace {

bool isLevelSet(const openvdb::GridBase& g) { return g.getGridClass() == openvdb::GRID_LEVEL_SET; }

std::string gridLabel(const openvdb::GridBase& g) { return "grid '" + g.getName() + "'"; }

// Visits every voxel (tiles expanded) of the grid's values that `pred` accepts; `allValues` includes inactive
// values (the level-set interior). fn(coord, value).
template <class GridT, class Pred, class Fn>
void visitValues(const GridT& grid, bool allValues, Pred&& pred, Fn&& fn) {
  auto run = [&](auto it) {
    for (; it; ++it) {
      auto value = *it;
      if (!pred(value)) continue;
      if (it.isVoxelValue()) {
        fn(it.getCoord(), value);
      } else {
        // 64-bit counters: a tile may end at the last coordinate (2^31 - 1), where an int's ++ overflows.
        openvdb::CoordBBox box = it.getBoundingBox();
        for (std::int64_t z = box.min().z(); z <= box.max().z(); ++z)
          for (std::int64_t y = box.min().y(); y <= box.max().y(); ++y)
            for (std::int64_t x = box.min().x(); x <= box.max().x(); ++x)
              fn(openvdb::Coord(int(x), int(y), int(z)), value);
      }
    }
  };
  if (allValues) run(grid.tree().cbeginValueAll());
  else run(grid.tree().cbeginValueOn());
}

// LoadOptions' size limits, the region-slot limit clamped to what a brickmap can hold.
struct GridLimits {
  std::uint64_t solidVoxels;
  std::int64_t regionSlots;
};

// The voxels of a box, or limit + 1 when they are more than limit. CoordBBox::volume() computes each side in
// 32-bit ints: a damaged file's tile at the end of the coordinate range (max 2^31 - 1) overflowed there.
std::uint64_t saturatedVolume(const openvdb::CoordBBox& box, std::uint64_t limit) {
  std::uint64_t volume = 1;
  for (int a = 0; a < 3; ++a) {
    const std::int64_t side = std::int64_t(box.max()[a]) - std::int64_t(box.min()[a]) + 1;
    if (side <= 0) return 0;
    if (std::uint64_t(side) > (limit + 1) / volume) return limit + 1;
    volume *= std::uint64_t(side);
  }
  return volume;
}

// Counts accepted voxels (tiles by volume) and their bounds, so that nothing is allocated for a grid whose
// solid set is absurdly large.
template <class GridT, class Pred>
void guardSize(const GridT& grid, bool allValues, Pred&& pred, const GridLimits& limits, const std::string& file) {
  // Node origins come from the file (the root's children and tiles by key, each leaf by its own stored
  // origin, which need not agree with its parent's), and every coordinate below one is computed from it in
  // 32-bit ints inside OpenVDB (a leaf's voxel coordinates, a node's bounding box). A damaged file's node near
  // the end of the range overflowed there: such a node is refused before anything in it is visited.
  auto refuseOverflowingNode = [&](const openvdb::Coord& origin, std::int64_t extent) {
    for (int a = 0; a < 3; ++a) {
      if (std::int64_t(origin[a]) + extent - 1 > std::int64_t(std::numeric_limits<std::int32_t>::max()))
        throwBadInput(file + ": " + gridLabel(grid) + " has a node at (" + std::to_string(origin.x()) + ", " +
                      std::to_string(origin.y()) + ", " + std::to_string(origin.z()) +
                      ") that reaches beyond the 32-bit index coordinate range");
    }
  };
  using RootT = typename GridT::TreeType::RootNodeType;
  using LeafT = typename GridT::TreeType::LeafNodeType;
  for (auto it = grid.tree().root().cbeginChildAll(); it; ++it)
    refuseOverflowingNode(it.getCoord(), std::int64_t(RootT::ChildNodeType::DIM));
  for (auto it = grid.tree().cbeginLeaf(); it; ++it) refuseOverflowingNode(it->origin(), std::int64_t(LeafT::DIM));
  const std::uint64_t limit = limits.solidVoxels;
  std::uint64_t count = 0;
  openvdb::CoordBBox bounds;
  auto run = [&](auto it) {
    for (; it; ++it) {
      if (!pred(*it)) continue;
      openvdb::CoordBBox box = it.isVoxelValue() ? openvdb::CoordBBox(it.getCoord(), it.getCoord()) : it.getBoundingBox();
      count += saturatedVolume(box, limit);
      if (count > limit) {
        throwBadInput(file + ": " + gridLabel(grid) + " has more than " + std::to_string(limit) +
                      " solid voxels, more than the loader accepts");
      }
      bounds.expand(box);
    }
  };
  if (allValues) run(grid.tree().cbeginValueAll());
  else run(grid.tree().cbeginValueOn());
  if (count == 0) return;
  // The brickmap's region table has a slot for every 128^3 region of the bounds, at most kMaxRegionSlots in
  // all. A grid needing more is refused here, before its voxels are extracted, and without overflowing the
  // product (each factor is checked first, so no product of two exceeds 2^48): three axes of a few million
  // regions each once overflowed the brickmap's own count.
  const std::int64_t maxSlots = limits.regionSlots;
  std::int64_t slots = 1;
  for (int a = 0; a < 3; ++a) {
    const std::int64_t regions = (std::int64_t(bounds.max()[a]) >> 7) - (std::int64_t(bounds.min()[a]) >> 7) + 1;
    if (regions > maxSlots || (slots *= regions) > maxSlots) {
      throwBadInput(file + ": " + gridLabel(grid) + " has index bounds too large for a brickmap (its region table " +
                    "would need more than " + std::to_string(maxSlots) + " slots)");
    }
  }
}

template <class GridT, class Pred, class MatFn>
std::vector<SolidVoxel> collect(const GridT& grid, bool allValues, Pred pred, MatFn mat, const GridLimits& limit,
                                const std::string& file) {
  guardSize(grid, allValues, pred, limit, file);
  std::vector<SolidVoxel> out;
  visitValues(grid, allValues, pred, [&](const openvdb::Coord& c, const auto& value) {
    out.push_back({glm::ivec3(c.x(), c.y(), c.z()), mat(value)});
  });
  return out;
}

struct ColourKey {
  float r, g, b;
  bool operator==(const ColourKey& o) const { return std::memcmp(this, &o, sizeof o) == 0; }
};
struct ColourHash {
  std::size_t operator()(const ColourKey& k) const {
    std::uint32_t w[3];
    std::memcpy(w, &k, sizeof w);
    return std::size_t(w[0]) * 73856093u ^ std::size_t(w[1]) * 19349663u ^ std::size_t(w[2]) * 83492791u;
  }
};

// Palette of at most 255 colours: exact when there are that few distinct colours, else median cut over the
// distinct colours weighted by their voxel counts. Assigns every voxel its entry.
template <class GridT, class ToColour>
SolidExtraction colourGrid(const GridT& grid, ToColour toColour, const GridLimits& limit, const std::string& file) {
  auto pred = [](const auto&) { return true; };
  guardSize(grid, false, pred, limit, file);
  std::unordered_map<ColourKey, std::uint32_t, ColourHash> ids;  // colour -> distinct index
  std::vector<ColourKey> distinct;
  std::vector<std::uint64_t> weight;
  std::vector<std::pair<glm::ivec3, std::uint32_t>> raw;
  visitValues(grid, false, pred, [&](const openvdb::Coord& c, const auto& value) {
    glm::vec3 col = toColour(value);
    ColourKey key{col.x, col.y, col.z};
    auto [it, inserted] = ids.try_emplace(key, std::uint32_t(distinct.size()));
    if (inserted) {
      distinct.push_back(key);
      weight.push_back(0);
    }
    ++weight[it->second];
    raw.push_back({glm::ivec3(c.x(), c.y(), c.z()), it->second});
  });
  SolidExtraction out;
  out.palette.assign(1, glm::vec3(0.0f));
  std::vector<std::uint8_t> entryOf(distinct.size());
  if (distinct.size() <= 255) {
    for (std::size_t i = 0; i < distinct.size(); ++i) {
      out.palette.push_back(glm::vec3(distinct[i].r, distinct[i].g, distinct[i].b));
      entryOf[i] = std::uint8_t(i + 1);
    }
  } else {
    std::vector<std::uint32_t> order(distinct.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = std::uint32_t(i);
    struct Box {
      std::size_t begin, end;
    };
    std::vector<Box> boxes{{0, order.size()}};
    auto channel = [&](std::uint32_t i, int a) { return a == 0 ? distinct[i].r : a == 1 ? distinct[i].g : distinct[i].b; };
    while (boxes.size() < 255) {
      // Split the box with the widest channel range.
      int bestBox = -1, bestAxis = 0;
      float bestRange = 0.0f;
      for (std::size_t b = 0; b < boxes.size(); ++b) {
        if (boxes[b].end - boxes[b].begin < 2) continue;
        for (int a = 0; a < 3; ++a) {
          float lo = INFINITY, hi = -INFINITY;
          for (std::size_t k = boxes[b].begin; k < boxes[b].end; ++k) {
            lo = std::min(lo, channel(order[k], a));
            hi = std::max(hi, channel(order[k], a));
          }
          if (hi - lo > bestRange) {
            bestRange = hi - lo;
            bestBox = int(b);
            bestAxis = a;
          }
        }
      }
      if (bestBox < 0) break;
      Box box = boxes[std::size_t(bestBox)];
      std::sort(order.begin() + std::ptrdiff_t(box.begin), order.begin() + std::ptrdiff_t(box.end),
                [&](std::uint32_t x, std::uint32_t y) {
                  return channel(x, bestAxis) != channel(y, bestAxis) ? channel(x, bestAxis) < channel(y, bestAxis) : x < y;
                });
      std::size_t mid = box.begin + (box.end - box.begin) / 2;
      boxes[std::size_t(bestBox)] = {box.begin, mid};
      boxes.push_back({mid, box.end});
    }
    for (const Box& box : boxes) {
      glm::dvec3 sum(0.0);
      double w = 0.0;
      for (std::size_t k = box.begin; k < box.end; ++k) {
        std::uint32_t i = order[k];
        sum += glm::dvec3(distinct[i].r, distinct[i].g, distinct[i].b) * double(weight[i]);
        w += double(weight[i]);
        entryOf[i] = std::uint8_t(out.palette.size());
      }
      out.palette.push_back(glm::vec3(sum / std::max(w, 1.0)));
    }
    // One refinement step: each colour takes its nearest entry, so no colour keeps a far box mean.
    for (std::size_t i = 0; i < distinct.size(); ++i) {
      glm::vec3 c(distinct[i].r, distinct[i].g, distinct[i].b);
      float best = INFINITY;
      for (std::size_t e = 1; e < out.palette.size(); ++e) {
        glm::vec3 d = out.palette[e] - c;
        float dd = glm::dot(d, d);
        if (dd < best) {
          best = dd;
          entryOf[i] = std::uint8_t(e);
        }
      }
    }
  }
  out.voxels.reserve(raw.size());
  for (const auto& [c, id] : raw) out.voxels.push_back({c, entryOf[id]});
  return out;
}

}  // namespace

namespace {

// `voxshadow convert` stores a .vox palette on each grid as 255 sRGB "rrggbb" words (colour indices 1..255).
void applyPaletteMetadata(const openvdb::GridBase& g, const std::string& file, std::vector<glm::vec3>& palette) {
  openvdb::StringMetadata::ConstPtr meta = g.getMetadata<openvdb::StringMetadata>("voxshadow:palette");
  if (!meta) return;
  const std::string& s = meta->value();
  if (s.size() != 255 * 7 - 1)
    throwBadInput(file + ": " + gridLabel(g) + ": voxshadow:palette metadata is not 255 rrggbb words");
  for (std::size_t i = 0; i < 255; ++i) {
    unsigned rgb = 0;
    for (std::size_t k = 0; k < 6; ++k) {
      char c = s[i * 7 + k];
      int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
      if (d < 0) throwBadInput(file + ": " + gridLabel(g) + ": voxshadow:palette metadata is not 255 rrggbb words");
      rgb = rgb << 4 | unsigned(d);
    }
    palette[i + 1] = {srgbToLinear(std::uint8_t(rgb >> 16)), srgbToLinear(std::uint8_t(rgb >> 8)), srgbToLinear(std::uint8_t(rgb))};
  }
}

}  // namespace

std::uint8_t integerMaterial(std::int64_t v) {
  std::int64_t m = (v - 1) % 255;
  if (m < 0) m += 255;
  return std::uint8_t(1 + m);
}

std::vector<glm::vec3> integerPalette(glm::vec3 color) {
  std::vector<glm::vec3> p(256, glm::vec3(0.0f));
  p[1] = color;
  for (int i = 2; i < 256; ++i) {
    // Golden-ratio hue steps at two lightness levels: neighbouring indices stay distinguishable.
    float h = std::fmod(0.61803398875f * float(i), 1.0f) * 6.0f;
    float v = (i & 1) ? 0.85f : 0.6f, s = 0.55f;
    float f = h - std::floor(h);
    float pp = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    switch (int(h) % 6) {
      case 0: p[std::size_t(i)] = {v, t, pp}; break;
      case 1: p[std::size_t(i)] = {q, v, pp}; break;
      case 2: p[std::size_t(i)] = {pp, v, t}; break;
      case 3: p[std::size_t(i)] = {pp, q, v}; break;
      case 4: p[std::size_t(i)] = {t, pp, v}; break;
      default: p[std::size_t(i)] = {v, pp, q}; break;
    }
  }
  return p;
}

std::string solidRuleOf(const openvdb::GridBase& g) {
  bool real = g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>();
  if (real && isLevelSet(g)) return "level set: value < 0 (interior filled)";
  if (real) return "scalar: active and value > density_threshold";
  if (g.isType<openvdb::BoolGrid>() || g.isType<openvdb::MaskGrid>()) return "mask: active";
  if (g.isType<openvdb::Int32Grid>() || g.isType<openvdb::Int64Grid>())
    return "integer: active and value != 0, material = 1 + (value - 1) mod 255";
  if (g.isType<openvdb::Vec3SGrid>() || g.isType<openvdb::Vec3DGrid>() || g.isType<openvdb::Vec3IGrid>())
    return "colour: active, colour quantised into the palette";
  return {};
}

SolidExtraction extractSolid(const openvdb::GridBase& g, const LoadOptions& options, const std::string& file) {
  SolidExtraction out;
  auto one = [](const auto&) { return std::uint8_t(1); };
  const float thr = options.densityThreshold;
  const GridLimits limit{options.maxSolidVoxels,
                         std::min(options.maxRegionSlots, std::int64_t(Brickmap::kMaxRegionSlots))};
  auto scalar = [&](const auto& grid) {
    if (isLevelSet(g)) return collect(grid, true, [](auto v) { return v < 0; }, one, limit, file);
    return collect(grid, false, [thr](auto v) { return double(v) > double(thr); }, one, limit, file);
  };
  if (const auto* fg = dynamic_cast<const openvdb::FloatGrid*>(&g)) {
    out.voxels = scalar(*fg);
  } else if (const auto* dg = dynamic_cast<const openvdb::DoubleGrid*>(&g)) {
    out.voxels = scalar(*dg);
  } else if (const auto* bg = dynamic_cast<const openvdb::BoolGrid*>(&g)) {
    out.voxels = collect(*bg, false, [](bool) { return true; }, one, limit, file);
  } else if (const auto* mg = dynamic_cast<const openvdb::MaskGrid*>(&g)) {
    out.voxels = collect(*mg, false, [](bool) { return true; }, one, limit, file);
  } else if (const auto* ig = dynamic_cast<const openvdb::Int32Grid*>(&g)) {
    out.voxels = collect(*ig, false, [](std::int32_t v) { return v != 0; },
                         [](std::int32_t v) { return integerMaterial(v); }, limit, file);
    out.palette = integerPalette(options.color);
    applyPaletteMetadata(g, file, out.palette);
    return out;
  } else if (const auto* lg = dynamic_cast<const openvdb::Int64Grid*>(&g)) {
    out.voxels = collect(*lg, false, [](std::int64_t v) { return v != 0; },
                         [](std::int64_t v) { return integerMaterial(v); }, limit, file);
    out.palette = integerPalette(options.color);
    return out;
  } else if (const auto* vs3 = dynamic_cast<const openvdb::Vec3SGrid*>(&g)) {
    return colourGrid(*vs3, [](const openvdb::Vec3f& v) { return glm::vec3(v.x(), v.y(), v.z()); }, limit, file);
  } else if (const auto* vd3 = dynamic_cast<const openvdb::Vec3DGrid*>(&g)) {
    return colourGrid(*vd3, [](const openvdb::Vec3d& v) { return glm::vec3(float(v.x()), float(v.y()), float(v.z())); }, limit, file);
  } else if (const auto* vi3 = dynamic_cast<const openvdb::Vec3IGrid*>(&g)) {
    // Integer colours are 8-bit channels.
    return colourGrid(*vi3, [](const openvdb::Vec3i& v) { return glm::vec3(v.x(), v.y(), v.z()) / 255.0f; }, limit, file);
  } else {
    throwBadInput(file + ": " + gridLabel(g) + " of type " + g.valueType() + " has no solid rule");
  }
  out.palette = {glm::vec3(0.0f), options.color};
  return out;
}

namespace {
// Six significant figures, the exponent when needed: std::to_string's fixed notation prints 1e-30 as 0.000000.
std::string figure(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}
}  // namespace

glm::dmat4 brickToObjectOf(const openvdb::GridBase& g, const std::string& file) {
  const openvdb::math::Transform& t = g.transform();
  if (!t.isLinear()) {
    throwBadInput(file + ": " + gridLabel(g) + " has a non-linear (" + t.mapType() +
                  ") transform; only linear transforms are supported");
  }
  // A scale map with a zero (or nearly zero) scale is read without complaint, but turning it into an affine
  // map throws from a place where OpenVDB cannot unwind (std::terminate): check the voxel size first.
  const openvdb::Vec3d size = t.voxelSize();
  for (int axis = 0; axis < 3; ++axis)
    if (!(size[axis] >= limits::kMinVoxelSize && size[axis] <= limits::kMaxVoxelSize))
      throwBadInput(file + ": " + gridLabel(g) + " has a voxel size of " + figure(size[axis]) + " along axis " +
                    std::to_string(axis) + "; the valid range is " + figure(limits::kMinVoxelSize) + " to " +
                    figure(limits::kMaxVoxelSize));
  openvdb::Mat4d m;
  try {
    m = t.baseMap()->getAffineMap()->getMat4();
  } catch (const openvdb::Exception& e) {
    throwBadInput(file + ": " + gridLabel(g) + " has a transform that is not invertible (" + printable(e.what()) + ")");
  }
  // Voxel sizes outside the valid range would push the tracers' float arithmetic out of its exact range.
  for (int axis = 0; axis < 3; ++axis) {
    double len = std::sqrt(m(axis, 0) * m(axis, 0) + m(axis, 1) * m(axis, 1) + m(axis, 2) * m(axis, 2));
    if (!(len >= limits::kMinVoxelSize && len <= limits::kMaxVoxelSize))
      throwBadInput(file + ": " + gridLabel(g) + " has a voxel size of " + figure(len) + " along axis " +
                    std::to_string(axis) + "; the valid range is " + figure(limits::kMinVoxelSize) + " to " +
                    figure(limits::kMaxVoxelSize));
    if (!std::isfinite(m(3, axis)) || std::abs(m(3, axis)) > limits::kMaxCoordinate)
      throwBadInput(file + ": " + gridLabel(g) + " has a translation of " + figure(m(3, axis)) +
                    " along axis " + std::to_string(axis) + "; coordinates must lie within +-" +
                    figure(limits::kMaxCoordinate));
  }
  // OpenVDB multiplies row vectors (translation in row 3); GLM's column-major m[col][row] of the
  // column-vector form holds the same numbers at the same indices.
  glm::dmat4 g4(1.0);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) g4[i][j] = m(i, j);
  return g4 * glm::translate(glm::dmat4(1.0), glm::dvec3(-0.5));
}

}  // namespace vs
