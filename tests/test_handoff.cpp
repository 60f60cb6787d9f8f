// Lock-free hand-offs under contention: the wrench seqlock never yields a torn or reordered
// sample, a reader of the model handle never sees two models in one answer nor a freed one, no
// model leaks, and the staleness rules of the live wrench. Run under ThreadSanitizer by
// tests/system/tsan_check.sh.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <limits>
#include <memory>
#include <thread>
#include <vector>

#include "stepcal/runtime/handoff.hpp"

namespace stepcal::runtime {
namespace {

using std::chrono::milliseconds;

// A sample whose every field is a function of its sequence number, so a torn read shows.
WrenchSample sampleFor(uint64_t sequence) {
  WrenchSample s;
  for (int i = 0; i < 6; ++i) s.wrench_Sensor(i) = static_cast<double>(sequence) + 0.125 * i;
  s.stamp_ns = static_cast<int64_t>(sequence) * 1000;
  s.sensor_status = static_cast<uint32_t>(sequence % 7);
  s.sequence = sequence;
  return s;
}

bool consistent(const WrenchSample& s) {
  const WrenchSample expected = sampleFor(s.sequence);
  return s.wrench_Sensor == expected.wrench_Sensor && s.stamp_ns == expected.stamp_ns &&
         s.sensor_status == expected.sensor_status;
}

TEST(WrenchSlot, EmptyUntilFirstPublish) {
  WrenchSlot slot;
  WrenchSample out;
  EXPECT_FALSE(slot.read(out));
  slot.publish(sampleFor(41));
  ASSERT_TRUE(slot.read(out));
  EXPECT_EQ(out.sequence, 41u);
  EXPECT_TRUE(consistent(out));
  // Every bit pattern travels unchanged, negative zero and NaN included.
  WrenchSample odd;
  odd.wrench_Sensor << -0.0, 1e-300, -7.5, std::numeric_limits<double>::quiet_NaN(), 3.0, -1.0;
  odd.stamp_ns = -5;
  odd.sensor_status = 0xFFFFFFFFu;
  odd.sequence = ~0ull;
  slot.publish(odd);
  ASSERT_TRUE(slot.read(out));
  EXPECT_EQ(std::memcmp(out.wrench_Sensor.data(), odd.wrench_Sensor.data(), sizeof(double) * 6), 0);
  EXPECT_EQ(out.stamp_ns, -5);
  EXPECT_EQ(out.sensor_status, 0xFFFFFFFFu);
  EXPECT_EQ(out.sequence, ~0ull);
}

TEST(WrenchSlot, OneWriterThreeReadersNeverTear) {
  WrenchSlot slot;
  std::atomic<bool> stop{false};
  slot.publish(sampleFor(1));
  struct ReaderStats {
    long reads = 0, misses = 0, torn = 0, backwards = 0;
    uint64_t distinct = 0;
    std::atomic<bool> enough{false};  // > 1000 reads and the writer seen moving on
  };
  std::array<ReaderStats, 3> stats{};
  std::vector<std::thread> readers;
  for (ReaderStats& mine : stats) {
    readers.emplace_back([&slot, &stop, &mine] {
      uint64_t last = 0;
      while (!stop.load(std::memory_order_relaxed)) {
        WrenchSample s;
        if (!slot.read(s)) {
          ++mine.misses;
          continue;
        }
        ++mine.reads;
        if (!consistent(s)) ++mine.torn;
        if (s.sequence < last) ++mine.backwards;
        if (s.sequence != last) ++mine.distinct;
        last = s.sequence;
        if (mine.reads > 1000 && mine.distinct >= 2) mine.enough.store(true, std::memory_order_relaxed);
      }
    });
  }
  // At least 500 ms, then until every reader has read enough (on a loaded machine a reader may
  // get few turns): a count, not a time, decides when the run is long enough.
  const auto enough = [&] {
    for (const ReaderStats& s : stats) {
      if (!s.enough.load(std::memory_order_relaxed)) return false;
    }
    return true;
  };
  uint64_t published = 1;
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < start + milliseconds(500) ||
         (!enough() && std::chrono::steady_clock::now() < start + std::chrono::seconds(30))) {
    for (int i = 0; i < 64; ++i) slot.publish(sampleFor(++published));
  }
  stop = true;
  for (std::thread& t : readers) t.join();
  for (const ReaderStats& s : stats) {
    EXPECT_EQ(s.torn, 0);
    EXPECT_EQ(s.backwards, 0);
    EXPECT_GT(s.reads, 1000);
    EXPECT_GE(s.distinct, 2u);  // it saw the writer move on
    std::cout << "[ reader     ] " << s.reads << " reads (" << s.distinct
              << " distinct samples), " << s.misses << " gave up on overlapping writes\n";
  }
  std::cout << "[ writer     ] " << published << " samples published\n";
}

TEST(WrenchSlot, StaleWrenchRules) {
  WrenchSlot slot;
  Vec6 out = Vec6::Constant(-1.0);
  EXPECT_EQ(wrenchFor(slot, 1'000'000, 5'000'000, out), Status::kStaleWrench);
  EXPECT_EQ(out, Vec6::Constant(-1.0));  // untouched when stale

  WrenchSample s;
  s.wrench_Sensor << 1, 2, 3, 4, 5, 6;
  s.stamp_ns = 10'000'000;
  slot.publish(s);
  EXPECT_EQ(wrenchFor(slot, 12'000'000, 5'000'000, out), Status::kOk);
  EXPECT_EQ(out, s.wrench_Sensor);
  EXPECT_EQ(wrenchFor(slot, 15'000'000, 5'000'000, out), Status::kOk);       // exactly the limit
  EXPECT_EQ(wrenchFor(slot, 15'000'001, 5'000'000, out), Status::kStaleWrench);  // too old
  EXPECT_EQ(wrenchFor(slot, 4'000'000, 5'000'000, out), Status::kStaleWrench);   // from the future
  EXPECT_EQ(wrenchFor(slot, 12'000'000, -1, out), Status::kStaleWrench);
  // Extreme stamps: the age is computed without overflow.
  EXPECT_EQ(wrenchFor(slot, std::numeric_limits<int64_t>::min(), 5'000'000, out),
            Status::kStaleWrench);
  s.stamp_ns = std::numeric_limits<int64_t>::min();
  slot.publish(s);
  EXPECT_EQ(wrenchFor(slot, std::numeric_limits<int64_t>::max(),
                      std::numeric_limits<int64_t>::max(), out),
            Status::kStaleWrench);

  s.stamp_ns = 10'000'000;
  s.sensor_status = 3;  // a sensor fault
  slot.publish(s);
  EXPECT_EQ(wrenchFor(slot, 12'000'000, 5'000'000, out), Status::kStaleWrench);
  s.sensor_status = 0;
  s.wrench_Sensor(2) = std::numeric_limits<double>::infinity();
  slot.publish(s);
  EXPECT_EQ(wrenchFor(slot, 12'000'000, 5'000'000, out), Status::kStaleWrench);
}

// A model whose data would show a mix of two models or a freed one, counting live instances.
struct CountedModel {
  static inline std::atomic<int> live{0};
  explicit CountedModel(uint64_t id) : model_id(id) {
    values.fill(id);
    ++live;
  }
  ~CountedModel() {
    values.fill(0);  // a reader still using a freed model would likely see these
    --live;
  }
  uint64_t model_id;
  std::array<uint64_t, 256> values{};
};

TEST(ModelHandle, SlotsAreExclusiveAndBounded) {
  HazardHandle<CountedModel> handle(std::make_unique<CountedModel>(7));
  EXPECT_EQ(handle.currentModelId(), 7u);
  EXPECT_FALSE(handle.acquire(-1));
  EXPECT_FALSE(handle.acquire(HazardHandle<CountedModel>::kReaderSlots));
  {
    auto guard = handle.acquire(2);
    ASSERT_TRUE(guard);
    EXPECT_EQ(guard->model_id, 7u);
    EXPECT_FALSE(handle.acquire(2));  // the slot is taken until the guard dies
    auto moved = std::move(guard);
    EXPECT_FALSE(guard);
    EXPECT_FALSE(handle.acquire(2));
    EXPECT_TRUE(handle.acquire(3));
  }
  EXPECT_TRUE(handle.acquire(2));
  handle.swap(nullptr);
  EXPECT_EQ(handle.currentModelId(), 0u);
  EXPECT_FALSE(handle.acquire(0));
  EXPECT_EQ(CountedModel::live.load(), 0);
  handle.swap(std::make_unique<CountedModel>(8));
  EXPECT_EQ(handle.acquire(0)->model_id, 8u);
}

TEST(ModelHandle, ReadersNeverMixModelsWhileTwoHundredSwapsRun) {
  const int live_before = CountedModel::live.load();
  {
    HazardHandle<CountedModel> handle(std::make_unique<CountedModel>(1));
    std::atomic<bool> stop{false};
    std::array<long, 3> answers{}, mixed{};
    std::vector<std::thread> readers;
    for (int slot = 0; slot < 3; ++slot) {
      readers.emplace_back([&, slot] {
        while (!stop.load(std::memory_order_relaxed)) {
          const auto guard = handle.acquire(slot);
          if (!guard) {
            ++mixed[static_cast<size_t>(slot)];  // never empty: a model is always in service
            continue;
          }
          const uint64_t id_at_start = guard->model_id;
          uint64_t sum = 0;
          for (const uint64_t v : guard->values) sum += v;
          std::this_thread::yield();  // give the swapper a chance to run mid-answer
          for (const uint64_t v : guard->values) sum += v;
          if (sum != 2 * 256 * id_at_start || guard->model_id != id_at_start) {
            ++mixed[static_cast<size_t>(slot)];
          }
          ++answers[static_cast<size_t>(slot)];
        }
      });
    }
    for (uint64_t id = 2; id <= 201; ++id) {
      handle.swap(std::make_unique<CountedModel>(id));
      // The previous model is freed before swap returns.
      EXPECT_EQ(CountedModel::live.load(), live_before + 1);
      EXPECT_EQ(handle.currentModelId(), id);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    stop = true;
    for (std::thread& t : readers) t.join();
    for (size_t i = 0; i < 3; ++i) {
      EXPECT_EQ(mixed[i], 0);
      EXPECT_GT(answers[i], 100);
      std::cout << "[ reader     ] " << answers[i] << " answers across 200 swaps\n";
    }
  }
  EXPECT_EQ(CountedModel::live.load(), live_before);
}

// Real runtime models: a two-joint arm whose base sits model_id metres along x, so the answer
// itself says which model computed it.
std::unique_ptr<const RuntimeModel> armModel(uint64_t id) {
  ChainJoint joint;
  joint.twist_Local << 0, 0, 0, 0, 0, 1;
  const auto translation = [](double x) {
    Pose X = Pose::Identity();
    X.translation() = Vec3(x, 0.0, 0.0);
    return X;
  };
  CalibratedModel model;
  model.chain_Tracker = KinematicChain({joint, joint}, {translation(static_cast<double>(id)),
                                                        translation(0.5), translation(0.25)});
  model.nominal_Base = model.chain_Tracker;
  return RuntimeModel::fromModel(model, id);
}

TEST(ModelHandle, RuntimeModelsSwappedUnderLoadAnswerConsistently) {
  ModelHandle handle(armModel(1));
  std::atomic<bool> stop{false};
  std::array<long, 3> answers{}, wrong{};
  std::vector<std::thread> readers;
  for (int slot = 0; slot < 3; ++slot) {
    readers.emplace_back([&, slot] {
      Workspace ws = [&] {  // every arm has the same shape
        const auto probe = handle.acquire(slot);
        return makeWorkspace(*probe);
      }();
      const JointVector q_rad = JointVector::Zero(2);
      while (!stop.load(std::memory_order_relaxed)) {
        const auto guard = handle.acquire(slot);
        const ForwardResult r =
            correctForward(*guard, ws, q_rad, Vec6::Zero(), kUnknownTemperature_c);
        const double x_expected = static_cast<double>(guard->model_id) + 0.75;
        if (r.status != Status::kOk || r.X_TrackerTip.translation().x() != x_expected) {
          ++wrong[static_cast<size_t>(slot)];
        }
        ++answers[static_cast<size_t>(slot)];
      }
    });
  }
  for (uint64_t id = 2; id <= 201; ++id) {
    handle.swap(armModel(id));
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  stop = true;
  for (std::thread& t : readers) t.join();
  EXPECT_EQ(handle.currentModelId(), 201u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(wrong[i], 0);
    EXPECT_GT(answers[i], 100);
  }
}

}  // namespace
}  // namespace stepcal::runtime
