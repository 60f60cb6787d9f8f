// The request side of the wire contract (lcmtypes/correction_request_t.lcm): encoding for every
// sender (stepcal-client, the Python client, tests) and the decoding and validation of the raw LCM
// bytes, the pure, allocation-free front of the daemon, fuzzed by
// tests/fuzz/fuzz_request_decoder.cpp. The reply side is reply.hpp; tests/test_wire.cpp round-trips
// both.
#pragma once

#include <cstdint>
#include <vector>

#include <stepcal_lcm/correction_request_t.hpp>

#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/types.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::service {

/// Joints in every LCM message (fixed-size arrays); the daemon refuses models with another dof.
inline constexpr int kMessageJoints = 6;
/// Largest |‖quaternion‖ − 1| accepted in a request (the common one, pose_quaternion.hpp).
using stepcal::kQuaternionNormTolerance;

/// What a request asks for (correction_request_t.mode).
enum class Mode : int8_t { kForward = 0, kInverse = 1 };
/// Where a request's wrench comes from (correction_request_t.wrench_source).
enum class WrenchSource : int8_t { kLiveSensor = 0, kGiven = 1, kPayload = 2 };

/// A decoded, validated request in the runtime's types.
struct Request {
  bool request_id_known = false;  ///< false: the bytes are not a request (no reply is due)
  /// 1 or 2: a request in that older message version (1: correction_request_v1_t's fingerprint;
  /// 2: this layout with message_version 2), refused by name with a BAD_REQUEST reply of that
  /// version (encodeOldVersionRefusal). 0: the current version, or not a request.
  int8_t old_version = 0;
  int64_t request_id = 0;
  int64_t utime = 0;  ///< send time, µs since the Unix epoch
  Mode mode = Mode::kForward;
  JointVector q_rad = JointVector::Zero(kMessageJoints);  ///< forward: commanded joints, rad
  /// Inverse: desired TCP pose in the request's frame (terms.frame), m; quaternion normalised.
  Pose X_FrameTcp_desired = Pose::Identity();
  WrenchSource wrench_source = WrenchSource::kLiveSensor;
  /// Frame, user frame, tool and load (the given wrench, or the payload; the service fills the
  /// live wrench in).
  runtime::CallTerms terms;
  /// Structure temperature, °C; NaN: not measured (no thermal correction).
  double temp_c = runtime::kUnknownTemperature_c;
  JointVector seed_q_rad = JointVector::Zero(kMessageJoints);  ///< inverse: start, rad
  int32_t deadline_us = 0;  ///< ≤ 0: the daemon's budget alone, µs
};

/// Decodes the LCM bytes of a correction_request_t (message version 3) and validates them: kOk,
/// or kBadRequest when the bytes are truncated, too long or of another type, message_version is
/// not 3, the mode, frame, tool origin, wrench source or centre-of-gravity frame is unknown, a
/// double other than temp_c is NaN or infinite, temp_c is neither NaN nor within
/// runtime::kMinTemperature_c … kMaxTemperature_c (runtime::validTemperature), the payload's
/// mass is negative, or a quaternion in use (the tool's always, the user frame's with
/// FRAME_USER, the desired pose's for an inverse) has a norm off by more than
/// kQuaternionNormTolerance. Bytes with the fingerprint of version 1 (correction_request_v1_t)
/// give kBadRequest with out.old_version 1, a well-formed request with message_version 2
/// kBadRequest with out.old_version 2. out.request_id_known says whether a reply can be
/// addressed (a known fingerprint and the id's bytes present). What the model must provide (a
/// flange, gravity) is checked by the runtime's calls. Never allocates, never throws, never reads
/// outside [data, data + size).
runtime::Status decodeRequest(const void* data, int size, Request& out) noexcept;

/// A version-3 request that asks nothing yet, where every sender starts: message_version set,
/// the quaternions (desired pose, user frame, tool) the identity, temp_c NaN (not measured),
/// everything else zero (forward, tracker frame, tool from the target, live sensor, ids 0).
stepcal_lcm::correction_request_t blankRequest() noexcept;

/// Bytes of one encoded correction_request_t.
int requestBytes() noexcept;

/// Encodes request into out[0 .. capacity): its size in bytes (requestBytes()), or 0 when
/// capacity is too small. The fields go as they are (decodeRequest judges them).
/// Allocation-free.
int encodeRequest(const stepcal_lcm::correction_request_t& request, uint8_t* out,
                  int capacity) noexcept;
/// The same into a new buffer of requestBytes().
std::vector<uint8_t> encodeRequest(const stepcal_lcm::correction_request_t& request);

}  // namespace stepcal::service
