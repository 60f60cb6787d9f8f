// Lock-free hand-offs between the non-real-time threads (sensor reader, model loader) and the
// real-time threads that answer requests.
//
// WrenchSlot: the latest F/T sample; one writer, any number of readers. A seqlock whose payload
// is stored as atomic words, so a read overlapping a write is detected and retried, never a data
// race. ModelHandle: the model in service, replaced while requests are answered. Hazard
// pointers: a reader publishes the model it uses in its own slot; the swapper frees the old
// model once no slot holds it, on its own (non-real-time) thread. Readers never lock, wait for
// the swapper or allocate.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>

#include "stepcal/common/error.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::runtime {

/// One F/T sensor sample as the sensor thread hands it over.
struct WrenchSample {
  Vec6 wrench_Sensor = Vec6::Zero();  ///< force N, moment N·m, sensor axes
  int64_t stamp_ns = 0;               ///< when it was taken or received, ns, the readers' clock
  uint32_t sensor_status = 0;         ///< 0 = valid; anything else is a sensor fault
  uint64_t sequence = 0;              ///< the sensor's sample counter
};

/// The latest wrench sample: one writer thread, any number of reader threads, lock-free.
class WrenchSlot {
 public:
  /// Attempts of read() before it gives up on writes that keep overlapping it.
  static constexpr int kMaxReadAttempts = 64;

  /// Publishes a sample. Only one thread may publish. Wait-free.
  void publish(const WrenchSample& sample) noexcept;
  /// Copies the latest sample; false before the first publish, or when each of kMaxReadAttempts
  /// attempts overlapped a write (a writer preempted mid-write on the reader's core). Bounded.
  bool read(WrenchSample& out) const noexcept;

 private:
  static constexpr size_t kWords = 9;  // wrench ×6, stamp, status, sequence
  std::atomic<uint64_t> version_{0};   // odd while a write is in progress; 0 = never written
  std::array<std::atomic<uint64_t>, kWords> words_{};
};

/// The live wrench for a request, N and N·m in sensor axes: STALE_WRENCH when nothing was
/// published, the sample reports a sensor fault or is not finite, or its stamp is more than
/// max_age_ns from now_ns (either side: a stamp from the future means clocks disagree); else OK
/// and out is set (and *stamp_ns, when given, to the sample's stamp). Lock-free, allocation-free.
Status wrenchFor(const WrenchSlot& slot, int64_t now_ns, int64_t max_age_ns, Vec6& out,
                 int64_t* stamp_ns = nullptr) noexcept;

/// An immutable model that a non-real-time thread replaces while real-time threads use it.
/// Each reader thread owns one slot (0 … kReaderSlots − 1) and holds at most one guard on it at a
/// time. Model needs a `uint64_t model_id` member. Instantiated for RuntimeModel (ModelHandle).
template <class Model>
class HazardHandle {
 public:
  static constexpr int kReaderSlots = 8;

  /// Keeps one model alive and in one piece: the handle frees it only after the guard is gone.
  class Guard {
   public:
    Guard() noexcept = default;
    Guard(Guard&& other) noexcept
        : slot_(std::exchange(other.slot_, nullptr)), model_(std::exchange(other.model_, nullptr)) {}
    Guard& operator=(Guard&& other) noexcept {
      if (this != &other) {
        release();
        slot_ = std::exchange(other.slot_, nullptr);
        model_ = std::exchange(other.model_, nullptr);
      }
      return *this;
    }
    Guard(const Guard&) = delete;
    Guard& operator=(const Guard&) = delete;
    ~Guard() { release(); }

    const Model* get() const noexcept { return model_; }
    const Model& operator*() const noexcept { return *model_; }
    const Model* operator->() const noexcept { return model_; }
    explicit operator bool() const noexcept { return model_ != nullptr; }

   private:
    friend class HazardHandle;
    Guard(std::atomic<const Model*>* slot, const Model* model) noexcept
        : slot_(slot), model_(model) {}
    void release() noexcept {
      if (slot_ != nullptr) slot_->store(nullptr, std::memory_order_release);
      slot_ = nullptr;
      model_ = nullptr;
    }

    std::atomic<const Model*>* slot_ = nullptr;
    const Model* model_ = nullptr;
  };

  explicit HazardHandle(std::unique_ptr<const Model> initial = nullptr) noexcept
      : current_(initial.release()) {
    const Model* model = current_.load(std::memory_order_relaxed);
    current_id_.store(model ? model->model_id : 0, std::memory_order_relaxed);
  }
  /// Frees the model in service; aborts if a guard is still alive (a bug of the caller).
  ~HazardHandle() {
    for (const ReaderSlot& slot : slots_) {
      STEPCAL_INVARIANT(slot.model.load() == nullptr, "model handle destroyed under a live guard");
    }
    delete current_.load();
  }
  HazardHandle(const HazardHandle&) = delete;
  HazardHandle& operator=(const HazardHandle&) = delete;

  /// The model in service, protected until the guard dies. Empty when there is none, reader_slot
  /// is out of range or already holds a guard. Lock-free (retries only while swaps race it),
  /// allocation-free.
  Guard acquire(int reader_slot) noexcept {
    if (reader_slot < 0 || reader_slot >= kReaderSlots) return {};
    std::atomic<const Model*>& hazard = slots_[static_cast<size_t>(reader_slot)].model;
    if (hazard.load(std::memory_order_relaxed) != nullptr) return {};
    const Model* model = current_.load();
    for (;;) {
      if (model == nullptr) {
        hazard.store(nullptr, std::memory_order_release);
        return {};
      }
      hazard.store(model);  // seq_cst: ordered before the re-check, as swap's exchange before its scan
      const Model* again = current_.load();
      if (again == model) return Guard(&hazard, model);
      model = again;
    }
  }

  /// Puts next (may be null) in service, waits until no reader slot holds the previous model,
  /// then frees it. Sleeps: call from a non-real-time thread. Concurrent swaps are serialised.
  void swap(std::unique_ptr<const Model> next) {
    std::lock_guard<std::mutex> lock(swap_mutex_);
    const uint64_t next_id = next ? next->model_id : 0;
    std::unique_ptr<const Model> previous(current_.exchange(next.release()));
    current_id_.store(next_id, std::memory_order_relaxed);
    if (!previous) return;
    for (const ReaderSlot& slot : slots_) {
      while (slot.model.load() == previous.get()) {
        std::this_thread::sleep_for(std::chrono::microseconds(50));
      }
    }
  }

  /// model_id of the model in service, 0 when none (a guard's model_id tells which one answered).
  uint64_t currentModelId() const noexcept {
    return current_id_.load(std::memory_order_relaxed);
  }

 private:
  struct alignas(64) ReaderSlot {
    std::atomic<const Model*> model{nullptr};
  };

  alignas(64) std::atomic<const Model*> current_{nullptr};
  std::atomic<uint64_t> current_id_{0};
  std::array<ReaderSlot, kReaderSlots> slots_{};
  std::mutex swap_mutex_;
};

/// The calibrated model in service of a runtime.
using ModelHandle = HazardHandle<RuntimeModel>;
extern template class HazardHandle<RuntimeModel>;

}  // namespace stepcal::runtime
