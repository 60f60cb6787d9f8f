// libFuzzer target for stepcal::service::decodeRequest (runtime/service): no input may crash it,
// read out of bounds, trip a sanitizer or throw; what it accepts must be a well-formed request.
// Not part of the CMake build (that uses g++); build and run with
// `tests/system/fuzz.sh request_decoder SECONDS`.
//
// Each input is decoded three times: as given (the type fingerprint refuses nearly every
// mutation), then with the fingerprint of correction_request_t stamped over its first 8 bytes,
// so the fuzzer reaches the field checks (a request of this layout with message_version 2 is
// refused by name as version 2), and with that of version 1, which is always refused by name.
//
// Built with -DSTEPCAL_FUZZ_SEED_MAIN (and without -fsanitize=fuzzer) the same file is instead
// a seed generator: `make_seeds FOLDER` writes valid forward and inverse requests (through the
// shared encoder, stepcal::service::encodeRequest).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <stepcal_lcm/correction_request_t.hpp>
#include <stepcal_lcm/correction_request_v1_t.hpp>

#include "stepcal/service/request.hpp"

using stepcal_lcm::correction_request_t;

#ifndef STEPCAL_FUZZ_SEED_MAIN

namespace {

using stepcal::runtime::Status;
using stepcal::service::Request;

constexpr size_t kFingerprintBytes = 8;

void stampFingerprint(uint8_t* bytes, int64_t fingerprint) {
  const auto hash = static_cast<uint64_t>(fingerprint);
  for (size_t i = 0; i < kFingerprintBytes; ++i) bytes[i] = uint8_t(hash >> (56 - 8 * i));
}

bool isRotation(const stepcal::Mat3& R) {
  return (R.transpose() * R - stepcal::Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
         std::abs(R.determinant() - 1.0) < 1e-9;
}

void check(bool condition) {
  if (!condition) std::abort();
}

void decodeAndCheck(const uint8_t* data, size_t size) {
  Request request;
  const Status status = stepcal::service::decodeRequest(data, static_cast<int>(size), request);
  check(status == Status::kOk || status == Status::kBadRequest);
  if (status == Status::kBadRequest) {
    // Refused as version 2: exactly one request of this layout, its message_version 2.
    if (request.old_version == 2) {
      correction_request_t msg{};
      check(request.request_id_known);
      check(msg.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size));
      check(msg.message_version == 2 && msg.request_id == request.request_id);
    }
    return;
  }
  // Accepted: the bytes are exactly one request with known id, mode and finite values.
  correction_request_t msg{};
  check(request.request_id_known);
  check(msg.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size));
  check(msg.request_id == request.request_id);
  check(request.mode == stepcal::service::Mode::kForward ||
        request.mode == stepcal::service::Mode::kInverse);
  check(request.q_rad.size() == stepcal::service::kMessageJoints && request.q_rad.allFinite());
  check(!request.old_version);
  check(msg.message_version == correction_request_t::VERSION);
  const stepcal::runtime::CallTerms& terms = request.terms;
  check(request.seed_q_rad.allFinite() && terms.wrench_Sensor.allFinite());
  check(terms.X_Tool.translation().allFinite() && isRotation(terms.X_Tool.linear()));
  check(terms.frame != stepcal::runtime::PoseFrame::kUser ||
        (terms.X_BaseUser.translation().allFinite() && isRotation(terms.X_BaseUser.linear())));
  check(terms.load_from != stepcal::runtime::LoadFrom::kPayload ||
        (std::isfinite(terms.payload.mass_kg) && terms.payload.mass_kg >= 0.0 &&
         terms.payload.p_CoG_m.allFinite()));
  check(std::isnan(request.temp_c) ||
        (request.temp_c >= stepcal::runtime::kMinTemperature_c &&
         request.temp_c <= stepcal::runtime::kMaxTemperature_c));
  check(std::isnan(request.temp_c) ? std::isnan(msg.temp_c) : msg.temp_c == request.temp_c);
  const stepcal::Pose& X = request.X_FrameTcp_desired;
  check(X.translation().allFinite() && isRotation(X.linear()));
}

/// Version-1 bytes with a readable id: always refused by name, never decoded.
void checkOldVersion(const uint8_t* data, size_t size) {
  Request request;
  const Status status = stepcal::service::decodeRequest(data, static_cast<int>(size), request);
  check(status == Status::kBadRequest);
  check(request.old_version == (size >= 16 ? 1 : 0));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  decodeAndCheck(data, size);
  if (size < kFingerprintBytes) return 0;
  std::vector<uint8_t> stamped(data, data + size);
  stampFingerprint(stamped.data(), correction_request_t::getHash());
  decodeAndCheck(stamped.data(), stamped.size());
  stampFingerprint(stamped.data(), stepcal_lcm::correction_request_v1_t::getHash());
  checkOldVersion(stamped.data(), stamped.size());
  return 0;
}

#else

#include <cstdio>
#include <string>

#include "seed_file.hpp"

namespace {

void writeSeed(const std::string& path, const correction_request_t& msg) {
  stepcal::fuzz::writeSeedBytes(path, stepcal::service::encodeRequest(msg));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s SEED_FOLDER\n", argv[0]);
    return 2;
  }
  const std::string folder = argv[1];
  correction_request_t forward = stepcal::service::blankRequest();
  forward.request_id = 1;
  forward.utime = 1700000000000000;
  forward.mode = correction_request_t::MODE_FORWARD;
  const double q_rad[6] = {0.1, -0.4, 0.3, 1.2, 0.7, -2.0};
  std::memcpy(forward.q_rad, q_rad, sizeof q_rad);
  forward.wrench_source = correction_request_t::WRENCH_GIVEN;
  const double wrench[6] = {3.0, -1.5, -196.0, 0.4, 0.2, -0.01};
  std::memcpy(forward.wrench, wrench, sizeof wrench);
  forward.temp_c = 23.5;
  forward.deadline_us = 150;
  writeSeed(folder + "/forward.request", forward);

  correction_request_t inverse = forward;
  inverse.request_id = 2;
  inverse.mode = correction_request_t::MODE_INVERSE;
  inverse.wrench_source = correction_request_t::WRENCH_LIVE_SENSOR;
  inverse.temp_c = std::nan("");  // not measured
  const double p_m[3] = {2.1, -0.3, 1.4};
  const double q_wxyz[4] = {0.5, 0.5, -0.5, 0.5};
  std::memcpy(inverse.desired_position_m, p_m, sizeof p_m);
  std::memcpy(inverse.desired_quaternion_wxyz, q_wxyz, sizeof q_wxyz);
  std::memcpy(inverse.seed_q_rad, q_rad, sizeof q_rad);
  writeSeed(folder + "/inverse.request", inverse);

  // In the controller's terms: a user frame, a tool from the flange, a payload.
  correction_request_t terms = inverse;
  terms.request_id = 3;
  terms.frame = correction_request_t::FRAME_USER;
  const double user_p_m[3] = {1.2, 0.4, 0.1};
  const double user_q_wxyz[4] = {0.9238795325112867, 0.0, 0.0, 0.3826834323650898};
  std::memcpy(terms.user_frame_position_m, user_p_m, sizeof user_p_m);
  std::memcpy(terms.user_frame_quaternion_wxyz, user_q_wxyz, sizeof user_q_wxyz);
  terms.tool_from = correction_request_t::TOOL_FROM_FLANGE;
  const double tool_p_m[3] = {0.0, 0.05, 0.3};
  std::memcpy(terms.tool_position_m, tool_p_m, sizeof tool_p_m);
  terms.wrench_source = correction_request_t::WRENCH_PAYLOAD;
  terms.payload_kg = 40.0;
  terms.payload_cog_frame = correction_request_t::COG_IN_TOOL;
  const double cog_m[3] = {0.0, 0.0, -0.1};
  std::memcpy(terms.payload_cog_m, cog_m, sizeof cog_m);
  writeSeed(folder + "/terms.request", terms);
  return 0;
}

#endif
