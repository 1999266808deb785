// allocation_cap.cpp: the global allocation functions of the fuzz targets and their replay driver.
//
// The .vdb loader relies on std::bad_alloc for the absurd sizes a damaged file makes OpenVDB ask for, but
// AddressSanitizer's operator new aborts instead of throwing when a request exceeds what it can map. These
// replacements throw as the standard requires, and also above a cap, so that one input cannot exhaust the
// fuzzing process's memory limit; they allocate through malloc and free, which ASan still checks (heap
// overflows, use after free, double free, leaks). The aligned forms stay ASan's own.
#include <cstddef>
#include <cstdlib>
#include <new>

namespace {

// 1 GiB in one request, or VOXSHADOW_FUZZ_ALLOCATION_CAP_MB. tools/fuzz.sh lowers it for the .vdb target:
// a damaged length field makes OpenVDB size a string or array from it and fill it before the read fails,
// and filling a gigabyte took most of each execution's time.
std::size_t cap() noexcept {
  static const std::size_t value = [] {
    const char* env = std::getenv("VOXSHADOW_FUZZ_ALLOCATION_CAP_MB");
    const long mb = env ? std::strtol(env, nullptr, 10) : 0;
    return mb > 0 && mb <= 1024 ? std::size_t(mb) << 20 : std::size_t(1) << 30;
  }();
  return value;
}

void* allocate(std::size_t n) noexcept { return n > cap() ? nullptr : std::malloc(n ? n : 1); }

}  // namespace

void* operator new(std::size_t n) {
  if (void* p = allocate(n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (void* p = allocate(n)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
