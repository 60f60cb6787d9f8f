#include "stepcal/ftsim/simulator.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <thread>

#include "stepcal/common/error.hpp"

namespace stepcal::ftsim {

using runtime::CanIo;
using runtime::netcan::Opcode;
namespace netcan = runtime::netcan;

runtime::netcan::Calibration defaultCalibration() {
  // Gauge count → counts: diagonal gains plus a fixed cross-coupling (a sensor's matrix is dense).
  constexpr float kForceGain = 46.0f, kMomentGain = 4.6f;  // counts per gauge count
  constexpr float kCoupling[6][6] = {
      {1.000f, 0.112f, -0.043f, 0.021f, -0.087f, 0.034f},
      {-0.065f, 1.000f, 0.078f, -0.052f, 0.016f, -0.029f},
      {0.031f, -0.024f, 1.000f, 0.093f, -0.041f, 0.057f},
      {0.048f, 0.017f, -0.069f, 1.000f, 0.103f, -0.012f},
      {-0.022f, 0.061f, 0.035f, -0.074f, 1.000f, 0.046f},
      {0.083f, -0.038f, 0.014f, 0.027f, -0.055f, 1.000f}};
  netcan::Calibration calibration;
  for (int i = 0; i < 6; ++i) {
    const float gain = i < 3 ? kForceGain : kMomentGain;
    for (int j = 0; j < 6; ++j) calibration.matrix[size_t(6 * i + j)] = gain * kCoupling[i][j];
  }
  calibration.counts_per_force = 1000;
  calibration.counts_per_torque = 1000;
  calibration.force_unit = 2;   // N
  calibration.torque_unit = 3;  // N·m
  return calibration;
}

can_frame errorFrame(canid_t error_classes) {
  can_frame frame{};
  frame.can_id = CAN_ERR_FLAG | (error_classes & CAN_ERR_MASK);
  frame.can_dlc = CAN_ERR_DLC;
  return frame;
}

SensorSimulator::SensorSimulator(SimulatorOptions options)
    : options_(std::move(options)),
      converter_(options_.calibration),
      random_(options_.seed) {
  if (options_.base_id > netcan::kMaxBaseId) throw InputError("simulated sensor: base id > 0x7F");
  if (options_.serial.size() > 8) throw InputError("simulated sensor: serial longer than 8 characters");
}

void SensorSimulator::setWrench(const Vec6& wrench_Sensor) {
  std::lock_guard<std::mutex> lock(mutex_);
  wrench_Sensor_ = wrench_Sensor;
  verbatim_ = false;
}

void SensorSimulator::setGauges(const std::array<int16_t, netcan::kGauges>& gauges) {
  std::lock_guard<std::mutex> lock(mutex_);
  verbatim_gauges_ = gauges;
  verbatim_ = true;
}

void SensorSimulator::setFaults(const Faults& faults) {
  std::lock_guard<std::mutex> lock(mutex_);
  faults_ = faults;
}

SimulatorCounters SensorSimulator::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

std::array<int16_t, netcan::kGauges> SensorSimulator::gaugesFor(const Vec6& wrench_Sensor) const {
  const Vec6 gauges = converter_.gaugesFor(wrench_Sensor);
  std::array<int16_t, netcan::kGauges> out{};
  for (int j = 0; j < netcan::kGauges; ++j) {
    out[size_t(j)] = int16_t(std::clamp(std::lround(gauges[j]), -32768L, 32767L));
  }
  return out;
}

can_frame SensorSimulator::corrupt(const can_frame& frame) {
  can_frame bad = frame;
  if (std::uniform_int_distribution<int>(0, 1)(random_) == 0) {
    bad.can_dlc = uint8_t(std::uniform_int_distribution<int>(0, frame.can_dlc - 1)(random_));
  } else {
    constexpr uint8_t kNoReply[] = {0xA, 0xB, 0xC, 0xD, 0xE};
    const uint8_t opcode = kNoReply[std::uniform_int_distribution<int>(0, 4)(random_)];
    bad.can_id = (frame.can_id & ~canid_t(0xF)) | opcode;
  }
  ++counters_.corrupted;
  return bad;
}

can_frame SensorSimulator::garbageFrame() {
  can_frame frame{};
  do {
    frame.can_id = canid_t(std::uniform_int_distribution<int>(0, CAN_SFF_MASK)(random_));
  } while ((frame.can_id >> netcan::kOpcodeBits) == options_.base_id);
  frame.can_dlc = uint8_t(std::uniform_int_distribution<int>(0, 8)(random_));
  for (uint8_t& byte : frame.data) byte = uint8_t(random_());
  ++counters_.garbage;
  return frame;
}

void SensorSimulator::addGaugeReplies(std::vector<can_frame>& replies) {
  std::array<int16_t, netcan::kGauges> gauges = verbatim_gauges_;
  if (!verbatim_) {
    std::normal_distribution<double> unit(0.0, 1.0);
    Vec6 felt = wrench_Sensor_ + options_.offset_Sensor;
    for (int i = 0; i < 3; ++i) felt[i] += options_.force_sigma_n * unit(random_);
    for (int i = 3; i < 6; ++i) felt[i] += options_.moment_sigma_nm * unit(random_);
    const Vec6 exact = converter_.gaugesFor(felt);
    for (int j = 0; j < netcan::kGauges; ++j) {
      const long rounded = std::lround(exact[j]);
      if (rounded < -32768 || rounded > 32767) ++counters_.saturated;
      gauges[size_t(j)] = int16_t(std::clamp(rounded, -32768L, 32767L));
    }
  }
  std::array<can_frame, 2> frames = netcan::encodeGauges(options_.base_id, faults_.status_word, gauges);
  if (faults_.second_half_first) std::swap(frames[0], frames[1]);
  ++counters_.gauge_replies;
  std::uniform_real_distribution<double> chance(0.0, 1.0);
  for (const can_frame& frame : frames) {
    for (int g = 0; g < faults_.garbage_per_poll; ++g) replies.push_back(garbageFrame());
    if (faults_.drop_probability > 0.0 && chance(random_) < faults_.drop_probability) {
      ++counters_.dropped;
      continue;
    }
    if (faults_.corrupt_probability > 0.0 && chance(random_) < faults_.corrupt_probability) {
      replies.push_back(corrupt(frame));
      continue;
    }
    replies.push_back(frame);
  }
}

void SensorSimulator::respond(const can_frame& frame, std::vector<can_frame>& replies) {
  if (frame.can_id & (CAN_ERR_FLAG | CAN_EFF_FLAG | CAN_RTR_FLAG)) return;
  if ((frame.can_id >> netcan::kOpcodeBits) != options_.base_id) return;
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.requests;
  const int64_t now_ns = runtime::steadyNowNs();
  if (faults_.stalled || now_ns < silent_until_ns_) return;
  const uint32_t base = options_.base_id;
  const auto opcode = Opcode(frame.can_id & 0xF);
  uint8_t data[8] = {};
  switch (opcode) {
    case Opcode::kReadGauges:
      if (frame.can_dlc == 0) addGaugeReplies(replies);
      return;
    case Opcode::kReadMatrixRow:
      if (frame.can_dlc == 1 && frame.data[0] < netcan::kAxes) {
        for (const can_frame& reply : netcan::encodeMatrixRow(base, options_.calibration, frame.data[0])) {
          replies.push_back(reply);
        }
      }
      return;
    case Opcode::kReadSerial:
      std::memcpy(data, options_.serial.data(), options_.serial.size());
      for (size_t k = options_.serial.size(); k < 8; ++k) data[k] = ' ';
      replies.push_back(netcan::makeFrame(base, opcode, data, 8));
      return;
    case Opcode::kSetActiveCalibration:
      if (frame.can_dlc != 1) return;
      if (frame.data[0] < options_.calibrations) active_calibration_ = frame.data[0];
      data[0] = uint8_t(active_calibration_);
      replies.push_back(netcan::makeFrame(base, opcode, data, 1));
      return;
    case Opcode::kReadCountsPerUnit:
      netcan::writeU32(data, options_.calibration.counts_per_force);
      netcan::writeU32(data + 4, options_.calibration.counts_per_torque);
      replies.push_back(netcan::makeFrame(base, opcode, data, 8));
      return;
    case Opcode::kReadUnitCodes:
      data[0] = options_.calibration.force_unit;
      data[1] = options_.calibration.torque_unit;
      replies.push_back(netcan::makeFrame(base, opcode, data, 2));
      return;
    case Opcode::kReadDiagnostic:
      if (frame.can_dlc != 1) return;
      netcan::writeU16(data, uint16_t(2500 + 100 * frame.data[0]));  // mV, fixed per channel
      replies.push_back(netcan::makeFrame(base, opcode, data, 2));
      return;
    case Opcode::kReset:
      ++counters_.resets;
      silent_until_ns_ = now_ns + options_.reset_silence_ns;
      return;
    case Opcode::kReadFirmware:
      data[0] = options_.firmware_major;
      data[1] = options_.firmware_minor;
      netcan::writeU16(data + 2, options_.firmware_build);
      replies.push_back(netcan::makeFrame(base, opcode, data, 4));
      return;
    default:
      return;  // replies of other sensors, unknown opcodes: a real sensor ignores them
  }
}

void SensorSimulator::serve(runtime::CanSocket& socket, const std::atomic<bool>& stop) {
  std::vector<can_frame> replies;
  replies.reserve(64);
  runtime::ReceivedFrame received;
  while (!stop.load(std::memory_order_relaxed)) {
    const CanIo io = socket.receive(received, runtime::Clock::now() + std::chrono::milliseconds(10));
    if (io == CanIo::kTimeout) continue;
    if (io == CanIo::kClosed) return;  // the driver's end of a socketpair went away
    if (io == CanIo::kDown) {
      // The interface is down (ip link set … down): a sensor on the wire waits for the bus.
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    if (io != CanIo::kOk) {
      throw InputError("simulated sensor on " + socket.name() + ": receive failed: " +
                       std::strerror(socket.lastErrno()));
    }
    replies.clear();
    respond(received.frame, replies);
    for (const can_frame& reply : replies) {
      // A full transmit queue drops the frame, as a real sensor's controller would.
      socket.send(reply);
    }
  }
}

}  // namespace stepcal::ftsim
