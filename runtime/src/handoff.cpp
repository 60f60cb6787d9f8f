#include "stepcal/runtime/handoff.hpp"

#include <cstring>

namespace stepcal::runtime {
namespace {

/// Tells the core a spin-wait is in progress (frees the sibling hyper-thread).
inline void spinPause() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

uint64_t bitsOf(double value) noexcept {
  uint64_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  return bits;
}

double doubleOf(uint64_t bits) noexcept {
  double value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

}  // namespace

// Seqlock with fences (Boehm, "Can seqlocks get along with programming language memory
// models?", 2012): the odd version is ordered before the payload stores by the release fence,
// the payload loads before the version re-check by the acquire fence.
void WrenchSlot::publish(const WrenchSample& sample) noexcept {
  std::array<uint64_t, kWords> words;
  for (int i = 0; i < 6; ++i) words[static_cast<size_t>(i)] = bitsOf(sample.wrench_Sensor(i));
  words[6] = static_cast<uint64_t>(sample.stamp_ns);
  words[7] = sample.sensor_status;
  words[8] = sample.sequence;
  const uint64_t version = version_.load(std::memory_order_relaxed);
  version_.store(version + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  for (size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_relaxed);
  version_.store(version + 2, std::memory_order_release);
}

bool WrenchSlot::read(WrenchSample& out) const noexcept {
  for (int attempt = 0; attempt < kMaxReadAttempts; ++attempt) {
    const uint64_t before = version_.load(std::memory_order_acquire);
    if (before == 0) return false;
    if (before % 2 == 1) {
      spinPause();
      continue;
    }
    std::array<uint64_t, kWords> words;
    for (size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (version_.load(std::memory_order_relaxed) != before) continue;
    for (int i = 0; i < 6; ++i) out.wrench_Sensor(i) = doubleOf(words[static_cast<size_t>(i)]);
    out.stamp_ns = static_cast<int64_t>(words[6]);
    out.sensor_status = static_cast<uint32_t>(words[7]);
    out.sequence = words[8];
    return true;
  }
  return false;
}

Status wrenchFor(const WrenchSlot& slot, int64_t now_ns, int64_t max_age_ns, Vec6& out,
                 int64_t* stamp_ns) noexcept {
  WrenchSample sample;
  if (max_age_ns < 0 || !slot.read(sample) || sample.sensor_status != 0 ||
      !sample.wrench_Sensor.allFinite()) {
    return Status::kStaleWrench;
  }
  // |now − stamp| in unsigned arithmetic: exact for any two int64 values, never overflows.
  const auto now = static_cast<uint64_t>(now_ns), stamp = static_cast<uint64_t>(sample.stamp_ns);
  const uint64_t distance_ns = now_ns >= sample.stamp_ns ? now - stamp : stamp - now;
  if (distance_ns > static_cast<uint64_t>(max_age_ns)) return Status::kStaleWrench;
  out = sample.wrench_Sensor;
  if (stamp_ns != nullptr) *stamp_ns = sample.stamp_ns;
  return Status::kOk;
}

template class HazardHandle<RuntimeModel>;

}  // namespace stepcal::runtime
