// ATI Net CAN OEM force/torque protocol: frame layouts, the calibration a sensor reports, and the
// gauge → wrench conversion. Pure functions on `struct can_frame`, no sockets: the driver
// (ft_sensor.hpp), the sensor simulator (tools/ftsim) and the tests share them.
//
// Every frame has an 11-bit id = base_id << 4 | opcode (base_id 0 … 0x7F). Multi-byte fields are
// big-endian. Requests and their replies (ATI document 9610-05-1030):
//   0x0 read gauges, no data     → 0x0: status u16, gauge 0, 2, 4 (i16)   (8 bytes)
//                                  0x1: gauge 1, 3, 5 (i16)               (6 bytes)
//   0x2 read matrix row r (1 B)  → 0x2, 0x3, 0x4: columns (0,1), (2,3), (4,5) of row r as
//                                  IEEE-754 float32                       (8 bytes each)
//   0x5 read serial number       → 0x5: 8 ASCII characters
//   0x6 set active calibration c → 0x6: c echoed (1 byte)
//   0x7 read counts per unit     → 0x7: counts per force unit u32, per torque unit u32
//   0x8 read unit codes          → 0x8: force unit u8, torque unit u8
//   0x9 read diagnostic ADC d    → 0x9: voltage u16
//   0xC reset                    → no reply; the sensor restarts
//   0xF read firmware version    → 0xF: major u8, minor u8, build u16
// Wrench (eq. of the manual): F_i = Σ_j M_ij (g_j − bias_j) / counts_per_unit_i, in the sensor's
// unit codes; converted here to N and N·m.
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <string>

#include "stepcal/common/types.hpp"

namespace stepcal::runtime::netcan {

constexpr uint32_t kMaxBaseId = 0x7F;
constexpr int kOpcodeBits = 4;
constexpr int kAxes = 6;
constexpr int kGauges = 6;

enum class Opcode : uint8_t {
  kReadGauges = 0x0,       ///< request; also the first reply (status, gauges 0, 2, 4)
  kGaugesSecond = 0x1,     ///< second reply (gauges 1, 3, 5)
  kReadMatrixRow = 0x2,    ///< request (row byte); also the first reply (columns 0, 1)
  kMatrixColumns23 = 0x3,  ///< second reply (columns 2, 3)
  kMatrixColumns45 = 0x4,  ///< third reply (columns 4, 5)
  kReadSerial = 0x5,
  kSetActiveCalibration = 0x6,
  kReadCountsPerUnit = 0x7,
  kReadUnitCodes = 0x8,
  kReadDiagnostic = 0x9,
  kReset = 0xC,
  kReadFirmware = 0xF,
};

/// The 11-bit CAN id of opcode on a sensor with base_id (≤ kMaxBaseId).
constexpr canid_t frameId(uint32_t base_id, Opcode opcode) noexcept {
  return canid_t(base_id << kOpcodeBits) | canid_t(opcode);
}

/// Bits of the sensor's 16-bit status word (first gauge reply).
namespace status_bit {
constexpr uint16_t kWatchdogReset = 1u << 0;
constexpr uint16_t kDacAdcTooHigh = 1u << 1;
constexpr uint16_t kDacAdcTooLow = 1u << 2;
constexpr uint16_t kAnalogGroundOutOfRange = 1u << 3;
constexpr uint16_t kPowerSupplyTooHigh = 1u << 4;
constexpr uint16_t kPowerSupplyTooLow = 1u << 5;
constexpr uint16_t kBadActiveCalibration = 1u << 6;
constexpr uint16_t kEepromFailure = 1u << 7;
constexpr uint16_t kConfigurationInvalid = 1u << 8;
constexpr uint16_t kSensorTooHot = 1u << 11;
constexpr uint16_t kSensorTooCold = 1u << 12;
constexpr uint16_t kCanBusError = 1u << 14;
constexpr uint16_t kAnyError = 1u << 15;
/// Bits that make the gauges untrustworthy (the manual's "critical" errors).
constexpr uint16_t kCritical = kDacAdcTooHigh | kDacAdcTooLow | kAnalogGroundOutOfRange |
                               kPowerSupplyTooHigh | kPowerSupplyTooLow | kBadActiveCalibration |
                               kEepromFailure | kSensorTooHot | kSensorTooCold;
}  // namespace status_bit

/// Comma-separated names of the set bits of a status word ("" for 0).
std::string describeStatus(uint16_t status_word);

/// Force unit codes: 1 lbf, 2 N, 3 klbf, 4 kN, 5 kgf, 6 gf. Newtons per unit; 0 when unknown.
double newtonsPerForceUnit(uint8_t code) noexcept;
/// Torque unit codes: 1 lbf·in, 2 lbf·ft, 3 N·m, 4 N·mm, 5 kgf·cm, 6 kN·m. N·m per unit; 0 when
/// unknown.
double newtonMetresPerTorqueUnit(uint8_t code) noexcept;

/// What a sensor reports about itself at start-up.
struct Calibration {
  /// Active calibration matrix, row-major: rows Fx Fy Fz Tx Ty Tz, columns gauges 0 … 5;
  /// counts per gauge count.
  std::array<float, kAxes * kGauges> matrix{};
  uint32_t counts_per_force = 0;   ///< counts per force unit
  uint32_t counts_per_torque = 0;  ///< counts per torque unit
  uint8_t force_unit = 2;          ///< N
  uint8_t torque_unit = 3;         ///< N·m
};

/// Gauges → wrench in SI, with the constants of one calibration folded in once.
class WrenchConverter {
 public:
  WrenchConverter() = default;
  /// Throws InputError (naming the field, its value and what is expected) when the calibration
  /// has a non-finite or singular matrix, a zero count or an unknown unit code.
  explicit WrenchConverter(const Calibration& calibration);

  /// Wrench the gauges measure against the bias: force N then moment N·m, sensor axes.
  /// W_i = unit_i / counts_i · Σ_j M_ij (g_j − bias_j), summed in j order in double.
  Vec6 wrench(const std::array<int16_t, kGauges>& gauges, const Vec6& bias_gauges) const noexcept;
  /// Gauges (real-valued) that measure wrench with zero bias: M⁻¹ · counts / unit · W.
  Vec6 gaugesFor(const Vec6& wrench_Sensor) const noexcept;

 private:
  Eigen::Matrix<double, 6, 6> matrix_ = Eigen::Matrix<double, 6, 6>::Zero();
  Vec6 si_per_count_ = Vec6::Zero();  ///< unit_i / counts_i
};

// ---- Encoding (requests for the driver, replies for the simulator) ----

/// A frame with id frameId(base_id, opcode) and the given data bytes (≤ 8).
can_frame makeFrame(uint32_t base_id, Opcode opcode, const uint8_t* data = nullptr,
                    uint8_t length = 0) noexcept;
/// The two replies to a gauge request: {status, g0, g2, g4}, {g1, g3, g5}.
std::array<can_frame, 2> encodeGauges(uint32_t base_id, uint16_t status_word,
                                      const std::array<int16_t, kGauges>& gauges) noexcept;
/// The three replies to a matrix-row request.
std::array<can_frame, 3> encodeMatrixRow(uint32_t base_id, const Calibration& calibration,
                                         int row) noexcept;

// ---- Decoding ----

/// One gauge reading assembled from the two replies.
struct GaugeReading {
  uint16_t status_word = 0;
  std::array<int16_t, kGauges> gauges{};
};

/// Big-endian field readers on frame data.
inline uint16_t readU16(const uint8_t* p) noexcept { return uint16_t((p[0] << 8) | p[1]); }
inline int16_t readI16(const uint8_t* p) noexcept { return int16_t(readU16(p)); }
uint32_t readU32(const uint8_t* p) noexcept;
float readF32(const uint8_t* p) noexcept;
void writeU16(uint8_t* p, uint16_t value) noexcept;
void writeU32(uint8_t* p, uint32_t value) noexcept;
void writeF32(uint8_t* p, float value) noexcept;

/// What a received frame is, for a driver talking to the sensor at base_id.
enum class FrameKind : uint8_t {
  kGaugesFirst,   ///< opcode 0x0, 8 bytes
  kGaugesSecond,  ///< opcode 0x1, 6 bytes
  kReply,         ///< a well-formed reply to a start-up request (0x2 … 0x9, 0xF)
  kError,         ///< a CAN error frame (CAN_ERR_FLAG)
  kForeignId,     ///< not this sensor's id (or an extended / remote frame)
  kBadLength,     ///< this sensor's id with a length its opcode never has
  kUnknownOpcode, ///< this sensor's id with an opcode that has no reply (0xA, 0xB, 0xC, 0xD, 0xE)
};
/// Classifies a frame received from the bus. Never reads beyond can_dlc (≤ 8).
FrameKind classify(const can_frame& frame, uint32_t base_id) noexcept;
/// Data length of a well-formed reply with this opcode; −1 for opcodes without a reply.
int replyLength(Opcode opcode) noexcept;

/// Assembles gauge readings from reply frames: a first half followed by a second half of the
/// same poll makes a reading. A second half without a first, or two firsts in a row, is a
/// mismatch (counted by the caller); halves never mix across polls.
class GaugeAssembler {
 public:
  /// Starts a new poll (drops a pending first half).
  void reset() noexcept { have_first_ = false; }
  /// Feeds a kGaugesFirst frame; returns false if a first half was already pending (replaced).
  bool first(const can_frame& frame) noexcept;
  /// Feeds a kGaugesSecond frame; true and out set when it completes a reading.
  bool second(const can_frame& frame, GaugeReading& out) noexcept;

 private:
  bool have_first_ = false;
  GaugeReading pending_;
};

}  // namespace stepcal::runtime::netcan
