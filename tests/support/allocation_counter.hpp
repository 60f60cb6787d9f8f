// Counts heap allocations made by this process while a counter is armed.
//
// Interposes malloc/calloc/realloc/aligned_alloc/posix_memalign (Eigen allocates with
// malloc, operator new goes through malloc too) and forwards to glibc's __libc_* entry
// points. Include from exactly one translation unit of a test executable.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstring>

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
}

namespace stepcal::test {

inline std::atomic<bool> g_counting{false};
inline std::atomic<long> g_allocations{0};

/// Counts allocations made between construction and count() (all threads).
class AllocationCounter {
 public:
  AllocationCounter() {
    g_allocations = 0;
    g_counting = true;
  }
  ~AllocationCounter() { g_counting = false; }
  long count() const { return g_allocations.load(); }
};

inline void noteAllocation() {
  if (g_counting.load(std::memory_order_relaxed)) ++g_allocations;
}

}  // namespace stepcal::test

extern "C" {
void* malloc(size_t size) {
  stepcal::test::noteAllocation();
  return __libc_malloc(size);
}
void* calloc(size_t n, size_t size) {
  stepcal::test::noteAllocation();
  return __libc_calloc(n, size);
}
void* realloc(void* p, size_t size) {
  stepcal::test::noteAllocation();
  return __libc_realloc(p, size);
}
void* aligned_alloc(size_t alignment, size_t size) {
  stepcal::test::noteAllocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, size_t alignment, size_t size) {
  stepcal::test::noteAllocation();
  *out = __libc_memalign(alignment, size);
  return *out ? 0 : 12;  // ENOMEM
}
}
