// stepcal-client --forward / --inverse: one request from the command line, in the controller's
// terms, or the same forward request repeated at a rate.
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>

#include "client.hpp"
#include "stepcal/service/request.hpp"

namespace stepcal::client {
namespace {

/// Says on stderr when x y z (mm) of an option look like metres (units.hpp): a warning only.
void warnIfMetres(const std::string& option, const double* xyz_mm) {
  if (looksLikeMetres(xyz_mm[0], xyz_mm[1], xyz_mm[2])) {
    std::cerr << "stepcal-client: warning: " << option << " x y z lie within "
              << kLooksLikeMetresBelow_mm << " mm of the origin: metres given where mm are "
              << "expected?\n";
  }
}

/// x y z qw qx qy qz (mm, unit quaternion) into a message's position (m) and quaternion fields.
void setPose(const std::string& option, const std::vector<double>& v, double* position_m,
             double* quaternion_wxyz) {
  const double norm = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
  if (!(std::abs(norm - 1.0) <= service::kQuaternionNormTolerance)) {
    throw InputError(option + ": the quaternion qw qx qy qz has norm " + std::to_string(norm) +
                     "; expected a unit quaternion (within 1e-6)");
  }
  warnIfMetres(option, v.data());
  for (int a = 0; a < 3; ++a) position_m[a] = v[size_t(a)] * kMPerMm;
  std::copy(v.begin() + 3, v.end(), quaternion_wxyz);
}

/// Joints in degrees into a message's joints (rad).
void setJoints(const std::vector<double>& q_deg, double* q_rad) {
  for (size_t j = 0; j < q_deg.size(); ++j) q_rad[j] = q_deg[j] * kRadPerDeg;
}

/// The frame, tool and payload options of a single request into its message.
void setTerms(const Args& args, correction_request_t& msg) {
  msg.frame = choice("--frame", args.frame, {"tracker", "base", "user"});
  if ((msg.frame == correction_request_t::FRAME_USER) != !args.user_frame.empty()) {
    throw InputError("--user-frame x y z qw qx qy qz goes with --frame user, and --frame user needs it");
  }
  if (!args.user_frame.empty()) {
    setPose("--user-frame", args.user_frame, msg.user_frame_position_m, msg.user_frame_quaternion_wxyz);
  }
  msg.tool_from = choice("--tool-from", args.tool_from, {"target", "flange"});
  if (!args.tool.empty()) setPose("--tool", args.tool, msg.tool_position_m, msg.tool_quaternion_wxyz);
  msg.payload_cog_frame = choice("--cog-frame", args.cog_frame, {"flange", "tool"});
  if (args.payload_kg >= 0.0) {
    if (!args.wrench.empty()) throw InputError("--payload and --wrench: give one load, not both");
    msg.wrench_source = correction_request_t::WRENCH_PAYLOAD;
    msg.payload_kg = args.payload_kg;
    for (size_t a = 0; a < args.cog_mm.size(); ++a) msg.payload_cog_m[a] = args.cog_mm[a] * kMPerMm;
  } else if (!args.cog_mm.empty()) {
    throw InputError("--cog goes with --payload");
  }
}

/// The forward request of the command line, args.count times at args.rate_hz: per request when it
/// left and when its reply came (Unix time, to line up with faults logged elsewhere), its status,
/// the age of the live wrench it used on arrival and the predicted position. SIGINT/SIGTERM end it
/// early: the requests sent so far are reported. Exit status as exitStatusOf.
int runRepeated(const Args& args, const correction_request_t& msg) {
  std::signal(SIGINT, onStopSignal);
  std::signal(SIGTERM, onStopSignal);
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  const Clock::time_point steady_origin = Clock::now();
  const double unix_origin_s = double(unixMicroseconds()) * 1e-6;
  service::LcmRequester requester(lcm.get(), loadKey(args.key_file));
  const std::vector<correction_reply_t> replies =
      sendRequests(lcm.get(), args, std::vector<correction_request_t>(size_t(args.count), msg),
                   exchange, requester);
  nlohmann::json rows = nlohmann::json::array();
  long status_counts[kStatusCount] = {};
  int sent = 0;
  for (size_t i = 0; i < replies.size() && exchange.sent[i] != Clock::time_point{}; ++i, ++sent) {
    const double sent_unix_s =
        unix_origin_s + std::chrono::duration<double>(exchange.sent[i] - steady_origin).count();
    nlohmann::json& row = rows.emplace_back(nlohmann::json{
        {"sent_unix_s", sent_unix_s}, {"status", nullptr}, {"wrench_age_ms", nullptr}});
    if (std::isnan(exchange.round_trip_us[i])) continue;
    const correction_reply_t& r = replies[i];
    if (r.status >= 0 && r.status < kStatusCount) ++status_counts[r.status];
    row["received_unix_s"] = sent_unix_s + exchange.round_trip_us[i] * 1e-6;
    row["status"] = runtime::toString(static_cast<runtime::Status>(r.status));
    if (r.wrench_stamp_ns > 0) {
      row["wrench_age_ms"] = double(receivedNs(exchange, i) - r.wrench_stamp_ns) * 1e-6;
    }
    row["predicted_position_m"] =
        std::vector<double>(r.predicted_position_m, r.predicted_position_m + 3);
  }
  const nlohmann::json statuses = statusesJson(status_counts);
  const nlohmann::json report = {{"requests", sent},   {"replies", exchange.answered},
                                 {"lost", sent - exchange.answered},
                                 {"rate_hz", args.rate_hz},  {"statuses", statuses},
                                 {"authentication", authenticationJson(requester)}, {"rows", rows}};
  if (exchange.answered == 0) explainSilence(requester, args.lcm_url);
  if (args.json) {
    std::cout << report.dump(1) << "\n";
  } else {
    std::cout << sent << " forward requests at " << args.rate_hz << " Hz: "
              << exchange.answered << " replies, statuses " << statuses.dump() << "\n";
  }
  return exitStatusOf(sent, exchange.answered, status_counts[0], "requests");
}

}  // namespace

correction_request_t emptyRequest(const Args& args) {
  correction_request_t msg = service::blankRequest();
  msg.deadline_us = args.deadline_us;
  return msg;
}

void setWrench(correction_request_t& msg, const Vec6& wrench_Sensor) {
  msg.wrench_source = correction_request_t::WRENCH_GIVEN;
  for (int i = 0; i < 6; ++i) msg.wrench[i] = wrench_Sensor[i];
}

/// One request from the command line; exit status 4 when no reply came, 3 when its status is not
/// OK.
int runSingle(const Args& args) {
  const bool inverse = !args.inverse_pose.empty();
  correction_request_t msg = emptyRequest(args);
  if (!args.wrench.empty()) setWrench(msg, Vec6(args.wrench.data()));
  setTerms(args, msg);
  msg.temp_c = args.temp_c;
  if (inverse) {
    msg.mode = correction_request_t::MODE_INVERSE;
    setPose("--inverse", args.inverse_pose, msg.desired_position_m, msg.desired_quaternion_wxyz);
    setJoints(args.seed_q_deg, msg.seed_q_rad);
  } else {
    msg.mode = correction_request_t::MODE_FORWARD;
    setJoints(args.forward_q_deg, msg.q_rad);
    if (args.count > 0) return runRepeated(args, msg);
  }
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  service::LcmRequester requester(lcm.get(), loadKey(args.key_file));
  const std::vector<correction_reply_t> replies =
      sendRequests(lcm.get(), args, {msg}, exchange, requester);
  if (exchange.answered == 0) {
    std::cerr << "stepcal-client: no reply within " << args.timeout_ms << " ms on " << args.lcm_url
              << "\n";
    explainSilence(requester, args.lcm_url);
    return exit_code::kNoService;
  }
  if (args.json) {
    nlohmann::json j = replyJson(replies[0], inverse);
    j["round_trip_us"] = exchange.round_trip_us[0];
    std::cout << j.dump(2) << "\n";
  } else {
    printReply(replies[0], exchange.round_trip_us[0], inverse, args.frame);
  }
  return exitStatusOf(1, 1, replies[0].status == int8_t(runtime::Status::kOk), "requests");
}

}  // namespace stepcal::client
