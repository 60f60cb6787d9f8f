#include "stepcal/runtime/ft_sensor.hpp"

#include <time.h>

#include <cmath>
#include <cstdio>
#include <thread>

#include "stepcal/common/error.hpp"

namespace stepcal::runtime {

using netcan::FrameKind;
using netcan::Opcode;

namespace {

std::string hexId(uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%02X", value);
  return text;
}

const char* requestName(Opcode opcode) {
  switch (opcode) {
    case Opcode::kReadGauges: return "read gauges";
    case Opcode::kReadMatrixRow: return "read matrix row";
    case Opcode::kReadSerial: return "read serial number";
    case Opcode::kSetActiveCalibration: return "set active calibration";
    case Opcode::kReadCountsPerUnit: return "read counts per unit";
    case Opcode::kReadUnitCodes: return "read unit codes";
    case Opcode::kReadFirmware: return "read firmware version";
    default: return "request";
  }
}

void sleepUntil(Clock::time_point when) noexcept {
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(when.time_since_epoch()).count();
  timespec wake{time_t(ns / 1'000'000'000), long(ns % 1'000'000'000)};
  // steady_clock is CLOCK_MONOTONIC on Linux; an absolute wake-up does not drift.
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
  }
}

/// Increments a counter only its one writer thread changes.
void bump(std::atomic<int64_t>& counter) noexcept {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

}  // namespace

const char* toString(FtSensorState state) noexcept {
  switch (state) {
    case FtSensorState::kRunning: return "running";
    case FtSensorState::kBusOff: return "bus-off";
    case FtSensorState::kResetting: return "resetting";
    case FtSensorState::kFault: return "fault";
  }
  return "unknown";
}

can_filter sensorFilter(uint32_t base_id) noexcept {
  can_filter filter{};
  filter.can_id = base_id << netcan::kOpcodeBits;
  // Only standard data frames: EFF and RTR must be clear; the opcode nibble is free.
  filter.can_mask = (CAN_SFF_MASK & ~0xFu) | CAN_EFF_FLAG | CAN_RTR_FLAG;
  return filter;
}

FtSensorDriver::FtSensorDriver(CanSocket socket, FtSensorOptions options)
    : socket_(std::move(socket)), options_(options) {
  const std::string where = "F/T sensor on " + socket_.name() + ", base id " + hexId(options_.base_id);
  if (options_.base_id > netcan::kMaxBaseId) {
    throw InputError(where + ": base id must be 0x00 … 0x7F (7 bits)");
  }
  if (!(options_.poll_hz > 0.0 && options_.poll_hz <= 10'000.0)) {
    throw InputError(where + ": poll rate " + std::to_string(options_.poll_hz) +
                     " Hz: expected 0 < rate ≤ 10000 Hz");
  }
  if (options_.calibration_index < -1 || options_.calibration_index > 15) {
    throw InputError(where + ": calibration index " + std::to_string(options_.calibration_index) +
                     ": expected 0 … 15, or −1 to keep the active one");
  }
  if (options_.bias_samples < 1) throw InputError(where + ": bias samples must be ≥ 1");
  if (options_.startup_attempts < 1 || options_.startup_timeout_ns <= 0) {
    throw InputError(where + ": start-up attempts and timeout must be > 0");
  }
  if (const std::string failure = readIdentity(); !failure.empty()) {
    throw InputError(where + ": " + failure +
                     "; check the base id, the bit rate, the wiring and that the sensor is powered");
  }
  try {
    converter_ = netcan::WrenchConverter(identity_.calibration);
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
  last_reading_ns_ = steadyNowNs();
}

bool FtSensorDriver::ask(Opcode opcode, const uint8_t* data, uint8_t length, int replies,
                         can_frame* out) {
  const can_frame request = netcan::makeFrame(options_.base_id, opcode, data, length);
  for (int attempt = 0; attempt < options_.startup_attempts; ++attempt) {
    const int64_t sent_ns = steadyNowNs();
    if (socket_.send(request) != CanIo::kOk) {
      bump(counters_.send_failures);
      std::this_thread::sleep_for(std::chrono::nanoseconds(options_.startup_timeout_ns));
      continue;
    }
    const Clock::time_point deadline = Clock::now() + std::chrono::nanoseconds(options_.startup_timeout_ns);
    int got = 0;
    ReceivedFrame received;
    while (got < replies && socket_.receive(received, deadline) == CanIo::kOk) {
      const FrameKind kind = netcan::classify(received.frame, options_.base_id);
      const auto expected = netcan::frameId(options_.base_id, Opcode(uint8_t(opcode) + got));
      if (kind == FrameKind::kError) {
        bump(counters_.error_frames);
      } else if (received.stamp_ns < sent_ns) {
        bump(counters_.late);
      } else if (received.frame.can_id == expected &&
                 (kind == FrameKind::kReply || kind == FrameKind::kGaugesFirst)) {
        out[got++] = received.frame;
      } else if (kind == FrameKind::kBadLength) {
        bump(counters_.bad_length);
      } else if (kind == FrameKind::kUnknownOpcode) {
        bump(counters_.unknown_opcode);
      } else if (kind == FrameKind::kForeignId) {
        bump(counters_.foreign_id);
      } else {
        bump(counters_.unexpected_reply);
      }
    }
    if (got == replies) return true;
  }
  return false;
}

std::string FtSensorDriver::readIdentity() {
  const auto noAnswer = [&](Opcode opcode, const std::string& detail) {
    return "no valid answer to '" + std::string(requestName(opcode)) + detail + "' (id " +
           hexId(netcan::frameId(options_.base_id, opcode)) + ") within " +
           std::to_string(options_.startup_timeout_ns / 1'000'000) + " ms, " +
           std::to_string(options_.startup_attempts) + " attempts";
  };
  FtSensorIdentity identity;
  can_frame replies[3];
  if (options_.calibration_index >= 0) {
    const uint8_t index = uint8_t(options_.calibration_index);
    if (!ask(Opcode::kSetActiveCalibration, &index, 1, 1, replies)) {
      return noAnswer(Opcode::kSetActiveCalibration, " " + std::to_string(index));
    }
    if (replies[0].data[0] != index) {
      return "the sensor refused calibration index " + std::to_string(index) + " (it answered " +
             std::to_string(replies[0].data[0]) + "): is that calibration loaded on it?";
    }
    identity.calibration_index = index;
  }
  if (!ask(Opcode::kReadSerial, nullptr, 0, 1, replies)) return noAnswer(Opcode::kReadSerial, "");
  identity.serial.assign(reinterpret_cast<const char*>(replies[0].data), 8);
  while (!identity.serial.empty() && (identity.serial.back() == ' ' || identity.serial.back() == '\0')) {
    identity.serial.pop_back();
  }
  if (!ask(Opcode::kReadFirmware, nullptr, 0, 1, replies)) return noAnswer(Opcode::kReadFirmware, "");
  identity.firmware_major = replies[0].data[0];
  identity.firmware_minor = replies[0].data[1];
  identity.firmware_build = netcan::readU16(replies[0].data + 2);
  for (uint8_t row = 0; row < netcan::kAxes; ++row) {
    if (!ask(Opcode::kReadMatrixRow, &row, 1, 3, replies)) {
      return noAnswer(Opcode::kReadMatrixRow, " " + std::to_string(row));
    }
    for (int k = 0; k < 3; ++k) {
      for (int half = 0; half < 2; ++half) {
        identity.calibration.matrix[size_t(row * netcan::kGauges + 2 * k + half)] =
            netcan::readF32(replies[k].data + 4 * half);
      }
    }
  }
  if (!ask(Opcode::kReadCountsPerUnit, nullptr, 0, 1, replies)) {
    return noAnswer(Opcode::kReadCountsPerUnit, "");
  }
  identity.calibration.counts_per_force = netcan::readU32(replies[0].data);
  identity.calibration.counts_per_torque = netcan::readU32(replies[0].data + 4);
  if (!ask(Opcode::kReadUnitCodes, nullptr, 0, 1, replies)) return noAnswer(Opcode::kReadUnitCodes, "");
  identity.calibration.force_unit = replies[0].data[0];
  identity.calibration.torque_unit = replies[0].data[1];
  identity_ = std::move(identity);
  return {};
}

void FtSensorDriver::publishFault(uint32_t status, WrenchSink& sink) noexcept {
  WrenchSample sample;
  sample.stamp_ns = steadyNowNs();
  sample.sensor_status = status;
  sample.sequence = ++sequence_;
  sink.publish(sample);
}

void FtSensorDriver::handleErrorFrame(const can_frame& frame, WrenchSink& sink) noexcept {
  bump(counters_.error_frames);
  const FtSensorState state = counters_.state.load(std::memory_order_relaxed);
  if ((frame.can_id & CAN_ERR_BUSOFF) && state != FtSensorState::kBusOff) {
    bump(counters_.bus_off);
    counters_.state.store(FtSensorState::kBusOff, std::memory_order_relaxed);
    bus_off_since_ns_ = steadyNowNs();
    publishFault(kSampleBusOff, sink);
  }
  if ((frame.can_id & CAN_ERR_RESTARTED) &&
      counters_.state.load(std::memory_order_relaxed) == FtSensorState::kBusOff) {
    bump(counters_.restarts);
    counters_.state.store(FtSensorState::kRunning, std::memory_order_relaxed);
  }
}

PollResult FtSensorDriver::pollOnce(Clock::time_point deadline, WrenchSink& sink,
                                    WrenchSample& out) noexcept {
  assembler_.reset();
  const can_frame request = netcan::makeFrame(options_.base_id, Opcode::kReadGauges);
  const int64_t sent_ns = steadyNowNs();
  if (socket_.send(request) != CanIo::kOk) {
    bump(counters_.send_failures);
    return PollResult::kSendFailed;
  }
  bump(counters_.polls);
  ReceivedFrame received;
  for (;;) {
    const CanIo io = socket_.receive(received, deadline);
    if (io != CanIo::kOk) {
      bump(counters_.timeouts);
      return PollResult::kTimeout;
    }
    const can_frame& frame = received.frame;
    switch (netcan::classify(frame, options_.base_id)) {
      case FrameKind::kError:
        handleErrorFrame(frame, sink);
        if (counters_.state.load(std::memory_order_relaxed) == FtSensorState::kBusOff) {
          return PollResult::kBusOff;
        }
        break;
      case FrameKind::kForeignId: bump(counters_.foreign_id); break;
      case FrameKind::kBadLength: bump(counters_.bad_length); break;
      case FrameKind::kUnknownOpcode: bump(counters_.unknown_opcode); break;
      case FrameKind::kReply: bump(counters_.unexpected_reply); break;
      case FrameKind::kGaugesFirst:
        if (received.stamp_ns < sent_ns) {
          bump(counters_.late);
        } else if (!assembler_.first(frame)) {
          bump(counters_.unpaired);
        }
        break;
      case FrameKind::kGaugesSecond: {
        netcan::GaugeReading reading;
        if (received.stamp_ns < sent_ns) {
          bump(counters_.late);
          break;
        }
        if (!assembler_.second(frame, reading)) {
          bump(counters_.unpaired);
          break;
        }
        const bool critical = (reading.status_word & netcan::status_bit::kCritical) != 0;
        counters_.last_status_word.store(reading.status_word, std::memory_order_relaxed);
        if (bias_pending_ > 0 && !critical) {
          for (int j = 0; j < netcan::kGauges; ++j) bias_sum_[j] += reading.gauges[size_t(j)];
          if (--bias_pending_ == 0) {
            bias_gauges_ = bias_sum_ / double(options_.bias_samples);
            biased_.store(true, std::memory_order_relaxed);
          }
        }
        out.wrench_Sensor = converter_.wrench(reading.gauges, bias_gauges_);
        out.stamp_ns = received.stamp_ns;
        out.sensor_status = critical ? reading.status_word : 0u;
        out.sequence = ++sequence_;
        last_reading_ns_ = received.stamp_ns;
        if (critical) bump(counters_.critical_status);
        bump(counters_.samples);
        sink.publish(out);
        return PollResult::kSample;
      }
    }
  }
}

void FtSensorDriver::applyCommands() noexcept {
  if (bias_clear_requested_.exchange(false, std::memory_order_relaxed)) {
    bias_gauges_.setZero();
    bias_pending_ = 0;
    biased_.store(false, std::memory_order_relaxed);
  }
  if (bias_requested_.exchange(false, std::memory_order_relaxed)) {
    bias_sum_.setZero();
    bias_pending_ = options_.bias_samples;
  }
}

void FtSensorDriver::doReset() noexcept {
  counters_.state.store(FtSensorState::kResetting, std::memory_order_relaxed);
  socket_.send(netcan::makeFrame(options_.base_id, Opcode::kReset));
  std::this_thread::sleep_for(std::chrono::nanoseconds(options_.reset_silence_ns));
  // The gauges restart from the sensor's power-on state: a bias taken before is void.
  bias_gauges_.setZero();
  bias_pending_ = 0;
  biased_.store(false, std::memory_order_relaxed);
  try {
    if (readIdentity().empty()) {
      converter_ = netcan::WrenchConverter(identity_.calibration);
      bump(counters_.resets);
      counters_.state.store(FtSensorState::kRunning, std::memory_order_relaxed);
      return;
    }
  } catch (const std::exception&) {
    // An unusable calibration after the reset: the sensor stays in fault.
  }
  counters_.state.store(FtSensorState::kFault, std::memory_order_relaxed);
}

bool FtSensorDriver::resync() noexcept {
  try {
    const FtSensorIdentity before = identity_;
    if (!readIdentity().empty()) return false;
    const netcan::Calibration& now = identity_.calibration;
    const netcan::Calibration& was = before.calibration;
    const bool same = identity_.serial == before.serial && now.matrix == was.matrix &&
                      now.counts_per_force == was.counts_per_force &&
                      now.counts_per_torque == was.counts_per_torque &&
                      now.force_unit == was.force_unit && now.torque_unit == was.torque_unit;
    if (!same) {
      // Another sensor or calibration: its gauges mean something else, and the tare is void.
      converter_ = netcan::WrenchConverter(identity_.calibration);
      bias_gauges_.setZero();
      bias_pending_ = 0;
      biased_.store(false, std::memory_order_relaxed);
    }
  } catch (const std::exception&) {
    // An unusable calibration: the silence goes on, and so do the attempts.
    return false;
  }
  bump(counters_.resyncs);
  last_reading_ns_ = steadyNowNs();
  return true;
}

void FtSensorDriver::run(WrenchSink& sink) noexcept {
  const auto period = std::chrono::nanoseconds(int64_t(std::llround(1e9 / options_.poll_hz)));
  const auto probe_period = std::chrono::nanoseconds(options_.bus_off_probe_ns);
  Clock::time_point next = Clock::now();
  Clock::time_point last_probe = next;
  WrenchSample sample;
  while (!stop_.load(std::memory_order_relaxed)) {
    applyCommands();
    if (reset_requested_.exchange(false, std::memory_order_relaxed)) {
      publishFault(kSampleBusOff, sink);  // no valid wrench until the sensor is back
      doReset();
      next = Clock::now();
    }
    next += period;
    const Clock::time_point now = Clock::now();
    if (next < now) next = now + period;  // missed polls are skipped, not caught up
    switch (counters_.state.load(std::memory_order_relaxed)) {
      case FtSensorState::kRunning:
        if (steadyNowNs() - last_reading_ns_ < options_.resync_after_silence_ns) {
          pollOnce(next, sink, sample);
        } else if (now - last_probe >= probe_period) {
          // Silent long enough to have restarted: its gauges count again once it is read anew.
          last_probe = now;
          resync();
        }
        sleepUntil(next);
        break;
      case FtSensorState::kBusOff:
      case FtSensorState::kResetting:
        if (now - last_probe >= probe_period) {
          // No restart reported: the bus may be back anyway (restart by hand, other tools).
          last_probe = now;
          if (pollOnce(next, sink, sample) == PollResult::kSample) {
            bump(counters_.restarts);
            counters_.state.store(FtSensorState::kRunning, std::memory_order_relaxed);
          }
        } else {
          // Listen for the controller's restart notice without transmitting.
          ReceivedFrame received;
          while (socket_.receive(received, next) == CanIo::kOk) {
            if (netcan::classify(received.frame, options_.base_id) == FrameKind::kError) {
              handleErrorFrame(received.frame, sink);
            }
          }
        }
        break;
      case FtSensorState::kFault:
        if (now - last_probe >= probe_period) {
          last_probe = now;
          doReset();
        }
        sleepUntil(next);
        break;
    }
  }
}

FtSensorCounters FtSensorDriver::counters() const noexcept {
  FtSensorCounters c;
  const auto get = [](const std::atomic<int64_t>& v) { return v.load(std::memory_order_relaxed); };
  c.polls = get(counters_.polls);
  c.samples = get(counters_.samples);
  c.timeouts = get(counters_.timeouts);
  c.critical_status = get(counters_.critical_status);
  c.foreign_id = get(counters_.foreign_id);
  c.bad_length = get(counters_.bad_length);
  c.unknown_opcode = get(counters_.unknown_opcode);
  c.unpaired = get(counters_.unpaired);
  c.late = get(counters_.late);
  c.unexpected_reply = get(counters_.unexpected_reply);
  c.error_frames = get(counters_.error_frames);
  c.bus_off = get(counters_.bus_off);
  c.restarts = get(counters_.restarts);
  c.send_failures = get(counters_.send_failures);
  c.resets = get(counters_.resets);
  c.resyncs = get(counters_.resyncs);
  c.last_status_word = counters_.last_status_word.load(std::memory_order_relaxed);
  c.state = counters_.state.load(std::memory_order_relaxed);
  return c;
}

}  // namespace stepcal::runtime
