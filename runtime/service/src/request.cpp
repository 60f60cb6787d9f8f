#include "stepcal/service/request.hpp"

#include <cmath>

#include <stepcal_lcm/correction_reply_v2_t.hpp>
#include <stepcal_lcm/correction_request_v1_t.hpp>

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
         allFinite(msg.desired_quaternion_wxyz, 4) && allFinite(msg.user_frame_position_m, 3) &&
         allFinite(msg.user_frame_quaternion_wxyz, 4) && allFinite(msg.tool_position_m, 3) &&
         allFinite(msg.tool_quaternion_wxyz, 4) && allFinite(msg.wrench, 6) &&
         allFinite(&msg.payload_kg, 1) && allFinite(msg.payload_cog_m, 3) &&
         allFinite(msg.seed_q_rad, kMessageJoints);
}

/// A pose from a position and a quaternion whose norm is 1 within kQuaternionNormTolerance
/// (normalised); false otherwise.
bool readPose(const double* position_m, const double* quaternion_wxyz, Pose& X) noexcept {
  const Eigen::Quaterniond q(quaternion_wxyz[0], quaternion_wxyz[1], quaternion_wxyz[2],
                             quaternion_wxyz[3]);
  if (!isUnitQuaternion(q)) return false;
  X = poseFromPositionQuaternion(Vec3(position_m[0], position_m[1], position_m[2]), q);
  return true;
}

bool inRange(int8_t value, int8_t first, int8_t last) noexcept {
  return value >= first && value <= last;
}

}  // namespace

Status decodeRequest(const void* data, int size, Request& out) noexcept {
  out = Request{};
  if (data == nullptr || size < kFingerprintBytes + kRequestIdBytes) return Status::kBadRequest;
  const auto* bytes = static_cast<const uint8_t*>(data);
  const int64_t fingerprint = bigEndian64(bytes);
  if (fingerprint == stepcal_lcm::correction_request_v1_t::getHash()) {
    out.request_id_known = true;
    out.old_version = 1;
    out.request_id = bigEndian64(bytes + kFingerprintBytes);
    return Status::kBadRequest;
  }
  if (fingerprint != correction_request_t::getHash()) return Status::kBadRequest;
  out.request_id_known = true;
  out.request_id = bigEndian64(bytes + kFingerprintBytes);

  correction_request_t msg{};
  if (msg.decode(data, 0, size) != size) return Status::kBadRequest;  // truncated or too long
  out.utime = msg.utime;
  out.deadline_us = msg.deadline_us;
  // Version 2 had this layout; its client reads only correction_reply_v2_t.
  if (msg.message_version == stepcal_lcm::correction_reply_v2_t::VERSION) {
    out.old_version = stepcal_lcm::correction_reply_v2_t::VERSION;
    return Status::kBadRequest;
  }
  if (msg.message_version != correction_request_t::VERSION ||
      !inRange(msg.mode, correction_request_t::MODE_FORWARD, correction_request_t::MODE_INVERSE) ||
      !inRange(msg.frame, correction_request_t::FRAME_TRACKER, correction_request_t::FRAME_USER) ||
      !inRange(msg.tool_from, correction_request_t::TOOL_FROM_TARGET,
               correction_request_t::TOOL_FROM_FLANGE) ||
      !inRange(msg.wrench_source, correction_request_t::WRENCH_LIVE_SENSOR,
               correction_request_t::WRENCH_PAYLOAD) ||
      !inRange(msg.payload_cog_frame, correction_request_t::COG_IN_FLANGE,
               correction_request_t::COG_IN_TOOL)) {
    return Status::kBadRequest;
  }
  if (!allFinite(msg) || !runtime::validTemperature(msg.temp_c) || msg.payload_kg < 0.0) {
    return Status::kBadRequest;
  }
  out.mode = static_cast<Mode>(msg.mode);
  out.wrench_source = static_cast<WrenchSource>(msg.wrench_source);
  for (int i = 0; i < kMessageJoints; ++i) {
    out.q_rad[i] = msg.q_rad[i];
    out.seed_q_rad[i] = msg.seed_q_rad[i];
  }
  out.temp_c = msg.temp_c;
  runtime::CallTerms& terms = out.terms;
  terms.frame = static_cast<runtime::PoseFrame>(msg.frame);
  terms.tool_from = static_cast<runtime::ToolFrom>(msg.tool_from);
  if (!readPose(msg.tool_position_m, msg.tool_quaternion_wxyz, terms.X_Tool)) {
    return Status::kBadRequest;
  }
  if (terms.frame == runtime::PoseFrame::kUser &&
      !readPose(msg.user_frame_position_m, msg.user_frame_quaternion_wxyz, terms.X_BaseUser)) {
    return Status::kBadRequest;
  }
  for (int i = 0; i < 6; ++i) terms.wrench_Sensor[i] = msg.wrench[i];
  if (out.wrench_source == WrenchSource::kPayload) {
    terms.load_from = runtime::LoadFrom::kPayload;
    terms.payload.mass_kg = msg.payload_kg;
    terms.payload.frame = static_cast<runtime::CogFrame>(msg.payload_cog_frame);
    terms.payload.p_CoG_m = Vec3(msg.payload_cog_m[0], msg.payload_cog_m[1], msg.payload_cog_m[2]);
  }
  if (out.mode == Mode::kInverse &&
      !readPose(msg.desired_position_m, msg.desired_quaternion_wxyz, out.X_FrameTcp_desired)) {
    return Status::kBadRequest;
  }
  return Status::kOk;
}

correction_request_t blankRequest() noexcept {
  correction_request_t request{};
  request.message_version = correction_request_t::VERSION;
  request.desired_quaternion_wxyz[0] = 1.0;
  request.user_frame_quaternion_wxyz[0] = 1.0;
  request.tool_quaternion_wxyz[0] = 1.0;
  request.temp_c = runtime::kUnknownTemperature_c;
  return request;
}

int requestBytes() noexcept {
  static const int bytes = correction_request_t{}.getEncodedSize();
  return bytes;
}

int encodeRequest(const correction_request_t& request, uint8_t* out, int capacity) noexcept {
  if (out == nullptr || capacity < requestBytes()) return 0;
  const int bytes = request.encode(out, 0, capacity);
  return bytes > 0 ? bytes : 0;
}

std::vector<uint8_t> encodeRequest(const correction_request_t& request) {
  std::vector<uint8_t> bytes(static_cast<size_t>(requestBytes()));
  encodeRequest(request, bytes.data(), int(bytes.size()));
  return bytes;
}

}  // namespace stepcal::service
