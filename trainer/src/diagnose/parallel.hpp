// A parallel for over independent items (internal to stepcal::trainer).
#pragma once

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace stepcal::trainer::diagnosis {

/// Runs body(i) for every i < count on the machine's cores (at most 4 threads). Each i must
/// write only its own result: then what comes out does not depend on the number of threads.
template <typename Body>
void parallelFor(size_t count, const Body& body) {
  const unsigned threads = std::min(4u, std::max(1u, std::thread::hardware_concurrency()));
  std::atomic<size_t> next{0};
  const auto work = [&] {
    for (size_t i = next++; i < count; i = next++) body(i);
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads && t < count; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

}  // namespace stepcal::trainer::diagnosis
