// stepcal-bench-can: the F/T driver's parsing path, natively (no CAN in the kernel needed).
//
//   stepcal-bench-can [--polls 100000] [--pairs 1000000] [--json]
//
// 1. In memory: one reading's frames through the driver's code (classify both frames, pair the
//    halves, gauges → wrench), timed per batch of 1000 readings; ns per reading.
// 2. Socketpair: FtSensorDriver::pollOnce against the simulated sensor serving on the other end
//    of a SOCK_SEQPACKET socketpair (the same read path as CAN_RAW: recvmsg with kernel
//    timestamps), one poll at a time. Per poll: request sent → sample published (the sensor's
//    thread answering included), and kernel receive of the last frame → sample published (the
//    driver's own receive + parse + hand-off).
// Reports p50, p99, p99.9 and the maximum, and heap allocations during the timed loops.
#include <CLI/CLI.hpp>
#include <sys/socket.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/ftsim/simulator.hpp"
#include "stepcal/runtime/ft_sensor.hpp"
#include "stepcal/allocation_counter.hpp"
#include "stepcal/service/latency.hpp"

namespace {

using namespace stepcal;
using runtime::Clock;

nlohmann::json summary(std::vector<double>& samples_us) {
  const service::LatencySummary s = service::summarizeLatencies(samples_us.data(), samples_us.size());
  return {{"samples", s.samples}, {"p50_us", s.p50_us}, {"p99_us", s.p99_us},
          {"p999_us", s.p999_us}, {"max_us", s.max_us}};
}

/// Keeps the latest sample and when it was handed over.
class TimingSink final : public runtime::WrenchSink {
 public:
  void publish(const runtime::WrenchSample& sample) noexcept override {
    published_ns = runtime::steadyNowNs();
    stamp_ns = sample.stamp_ns;
  }
  int64_t published_ns = 0, stamp_ns = 0;
};

nlohmann::json benchInMemory(int pairs) {
  const runtime::netcan::Calibration calibration = ftsim::defaultCalibration();
  const runtime::netcan::WrenchConverter converter(calibration);
  const auto frames = runtime::netcan::encodeGauges(0x20, 0, {1200, -3400, 560, 78, -9000, 10});
  runtime::netcan::GaugeAssembler assembler;
  const Vec6 bias = Vec6::Zero();
  constexpr int kBatch = 1000;
  std::vector<double> per_reading_ns;
  per_reading_ns.reserve(size_t(pairs / kBatch));
  double checksum = 0.0;
  long allocations = 0;
  {
    test::AllocationCounter counter;
    for (int b = 0; b < pairs / kBatch; ++b) {
      const auto start = Clock::now();
      for (int k = 0; k < kBatch; ++k) {
        runtime::netcan::GaugeReading reading;
        if (runtime::netcan::classify(frames[0], 0x20) == runtime::netcan::FrameKind::kGaugesFirst) {
          assembler.first(frames[0]);
        }
        if (runtime::netcan::classify(frames[1], 0x20) == runtime::netcan::FrameKind::kGaugesSecond &&
            assembler.second(frames[1], reading)) {
          checksum += converter.wrench(reading.gauges, bias)[k % 6];
        }
      }
      per_reading_ns.push_back(
          double(std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count()) /
          kBatch);
    }
    allocations = counter.count();
  }
  std::vector<double> as_us = per_reading_ns;
  for (double& v : as_us) v *= 1e-3;
  nlohmann::json j = summary(as_us);
  j["readings"] = pairs / kBatch * kBatch;
  j["allocations"] = allocations;
  j["checksum"] = checksum;
  return j;
}

nlohmann::json benchSocketpair(int polls) {
  int ends[2];
  if (socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, ends) != 0) throw std::runtime_error("socketpair");
  runtime::CanSocket sensor_end = runtime::CanSocket::adopt(ends[1], "socketpair");
  ftsim::SensorSimulator simulator({});
  simulator.setWrench((Vec6() << 12.5, -31.0, -402.0, 18.25, 9.5, -1.75).finished());
  std::atomic<bool> stop{false};
  std::thread sensor([&] { simulator.serve(sensor_end, stop); });
  nlohmann::json j;
  {
    runtime::FtSensorDriver driver(runtime::CanSocket::adopt(ends[0], "socketpair"), {});
    TimingSink sink;
    runtime::WrenchSample sample;
    std::vector<double> poll_us, receive_to_publish_us;
    poll_us.reserve(size_t(polls));
    receive_to_publish_us.reserve(size_t(polls));
    for (int k = 0; k < 1000; ++k) driver.pollOnce(Clock::now() + std::chrono::milliseconds(100), sink, sample);
    long allocations = 0;
    int timeouts = 0;
    {
      test::AllocationCounter counter;
      for (int k = 0; k < polls; ++k) {
        const int64_t sent_ns = runtime::steadyNowNs();
        if (driver.pollOnce(Clock::now() + std::chrono::milliseconds(100), sink, sample) !=
            runtime::PollResult::kSample) {
          ++timeouts;
          continue;
        }
        poll_us.push_back(double(sink.published_ns - sent_ns) * 1e-3);
        receive_to_publish_us.push_back(double(sink.published_ns - sink.stamp_ns) * 1e-3);
      }
      allocations = counter.count();
    }
    const runtime::FtSensorCounters c = driver.counters();
    j = {{"polls", polls},
         {"timeouts", timeouts},
         {"late_frames", c.late},
         {"unpaired_frames", c.unpaired},
         {"allocations", allocations},
         {"request_to_sample_us", summary(poll_us)},
         {"kernel_receive_to_sample_us", summary(receive_to_publish_us)}};
  }
  stop = true;
  sensor.join();
  return j;
}

void printLine(const char* name, const nlohmann::json& s) {
  std::printf("%-34s p50 %8.3f us  p99 %8.3f us  p99.9 %8.3f us  max %9.3f us  (%zu)\n", name,
              s["p50_us"].get<double>(), s["p99_us"].get<double>(), s["p999_us"].get<double>(),
              s["max_us"].get<double>(), s["samples"].get<size_t>());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal-bench-can: the F/T driver's parsing path, in memory and over a socketpair"};
  int polls = 100000, pairs = 1000000;
  bool json = false;
  app.add_option("--polls", polls, "socketpair polls")->capture_default_str()->check(CLI::Range(1, 100000000));
  app.add_option("--pairs", pairs, "in-memory readings (batches of 1000)")
      ->capture_default_str()->check(CLI::Range(1000, 1000000000));
  app.add_flag("--json", json, "print JSON");
  CLI11_PARSE(app, argc, argv);
  const nlohmann::json report = {{"in_memory_per_reading", benchInMemory(pairs)},
                                 {"socketpair", benchSocketpair(polls)}};
  if (json) {
    std::cout << report.dump(2) << "\n";
    return 0;
  }
  printLine("in memory, per reading (batch mean)", report["in_memory_per_reading"]);
  printLine("socketpair, request -> sample", report["socketpair"]["request_to_sample_us"]);
  printLine("socketpair, kernel rx -> sample", report["socketpair"]["kernel_receive_to_sample_us"]);
  const nlohmann::json& pair = report["socketpair"];
  std::printf("allocations in the timed loops: %ld in memory, %ld socketpair; polls timed out "
              "(100 ms): %d; late frames %lld, unpaired %lld\n",
              report["in_memory_per_reading"]["allocations"].get<long>(),
              pair["allocations"].get<long>(), pair["timeouts"].get<int>(),
              pair["late_frames"].get<long long>(), pair["unpaired_frames"].get<long long>());
  return 0;
}
