// stepcal-bench: time of the runtime's two real-time calls on a model file.
//
//   build/bin/stepcal-bench --model MODEL [--campaign DIR] [--calls N] [--temp-c T] [--compare-kdl]
//                           [--realtime] [--json] [--answers CSV]
//
// Poses (the report says which, `pose_source`): the model's GPR training inputs de-normalised
// (joints q and wrench), so every call lies in the model's workspace; when the model has no GPR,
// 400 poses uniform within its joint limits (2° inside, so the seeds are too; a continuous joint
// within ±π; unloaded; a fixed random seed); with --campaign, that campaign's rows (joints and
// measured wrench). Only poses whose forward correction is answered plainly are kept. Every
// call at the structure temperature --temp-c (°C; default NaN, not measured). correctForward runs at (q, wrench); solveInverse targets the forward
// correction of the same (q, wrench) from a seed 2° off on every joint (alternating sign), with a
// deadline far away so that the solver's own tolerances end it. Each call is timed alone with
// std::chrono::steady_clock after a warm-up; heap allocations are counted over the timed calls.
// After the calls, the model file is loaded 20 times (`load`: p50 and max, ms).
// Beside it, the same inverse seeded by the nominal chain's closed form in the pose's branch
// (`inverse_closed_form_seed`: runtime/closed_form_seed.hpp, the 2°-off joints only choosing the
// turns; the seed's own cost is timed with it), and each inverse's step count at p50 and p99
// (a step costs about one forward call).
// Beside them, the machine's own spread: the inverse at one pose (its iteration count the bench
// poses' most common) timed the same number of times (`inverse_one_pose`): identical work, so its
// p99 ÷ p50 is the machine's, and what the bench poses' tail has beyond it is theirs.
// --compare-kdl (built with Debian's liborocos-kdl-dev) times KDL's ChainIkSolverPos_NR_JL on
// the model's nominal chain (uncorrected, base frame): the nominal pose at each bench pose's q,
// from the same seed, at the same tolerance (1e-6), and prints the ratios.
// The series are timed in rounds of kRoundCalls calls each, one series after the other, so that
// every series sees the same stretches of the machine: on a shared VM whose speed drifts by tens
// of per cent from second to second, series timed one after the other would compare different
// machines. Each round opens with a few untimed calls of its series, so that the caches hold
// its code and data as in a run of that series alone. Each series' report also has the p50 of
// its quietest 1 000 calls in a row (`p50_quietest_batch_us`): the code's own speed when
// undisturbed; p50 and p99 over every call are what a controller there would see.
// The forward and the inverse are timed once more with the stated accuracy switched off
// (Workspace::with_accuracy, `forward_without_bound`, `inverse_without_bound`), in the same
// rounds: the bound's cost is the difference.
// --realtime: locked memory, SCHED_FIFO and one CPU for the timing thread (the daemon's settings,
// stepcal/service/realtime.hpp), so that other processes do not preempt the calls.
// --answers writes every bench pose's answers (forward pose, inverse status and joint targets)
// at full precision, untimed, so that two builds' answers can be compared (tools/bench/compare_answers.sh).
// Beside the two calls in the calibration's terms: the inverse in a controller's terms
// (`inverse_terms`: a user frame, a TCP 0.3 m out from the flange, or from the target when the
// model knows no flange, a 30 kg payload instead of the wrench), and what the cell key costs the
// daemon per request (`authentication`: checking a sealed request's code and counter, and
// sealing the reply; runtime/service/auth.hpp), on the messages' real sizes.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>

#include "stepcal/common/units.hpp"
#include "stepcal/runtime/closed_form_seed.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/latency.hpp"
#include "stepcal/service/realtime.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"
#ifdef STEPCAL_BENCH_WITH_KDL
#include "kdl_compare.hpp"
#endif
#include "stepcal/allocation_counter.hpp"

namespace {

using namespace stepcal;

constexpr double kSeedOffsetRad = 2.0 * kRadPerDeg;
constexpr int kWarmupCalls = 1000;
constexpr int kStatusCount = 7;
/// Calls of one series in a row before the next series' (every series sees the same stretches).
constexpr int kRoundCalls = 100;
/// Untimed calls that open each series' round: its code and data back in the caches the
/// previous series' round used (KDL's, another code path), as in a run of that series alone.
constexpr int kRoundWarmupCalls = 5;

/// One point of the model's workspace and the inverse problem built on it.
struct BenchPose {
  JointVector q_rad;
  Vec6 wrench_Sensor;
  Pose X_TrackerTip_target;  ///< forward correction at (q, wrench), m
  JointVector seed_q_rad;    ///< q ± 2°, rad
  Pose X_FrameTcp_target;    ///< forward correction at q in benchTerms, m
  ArmBranch branch;          ///< the nominal closed form's branch of q (a program's configuration)
};

/// A controller's terms for inverse_terms: a user frame, a TCP 0.3 m beyond the target (from
/// the flange when the model knows it), a 30 kg payload 0.1 m before the TCP.
runtime::CallTerms benchTerms(const runtime::RuntimeModel& model) {
  runtime::CallTerms terms;
  terms.frame = runtime::PoseFrame::kUser;
  terms.X_BaseUser.translation() = Vec3(1.2, -0.4, 0.3);
  terms.X_BaseUser.linear() = Eigen::AngleAxisd(0.6, Vec3::UnitZ()).toRotationMatrix();
  Pose X_TargetTcp = Pose::Identity();
  X_TargetTcp.translation() = Vec3(0.0, 0.0, 0.3);
  if (model.has_flange) {
    terms.tool_from = runtime::ToolFrom::kFlange;
    terms.X_Tool = model.X_TipFlange.inverse() * X_TargetTcp;
  } else {
    terms.X_Tool = X_TargetTcp;
  }
  terms.load_from = runtime::LoadFrom::kPayload;
  terms.payload.mass_kg = 30.0;
  terms.payload.frame = runtime::CogFrame::kTool;
  terms.payload.p_CoG_m = Vec3(0.0, 0.0, -0.1);
  return terms;
}

/// The bench pose at (q, wrench): its inverse targets are the forward corrections there. None
/// when the forward correction is not answered plainly (only such poses are timed).
std::optional<BenchPose> benchPoseAt(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                                     const JointVector& q_rad, const Vec6& wrench_Sensor,
                                     double temp_c) {
  BenchPose pose;
  pose.q_rad = q_rad;
  pose.wrench_Sensor = wrench_Sensor;
  pose.seed_q_rad = pose.q_rad;
  for (int i = 0; i < q_rad.size(); ++i) {
    pose.seed_q_rad[i] += (i % 2 ? -kSeedOffsetRad : kSeedOffsetRad);
  }
  const runtime::ForwardResult forward =
      runtime::correctForward(model, ws, pose.q_rad, pose.wrench_Sensor, temp_c);
  if (forward.status != runtime::Status::kOk) return std::nullopt;
  pose.X_TrackerTip_target = forward.X_TrackerTip;
  pose.branch = model.nominal_inverse.branchOf(pose.q_rad);
  pose.X_FrameTcp_target =
      runtime::correctForward(model, ws, pose.q_rad, benchTerms(model), temp_c).X_FrameTcp;
  return pose;
}

/// The bench poses and where they came from (the report's pose_source).
struct BenchPoses {
  std::vector<BenchPose> poses;
  std::string source;       ///< "gpr_training_inputs", "joint_limits_uniform" or "campaign"
  std::string description;  ///< the same in words, for the text report
  ArmLayout layout = ArmLayout::kOther;  ///< the nominal chain's closed form
};

/// The model's GPR training inputs de-normalised (joints q and wrench): the model's workspace.
BenchPoses posesFromGpr(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                        double temp_c, const std::string& path) {
  const GprParameters& gpr = *model.file.gpr;
  const int dof = model.file.chain_Tracker.dof();
  BenchPoses drawn{{}, "gpr_training_inputs", "the model's GPR training inputs"};
  for (Eigen::Index r = 0; r < gpr.inputs_normalised.rows(); ++r) {
    const Eigen::VectorXd x_raw =
        gpr.input_offset + gpr.input_scale.cwiseProduct(gpr.inputs_normalised.row(r).transpose());
    const std::optional<BenchPose> pose =
        benchPoseAt(model, ws, x_raw.head(dof), x_raw.segment<6>(dof), temp_c);
    if (pose) drawn.poses.push_back(*pose);
  }
  if (drawn.poses.empty()) {
    throw InputError("no GPR training input gives a forward correction", path);
  }
  return drawn;
}

/// Poses drawn when the model has no GPR: as many as the GPR's default training set.
constexpr int kUniformPoses = 400;
/// Draws per wanted pose before giving up on a model whose forward correction refuses them.
constexpr int kUniformDrawsPerPose = 100;

/// Joints uniform within the model's limits (a continuous joint within ±π), kept 2° inside them
/// so that every seed is within them too; unloaded (zero wrench); a fixed random seed, so that
/// two runs and two builds time the same poses.
BenchPoses posesWithinJointLimits(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                                  double temp_c, const std::string& path) {
  const std::vector<ChainJoint>& joints = model.file.chain_Tracker.joints();
  std::vector<std::uniform_real_distribution<double>> joint_rad;
  for (const ChainJoint& joint : joints) {
    double lower_rad = std::max(joint.lower_rad, -M_PI), upper_rad = std::min(joint.upper_rad, M_PI);
    if (upper_rad - lower_rad > 2.0 * kSeedOffsetRad) {
      lower_rad += kSeedOffsetRad;
      upper_rad -= kSeedOffsetRad;
    }
    joint_rad.emplace_back(lower_rad, upper_rad);
  }
  std::mt19937_64 random(1);
  BenchPoses drawn{{}, "joint_limits_uniform",
                   "uniform within the model's joint limits, unloaded (the model has no GPR "
                   "training inputs)"};
  JointVector q_rad(static_cast<Eigen::Index>(joints.size()));
  for (int draw = 0; draw < kUniformPoses * kUniformDrawsPerPose &&
                     drawn.poses.size() < size_t(kUniformPoses);
       ++draw) {
    for (size_t i = 0; i < joints.size(); ++i) q_rad[Eigen::Index(i)] = joint_rad[i](random);
    const std::optional<BenchPose> pose = benchPoseAt(model, ws, q_rad, Vec6::Zero(), temp_c);
    if (pose) drawn.poses.push_back(*pose);
  }
  if (drawn.poses.empty()) {
    throw InputError("no pose within the joint limits gives a forward correction", path);
  }
  return drawn;
}

/// Every row of a campaign of the model's robot (its joints and measured wrench).
BenchPoses posesFromCampaign(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                             double temp_c, const std::string& campaign_path) {
  const Campaign campaign = readCampaign(campaign_path);
  const int dof = model.file.chain_Tracker.dof();
  if (campaign.joint_count != dof) {
    throw InputError("--campaign: " + std::to_string(campaign.joint_count) +
                         " joints, the model has " + std::to_string(dof),
                     campaign_path);
  }
  BenchPoses drawn{{}, "campaign", "the rows of the campaign " + campaign_path};
  for (const Measurement& row : campaign.rows) {
    const std::optional<BenchPose> pose =
        benchPoseAt(model, ws, row.q_rad, row.wrenchOrZero(), temp_c);
    if (pose) drawn.poses.push_back(*pose);
  }
  if (drawn.poses.empty()) {
    throw InputError("no campaign row gives a forward correction", campaign_path);
  }
  return drawn;
}

/// The campaign's rows when one is given, else the model's GPR training inputs, else poses
/// drawn within its joint limits.
BenchPoses benchPoses(const runtime::RuntimeModel& model, runtime::Workspace& ws, double temp_c,
                      const std::string& model_path, const std::string& campaign_path) {
  if (!campaign_path.empty()) return posesFromCampaign(model, ws, temp_c, campaign_path);
  if (model.file.gpr) return posesFromGpr(model, ws, temp_c, model_path);
  return posesWithinJointLimits(model, ws, temp_c, model_path);
}

struct CallStats {
  std::vector<double> latency_us;
  long status_counts[kStatusCount] = {};
  std::vector<long> iterations;  ///< inverse: calls per Newton step count
};

/// Consecutive calls per batch of p50_quietest_batch_us (all of them when fewer).
constexpr size_t kQuietBatchCalls = 1000;

nlohmann::json latencyJson(std::vector<double> latency_us) {  // a copy: summarizing sorts it
  double quietest_p50_us = std::numeric_limits<double>::infinity();
  for (size_t first = 0; first < latency_us.size(); first += kQuietBatchCalls) {
    std::vector<double> batch(latency_us.begin() + long(first),
                              latency_us.begin() + long(std::min(latency_us.size(),
                                                                 first + kQuietBatchCalls)));
    quietest_p50_us = std::min(
        quietest_p50_us, service::summarizeLatencies(batch.data(), batch.size()).p50_us);
  }
  const service::LatencySummary s =
      service::summarizeLatencies(latency_us.data(), latency_us.size());
  return {{"calls", s.samples}, {"p50_us", s.p50_us}, {"p99_us", s.p99_us},
          {"p999_us", s.p999_us}, {"max_us", s.max_us},
          {"p50_quietest_batch_us", s.samples ? quietest_p50_us : 0.0}};
}

/// The smallest step count at or below which a fraction `quantile` of the calls ended.
long iterationQuantile(const std::vector<long>& histogram, long calls, double quantile) {
  long below = 0;
  for (size_t k = 0; k < histogram.size(); ++k) {
    below += histogram[k];
    if (double(below) >= quantile * double(calls)) return long(k);
  }
  return long(histogram.size()) - 1;
}

nlohmann::json toJson(CallStats& stats, bool inverse) {
  nlohmann::json j = latencyJson(stats.latency_us);
  nlohmann::json statuses = nlohmann::json::object();
  for (int k = 0; k < kStatusCount; ++k) {
    if (stats.status_counts[k]) {
      statuses[runtime::toString(static_cast<runtime::Status>(k))] = stats.status_counts[k];
    }
  }
  j["statuses"] = statuses;
  if (inverse) {
    long calls = 0, sum = 0;
    nlohmann::json histogram = nlohmann::json::object();
    for (size_t k = 0; k < stats.iterations.size(); ++k) {
      if (stats.iterations[k] == 0) continue;
      histogram[std::to_string(k)] = stats.iterations[k];
      calls += stats.iterations[k];
      sum += static_cast<long>(k) * stats.iterations[k];
    }
    j["mean_iterations"] = double(sum) / double(std::max(1L, calls));
    j["iterations"] = histogram;
    j["iterations_p50"] = iterationQuantile(stats.iterations, calls, 0.50);
    j["iterations_p99"] = iterationQuantile(stats.iterations, calls, 0.99);
  }
  return j;
}

double microsecondsBetween(runtime::Clock::time_point a, runtime::Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

/// KDL's inverse on the model's nominal chain at the bench poses: the nominal pose at each
/// pose's q from its seed, at the inverse's own tolerance.
struct KdlSide {
  static constexpr double kEps = 1e-6;  // InverseOptions' tolerances
  std::function<bool(size_t)> solve;    ///< bench pose index → converged
  double chain_mismatch_m = 0.0;        ///< KDL's FK against ours over the seeds
};

/// KdlSide on the bench poses; throws InputError when the bench was built without KDL.
KdlSide kdlSide(const runtime::RuntimeModel& model, const std::vector<BenchPose>& poses) {
#ifdef STEPCAL_BENCH_WITH_KDL
  std::vector<bench::KdlTarget> targets;
  ChainWorkspace ws;
  for (const BenchPose& p : poses) {
    forwardKinematics(model.file.nominal_Base, p.q_rad, ws);
    targets.push_back({tipPose(ws), p.seed_q_rad});
  }
  const auto kdl =
      std::make_shared<bench::KdlInverse>(model.file.nominal_Base, targets, KdlSide::kEps);
  return {[kdl](size_t i) { return kdl->solve(i); },
          bench::kdlChainMismatch_m(model.file.nominal_Base, targets)};
#else
  (void)model, (void)poses;
  throw InputError("--compare-kdl: this stepcal-bench was built without KDL (install "
                   "liborocos-kdl-dev and build again)");
#endif
}

/// One CSV line per bench pose: its index, the forward status and corrected pose (translation m,
/// then the rotation's 9 entries column-major), the inverse's status, iterations, joint targets
/// (rad) and residuals (m, rad); every number with 17 significant digits.
void writeAnswers(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                  const std::vector<BenchPose>& poses, double temp_c, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError("cannot write the answers file", path);
  const int dof = model.file.chain_Tracker.dof();
  out << "pose,forward_status,x_m,y_m,z_m";
  for (int i = 0; i < 9; ++i) out << ",r" << i;
  out << ",inverse_status,iterations";
  for (int i = 0; i < dof; ++i) out << ",q" << i + 1 << "_rad";
  out << ",residual_position_m,residual_orientation_rad\n";
  char number[32];
  const auto put = [&](double v) {
    std::snprintf(number, sizeof number, ",%.17g", v);
    out << number;
  };
  for (size_t k = 0; k < poses.size(); ++k) {
    const BenchPose& p = poses[k];
    const runtime::ForwardResult f =
        runtime::correctForward(model, ws, p.q_rad, p.wrench_Sensor, temp_c);
    out << k << "," << runtime::toString(f.status);
    for (int i = 0; i < 3; ++i) put(f.X_TrackerTip.translation()(i));
    for (int i = 0; i < 9; ++i) put(f.X_TrackerTip.linear()(i % 3, i / 3));
    const runtime::InverseResult r =
        runtime::solveInverse(model, ws, p.X_TrackerTip_target, p.wrench_Sensor, temp_c,
                              p.seed_q_rad, runtime::Clock::now() + std::chrono::seconds(1));
    out << "," << runtime::toString(r.status) << "," << r.iterations;
    for (int i = 0; i < dof; ++i) put(r.q_target_rad.size() == dof ? r.q_target_rad(i) : NAN);
    put(r.residual_position_m);
    put(r.residual_orientation_rad);
    out << "\n";
  }
  if (!out) throw InputError("cannot write the answers file", path);
}

/// The command line.
struct BenchOptions {
  std::string model_path, campaign_path, answers_path;
  int calls = 10000;
  double temp_c = runtime::kUnknownTemperature_c;
  bool json = false, compare_kdl = false, realtime = false;
};

void addOptions(CLI::App& app, BenchOptions& options) {
  app.add_option("--model", options.model_path, "model file (stepcal calibrate --out)")
      ->required();
  app.add_option("--campaign", options.campaign_path,
                 "time at this campaign's rows (joints and wrench; default: the model's GPR "
                 "training inputs, or poses uniform within its joint limits when it has no GPR)");
  app.add_option("--temp-c", options.temp_c,
                 "structure temperature of every call, °C (default: not measured)");
  app.add_option("--calls", options.calls, "timed calls of each function after the warm-up")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_flag("--compare-kdl", options.compare_kdl,
               "also time KDL's ChainIkSolverPos_NR_JL on the nominal chain (same poses, seeds, "
               "tolerance)");
  app.add_flag("--realtime", options.realtime,
               "time with locked memory, SCHED_FIFO priority 80 and one CPU (the daemon's "
               "--realtime; needs root or CAP_SYS_NICE and CAP_IPC_LOCK)");
  app.add_flag("--json", options.json, "print JSON");
  app.add_option("--answers", options.answers_path,
                 "also write every bench pose's answers to this CSV file (untimed)");
}

void checkTemperature(double temp_c) {
  if (!runtime::validTemperature(temp_c)) {
    throw InputError("--temp-c " + std::to_string(temp_c) + ": expected " +
                     std::to_string(int(runtime::kMinTemperature_c)) + " … " +
                     std::to_string(int(runtime::kMaxTemperature_c)) + " °C");
  }
}

/// The daemon's real-time settings for this thread, when asked; what was taken or refused.
nlohmann::json enterRealtimeIfAsked(bool realtime) {
  nlohmann::json report = {{"on", false}};
  if (!realtime) return report;
  std::string refusal = service::enterRealtime(), pin_refusal;
  const int cpu = refusal.empty() ? service::pinToLastAllowedCpu(pin_refusal) : -1;
  if (!refusal.empty()) {
    std::cerr << "stepcal-bench: --realtime: " << refusal
              << "; timing without real-time settings\n";
    report["refused"] = refusal;
  } else {
    report = {{"on", true}, {"priority", service::kRealtimePriority}, {"cpu", cpu}};
    if (cpu < 0) {
      std::cerr << "stepcal-bench: --realtime: " << pin_refusal << "; not pinned to a CPU\n";
      report["pin_refused"] = pin_refusal;
    }
  }
  return report;
}

/// The cell key's cost per request: a request sealed by the controller (before the timing, one
/// per call ever made: every counter fresh), checked, and the reply sealed.
class AuthenticationCalls {
 public:
  explicit AuthenticationCalls(int calls)
      : key_(randomKey()),
        controller_(key_),
        daemon_(key_),
        verifier_(key_, 3'600'000'000),  // an hour: the pool is sealed once
        reply_bytes_(size_t(service::Service::replyBytes())),
        reply_size_(stepcal_lcm::correction_reply_t{}.getEncodedSize()) {
    stepcal_lcm::correction_request_t request_msg = service::blankRequest();
    request_size_ = size_t(service::requestBytes());
    sealed_count_ =
        size_t(calls + (calls / kRoundCalls + 1) * kRoundWarmupCalls + kWarmupCalls);
    sealed_requests_.resize(sealed_count_ * request_size_);
    for (size_t i = 0; i < sealed_count_; ++i) {
      request_msg.request_id = int64_t(i);
      uint8_t* bytes = sealed_requests_.data() + i * request_size_;
      service::encodeRequest(request_msg, bytes, int(request_size_));
      controller_.seal(bytes, int(request_size_));
    }
  }

  /// Checks the next sealed request and seals a reply: kOk when the request was authentic.
  runtime::Status operator()(int) {
    const uint8_t* bytes =
        sealed_requests_.data() + (next_sealed_++ % sealed_count_) * request_size_;
    const service::Verdict verdict =
        verifier_.verify(bytes, int(request_size_), service::unixMicroseconds());
    daemon_.seal(reply_bytes_.data(), reply_size_);
    return verdict == service::Verdict::kAuthentic ? runtime::Status::kOk
                                                   : runtime::Status::kBadRequest;
  }

 private:
  static service::CellKey randomKey() {
    std::array<uint8_t, service::kKeyBytes> key_bytes{};
    randombytes_buf(key_bytes.data(), key_bytes.size());
    return service::CellKey::fromBytes(key_bytes);
  }

  service::CellKey key_;
  service::MessageSigner controller_, daemon_;
  service::MessageVerifier verifier_;
  std::vector<uint8_t> reply_bytes_;
  int reply_size_;
  size_t request_size_ = 0, sealed_count_ = 0, next_sealed_ = 0;
  std::vector<uint8_t> sealed_requests_;
};

/// The timed calls on the bench poses, call i at pose i modulo their count; an inverse leaves
/// its Newton step count in `iterations`.
struct BenchCalls {
  const runtime::RuntimeModel& model;
  runtime::Workspace& ws;
  const std::vector<BenchPose>& poses;
  double temp_c;
  runtime::CallTerms terms;
  KdlSide kdl_side;
  AuthenticationCalls authentication;
  int iterations = 0;

  const BenchPose& pose(int call) const { return poses[static_cast<size_t>(call) % poses.size()]; }
  runtime::Status forward(int call) {
    const BenchPose& p = pose(call);
    return runtime::correctForward(model, ws, p.q_rad, p.wrench_Sensor, temp_c).status;
  }
  runtime::Status inverse(int call) {
    const BenchPose& p = pose(call);
    const runtime::InverseResult r =
        runtime::solveInverse(model, ws, p.X_TrackerTip_target, p.wrench_Sensor, temp_c,
                              p.seed_q_rad, runtime::Clock::now() + std::chrono::seconds(1));
    iterations = r.iterations;
    return r.status;
  }
  /// The inverse seeded by the nominal closed form in the pose's branch (the 2°-off joints as
  /// the nearest turns), the seed's cost included.
  runtime::Status inverseClosedForm(int call) {
    const BenchPose& p = pose(call);
    const runtime::InverseResult r = runtime::solveInverseInBranch(
        model, ws, p.X_TrackerTip_target, p.wrench_Sensor, temp_c, p.branch, p.seed_q_rad,
        runtime::Clock::now() + std::chrono::seconds(1));
    iterations = r.iterations;
    return r.status;
  }
  runtime::Status inverseTerms(int call) {
    const BenchPose& p = pose(call);
    const runtime::InverseResult r =
        runtime::solveInverse(model, ws, p.X_FrameTcp_target, terms, temp_c, p.seed_q_rad,
                              runtime::Clock::now() + std::chrono::seconds(1));
    iterations = r.iterations;
    return r.status;
  }
  /// A call with the stated accuracy switched off (Workspace::with_accuracy): its cost.
  template <typename Call>
  runtime::Status withoutBound(int call, Call&& run) {
    ws.with_accuracy = false;
    const runtime::Status status = run(call);
    ws.with_accuracy = true;
    return status;
  }
  /// KDL's outcome as a status: converged within eps, or not.
  runtime::Status kdl(int call) {
    return kdl_side.solve(static_cast<size_t>(call) % poses.size())
               ? runtime::Status::kOk
               : runtime::Status::kNotConverged;
  }
};

/// Every series' calls, and the heap allocations of ours.
struct BenchSeries {
  CallStats forward, inverse, inverse_closed_form, one_pose, kdl, inverse_terms, authentication;
  CallStats forward_without_bound, inverse_without_bound;  ///< Workspace::with_accuracy off
  long allocations = 0;

  explicit BenchSeries(int calls) {
    for (CallStats* stats : {&forward, &inverse, &inverse_closed_form, &one_pose, &kdl,
                             &inverse_terms, &authentication, &forward_without_bound,
                             &inverse_without_bound}) {
      stats->latency_us.resize(static_cast<size_t>(calls));
    }
    inverse.iterations.resize(static_cast<size_t>(runtime::InverseOptions{}.max_iterations) + 1);
    inverse_without_bound.iterations.resize(inverse.iterations.size());
    one_pose.iterations.resize(inverse.iterations.size());
    inverse_closed_form.iterations.resize(inverse.iterations.size());
    inverse_terms.iterations.resize(inverse.iterations.size());
  }
};

/// Untimed warm-up of every series; returns the pose of the machine's baseline: the first whose
/// inverse iteration count is the most common.
int warmUpAndFindBaseline(BenchCalls& calls, bool compare_kdl, size_t iteration_counts) {
  std::vector<long> warmup_iterations(iteration_counts);
  for (int call = 0; call < kWarmupCalls; ++call) {
    calls.forward(call);
    calls.inverse(call);
    ++warmup_iterations[size_t(calls.iterations)];
    calls.inverseClosedForm(call);
    calls.inverseTerms(call);
    calls.authentication(call);
    if (compare_kdl) calls.kdl(call);
  }
  const int common = static_cast<int>(
      std::max_element(warmup_iterations.begin(), warmup_iterations.end()) -
      warmup_iterations.begin());
  int baseline_call = 0;
  while (baseline_call + 1 < static_cast<int>(calls.poses.size()) &&
         (calls.inverse(baseline_call), calls.iterations != common)) {
    ++baseline_call;
  }
  return baseline_call;
}

/// Calls [first, last) of one series, each timed alone, after kRoundWarmupCalls untimed ones
/// (the round's first poses); the inverse's also counted by its Newton step count.
template <typename Run>
void timeCalls(CallStats& stats, int first, int last, const int& iterations, Run&& run) {
  for (int call = first; call < first + kRoundWarmupCalls; ++call) run(call);
  for (int call = first; call < last; ++call) {
    const auto start = runtime::Clock::now();
    const runtime::Status status = run(call);
    stats.latency_us[size_t(call)] = microsecondsBetween(start, runtime::Clock::now());
    ++stats.status_counts[static_cast<int>(status)];
    if (!stats.iterations.empty()) ++stats.iterations[size_t(iterations)];
  }
}

/// Every series in rounds of kRoundCalls calls, one series after the other.
void timeSeries(BenchCalls& calls, BenchSeries& series, int call_count, int baseline_call,
                bool compare_kdl) {
  const int& iterations = calls.iterations;
  for (int first = 0; first < call_count; first += kRoundCalls) {
    const int last = std::min(call_count, first + kRoundCalls);
    {
      const test::AllocationCounter counter;  // ours only: KDL's are its own
      timeCalls(series.forward, first, last, iterations,
                [&](int call) { return calls.forward(call); });
      timeCalls(series.inverse, first, last, iterations,
                [&](int call) { return calls.inverse(call); });
      timeCalls(series.inverse_closed_form, first, last, iterations,
                [&](int call) { return calls.inverseClosedForm(call); });
      timeCalls(series.one_pose, first, last, iterations,
                [&](int) { return calls.inverse(baseline_call); });
      timeCalls(series.inverse_terms, first, last, iterations,
                [&](int call) { return calls.inverseTerms(call); });
      timeCalls(series.authentication, first, last, iterations, calls.authentication);
      timeCalls(series.forward_without_bound, first, last, iterations, [&](int call) {
        return calls.withoutBound(call, [&](int c) { return calls.forward(c); });
      });
      timeCalls(series.inverse_without_bound, first, last, iterations, [&](int call) {
        return calls.withoutBound(call, [&](int c) { return calls.inverse(c); });
      });
      series.allocations += counter.count();
    }
    if (compare_kdl) {
      timeCalls(series.kdl, first, last, iterations, [&](int call) { return calls.kdl(call); });
    }
  }
}

nlohmann::json makeReport(const BenchOptions& options, const BenchPoses& drawn,
                          BenchSeries& series, const KdlSide& kdl_side,
                          const nlohmann::json& realtime_report) {
  const double temp_c = options.temp_c;
  nlohmann::json report = {{"model", options.model_path},
                           {"poses", drawn.poses.size()},
                           {"pose_source", drawn.source},
                           {"temp_c", std::isnan(temp_c) ? nlohmann::json(nullptr)
                                                         : nlohmann::json(temp_c)},
                           {"forward", toJson(series.forward, false)},
                           {"inverse", toJson(series.inverse, true)},
                           {"inverse_closed_form_seed", toJson(series.inverse_closed_form, true)},
                           {"closed_form_layout", toString(drawn.layout)},
                           {"inverse_one_pose", toJson(series.one_pose, true)},
                           {"inverse_terms", toJson(series.inverse_terms, true)},
                           {"authentication", toJson(series.authentication, false)},
                           {"forward_without_bound", toJson(series.forward_without_bound, false)},
                           {"inverse_without_bound", toJson(series.inverse_without_bound, true)},
                           {"allocations", series.allocations},
                           {"realtime", realtime_report}};
  if (options.compare_kdl) {
    nlohmann::json j = latencyJson(series.kdl.latency_us);
    j["eps"] = KdlSide::kEps;
    j["failures"] = series.kdl.status_counts[static_cast<int>(runtime::Status::kNotConverged)];
    j["chain_mismatch_m"] = kdl_side.chain_mismatch_m;
    j["ratio_p50"] = j["p50_us"].get<double>() / report["inverse"]["p50_us"].get<double>();
    j["ratio_p99"] = j["p99_us"].get<double>() / report["inverse"]["p99_us"].get<double>();
    report["kdl"] = j;
  }
  return report;
}

void printText(const nlohmann::json& report, const std::string& pose_description) {
  std::cout << "poses: " << report["poses"] << ", " << pose_description << "\n";
  for (const char* name :
       {"forward", "inverse", "inverse_closed_form_seed", "inverse_one_pose", "inverse_terms",
        "authentication", "forward_without_bound", "inverse_without_bound"}) {
    const nlohmann::json& r = report[name];
    std::cout << name << ": " << r["calls"] << " calls, p50 " << r["p50_us"].get<double>()
              << " us, p99 " << r["p99_us"].get<double>() << " us, max "
              << r["max_us"].get<double>() << " us, p50 of the quietest " << kQuietBatchCalls
              << " " << r["p50_quietest_batch_us"].get<double>() << " us";
    if (r.contains("mean_iterations")) {
      std::cout << ", iterations mean " << r["mean_iterations"].get<double>() << " p50 "
                << r["iterations_p50"] << " p99 " << r["iterations_p99"];
    }
    std::cout << ", statuses " << r["statuses"].dump() << "\n";
  }
  std::cout << "closed-form layout of the nominal chain: " << report["closed_form_layout"]
            << "\n";
  std::cout << "allocations during the timed calls: " << report["allocations"] << "\n";
  const nlohmann::json& load = report["load"];
  std::cout << "model load (RuntimeModel::load, " << load["loads"] << " times): p50 "
            << load["p50_ms"].get<double>() << " ms, max " << load["max_ms"].get<double>()
            << " ms\n";
  std::cout << "real-time settings: " << report["realtime"].dump() << "\n";
  if (report.contains("kdl")) {
    const nlohmann::json& k = report["kdl"];
    std::cout << "KDL ChainIkSolverPos_NR_JL, nominal chain, eps " << k["eps"].get<double>()
              << ": p50 " << k["p50_us"].get<double>() << " us, p99 " << k["p99_us"].get<double>()
              << " us, max " << k["max_us"].get<double>() << " us, failures " << k["failures"]
              << "; KDL / stepcal inverse: p50 " << k["ratio_p50"].get<double>() << "x, p99 "
              << k["ratio_p99"].get<double>() << "x\n";
  }
}

/// RuntimeModel::load of the model file, kLoads times (its GPR's factor and white noise, the
/// physical model's constants): p50 and max, ms.
nlohmann::json loadTimes(const std::string& model_path) {
  constexpr int kLoads = 20;
  std::vector<double> ms;
  for (int i = 0; i < kLoads; ++i) {
    const auto start = std::chrono::steady_clock::now();
    const std::unique_ptr<const runtime::RuntimeModel> model = runtime::RuntimeModel::load(model_path);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(ms.begin(), ms.end());
  return {{"loads", kLoads}, {"p50_ms", ms[kLoads / 2]}, {"max_ms", ms.back()}};
}

/// Loads the model, draws the poses, times every series and prints the report.
void runBench(const BenchOptions& options) {
  checkTemperature(options.temp_c);
  const std::unique_ptr<const runtime::RuntimeModel> model =
      runtime::RuntimeModel::load(options.model_path);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  BenchPoses drawn =
      benchPoses(*model, ws, options.temp_c, options.model_path, options.campaign_path);
  drawn.layout = model->nominal_inverse.layout();
  KdlSide kdl_side;
  if (options.compare_kdl) kdl_side = kdlSide(*model, drawn.poses);
  const nlohmann::json realtime_report = enterRealtimeIfAsked(options.realtime);

  BenchSeries series(options.calls);
  BenchCalls calls{*model, ws, drawn.poses, options.temp_c, benchTerms(*model),
                   std::move(kdl_side), AuthenticationCalls(options.calls)};
  const int baseline_call =
      warmUpAndFindBaseline(calls, options.compare_kdl, series.inverse.iterations.size());
  timeSeries(calls, series, options.calls, baseline_call, options.compare_kdl);
  if (!options.answers_path.empty()) {
    writeAnswers(*model, ws, drawn.poses, options.temp_c, options.answers_path);
  }

  nlohmann::json report = makeReport(options, drawn, series, calls.kdl_side, realtime_report);
  report["load"] = loadTimes(options.model_path);
  if (options.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    printText(report, drawn.description);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal-bench: latency of correctForward and solveInverse on a model file"};
  BenchOptions options;
  addOptions(app, options);
  CLI11_PARSE(app, argc, argv);
  try {
    runBench(options);
  } catch (const InputError& e) {
    std::cerr << "stepcal-bench: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
