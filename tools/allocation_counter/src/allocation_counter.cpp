// The allocation counter (see allocation_counter.hpp): malloc and its kin interposed.
#include "stepcal/allocation_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstddef>

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
}

namespace stepcal::test {
namespace {

std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};

void noteAllocation() {
  if (g_counting.load(std::memory_order_relaxed)) ++g_allocations;
}

}  // namespace

AllocationCounter::AllocationCounter() {
  g_allocations = 0;
  g_counting = true;
}
AllocationCounter::~AllocationCounter() { g_counting = false; }
long AllocationCounter::count() const { return g_allocations.load(); }

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
  return *out ? 0 : ENOMEM;
}
}
