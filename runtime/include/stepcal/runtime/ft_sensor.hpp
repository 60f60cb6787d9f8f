// Driver of an ATI Net CAN OEM F/T sensor (protocol: netcan.hpp). At start-up it reads the
// sensor's identity and active calibration; then it polls the gauges at a fixed rate, turns them
// into a wrench (N, N·m, sensor axes) and hands each sample, stamped with the kernel's receive
// time, to a sink (the runtime's lock-free WrenchSlot, optionally LCM).
//
// Faults, and what the runtime sees:
//   no reply before the next poll   → counted; nothing published, so the slot ages into
//                                     STALE_WRENCH after the runtime's max age
//   critical sensor status bits     → the sample is published with sensor_status = status word:
//                                     STALE_WRENCH at once
//   bus-off (CAN error frame)       → a sample with kSampleBusOff is published (STALE_WRENCH at
//                                     once); polling stops until the controller reports its
//                                     restart (CAN_ERR_RESTARTED, e.g. `ip link set can0 type can
//                                     restart-ms 100`) or a probe every bus_off_probe_ns answers
//   no reading for resync_after_silence_ns
//                                   → the sensor may have restarted (power cycle, another
//                                     calibration active): no gauge polls until its identity
//                                     and calibration were read again (tried every
//                                     bus_off_probe_ns); a changed calibration voids the bias
//   frames of other ids, wrong lengths, unknown opcodes, late or unpaired halves
//                                   → ignored and counted
// The poll loop allocates nothing, locks nothing and throws nothing (the reads of the identity
// after a reset or a silence do allocate: no wrench is delivered then).
#pragma once



#include <atomic>
#include <cstdint>
#include <string>

#include "stepcal/runtime/can_socket.hpp"
#include "stepcal/runtime/handoff.hpp"
#include "stepcal/runtime/netcan.hpp"

namespace stepcal::runtime {

/// Set in WrenchSample::sensor_status (above the 16 status-word bits) for driver-side faults.
constexpr uint32_t kSampleBusOff = 1u << 16;

struct FtSensorOptions {
  uint32_t base_id = 0x20;  ///< the sensor's base id (0 … 0x7F); frames are base_id << 4 | opcode
  double poll_hz = 1000.0;  ///< gauge requests per second
  /// Calibration index to make active at start-up (0 … 15); −1 keeps the sensor's active one.
  int calibration_index = 0;
  int bias_samples = 16;    ///< readings averaged into the bias (tare) when one is requested
  int64_t startup_timeout_ns = 100'000'000;  ///< per start-up request, ns
  int startup_attempts = 3;                  ///< tries per start-up request
  int64_t bus_off_probe_ns = 200'000'000;    ///< poll attempt while bus-off without restart, ns
  int64_t reset_silence_ns = 300'000'000;    ///< wait after a reset before reading again, ns
  int64_t resync_after_silence_ns = 500'000'000;  ///< no reading this long: read identity again, ns
};

/// What the sensor reported at start-up.
struct FtSensorIdentity {
  std::string serial;  ///< 8 ASCII characters, trailing spaces/NULs trimmed
  uint8_t firmware_major = 0, firmware_minor = 0;
  uint16_t firmware_build = 0;
  int calibration_index = -1;  ///< active calibration (−1: not changed, unknown)
  netcan::Calibration calibration;
};

/// Receives every sample the driver produces. Called on the driver's thread.
class WrenchSink {
 public:
  virtual ~WrenchSink() = default;
  virtual void publish(const WrenchSample& sample) noexcept = 0;
};

enum class FtSensorState : uint8_t { kRunning = 0, kBusOff = 1, kResetting = 2, kFault = 3 };
const char* toString(FtSensorState state) noexcept;

/// Counters since start, readable from any thread.
struct FtSensorCounters {
  int64_t polls = 0;           ///< gauge requests sent
  int64_t samples = 0;         ///< readings published (valid or with critical status)
  int64_t timeouts = 0;        ///< polls without a complete reading before the next poll
  int64_t critical_status = 0; ///< readings with critical status bits
  int64_t foreign_id = 0;      ///< frames of other ids (only when the kernel filter lets them in)
  int64_t bad_length = 0;      ///< the sensor's id with a wrong data length
  int64_t unknown_opcode = 0;  ///< the sensor's id with an opcode that has no reply
  int64_t unpaired = 0;        ///< gauge halves that do not pair up within one poll
  int64_t late = 0;            ///< frames received before the poll they would answer was sent
  int64_t unexpected_reply = 0;///< well-formed replies to requests not in flight
  int64_t error_frames = 0;    ///< CAN error frames of any class
  int64_t bus_off = 0;         ///< bus-off events
  int64_t restarts = 0;        ///< recoveries from bus-off
  int64_t send_failures = 0;   ///< requests the socket refused
  int64_t resets = 0;          ///< sensor resets done
  int64_t resyncs = 0;         ///< identity and calibration read again after a silence
  uint16_t last_status_word = 0;  ///< of the latest reading
  FtSensorState state = FtSensorState::kRunning;
};

/// Outcome of one poll.
enum class PollResult : uint8_t { kSample, kTimeout, kBusOff, kSendFailed };

class FtSensorDriver {
 public:
  /// Reads the sensor's identity and calibration over socket (makes options.calibration_index
  /// active first). Throws InputError naming the interface, the base id and the request that
  /// got no valid answer.
  FtSensorDriver(CanSocket socket, FtSensorOptions options);
  FtSensorDriver(const FtSensorDriver&) = delete;
  FtSensorDriver& operator=(const FtSensorDriver&) = delete;

  const FtSensorIdentity& identity() const noexcept { return identity_; }
  const FtSensorOptions& options() const noexcept { return options_; }

  /// Polls at options.poll_hz on the calling thread until stop(), publishing to sink.
  void run(WrenchSink& sink) noexcept;
  /// Asks run() to return (any thread).
  void stop() noexcept { stop_.store(true, std::memory_order_relaxed); }

  /// One poll: sends a gauge request and reads frames until a reading completes or deadline.
  /// kSample: out holds the published sample (also handed to sink). Handles error frames and
  /// counts garbage on the way. Used by run(); tests and benchmarks call it directly.
  PollResult pollOnce(Clock::time_point deadline, WrenchSink& sink, WrenchSample& out) noexcept;

  /// The next options.bias_samples readings become the bias (tare). Any thread.
  void requestBias() noexcept { bias_requested_.store(true, std::memory_order_relaxed); }
  /// Drops the bias. Any thread.
  void clearBias() noexcept { bias_clear_requested_.store(true, std::memory_order_relaxed); }
  /// Resets the sensor and reads its calibration again (in run()'s thread). Any thread.
  void requestReset() noexcept { reset_requested_.store(true, std::memory_order_relaxed); }
  /// Whether a bias is in use (after a completed request).
  bool biased() const noexcept { return biased_.load(std::memory_order_relaxed); }

  /// A consistent-enough copy of the counters (each field read atomically). Any thread.
  FtSensorCounters counters() const noexcept;

 private:
  struct AtomicCounters;
  /// Sends request and collects its `replies` frames with the given opcodes' lengths; the
  /// start-up path (allocates, may throw from the caller).
  bool ask(netcan::Opcode opcode, const uint8_t* data, uint8_t length, int replies,
           can_frame* out);
  /// Reads identity and calibration into identity_; "" or what failed.
  std::string readIdentity();
  void handleErrorFrame(const can_frame& frame, WrenchSink& sink) noexcept;
  void publishFault(uint32_t status, WrenchSink& sink) noexcept;
  void applyCommands() noexcept;
  void doReset() noexcept;
  /// After a silence: reads identity and calibration again; true when the sensor answered.
  bool resync() noexcept;

  CanSocket socket_;
  FtSensorOptions options_;
  FtSensorIdentity identity_;
  netcan::WrenchConverter converter_;
  netcan::GaugeAssembler assembler_;

  Vec6 bias_gauges_ = Vec6::Zero();
  Vec6 bias_sum_ = Vec6::Zero();
  int bias_pending_ = 0;  ///< readings still to average into a requested bias
  uint64_t sequence_ = 0;
  int64_t bus_off_since_ns_ = 0;
  int64_t last_reading_ns_ = 0;  ///< kernel receive time of the latest reading

  std::atomic<bool> stop_{false};
  std::atomic<bool> bias_requested_{false};
  std::atomic<bool> bias_clear_requested_{false};
  std::atomic<bool> reset_requested_{false};
  std::atomic<bool> biased_{false};

  struct AtomicCounters {
    std::atomic<int64_t> polls{0}, samples{0}, timeouts{0}, critical_status{0}, foreign_id{0},
        bad_length{0}, unknown_opcode{0}, unpaired{0}, late{0}, unexpected_reply{0},
        error_frames{0}, bus_off{0}, restarts{0}, send_failures{0}, resets{0}, resyncs{0};
    std::atomic<uint16_t> last_status_word{0};
    std::atomic<FtSensorState> state{FtSensorState::kRunning};
  } counters_;
};

/// The kernel receive filter for one sensor: standard data frames base_id << 4 | 0x0 … 0xF.
can_filter sensorFilter(uint32_t base_id) noexcept;
/// Error classes the driver listens to (bus-off, restarted, controller, protocol, bus error, …).
constexpr can_err_mask_t kSensorErrorMask = CAN_ERR_MASK;

}  // namespace stepcal::runtime
