// stepcal-client --campaign: a campaign's rows as requests (latency, lost replies, statuses,
// accuracy), with the daemon's live sensor fed by a simulated one (--live-wrench) and every reply
// recomputed offline (--check-model, checks.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>

#include <stepcal_lcm/robot_state_t.hpp>
#include <stepcal_lcm/wrench_t.hpp>

#include "checks.hpp"
#include "client.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/runtime/can_socket.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal::client {
namespace {

// ---- the requests ------------------------------------------------------------------------------

void setDesiredPose(correction_request_t& msg, const Pose& X_TrackerTip) {
  toPositionQuaternion(X_TrackerTip, msg.desired_position_m, msg.desired_quaternion_wxyz);
}

/// The requests for a campaign's rows (cycled up to count), and the rows they came from.
std::vector<correction_request_t> campaignRequests(const Args& args,
                                                   const std::vector<const Measurement*>& rows,
                                                   std::vector<const Measurement*>& row_of) {
  const bool inverse = args.mode == "inverse";
  std::vector<correction_request_t> requests;
  for (int i = 0; i < args.count; ++i) {
    const Measurement& row = *rows[size_t(i) % rows.size()];
    correction_request_t msg = emptyRequest(args);
    msg.mode = inverse ? correction_request_t::MODE_INVERSE : correction_request_t::MODE_FORWARD;
    if (!args.live_wrench) setWrench(msg, row.wrenchOrZero());
    if (row.temp_c) msg.temp_c = *row.temp_c;
    for (int j = 0; j < service::kMessageJoints; ++j) {
      msg.q_rad[j] = row.q_rad[j];
      msg.seed_q_rad[j] = row.q_rad[j] + (j % 2 ? -kSeedOffsetRad : kSeedOffsetRad);
    }
    if (inverse) setDesiredPose(msg, row.X_TrackerTip());
    requests.push_back(msg);
    row_of.push_back(&row);
  }
  return requests;
}

RowSet parseSet(const std::string& name) {
  for (RowSet set : {RowSet::kGeometry, RowSet::kStiffness, RowSet::kResidual,
                     RowSet::kValidation}) {
    if (name == toString(set)) return set;
  }
  throw InputError("--set '" + name + "': expected geometry, stiffness, residual or validation");
}

/// The campaign and the rows its requests go through, as --set, --mode and --count ask.
struct CampaignRows {
  Campaign campaign;
  std::vector<const Measurement*> rows;
};

/// Reads the campaign and checks it fits the options; args.count defaults to one request per row.
CampaignRows readCampaignRows(Args& args) {
  CampaignRows result;
  result.campaign = readCampaign(args.campaign_dir);
  const Campaign& campaign = result.campaign;
  if (campaign.joint_count != service::kMessageJoints) {
    throw InputError("the campaign has " + std::to_string(campaign.joint_count) +
                         " joints; the LCM messages carry " +
                         std::to_string(service::kMessageJoints),
                     args.campaign_dir);
  }
  result.rows = campaign.rowsIn(parseSet(args.set));
  if (result.rows.empty()) throw InputError("--set " + args.set + ": the campaign has no such rows", args.campaign_dir);
  if (args.mode == "inverse") {
    for (const Measurement* row : result.rows) {
      if (!row->has_orientation) {
        throw InputError("--mode inverse needs measured orientations; this row has none",
                         campaign.directory + "/" + campaign.measurements_file, row->source_line);
      }
    }
  }
  if (args.count <= 0) args.count = int(result.rows.size());
  return result;
}

std::optional<twin::TwinRobot> readTruth(const std::string& path) {
  if (path.empty()) return std::nullopt;
  std::ifstream in(path);
  if (!in) throw InputError("--truth: cannot read the file", path);
  nlohmann::json truth;
  try {
    truth = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("--truth: not JSON: ") + e.what(), path);
  }
  return twin::TwinRobot::fromTruthJson(truth);
}

// ---- --live-wrench: the robot's state through the simulated sensor -------------------------------

/// Publishes each row's joints and payload as robot_state_t before its request, and waits until a
/// simulated sensor echoes it as applied and the daemon has taken two samples stamped after the
/// echo (the first may still be the reading made just before the state was applied).
class RobotStatePacer {
 public:
  RobotStatePacer(lcm_t* lcm, const Args& args)
      : lcm_(lcm), buffer_(size_t(stepcal_lcm::robot_state_t{}.getEncodedSize())) {
    applied_ = service::subscribeQueued(lcm_, service::kRobotStateAppliedChannel, &onApplied, this);
    if (args.live_wrench) {
      samples_ = service::subscribeQueued(lcm_, args.wrench_channel.c_str(), &onSample, this);
    }
  }
  ~RobotStatePacer() { unsubscribe(); }
  RobotStatePacer(const RobotStatePacer&) = delete;
  RobotStatePacer& operator=(const RobotStatePacer&) = delete;

  /// States not echoed, or not read twice after, within 10 s (no simulator?).
  int missing() const { return missing_; }

  void unsubscribe() {
    if (applied_) lcm_unsubscribe(lcm_, applied_);
    if (samples_) lcm_unsubscribe(lcm_, samples_);
    applied_ = samples_ = nullptr;
  }

  void publish(const Measurement& row) {
    // Where the robot now is and what it carries, tagged with a fresh utime.
    stepcal_lcm::robot_state_t state{};
    state.utime = std::max(unixMicroseconds(), wanted_utime_ + 1);
    for (int j = 0; j < service::kMessageJoints; ++j) state.q_rad[j] = row.q_rad[j];
    state.payload_kg = row.load_kg;
    wanted_utime_ = state.utime;
    seen_ = false;
    const int size = state.encode(buffer_.data(), 0, int(buffer_.size()));
    lcm_publish(lcm_, service::kRobotStateChannel, buffer_.data(), unsigned(size));
    const Clock::time_point give_up = Clock::now() + std::chrono::seconds(10);
    while (!seen_ && Clock::now() < give_up) service::handleLcmUntil(lcm_, give_up);
    fresh_after_ns_ = runtime::steadyNowNs();
    fresh_count_ = 0;
    while (seen_ && fresh_count_ < 2 && Clock::now() < give_up) {
      service::handleLcmUntil(lcm_, give_up);
    }
    if (!seen_ || fresh_count_ < 2) ++missing_;
  }

 private:
  /// The simulated sensor's echo of a robot_state_t (by its utime).
  static void onApplied(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    auto* self = static_cast<RobotStatePacer*>(user);
    stepcal_lcm::robot_state_t state{};
    if (state.decode(rbuf->data, 0, int(rbuf->data_size)) > 0 && state.utime == self->wanted_utime_) {
      self->seen_ = true;
    }
  }
  /// The daemon's samples (wrench_t) stamped after the echo: at two, its live wrench is of the
  /// state applied.
  static void onSample(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    auto* self = static_cast<RobotStatePacer*>(user);
    stepcal_lcm::wrench_t sample{};
    if (sample.decode(rbuf->data, 0, int(rbuf->data_size)) > 0 &&
        sample.stamp_ns > self->fresh_after_ns_) {
      ++self->fresh_count_;
    }
  }

  lcm_t* lcm_;
  std::vector<uint8_t> buffer_;
  lcm_subscription_t* applied_ = nullptr;
  lcm_subscription_t* samples_ = nullptr;
  int64_t wanted_utime_ = 0;
  bool seen_ = false;
  int64_t fresh_after_ns_ = 0;  ///< CLOCK_MONOTONIC, as the samples' stamps
  int fresh_count_ = 0;
  int missing_ = 0;
};

// ---- the replies ---------------------------------------------------------------------------------

struct Accuracy {
  int poses = 0;
  double sum_position_m = 0, max_position_m = 0, sum_orientation_rad = 0;
  int orientations = 0;

  void add(double position_m, std::optional<double> orientation_rad) {
    ++poses;
    sum_position_m += position_m;
    max_position_m = std::max(max_position_m, position_m);
    if (orientation_rad) {
      sum_orientation_rad += *orientation_rad;
      ++orientations;
    }
  }
  nlohmann::json toJson(const std::string& against) const {
    return {{"against", against},
            {"poses", poses},
            {"mean_position_mm", poses ? sum_position_m / poses * kMmPerM : 0.0},
            {"max_position_mm", max_position_m * kMmPerM},
            {"mean_orientation_deg",
             orientations ? sum_orientation_rad / orientations * kDegPerRad : 0.0}};
  }
};

/// What the replies of a campaign tell.
struct CampaignTally {
  long status_counts[kStatusCount] = {};
  std::vector<double> compute_us;
  Accuracy accuracy, forward_truth;
  std::vector<double> frame_to_reply_us;
  double iterations = 0;
  int64_t model_id = 0;
  /// Per request: its row, status and GPR std (row by row comparisons of two runs).
  nlohmann::json per_row = nlohmann::json::array();
};

/// Adds an OK reply's accuracy: forward against the row's measured pose (and the truth, when
/// given), inverse against the truth at q_target when given, else the solver's own residual.
void addAccuracy(const correction_reply_t& r, const Measurement& row, bool inverse,
                 const std::optional<twin::TwinRobot>& truth, CampaignTally& tally) {
  if (!inverse) {
    const Pose X = poseFromPositionQuaternion(r.predicted_position_m, r.predicted_quaternion_wxyz);
    tally.accuracy.add((X.translation() - row.p_TipInTracker_m).norm(),
                       row.has_orientation ? std::optional<double>(lie::angleBetween(
                                                 row.q_TrackerTip.toRotationMatrix(), X.linear()))
                                           : std::nullopt);
    if (truth) {
      const Pose X_true = truth->X_TrackerTip(row.q_rad, row.load_kg);
      tally.forward_truth.add((X.translation() - X_true.translation()).norm(),
                              lie::angleBetween(X_true.linear(), X.linear()));
    }
  } else if (truth) {
    const Pose X_true = truth->X_TrackerTip(jointsOf(r.q_target_rad), row.load_kg);
    const Pose X_desired = row.X_TrackerTip();
    tally.accuracy.add((X_true.translation() - X_desired.translation()).norm(),
                       lie::angleBetween(X_desired.linear(), X_true.linear()));
  } else {
    tally.accuracy.add(r.residual_position_m, r.residual_orientation_rad);
  }
}

CampaignTally tallyReplies(const std::vector<correction_request_t>& requests,
                           const std::vector<correction_reply_t>& replies,
                           const std::vector<const Measurement*>& row_of,
                           const Exchange& exchange, bool inverse,
                           const std::optional<twin::TwinRobot>& truth,
                           std::optional<ReplyChecker>& checker) {
  CampaignTally tally;
  for (size_t i = 0; i < replies.size(); ++i) {
    nlohmann::json& entry = tally.per_row.emplace_back(nlohmann::json{
        {"line", row_of[i]->source_line}, {"load_kg", row_of[i]->load_kg}, {"status", nullptr}});
    if (std::isnan(exchange.round_trip_us[i])) continue;
    const correction_reply_t& r = replies[i];
    entry["status"] = runtime::toString(static_cast<runtime::Status>(r.status));
    entry["gpr_std"] = std::vector<double>(r.gpr_std, r.gpr_std + 6);
    entry["accuracy"] = accuracyJson(r);
    if (r.status >= 0 && r.status < kStatusCount) ++tally.status_counts[r.status];
    tally.compute_us.push_back(double(r.compute_ns) * 1e-3);
    tally.model_id = r.model_id;
    if (checker) checker->check(requests[i], r);
    if (r.wrench_stamp_ns > 0) {
      tally.frame_to_reply_us.push_back(double(receivedNs(exchange, i) - r.wrench_stamp_ns) * 1e-3);
    }
    if (r.status != int8_t(runtime::Status::kOk)) continue;  // accuracy of plain answers
    tally.iterations += r.iterations;
    addAccuracy(r, *row_of[i], inverse, truth, tally);
  }
  return tally;
}

nlohmann::json campaignReport(const Args& args, const Exchange& exchange,
                              const CampaignTally& tally, bool with_truth,
                              const service::LcmRequester& requester, int states_not_applied,
                              const std::optional<ReplyChecker>& checker) {
  const bool inverse = args.mode == "inverse";
  nlohmann::json report = {
      {"mode", args.mode},
      {"requests", args.count},
      {"replies", exchange.answered},
      {"lost", args.count - exchange.answered},
      {"late", exchange.late},
      {"duplicates", exchange.duplicates},
      {"rate_hz", args.rate_hz},
      {"model_id", modelIdText(tally.model_id)},
      {"round_trip_us", latencyJson(exchange.round_trip_us)},
      {"compute_us", latencyJson(tally.compute_us)},
      {"statuses", statusesJson(tally.status_counts)},
      {"accuracy", tally.accuracy.toJson(inverse ? (with_truth ? "twin truth" : "solver residual")
                                                 : "measured pose")}};
  report["authentication"] = authenticationJson(requester);
  report["rows"] = tally.per_row;
  if (inverse) {
    report["mean_iterations"] =
        tally.accuracy.poses ? tally.iterations / tally.accuracy.poses : 0.0;
  } else if (with_truth) {
    report["accuracy_truth"] = tally.forward_truth.toJson("twin truth");
  }
  report["wrench"] = args.live_wrench ? "live sensor" : "given (the rows' measured wrench)";
  if (args.live_wrench) {
    report["sensor_frame_to_reply_us"] = latencyJson(tally.frame_to_reply_us);
    report["robot_states_not_applied"] = states_not_applied;
  }
  if (checker) report["check"] = checker->toJson();
  return report;
}

void printCampaignText(const Args& args, const nlohmann::json& report, int answered,
                       int accurate_answers) {
  std::cout << args.count << " " << args.mode << " requests (" << args.set << " rows of "
            << args.campaign_dir << "): " << answered << " replies, " << report["lost"]
            << " lost\n"
            << "round trip: " << latencyText(report["round_trip_us"]) << "\n"
            << "compute (daemon): " << latencyText(report["compute_us"]) << "\n"
            << "statuses: " << report["statuses"].dump() << "\n";
  const nlohmann::json& a = report["accuracy"];
  std::printf("accuracy (%s, %d answers): mean %.4f mm, max %.4f mm, mean %.4f deg\n",
              a["against"].get<std::string>().c_str(), accurate_answers,
              a["mean_position_mm"].get<double>(), a["max_position_mm"].get<double>(),
              a["mean_orientation_deg"].get<double>());
  if (report.contains("accuracy_truth")) {
    const nlohmann::json& t = report["accuracy_truth"];
    std::printf("accuracy (twin truth): mean %.4f mm, max %.4f mm, mean %.4f deg\n",
                t["mean_position_mm"].get<double>(), t["max_position_mm"].get<double>(),
                t["mean_orientation_deg"].get<double>());
  }
  if (args.live_wrench) {
    std::cout << "CAN frame to reply: " << latencyText(report["sensor_frame_to_reply_us"]) << "\n";
  }
  if (report.contains("check")) {
    const nlohmann::json& c = report["check"];
    std::cout << "checked against their models: " << c["checked"] << " replies, "
              << c["mismatched"] << " differ, " << c["unknown_model"]
              << " from an unknown model, largest difference " << c["max_difference"] << "\n";
  }
}

}  // namespace

int runCampaign(Args args) {
  if (args.mode != "forward" && args.mode != "inverse") {
    throw InputError("--mode '" + args.mode + "': expected forward or inverse");
  }
  const bool inverse = args.mode == "inverse";
  if (args.live_wrench && args.rate_hz > 0.0) {
    throw InputError("--live-wrench sends one request at a time: drop --rate");
  }
  const CampaignRows campaign = readCampaignRows(args);
  const std::optional<twin::TwinRobot> truth = readTruth(args.truth_path);
  if (args.live_wrench && !args.check_models.empty()) {
    throw InputError("--check-model recomputes replies from the requests' wrenches: drop --live-wrench");
  }
  std::optional<ReplyChecker> checker;
  if (!args.check_models.empty()) {
    checker.emplace(args.check_models);
    checker->requireRobotOf(campaign.campaign);
  }

  std::vector<const Measurement*> row_of;
  const std::vector<correction_request_t> requests = campaignRequests(args, campaign.rows, row_of);
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  RobotStatePacer pacer(lcm.get(), args);
  service::LcmRequester requester(lcm.get(), loadKey(args.key_file));
  const auto publishRobotState = [&](size_t i) { pacer.publish(*row_of[i]); };
  const std::vector<correction_reply_t> replies =
      sendRequests(lcm.get(), args, requests, exchange, requester,
                   args.live_wrench ? std::function<void(size_t)>(publishRobotState) : nullptr);
  if (exchange.answered == 0) explainSilence(requester, args.lcm_url);
  pacer.unsubscribe();

  const CampaignTally tally =
      tallyReplies(requests, replies, row_of, exchange, inverse, truth, checker);
  const nlohmann::json report = campaignReport(args, exchange, tally, truth.has_value(), requester,
                                               pacer.missing(), checker);
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    printCampaignText(args, report, exchange.answered, tally.accuracy.poses);
  }
  if (checker && !checker->passed()) {
    std::cerr << "stepcal-client: torn answer: " << checker->toJson()["first_problem"].get<std::string>()
              << "\n";
    return exit_code::kFailed;
  }
  return exitStatusOf(args.count, exchange.answered,
                      tally.status_counts[size_t(runtime::Status::kOk)], "requests");
}

}  // namespace stepcal::client
