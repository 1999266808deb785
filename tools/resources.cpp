#include "tools/resources.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

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

}  // namespace vs::cli
