// Counts heap allocations made by this process while a counter is armed: the proof that a hot
// path allocates nothing, for the tests and the benches (target stepcal::allocation_counter).
//
// Its library interposes malloc/calloc/realloc/aligned_alloc/posix_memalign (Eigen allocates with
// malloc, operator new goes through malloc too) and forwards to glibc's __libc_* entry points. An
// executable gets the interposition only when it uses AllocationCounter (a static library's
// object is linked when referenced), so linking the target is harmless elsewhere.
#pragma once

namespace stepcal::test {

/// Counts allocations made between construction and count() (all threads).
class AllocationCounter {
 public:
  AllocationCounter();
  ~AllocationCounter();
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  long count() const;
};

}  // namespace stepcal::test
