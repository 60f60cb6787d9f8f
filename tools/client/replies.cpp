// stepcal-client's replies as text and JSON.
#include <cmath>
#include <cstdio>

#include "client.hpp"

namespace stepcal::client {
namespace {

std::string vectorText(const double* v, int n, double scale = 1.0, const char* format = "%.6f") {
  std::string text = "[";
  char number[32];
  for (int i = 0; i < n; ++i) {
    if (i) text += ", ";
    std::snprintf(number, sizeof number, format, v[i] * scale);
    text += number;
  }
  return text + "]";
}

/// The joints (1-based) of a reply's uncovered_joints bits, e.g. [1, 4].
nlohmann::json uncoveredJoints(int32_t bits) {
  nlohmann::json joints = nlohmann::json::array();
  for (int j = 0; j < 32; ++j) {
    if ((static_cast<uint32_t>(bits) >> j) & 1u) joints.push_back(j + 1);
  }
  return joints;
}

}  // namespace

JointVector jointsOf(const double* q_rad) {
  JointVector q(service::kMessageJoints);
  for (int i = 0; i < service::kMessageJoints; ++i) q[i] = q_rad[i];
  return q;
}

/// A model id as printed by stepcal-runtime: 16 hex digits.
std::string modelIdText(int64_t model_id) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(model_id));
  return text;
}

nlohmann::json accuracyJson(const correction_reply_t& r) {
  // NaN (the model states none) is written as null.
  return {{"position_rms_m", r.position_rms_m},
          {"position_bound_m", r.position_bound_m},
          {"orientation_rms_rad", r.orientation_rms_rad},
          {"orientation_bound_rad", r.orientation_bound_rad}};
}

nlohmann::json replyJson(const correction_reply_t& r, bool inverse) {
  const auto array = [](const double* v, int n) { return std::vector<double>(v, v + n); };
  nlohmann::json j = {
      {"request_id", r.request_id},
      {"status", runtime::toString(static_cast<runtime::Status>(r.status))},
      {"model_id", modelIdText(r.model_id)},
      {"compute_us", double(r.compute_ns) * 1e-3},
      {"predicted_position_m", array(r.predicted_position_m, 3)},
      {"predicted_quaternion_wxyz", array(r.predicted_quaternion_wxyz, 4)},
      {"gpr_std", array(r.gpr_std, 6)},
      {"wrench", array(r.wrench, 6)},
      {"uncovered_joints", uncoveredJoints(r.uncovered_joints)},
      {"accuracy", accuracyJson(r)}};
  if (inverse) {
    j["q_target_rad"] = array(r.q_target_rad, 6);
    j["commanded_position_m"] = array(r.commanded_position_m, 3);
    j["commanded_quaternion_wxyz"] = array(r.commanded_quaternion_wxyz, 4);
    j["iterations"] = r.iterations;
    j["residual_position_m"] = r.residual_position_m;
    j["residual_orientation_rad"] = r.residual_orientation_rad;
  }
  return j;
}

void printReply(const correction_reply_t& r, double round_trip_us, bool inverse,
                const std::string& frame) {
  std::printf("request %lld: %s, model %016llx, compute %.1f us, round trip %.1f us\n",
              static_cast<long long>(r.request_id),
              runtime::toString(static_cast<runtime::Status>(r.status)),
              static_cast<unsigned long long>(r.model_id), double(r.compute_ns) * 1e-3,
              round_trip_us);
  if (inverse) {
    std::printf("q_target_rad              %s\n", vectorText(r.q_target_rad, 6).c_str());
    std::printf("q_target_deg              %s\n",
                vectorText(r.q_target_rad, 6, kDegPerRad).c_str());
    std::printf("commanded (%s) p_m %s  q_wxyz %s\n", frame == "user" ? "user   " : "base   ",
                vectorText(r.commanded_position_m, 3).c_str(),
                vectorText(r.commanded_quaternion_wxyz, 4).c_str());
  }
  std::printf("predicted (%-7s) p_m %s  q_wxyz %s\n", frame.c_str(),
              vectorText(r.predicted_position_m, 3).c_str(),
              vectorText(r.predicted_quaternion_wxyz, 4).c_str());
  std::printf("wrench used (N, N m)      %s\n", vectorText(r.wrench, 6, 1.0, "%.3f").c_str());
  std::printf("gpr_std (v m, w rad)      %s\n", vectorText(r.gpr_std, 6, 1.0, "%.3e").c_str());
  if (std::isnan(r.position_bound_m)) {
    std::printf("accuracy                  not stated (the model file has no ACCU section)\n");
  } else {
    std::printf("accuracy (95 %%)           %.4f mm, %.5f deg (RMS %.4f mm, %.5f deg)\n",
                r.position_bound_m * kMmPerM, r.orientation_bound_rad * kDegPerRad,
                r.position_rms_m * kMmPerM, r.orientation_rms_rad * kDegPerRad);
  }
  if (r.uncovered_joints != 0) {
    std::printf("outside the fitted angles of the profile of joint(s) %s\n",
                uncoveredJoints(r.uncovered_joints).dump().c_str());
  }
  if (inverse) {
    std::printf("iterations %d, residual %.4f mm, %.5f deg\n", r.iterations,
                r.residual_position_m * kMmPerM, r.residual_orientation_rad * kDegPerRad);
  }
}

/// The replies per status, by name (statuses never seen left out).
nlohmann::json statusesJson(const long (&status_counts)[kStatusCount]) {
  nlohmann::json statuses = nlohmann::json::object();
  for (int k = 0; k < kStatusCount; ++k) {
    if (status_counts[k]) statuses[runtime::toString(static_cast<runtime::Status>(k))] = status_counts[k];
  }
  return statuses;
}

/// One of `names` (the index), or an InputError naming the option and the choices.
int8_t choice(const std::string& option, const std::string& value,
              const std::vector<std::string>& names) {
  for (size_t i = 0; i < names.size(); ++i) {
    if (value == names[i]) return int8_t(i);
  }
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : " | ") + n;
  throw InputError(option + " '" + value + "': expected " + list);
}

}  // namespace stepcal::client
