// The other side of the ATI Net CAN OEM protocol (runtime/netcan.hpp): a simulated F/T sensor
// that answers requests with gauges encoding a wrench it is given, with noise, and with faults on
// request. Used by the driver's tests (in-process, over vcan or a socketpair) and by the
// stepcal-ftsim tool (end-to-end runs beside stepcal-runtime).
//
// Not real-time: setters lock a mutex shared with respond().
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include "stepcal/runtime/can_socket.hpp"
#include "stepcal/runtime/netcan.hpp"

namespace stepcal::ftsim {

/// A plausible calibration of a large 6-axis sensor: about 0.046 N and 0.0046 N·m per gauge
/// count (full scale ≈ ±1500 N, ±150 N·m), gauges mixed as in a real cross-coupled sensor,
/// 1000 counts per N and per N·m.
runtime::netcan::Calibration defaultCalibration();

struct SimulatorOptions {
  uint32_t base_id = 0x20;
  std::string serial = "FT24093";  ///< up to 8 ASCII characters
  uint8_t firmware_major = 3, firmware_minor = 2;
  uint16_t firmware_build = 41;
  runtime::netcan::Calibration calibration = defaultCalibration();
  int calibrations = 1;           ///< calibration indices 0 … calibrations − 1 exist
  double force_sigma_n = 0.0;     ///< noise per force axis and sample, 1-σ, N
  double moment_sigma_nm = 0.0;   ///< noise per moment axis and sample, 1-σ, N·m
  Vec6 offset_Sensor = Vec6::Zero();  ///< reading with nothing attached (removed by a tare), N, N·m
  uint64_t seed = 1;
  int64_t reset_silence_ns = 100'000'000;  ///< silent after a reset request, ns
};

/// Faults injected into the replies. Probabilities per reply frame.
struct Faults {
  double drop_probability = 0.0;     ///< a reply frame is not sent
  double corrupt_probability = 0.0;  ///< a reply frame is sent truncated or with a bad opcode
  bool stalled = false;              ///< nothing is answered
  uint16_t status_word = 0;          ///< status word of every gauge reply
  int garbage_per_poll = 0;          ///< frames of random ids and lengths sent before each reply
  bool second_half_first = false;    ///< gauge replies sent in the wrong order
};

struct SimulatorCounters {
  int64_t requests = 0;        ///< frames addressed to the sensor
  int64_t gauge_replies = 0;   ///< gauge requests answered (both frames sent or dropped)
  int64_t dropped = 0, corrupted = 0, garbage = 0, saturated = 0;
  int64_t resets = 0;
};

class SensorSimulator {
 public:
  explicit SensorSimulator(SimulatorOptions options);

  /// The wrench the sensor feels from now on (before offset and noise), N, N·m, sensor axes.
  void setWrench(const Vec6& wrench_Sensor);
  void setFaults(const Faults& faults);
  /// Sends these gauges verbatim (no wrench, noise or offset) until setWrench is called again.
  void setGauges(const std::array<int16_t, runtime::netcan::kGauges>& gauges);
  const SimulatorOptions& options() const noexcept { return options_; }
  SimulatorCounters counters() const;

  /// Appends the replies to one received frame (none for frames not addressed to it).
  void respond(const can_frame& frame, std::vector<can_frame>& replies);
  /// Gauges that encode wrench_Sensor exactly rounded (no noise, no offset), saturated to int16.
  std::array<int16_t, runtime::netcan::kGauges> gaugesFor(const Vec6& wrench_Sensor) const;

  /// Answers frames on socket until stop is set (checked every 10 ms) or an adopted socket's peer
  /// closes it; waits while the interface is down. Throws InputError when the socket fails.
  void serve(runtime::CanSocket& socket, const std::atomic<bool>& stop);

 private:
  void addGaugeReplies(std::vector<can_frame>& replies);
  can_frame corrupt(const can_frame& frame);
  can_frame garbageFrame();

  SimulatorOptions options_;
  runtime::netcan::WrenchConverter converter_;
  mutable std::mutex mutex_;
  Vec6 wrench_Sensor_ = Vec6::Zero();
  bool verbatim_ = false;
  std::array<int16_t, runtime::netcan::kGauges> verbatim_gauges_{};
  Faults faults_;
  int active_calibration_ = 0;
  int64_t silent_until_ns_ = 0;
  std::mt19937_64 random_;
  SimulatorCounters counters_;
};

/// A CAN error frame of the given classes (CAN_ERR_BUSOFF, CAN_ERR_RESTARTED, …), as a
/// controller reports it; on vcan a simulator injects it.
can_frame errorFrame(canid_t error_classes);

}  // namespace stepcal::ftsim
