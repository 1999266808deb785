#include "tools/resources.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>

#include <sys/resource.h>
#include <unistd.h>

#include "voxel/error.h"

namespace vs::cli {

void addThreadsOption(CLI::App* app, int& threads, const std::string& help, int minimum) {
  const std::string range = "a whole number from " + std::to_string(minimum) + " to " + std::to_string(kMaxThreads);
  app->add_option_function<std::string>(
         "--threads",
         [&threads, minimum, range](const std::string& text) {
           bool digits = !text.empty() && text.size() <= 9 &&
                         std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c); });
           int v = digits ? std::stoi(text) : -1;
           if (!digits || v < minimum || v > kMaxThreads) throwBadInput("--threads: '" + text + "' is not " + range);
           threads = v;
         },
         help + " (" + range + ")")
      ->type_name("N");
}

std::uint64_t parseByteSize(const std::string& text, const std::string& what) {
  auto bad = [&] {
    throwBadInput(what + ": '" + text + "' is not a size (e.g. 8G, 512M, 1.5G or a number of bytes)");
  };
  std::size_t end = 0;
  while (end < text.size() && (std::isdigit(static_cast<unsigned char>(text[end])) || text[end] == '.')) ++end;
  if (end == 0 || end > 24) bad();
  double value = 0.0;
  std::istringstream number(text.substr(0, end));
  if (!(number >> value) || !number.eof()) bad();
  std::string unit = text.substr(end);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() >= 2 && unit.substr(unit.size() - 2) == "IB") unit.resize(unit.size() - 2);
  else if (!unit.empty() && unit.back() == 'B') unit.pop_back();
  double scale = 1.0;
  if (unit == "K") scale = 1024.0;
  else if (unit == "M") scale = 1024.0 * 1024.0;
  else if (unit == "G") scale = 1024.0 * 1024.0 * 1024.0;
  else if (unit == "T") scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else if (!unit.empty()) bad();
  const double bytes = std::floor(value * scale);
  if (!(bytes >= 1.0) || bytes > double(1ull << 60)) bad();
  return std::uint64_t(bytes);
}

namespace {

std::uint64_t readNumber(const char* path) {
  std::ifstream in(path);
  std::string s;
  if (!(in >> s) || s.empty() || !std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); }))
    return 0;  // "max", missing, or unreadable: no limit known
  return std::stoull(s);
}

}  // namespace

std::uint64_t availableMemoryBytes() {
  std::uint64_t available = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  std::uint64_t kib = 0;
  std::string unit;
  while (meminfo >> key >> kib) {
    std::getline(meminfo, unit);
    if (key == "MemAvailable:") {
      available = kib * 1024;
      break;
    }
  }
  if (available == 0) available = std::uint64_t(::sysconf(_SC_PHYS_PAGES)) * std::uint64_t(::sysconf(_SC_PAGESIZE));
  const std::uint64_t limit = readNumber("/sys/fs/cgroup/memory.max");
  if (limit > 0) {
    const std::uint64_t used = readNumber("/sys/fs/cgroup/memory.current");
    available = std::min(available, limit > used ? limit - used : 0);
  }
  return available;
}

std::string formatBytes(std::uint64_t bytes) {
  static const char* const kUnits[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  if (bytes < 1024) return std::to_string(bytes) + " B";
  double value = double(bytes) / 1024.0;
  std::size_t unit = 0;
  // Rounded to two decimals, 1023.999 MiB would print as "1024.00 MiB": move up before it does.
  while (value >= 1023.995 && unit + 1 < std::size(kUnits)) {
    value /= 1024.0;
    ++unit;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f %s", value, kUnits[unit]);
  return buf;
}

namespace {

// A field of /proc/self/status in bytes ("VmSize:  123 kB"), or a count ("Threads:  7"); 0 when absent.
std::uint64_t processStatus(const std::string& field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.compare(0, field.size() + 1, field + ":") != 0) continue;
    std::istringstream in(line.substr(field.size() + 1));
    std::uint64_t value = 0;
    std::string unit;
    in >> value >> unit;
    return unit == "kB" ? value * 1024 : value;
  }
  return 0;
}

std::optional<std::uint64_t> softLimit(int resource) {
  struct rlimit limit {};
  if (::getrlimit(resource, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return std::nullopt;
  return std::uint64_t(limit.rlim_cur);
}

// glibc gives each thread that allocates its own malloc arena, up to 8 per core, and reserves 64 MiB of
// address space for each (HEAP_MAX_SIZE): under ulimit -v that reservation takes room from the data.
constexpr std::uint64_t kArenaBytes = 64ull << 20;

// A new thread's stack: glibc's default is the soft stack limit (8 MiB unless changed), TBB's 4 MiB; take the
// larger, as most of the pools use glibc's default.
std::uint64_t threadStackBytes() {
  const std::optional<std::uint64_t> stack = softLimit(RLIMIT_STACK);
  return std::clamp<std::uint64_t>(stack.value_or(8ull << 20), 4ull << 20, 64ull << 20);
}

}  // namespace

unsigned tracingCommandThreads(int threadsOption) {
  const unsigned hardware = std::max(1u, std::thread::hardware_concurrency());
  const unsigned tbb = threadsOption > 0 ? std::max(unsigned(threadsOption), hardware) : hardware;
  return tbb + 2 * hardware + 1;
}

MemoryBudget memoryBudget(const std::optional<std::uint64_t>& requested, unsigned peakThreads) {
  MemoryBudget budget;
  if (requested) {
    budget = {*requested, "--memory-budget"};
  } else {
    budget = {availableMemoryBytes(), "the memory available now; --memory-budget sets another"};
  }
  const std::uint64_t running = std::max<std::uint64_t>(1, processStatus("Threads"));
  const std::uint64_t later = peakThreads > running ? peakThreads - running : 0;
  const std::uint64_t stacks = later * threadStackBytes();
  const unsigned maxArenas = 8 * std::max(1u, std::thread::hardware_concurrency());
  const std::uint64_t arenas = std::min<std::uint64_t>(later, maxArenas) * kArenaBytes;
  struct Limit {
    int resource;
    const char* name;
    const char* field;  // what of this process the limit already holds
    std::uint64_t threads;
  };
  for (const Limit& l : {Limit{RLIMIT_AS, "ulimit -v (RLIMIT_AS)", "VmSize", stacks + arenas},
                         Limit{RLIMIT_DATA, "ulimit -d (RLIMIT_DATA)", "VmData", stacks}}) {
    const std::optional<std::uint64_t> limit = softLimit(l.resource);
    if (!limit) continue;
    const std::uint64_t used = processStatus(l.field) + l.threads;
    const std::uint64_t room = *limit > used ? *limit - used : 0;
    if (room >= budget.bytes) continue;
    budget.bytes = room;
    budget.setBy = std::string("the room left under ") + l.name + " of " + formatBytes(*limit) + ", of which this process " +
                   (l.resource == RLIMIT_AS ? "maps " : "holds ") + formatBytes(processStatus(l.field)) +
                   " already and the threads it has yet to start need " + formatBytes(l.threads);
  }
  return budget;
}

void checkMemoryNeed(std::uint64_t need, const MemoryBudget& budget, const std::string& what, const std::string& advice) {
  if (need <= budget.bytes) return;
  throwBadInput(what + " about " + formatBytes(need) + " of memory, more than the budget of " +
                formatBytes(budget.bytes) + " (" + budget.setBy + "); " + advice);
}

}  // namespace vs::cli
