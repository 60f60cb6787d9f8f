#include "stepcal/common/units.hpp"
#include "stepcal/trainer/plan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/mechanisms/off_axis_compliance.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"

namespace stepcal::trainer {
namespace {

// The cache sizes Eigen's products are told, bytes: the GPR's (gpr.cpp, pinEigenBlocking). Eigen
// blocks its products by the CPU's caches, which orders the sums; the greedy choice between
// candidates of nearly equal gain then followed the last bits: the same plan came out different
// on another CPU, or after a GPR fit had pinned the blocking in the same process (a 60-pose plan
// among Series C's poses changed 7 poses between `stepcal plan` and a test that calibrated first).
constexpr std::ptrdiff_t kPinnedL1CacheBytes = 32 * 1024;
constexpr std::ptrdiff_t kPinnedL2CacheBytes = 256 * 1024;
constexpr std::ptrdiff_t kPinnedL3CacheBytes = 2 * 1024 * 1024;

/// Uniform in [0, 1) from the engine's 53 high bits: mt19937_64's output is fixed by the
/// standard, std::uniform_real_distribution's is not.
double uniform01(std::mt19937_64& engine) {
  return static_cast<double>(engine() >> 11) * 0x1.0p-53;
}

/// The range a joint's candidate angles are drawn from and its coverage binned over: its limits,
/// or one turn (−π, π) for a continuous joint. rad.
std::pair<double, double> jointRange(const ChainJoint& joint) {
  if (std::isfinite(joint.lower_rad) && std::isfinite(joint.upper_rad)) {
    return {joint.lower_rad, joint.upper_rad};
  }
  return {-kPi, kPi};
}

/// Shortest distance between segments [a0, a1] and [b0, b1], m.
double segmentDistance(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  const Vec3 u = a1 - a0, v = b1 - b0, w = a0 - b0;
  const double uu = u.dot(u), uv = u.dot(v), vv = v.dot(v), uw = u.dot(w), vw = v.dot(w);
  const double denominator = uu * vv - uv * uv;
  // s on a, t on b: the unconstrained closest points, then each clamped with the other re-solved.
  double s = denominator > 1e-15 * uu * vv ? std::clamp((uv * vw - vv * uw) / denominator, 0.0, 1.0)
                                           : 0.0;
  double t = vv > 0.0 ? std::clamp((uv * s + vw) / vv, 0.0, 1.0) : 0.0;
  s = uu > 0.0 ? std::clamp((uv * t - uw) / uu, 0.0, 1.0) : 0.0;
  return (w + s * u - t * v).norm();
}

/// A visible candidate pose and its identification block (rows: unloaded position, then each
/// payload's deflection; columns: 6(n+1) geometry, n compliance, two tilt compliances per
/// PlanOptions::off_axis_joints, three mount compliances with PlanOptions::tool_mount).
struct Candidate {
  JointVector q_rad;
  Eigen::MatrixXd block;
};

enum class Visibility { kVisible, kRange, kFloor, kLineOfSight };

Visibility visibility(const ChainWorkspace& ws, const PlanOptions& o) {
  const int n = ws.dof;
  const Vec3 p_TipInBase = tipPose(ws).translation();
  const double range_m = (p_TipInBase - o.p_TrackerInBase_m).norm();
  if (range_m < o.min_range_m || range_m > o.max_range_m) return Visibility::kRange;
  for (int k = 2; k <= n + 1; ++k) {
    if (ws.X_RootFrame[static_cast<size_t>(k)].translation().z() < o.min_link_height_m) {
      return Visibility::kFloor;
    }
  }
  const Vec3 sight_end = p_TipInBase + (o.p_TrackerInBase_m - p_TipInBase) * (o.tip_exclusion_m / range_m);
  for (int k = 0; k < n; ++k) {
    const Vec3& a = ws.X_RootFrame[static_cast<size_t>(k)].translation();
    const Vec3& b = ws.X_RootFrame[static_cast<size_t>(k + 1)].translation();
    if (segmentDistance(o.p_TrackerInBase_m, sight_end, a, b) < o.line_of_sight_clearance_m) {
      return Visibility::kLineOfSight;
    }
  }
  return Visibility::kVisible;
}

/// The tip's motion per unit tilt compliance of each off_axis joint under the payload's wrench
/// W_Base (mechanisms/off_axis_compliance.hpp): the tilt c (d·M) d about direction d at the
/// joint's origin, in the rows from `first`, the columns from `column`.
void addTiltColumns(const KinematicChain& chain, const ChainWorkspace& ws, const Vec6& W_Base,
                    const PlanOptions& o, int first, int column, Eigen::MatrixXd& block) {
  const bool rotation = o.orientation_sigma_rad > 0.0;
  const Vec3 p_TipInBase = tipPose(ws).translation();
  for (const int joint : o.off_axis_joints) {
    const Pose& X_BaseJoint = ws.X_RootFrame[static_cast<size_t>(joint + 1)];
    const Vec3 moment_Base =
        W_Base.tail<3>() - X_BaseJoint.translation().cross(W_Base.head<3>());
    Vec3 u, v;
    mechanism::tiltDirections(chain.joints()[static_cast<size_t>(joint)].twist_Local.tail<3>(), u,
                              v);
    for (const Vec3& direction : {u, v}) {
      const Vec3 d_Base = X_BaseJoint.linear() * direction;
      const Vec3 turn = d_Base.dot(moment_Base) * d_Base;  // rad per rad/(N·m)
      block.block(first, column, 3, 1) =
          turn.cross(p_TipInBase - X_BaseJoint.translation()) / o.position_sigma_m;
      if (rotation) block.block(first + 3, column, 3, 1) = turn / o.orientation_sigma_rad;
      ++column;
    }
  }
}

/// The tip's motion per unit mount compliance along each of the sensor's axes under the
/// payload's force force_Sensor (mechanisms/tool_mount_compliance.hpp): a shift (F·e) e, e the
/// axis, that turns nothing; in the rows from `first`, the columns from `column`.
void addToolMountColumns(const Pose& X_BaseSensor, const Vec3& force_Sensor, const PlanOptions& o,
                         int first, int column, Eigen::MatrixXd& block) {
  if (!o.tool_mount) return;
  for (int axis = 0; axis < 3; ++axis) {
    block.block(first, column + axis, 3, 1) =
        X_BaseSensor.linear().col(axis) * force_Sensor(axis) / o.position_sigma_m;
  }
}

/// The re-check's columns of the initial-pose Jacobian A (6 × 6(n+1)): the registration's and
/// the tool's blocks, and each inner joint's zero (its block times its twist: recheck.cpp).
Eigen::Matrix<double, 6, Eigen::Dynamic> recheckColumns(const KinematicChain& chain,
                                                        const Eigen::Matrix<double, 6, Eigen::Dynamic>& A) {
  const int n = chain.dof();
  Eigen::Matrix<double, 6, Eigen::Dynamic> out(6, 12 + std::max(0, n - 2));
  out.leftCols(6) = A.leftCols(6);
  out.middleCols(6, 6) = A.middleCols(6 * n, 6);
  for (int j = 1; j + 1 < n; ++j) {
    out.col(11 + j) = A.middleCols(6 * j, 6) * chain.joints()[static_cast<size_t>(j)].twist_Local;
  }
  return out;
}

Eigen::MatrixXd identificationBlock(const KinematicChain& chain, int sensor_frame,
                                    const ChainWorkspace& ws, const std::vector<double>& payloads_kg,
                                    const PlanOptions& o) {
  const int n = chain.dof();
  const int geometry_columns = o.recheck ? 12 + std::max(0, n - 2) : 6 * (n + 1);
  // Rows in units of the tracker's noise: position, then rotation when it is measured.
  const bool rotation = o.orientation_sigma_rad > 0.0;
  const int rows = rotation ? 6 : 3;
  const int tilt_columns = 2 * static_cast<int>(o.off_axis_joints.size());
  const int mount_columns = o.tool_mount ? 3 : 0;
  Eigen::MatrixXd block = Eigen::MatrixXd::Zero(rows * (1 + static_cast<int>(payloads_kg.size())),
                                                geometry_columns + n + tilt_columns + mount_columns);
  Eigen::Matrix<double, 6, Eigen::Dynamic> A(6, 6 * (n + 1));
  parameterJacobian(chain, ws, A);
  if (o.recheck) A = recheckColumns(chain, A);
  const Vec3 p_TipInBase = tipPose(ws).translation();
  block.topLeftCorner(3, geometry_columns) =
      (A.topRows<3>() - lie::hat(p_TipInBase) * A.bottomRows<3>()) / o.position_sigma_m;
  if (rotation) block.block(3, 0, 3, geometry_columns) = A.bottomRows<3>() / o.orientation_sigma_rad;

  Jacobian J_tip(6, n), J_s(6, n);
  tipPointJacobian(chain, ws, J_tip);
  spatialJacobian(chain, ws, J_s);
  if (payloads_kg.empty()) return block;
  const Pose X_BaseSensor = framePose(chain, ws, sensor_frame);
  for (size_t l = 0; l < payloads_kg.size(); ++l) {
    Vec6 wrench_Sensor;  // the payload's weight at its centre of gravity, about the sensor origin
    wrench_Sensor.head<3>() =
        X_BaseSensor.linear().transpose() * (payloads_kg[l] * o.gravity_in_base_m_per_s2);
    wrench_Sensor.tail<3>() = o.p_CoGInSensor_m.cross(wrench_Sensor.head<3>());
    const Vec6 W_Base = wrenchInRoot(X_BaseSensor, wrench_Sensor);
    const JointVector tau_nm = jointTorques(J_s, W_Base);
    const int first = rows * (1 + static_cast<int>(l));
    block.block(first, geometry_columns, 3, n) =
        J_tip.topRows<3>() * tau_nm.asDiagonal() / o.position_sigma_m;
    if (rotation) {
      block.block(first + 3, geometry_columns, 3, n) =
          J_tip.bottomRows<3>() * tau_nm.asDiagonal() / o.orientation_sigma_rad;
    }
    addTiltColumns(chain, ws, W_Base, o, first, geometry_columns + n, block);
    addToolMountColumns(X_BaseSensor, wrench_Sensor.head<3>(), o, first,
                        geometry_columns + n + tilt_columns, block);
  }
  return block;
}

void validate(const KinematicChain& chain, int sensor_frame, const PlanOptions& o) {
  auto fail = [](const std::string& what, const std::string& expected, const std::string& hint) {
    throw InputError(what + "; expected " + expected + " (hint: " + hint + ")");
  };
  if (sensor_frame < -1 || sensor_frame >= static_cast<int>(chain.frames().size())) {
    fail("sensor frame " + std::to_string(sensor_frame), "an attached frame of the chain or -1",
         "the F/T sensor link the payload hangs from");
  }
  if (sensor_frame < 0 && (o.loads_kg.size() != 1 || o.loads_kg.front() != 0.0)) {
    fail("loads of " + std::to_string(o.loads_kg.size()) + " values on a robot without a payload "
         "link", "0 only",
         "a payload needs the link it hangs from, whose axes its wrench is given in: an F/T "
         "sensor's, or the flange for a payload of known mass and centre of gravity");
  }
  if (!o.p_CoGInSensor_m.allFinite()) fail("payload centre of gravity", "finite", "e.g. 0,0,0.1 m");
  for (const int joint : o.off_axis_joints) {
    if (joint < 0 || joint >= chain.dof() || sensor_frame < 0) {
      fail("off-axis joint " + std::to_string(joint + 1),
           "a joint 1 to " + std::to_string(chain.dof()) + " of a robot with a payload link",
           "a tilt across a joint's axis is identified by a payload's moment");
    }
  }
  if (o.tool_mount && sensor_frame < 0) {
    fail("the tool mount's compliance on a robot without a payload link", "a payload link",
         "the mount gives under a payload's force, read in the sensor's axes");
  }
  if (o.poses < 1) fail("poses = " + std::to_string(o.poses), ">= 1", "e.g. 30");
  if (!o.given_candidates.empty()) {
    if (static_cast<int>(o.given_candidates.size()) < o.poses) {
      fail(std::to_string(o.given_candidates.size()) + " given candidate poses",
           "at least as many as poses (" + std::to_string(o.poses) + ")",
           "plan fewer poses or give more candidates");
    }
    for (const PlannedMeasurement& c : o.given_candidates) {
      if (c.q_rad.size() != chain.dof() || !c.q_rad.allFinite()) {
        fail("candidate '" + c.pose_id + "' with " + std::to_string(c.q_rad.size()) +
                 " joint angles", std::to_string(chain.dof()) + " finite angles",
             "candidates of the robot planned for");
      }
    }
  } else if (o.candidates < o.poses) {
    fail("candidates = " + std::to_string(o.candidates), "at least as many as poses (" +
         std::to_string(o.poses) + ")", "a few thousand");
  }
  if (std::count(o.loads_kg.begin(), o.loads_kg.end(), 0.0) != 1) {
    fail("loads " + std::to_string(o.loads_kg.size()) + " values with " +
             std::to_string(std::count(o.loads_kg.begin(), o.loads_kg.end(), 0.0)) + " zeros",
         "0 exactly once", "every pose is measured unloaded, e.g. 0,20,40");
  }
  for (double load_kg : o.loads_kg) {
    if (!(std::isfinite(load_kg) && load_kg >= 0.0)) {
      fail("load " + formatShortest(load_kg) + " kg", "finite payloads >= 0", "e.g. 0,20,40");
    }
    if (std::count(o.loads_kg.begin(), o.loads_kg.end(), load_kg) > 1) {
      fail("load " + formatShortest(load_kg) + " kg given twice", "each payload once", "e.g. 0,20,40");
    }
  }
  if (!(o.min_range_m >= 0.0 && o.max_range_m > o.min_range_m && std::isfinite(o.max_range_m))) {
    fail("tracker range " + formatShortest(o.min_range_m) + "–" + formatShortest(o.max_range_m) + " m",
         "0 <= min < max, finite", "a laser tracker measures about 1.5–15 m");
  }
  if (!(o.line_of_sight_clearance_m >= 0.0 && o.tip_exclusion_m >= 0.0 &&
        std::isfinite(o.line_of_sight_clearance_m) && std::isfinite(o.tip_exclusion_m))) {
    fail("line-of-sight clearance " + formatShortest(o.line_of_sight_clearance_m) +
             " m, tip exclusion " + formatShortest(o.tip_exclusion_m) + " m",
         "finite values >= 0", "0.15 m and 0.3 m");
  }
  if (!(o.position_sigma_m > 0.0 && o.orientation_sigma_rad >= 0.0 &&
        std::isfinite(o.position_sigma_m) && std::isfinite(o.orientation_sigma_rad))) {
    fail("tracker noise " + formatShortest(o.position_sigma_m) + " m, " +
             formatShortest(o.orientation_sigma_rad) + " rad",
         "position > 0 and orientation >= 0, finite", "0 orientation for a position-only tracker");
  }
  if (!o.p_TrackerInBase_m.allFinite()) fail("tracker position", "finite", "e.g. 4,0,1.2 m");
  if (!(o.ridge > 0.0 && o.spread_weight >= 0.0 && o.spread_bins >= 1)) {
    fail("ridge " + formatShortest(o.ridge) + ", spread weight " + formatShortest(o.spread_weight) +
             ", bins " + std::to_string(o.spread_bins),
         "ridge > 0, weight >= 0, bins >= 1", "the defaults");
  }
}

/// Which bins of each joint's range the selected poses cover.
class Coverage {
 public:
  Coverage(const KinematicChain& chain, int bins)
      : chain_(chain), bins_(bins), covered_(static_cast<size_t>(chain.dof() * bins), false) {}

  /// Joints whose angle in q falls in a bin not covered yet.
  int newBins(const JointVector& q) const {
    int count = 0;
    for (int i = 0; i < chain_.dof(); ++i) count += covered_[index(i, q(i))] ? 0 : 1;
    return count;
  }
  void add(const JointVector& q) {
    for (int i = 0; i < chain_.dof(); ++i) covered_[index(i, q(i))] = true;
  }
  /// Share of joint i's bins covered, 0–1.
  double share(int i) const {
    const auto first = covered_.begin() + i * bins_;
    return static_cast<double>(std::count(first, first + bins_, true)) / bins_;
  }

 private:
  size_t index(int joint, double q_rad) const {
    const auto [lower, upper] = jointRange(chain_.joints()[static_cast<size_t>(joint)]);
    const double share = std::clamp((q_rad - lower) / (upper - lower), 0.0, 1.0);
    return static_cast<size_t>(joint * bins_ + std::min(static_cast<int>(share * bins_), bins_ - 1));
  }

  const KinematicChain& chain_;
  int bins_;
  std::vector<bool> covered_;
};

/// The given candidate poses (PlanOptions::given_candidates), each with its pose_id.
void takeGivenCandidates(const KinematicChain& nominal_Base, int sensor_frame,
                         const std::vector<double>& payloads_kg, const PlanOptions& options,
                         std::vector<Candidate>& candidates,
                         std::vector<std::string>& candidate_ids, CampaignPlan& plan) {
  ChainWorkspace ws;
  for (const PlannedMeasurement& given : options.given_candidates) {
    forwardKinematics(nominal_Base, given.q_rad, ws);
    candidates.push_back(
        {given.q_rad, identificationBlock(nominal_Base, sensor_frame, ws, payloads_kg, options)});
    candidate_ids.push_back(given.pose_id);
    ++plan.candidates_drawn;
  }
}

/// options.candidates poses drawn uniformly in the joint ranges; the visible ones kept, the
/// others counted in the plan by the reason they were rejected.
void drawVisibleCandidates(const KinematicChain& nominal_Base, int sensor_frame,
                           const std::vector<double>& payloads_kg, const PlanOptions& options,
                           std::mt19937_64& engine, std::vector<Candidate>& candidates,
                           CampaignPlan& plan) {
  const int n = nominal_Base.dof();
  ChainWorkspace ws;
  for (int draw = 0; draw < options.candidates; ++draw) {
    JointVector q(n);
    for (int i = 0; i < n; ++i) {
      const auto [lower, upper] = jointRange(nominal_Base.joints()[static_cast<size_t>(i)]);
      q(i) = lower + (upper - lower) * uniform01(engine);
    }
    ++plan.candidates_drawn;
    forwardKinematics(nominal_Base, q, ws);
    switch (visibility(ws, options)) {
      case Visibility::kRange: ++plan.rejected_range; continue;
      case Visibility::kFloor: ++plan.rejected_floor; continue;
      case Visibility::kLineOfSight: ++plan.rejected_line_of_sight; continue;
      case Visibility::kVisible: break;
    }
    candidates.push_back(
        {q, identificationBlock(nominal_Base, sensor_frame, ws, payloads_kg, options)});
  }
}

void requireEnoughCandidates(size_t visible, const CampaignPlan& plan, const PlanOptions& options) {
  if (static_cast<int>(visible) < options.poses) {
    throw InputError(std::to_string(visible) + " of " +
                     std::to_string(plan.candidates_drawn) + " candidate poses are visible (" +
                     std::to_string(plan.rejected_range) + " out of the tracker's range, " +
                     std::to_string(plan.rejected_floor) + " below the floor, " +
                     std::to_string(plan.rejected_line_of_sight) +
                     " with the arm in the line of sight); expected at least " +
                     std::to_string(options.poses) +
                     " (hint: move the tracker nearer the robot, widen the range or draw more "
                     "candidates)");
  }
}

/// Columns normalised to unit mean square per candidate; columns no candidate excites (a
/// vertical payload's torque on a vertical joint 1) are left out, the ridge stands for them.
/// Returns the number of columns.
Eigen::Index normaliseColumns(std::vector<Candidate>& candidates) {
  const Eigen::Index columns = candidates.front().block.cols();
  Eigen::VectorXd column_scale = Eigen::VectorXd::Zero(columns);
  for (const Candidate& c : candidates) column_scale += c.block.colwise().squaredNorm().transpose();
  column_scale = (column_scale / static_cast<double>(candidates.size())).cwiseSqrt();
  const double excited = 1e-9 * column_scale.maxCoeff();
  for (Eigen::Index j = 0; j < columns; ++j) {
    column_scale(j) = column_scale(j) > excited ? 1.0 / column_scale(j) : 0.0;
  }
  for (Candidate& c : candidates) c.block = c.block * column_scale.asDiagonal();
  return columns;
}

/// The first `poses` of the candidates in a random order (Fisher–Yates).
std::vector<size_t> randomPoses(size_t candidates, int poses, std::mt19937_64& engine) {
  std::vector<size_t> order(candidates);
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (size_t i = order.size() - 1; i > 0; --i) {
    std::swap(order[i], order[static_cast<size_t>(uniform01(engine) * static_cast<double>(i + 1))]);
  }
  return std::vector<size_t>(order.begin(), order.begin() + poses);
}

/// Poses added to `chosen` until it holds options.poses, each the candidate not chosen yet of
/// the largest gain in log det of the information, weighted by the joint bins it covers anew;
/// the information and coverage updated with each.
void chooseGreedily(const std::vector<Candidate>& candidates, const PlanOptions& options, int n,
                    std::vector<size_t>& chosen, Eigen::MatrixXd& information,
                    Coverage& coverage) {
  std::vector<bool> taken(candidates.size(), false);
  while (static_cast<int>(chosen.size()) < options.poses) {
    const Eigen::LLT<Eigen::MatrixXd> factor(information);
    double best_score = -1.0;
    size_t best = 0;
    for (size_t c = 0; c < candidates.size(); ++c) {
      if (taken[c]) continue;
      // log det(M + BᵀB) − log det M = log det(I + B M⁻¹ Bᵀ), with M = L Lᵀ.
      const Eigen::MatrixXd X = factor.matrixL().solve(candidates[c].block.transpose());
      const Eigen::MatrixXd gain_matrix =
          Eigen::MatrixXd::Identity(X.cols(), X.cols()) + X.transpose() * X;
      const Eigen::LLT<Eigen::MatrixXd> gain_factor(gain_matrix);
      const double gain = 2.0 * gain_factor.matrixLLT().diagonal().array().log().sum();
      const double score =
          gain * (1.0 + options.spread_weight * coverage.newBins(candidates[c].q_rad) / n);
      if (score > best_score) {
        best_score = score;
        best = c;
      }
    }
    chosen.push_back(best);
    taken[best] = true;
    information += candidates[best].block.transpose() * candidates[best].block;
    coverage.add(candidates[best].q_rad);
  }
}

/// Measurement order: every pose unloaded, then every pose at each payload (changing the
/// payload is the slow step).
std::vector<PlannedMeasurement> measurementOrder(const std::vector<double>& loads_kg,
                                                 const std::vector<size_t>& chosen,
                                                 const std::vector<Candidate>& candidates,
                                                 const std::vector<std::string>& candidate_ids) {
  std::vector<PlannedMeasurement> rows;
  for (double load_kg : loads_kg) {
    for (size_t k = 0; k < chosen.size(); ++k) {
      char pose_id[32];
      std::snprintf(pose_id, sizeof pose_id, "plan-%03zu", k);
      rows.push_back({candidate_ids.empty() ? std::string(pose_id) : candidate_ids[chosen[k]],
                      load_kg, candidates[chosen[k]].q_rad, 0});
    }
  }
  std::stable_sort(rows.begin(), rows.end(),
                   [](const PlannedMeasurement& a, const PlannedMeasurement& b) {
                     return a.load_kg < b.load_kg;
                   });
  return rows;
}

}  // namespace

CampaignPlan planCampaign(const KinematicChain& nominal_Base, int sensor_frame,
                          const PlanOptions& options) {
  validate(nominal_Base, sensor_frame, options);
  Eigen::setCpuCacheSizes(kPinnedL1CacheBytes, kPinnedL2CacheBytes, kPinnedL3CacheBytes);
  const int n = nominal_Base.dof();
  std::vector<double> payloads_kg;
  for (double load_kg : options.loads_kg) {
    if (load_kg > 0.0) payloads_kg.push_back(load_kg);
  }

  CampaignPlan plan;
  std::vector<Candidate> candidates;
  std::vector<std::string> candidate_ids;  // given candidates' pose_ids
  std::mt19937_64 engine(options.seed);
  takeGivenCandidates(nominal_Base, sensor_frame, payloads_kg, options, candidates, candidate_ids,
                      plan);
  if (options.given_candidates.empty()) {
    drawVisibleCandidates(nominal_Base, sensor_frame, payloads_kg, options, engine, candidates,
                          plan);
  }
  requireEnoughCandidates(candidates.size(), plan, options);
  const Eigen::Index columns = normaliseColumns(candidates);

  std::vector<size_t> chosen;
  Coverage coverage(nominal_Base, options.spread_bins);
  Eigen::MatrixXd information = options.ridge * Eigen::MatrixXd::Identity(columns, columns);
  if (options.selection == PoseSelection::kRandom) {
    chosen = randomPoses(candidates.size(), options.poses, engine);
  }
  chooseGreedily(candidates, options, n, chosen, information, coverage);
  if (options.selection == PoseSelection::kRandom) {
    for (size_t c : chosen) {
      information += candidates[c].block.transpose() * candidates[c].block;
      coverage.add(candidates[c].q_rad);
    }
  }
  plan.log_det_information =
      2.0 * Eigen::LLT<Eigen::MatrixXd>(information).matrixLLT().diagonal().array().log().sum();
  for (int i = 0; i < n; ++i) plan.joint_coverage.push_back(coverage.share(i));
  plan.rows = measurementOrder(options.loads_kg, chosen, candidates, candidate_ids);
  return plan;
}

}  // namespace stepcal::trainer
