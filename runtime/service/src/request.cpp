#include "stepcal/service/request.hpp"

#include <cmath>

#include <stepcal_lcm/correction_request_t.hpp>

namespace stepcal::service {
namespace {

using runtime::Status;
using stepcal_lcm::correction_request_t;

constexpr int kFingerprintBytes = 8;
constexpr int kRequestIdBytes = 8;

int64_t bigEndian64(const uint8_t* bytes) noexcept {
  uint64_t value = 0;
  for (int i = 0; i < 8; ++i) value = (value << 8) | bytes[i];
  return static_cast<int64_t>(value);
}

bool allFinite(const double* values, int count) noexcept {
  for (int i = 0; i < count; ++i) {
    if (!std::isfinite(values[i])) return false;
  }
  return true;
}

bool allFinite(const correction_request_t& msg) noexcept {
  return allFinite(msg.q_rad, kMessageJoints) && allFinite(msg.desired_position_m, 3) &&
         allFinite(msg.desired_quaternion_wxyz, 4) && allFinite(msg.wrench, 6) &&
         allFinite(msg.seed_q_rad, kMessageJoints);
}

}  // namespace

Status decodeRequest(const void* data, int size, Request& out) noexcept {
  out = Request{};
  if (data == nullptr || size < kFingerprintBytes + kRequestIdBytes) return Status::kBadRequest;
  const auto* bytes = static_cast<const uint8_t*>(data);
  if (bigEndian64(bytes) != correction_request_t::getHash()) return Status::kBadRequest;
  out.request_id_known = true;
  out.request_id = bigEndian64(bytes + kFingerprintBytes);

  correction_request_t msg{};
  if (msg.decode(data, 0, size) != size) return Status::kBadRequest;  // truncated or too long
  out.utime = msg.utime;
  out.deadline_us = msg.deadline_us;
  if (msg.mode != correction_request_t::MODE_FORWARD &&
      msg.mode != correction_request_t::MODE_INVERSE) {
    return Status::kBadRequest;
  }
  if (msg.wrench_source != correction_request_t::WRENCH_LIVE_SENSOR &&
      msg.wrench_source != correction_request_t::WRENCH_GIVEN) {
    return Status::kBadRequest;
  }
  if (!allFinite(msg) || !runtime::validTemperature(msg.temp_c)) return Status::kBadRequest;
  out.mode = static_cast<Mode>(msg.mode);
  out.wrench_source = static_cast<WrenchSource>(msg.wrench_source);
  for (int i = 0; i < kMessageJoints; ++i) {
    out.q_rad[i] = msg.q_rad[i];
    out.seed_q_rad[i] = msg.seed_q_rad[i];
  }
  for (int i = 0; i < 6; ++i) out.wrench_Sensor[i] = msg.wrench[i];
  out.temp_c = msg.temp_c;
  if (out.mode == Mode::kInverse) {
    const Eigen::Quaterniond q_TrackerTip(msg.desired_quaternion_wxyz[0],
                                          msg.desired_quaternion_wxyz[1],
                                          msg.desired_quaternion_wxyz[2],
                                          msg.desired_quaternion_wxyz[3]);
    if (!(std::abs(q_TrackerTip.norm() - 1.0) <= kQuaternionNormTolerance)) {
      return Status::kBadRequest;
    }
    out.X_TrackerTip_desired.linear() = q_TrackerTip.normalized().toRotationMatrix();
    out.X_TrackerTip_desired.translation() =
        Vec3(msg.desired_position_m[0], msg.desired_position_m[1], msg.desired_position_m[2]);
  }
  return Status::kOk;
}

}  // namespace stepcal::service
