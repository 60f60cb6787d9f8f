// Percentiles of latency samples (nearest rank), for the daemon's status window, the client and
// the bench.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace stepcal::service {

/// Nearest-rank p-quantile (p in (0, 1]) of n ascending samples; 0 when n = 0.
inline double quantileOfSorted(const double* sorted, size_t n, double p) noexcept {
  if (n == 0) return 0.0;
  const auto rank = static_cast<size_t>(std::ceil(p * static_cast<double>(n)));
  return sorted[std::clamp<size_t>(rank, 1, n) - 1];
}

/// Median, tail and maximum of a set of latencies, µs.
struct LatencySummary {
  size_t samples = 0;
  double p50_us = 0, p99_us = 0, p999_us = 0, max_us = 0;
};

/// Sorts [first, first + n) in place and summarises it.
inline LatencySummary summarizeLatencies(double* first, size_t n) noexcept {
  std::sort(first, first + n);
  LatencySummary s;
  s.samples = n;
  s.p50_us = quantileOfSorted(first, n, 0.50);
  s.p99_us = quantileOfSorted(first, n, 0.99);
  s.p999_us = quantileOfSorted(first, n, 0.999);
  s.max_us = n ? first[n - 1] : 0.0;
  return s;
}

}  // namespace stepcal::service
