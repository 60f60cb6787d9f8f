#include "stepcal/runtime/netcan.hpp"

#include <cmath>
#include <cstring>
#include <sstream>

#include <Eigen/LU>

#include "stepcal/common/error.hpp"

namespace stepcal::runtime::netcan {

std::string describeStatus(uint16_t status_word) {
  static constexpr std::pair<uint16_t, const char*> kNames[] = {
      {status_bit::kWatchdogReset, "watchdog reset"},
      {status_bit::kDacAdcTooHigh, "DAC/ADC check too high"},
      {status_bit::kDacAdcTooLow, "DAC/ADC check too low"},
      {status_bit::kAnalogGroundOutOfRange, "analog ground out of range"},
      {status_bit::kPowerSupplyTooHigh, "power supply too high"},
      {status_bit::kPowerSupplyTooLow, "power supply too low"},
      {status_bit::kBadActiveCalibration, "bad active calibration"},
      {status_bit::kEepromFailure, "EEPROM failure"},
      {status_bit::kConfigurationInvalid, "configuration invalid"},
      {status_bit::kSensorTooHot, "sensor too hot"},
      {status_bit::kSensorTooCold, "sensor too cold"},
      {status_bit::kCanBusError, "CAN bus error"},
      {status_bit::kAnyError, "error"},
  };
  std::string out;
  uint16_t named = 0;
  for (const auto& [bit, name] : kNames) {
    if ((status_word & bit) == 0) continue;
    named |= bit;
    if (!out.empty()) out += ", ";
    out += name;
  }
  if (const uint16_t reserved = status_word & uint16_t(~named)) {
    std::ostringstream hex;
    hex << std::hex << "0x" << reserved;
    if (!out.empty()) out += ", ";
    out += "reserved bits " + hex.str();
  }
  return out;
}

double newtonsPerForceUnit(uint8_t code) noexcept {
  constexpr double kLbf = 4.4482216152605;  // N, exact by definition of the pound-force
  switch (code) {
    case 1: return kLbf;
    case 2: return 1.0;
    case 3: return 1000.0 * kLbf;
    case 4: return 1000.0;
    case 5: return 9.80665;
    case 6: return 9.80665e-3;
    default: return 0.0;
  }
}

double newtonMetresPerTorqueUnit(uint8_t code) noexcept {
  constexpr double kLbfIn = 4.4482216152605 * 0.0254;
  switch (code) {
    case 1: return kLbfIn;
    case 2: return 12.0 * kLbfIn;
    case 3: return 1.0;
    case 4: return 1e-3;
    case 5: return 9.80665e-2;
    case 6: return 1000.0;
    default: return 0.0;
  }
}

WrenchConverter::WrenchConverter(const Calibration& calibration) {
  for (int i = 0; i < kAxes; ++i) {
    for (int j = 0; j < kGauges; ++j) {
      const float value = calibration.matrix[size_t(i * kGauges + j)];
      if (!std::isfinite(value)) {
        throw InputError("sensor calibration matrix row " + std::to_string(i) + " column " +
                         std::to_string(j) + " is " + std::to_string(value) +
                         ": expected a finite number; the sensor's active calibration is "
                         "corrupt or another calibration index is needed");
      }
      matrix_(i, j) = double(value);
    }
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(matrix_);
  if (lu.rank() < 6) {
    throw InputError("sensor calibration matrix has rank " + std::to_string(lu.rank()) +
                     ": expected 6 (a 6-axis calibration); check the active calibration index");
  }
  if (calibration.counts_per_force == 0 || calibration.counts_per_torque == 0) {
    throw InputError("sensor counts per unit are " + std::to_string(calibration.counts_per_force) +
                     " (force) and " + std::to_string(calibration.counts_per_torque) +
                     " (torque): expected both > 0");
  }
  const double force_si = newtonsPerForceUnit(calibration.force_unit);
  const double torque_si = newtonMetresPerTorqueUnit(calibration.torque_unit);
  if (force_si == 0.0 || torque_si == 0.0) {
    throw InputError("sensor unit codes are " + std::to_string(calibration.force_unit) +
                     " (force) and " + std::to_string(calibration.torque_unit) +
                     " (torque): expected force 1–6 (lbf, N, klbf, kN, kgf, gf) and torque 1–6 "
                     "(lbf·in, lbf·ft, N·m, N·mm, kgf·cm, kN·m)");
  }
  si_per_count_.head<3>().setConstant(force_si / double(calibration.counts_per_force));
  si_per_count_.tail<3>().setConstant(torque_si / double(calibration.counts_per_torque));
}

Vec6 WrenchConverter::wrench(const std::array<int16_t, kGauges>& gauges,
                             const Vec6& bias_gauges) const noexcept {
  Vec6 out;
  for (int i = 0; i < kAxes; ++i) {
    double counts = 0.0;
    for (int j = 0; j < kGauges; ++j) counts += matrix_(i, j) * (double(gauges[size_t(j)]) - bias_gauges[j]);
    out[i] = counts * si_per_count_[i];
  }
  return out;
}

Vec6 WrenchConverter::gaugesFor(const Vec6& wrench_Sensor) const noexcept {
  const Vec6 counts = wrench_Sensor.cwiseQuotient(si_per_count_);
  return matrix_.fullPivLu().solve(counts);
}

uint32_t readU32(const uint8_t* p) noexcept {
  return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | uint32_t(p[3]);
}

float readF32(const uint8_t* p) noexcept {
  const uint32_t bits = readU32(p);
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

void writeU16(uint8_t* p, uint16_t value) noexcept {
  p[0] = uint8_t(value >> 8);
  p[1] = uint8_t(value);
}

void writeU32(uint8_t* p, uint32_t value) noexcept {
  p[0] = uint8_t(value >> 24);
  p[1] = uint8_t(value >> 16);
  p[2] = uint8_t(value >> 8);
  p[3] = uint8_t(value);
}

void writeF32(uint8_t* p, float value) noexcept {
  uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  writeU32(p, bits);
}

can_frame makeFrame(uint32_t base_id, Opcode opcode, const uint8_t* data, uint8_t length) noexcept {
  can_frame frame{};
  frame.can_id = frameId(base_id, opcode);
  frame.can_dlc = length > CAN_MAX_DLEN ? CAN_MAX_DLEN : length;
  if (data != nullptr) std::memcpy(frame.data, data, frame.can_dlc);
  return frame;
}

std::array<can_frame, 2> encodeGauges(uint32_t base_id, uint16_t status_word,
                                      const std::array<int16_t, kGauges>& gauges) noexcept {
  uint8_t first[8], second[6];
  writeU16(first, status_word);
  for (int k = 0; k < 3; ++k) {
    writeU16(first + 2 + 2 * k, uint16_t(gauges[size_t(2 * k)]));
    writeU16(second + 2 * k, uint16_t(gauges[size_t(2 * k + 1)]));
  }
  return {makeFrame(base_id, Opcode::kReadGauges, first, 8),
          makeFrame(base_id, Opcode::kGaugesSecond, second, 6)};
}

std::array<can_frame, 3> encodeMatrixRow(uint32_t base_id, const Calibration& calibration,
                                         int row) noexcept {
  constexpr Opcode kOpcodes[3] = {Opcode::kReadMatrixRow, Opcode::kMatrixColumns23,
                                  Opcode::kMatrixColumns45};
  std::array<can_frame, 3> frames{};
  for (int k = 0; k < 3; ++k) {
    uint8_t data[8];
    writeF32(data, calibration.matrix[size_t(row * kGauges + 2 * k)]);
    writeF32(data + 4, calibration.matrix[size_t(row * kGauges + 2 * k + 1)]);
    frames[size_t(k)] = makeFrame(base_id, kOpcodes[k], data, 8);
  }
  return frames;
}

int replyLength(Opcode opcode) noexcept {
  switch (opcode) {
    case Opcode::kReadGauges: return 8;
    case Opcode::kGaugesSecond: return 6;
    case Opcode::kReadMatrixRow:
    case Opcode::kMatrixColumns23:
    case Opcode::kMatrixColumns45: return 8;
    case Opcode::kReadSerial: return 8;
    case Opcode::kSetActiveCalibration: return 1;
    case Opcode::kReadCountsPerUnit: return 8;
    case Opcode::kReadUnitCodes: return 2;
    case Opcode::kReadDiagnostic: return 2;
    case Opcode::kReadFirmware: return 4;
    case Opcode::kReset: return -1;
  }
  return -1;
}

FrameKind classify(const can_frame& frame, uint32_t base_id) noexcept {
  if (frame.can_id & CAN_ERR_FLAG) return FrameKind::kError;
  if (frame.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) return FrameKind::kForeignId;
  if ((frame.can_id >> kOpcodeBits) != base_id) return FrameKind::kForeignId;
  const auto opcode = Opcode(frame.can_id & 0xF);
  const int length = replyLength(opcode);
  if (length < 0) return FrameKind::kUnknownOpcode;
  if (frame.can_dlc != length) return FrameKind::kBadLength;
  if (opcode == Opcode::kReadGauges) return FrameKind::kGaugesFirst;
  if (opcode == Opcode::kGaugesSecond) return FrameKind::kGaugesSecond;
  return FrameKind::kReply;
}

bool GaugeAssembler::first(const can_frame& frame) noexcept {
  const bool clean = !have_first_;
  pending_.status_word = readU16(frame.data);
  for (int k = 0; k < 3; ++k) pending_.gauges[size_t(2 * k)] = readI16(frame.data + 2 + 2 * k);
  have_first_ = true;
  return clean;
}

bool GaugeAssembler::second(const can_frame& frame, GaugeReading& out) noexcept {
  if (!have_first_) return false;
  for (int k = 0; k < 3; ++k) pending_.gauges[size_t(2 * k + 1)] = readI16(frame.data + 2 * k);
  have_first_ = false;
  out = pending_;
  return true;
}

}  // namespace stepcal::runtime::netcan
