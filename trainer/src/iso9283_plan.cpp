#include "stepcal/trainer/iso9283_plan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::trainer {
namespace {

constexpr double kPositionTolerance_m = 1e-7;
constexpr double kOrientationTolerance_rad = 1e-6;
constexpr int kInverseIterations = 60;
constexpr double kMaxStep_rad = 0.3;
constexpr double kDamping = 1e-8;
constexpr int kEdgeBisections = 14;
constexpr double kSmallestEdge_m = 0.01;
/// The share of the plane's diagonal between a corner and its test pose (ISO 9283: 10 %).
constexpr double kCornerShare = 0.1;
/// Smallest singular value of the tip point Jacobian a test pose keeps (the runtime's
/// NEAR_SINGULAR threshold, InverseOptions::singular_value_threshold).
constexpr double kMinSingularValue = 1e-2;

double uniform01(std::mt19937_64& engine) {
  return static_cast<double>(engine() >> 11) * 0x1.0p-53;
}

/// A joint's range for the draw: its limits, or one turn for a continuous joint, rad.
std::pair<double, double> drawRange(const ChainJoint& joint) {
  if (std::isfinite(joint.lower_rad) && std::isfinite(joint.upper_rad)) {
    return {joint.lower_rad, joint.upper_rad};
  }
  return {-kPi, kPi};
}

void clampIntoLimits(const KinematicChain& chain, JointVector& q) {
  for (int i = 0; i < chain.dof(); ++i) {
    const ChainJoint& joint = chain.joints()[static_cast<size_t>(i)];
    q(i) = std::clamp(q(i), joint.lower_rad, joint.upper_rad);
  }
}

bool linksAboveFloor(const ChainWorkspace& ws, int dof, double min_height_m) {
  for (int k = 2; k <= dof + 1; ++k) {
    if (ws.X_RootFrame[static_cast<size_t>(k)].translation().z() < min_height_m) return false;
  }
  return true;
}

/// The cube's corners, base_link, m: bit 0 of the index +x, bit 1 +y, bit 2 +z.
std::array<Vec3, 8> cubeCorners(const Vec3& centre, double edge_m) {
  std::array<Vec3, 8> corners;
  for (int c = 0; c < 8; ++c) {
    const Vec3 sign((c & 1) ? 1.0 : -1.0, (c & 2) ? 1.0 : -1.0, (c & 4) ? 1.0 : -1.0);
    corners[static_cast<size_t>(c)] = centre + 0.5 * edge_m * sign;
  }
  return corners;
}

/// P1 … P5: the centre and the diagonal plane's corners (−,−,−), (−,+,−), (+,+,+), (+,−,+)
/// moved 10 % of the plane's diagonal towards the centre.
std::array<Vec3, kIsoPoseCount> testPoses(const Vec3& centre, double edge_m) {
  const std::array<Vec3, 8> corners = cubeCorners(centre, edge_m);
  const std::array<int, 4> plane_corners = {0, 2, 7, 5};
  std::array<Vec3, kIsoPoseCount> poses;
  poses[0] = centre;
  for (size_t k = 0; k < plane_corners.size(); ++k) {
    const Vec3& corner = corners[static_cast<size_t>(plane_corners[k])];
    poses[k + 1] = centre + (1.0 - 2.0 * kCornerShare) * (corner - centre);
  }
  return poses;
}

/// Joints reaching p with orientation R from the seed, links above the floor; nullopt if none.
std::optional<JointVector> reachable(const KinematicChain& chain, const Vec3& p, const Mat3& R,
                                     const JointVector& seed, double min_height_m,
                                     ChainWorkspace& ws) {
  Pose X = Pose::Identity();
  X.linear() = R;
  X.translation() = p;
  std::optional<JointVector> q = nominalInverse(chain, X, seed);
  if (!q) return std::nullopt;
  forwardKinematics(chain, *q, ws);
  if (!linksAboveFloor(ws, chain.dof(), min_height_m)) return std::nullopt;
  Jacobian J(6, chain.dof());
  tipPointJacobian(chain, ws, J);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J);
  if (svd.singularValues().minCoeff() < kMinSingularValue) return std::nullopt;
  return q;
}

/// Whether a cube of this edge about the centre is reached at every corner and test pose;
/// the test poses' joints into q_poses.
bool cubeReached(const KinematicChain& chain, const Vec3& centre, const Mat3& R,
                 const JointVector& q_centre, double edge_m, double min_height_m,
                 std::array<JointVector, kIsoPoseCount>& q_poses) {
  ChainWorkspace ws;
  for (const Vec3& corner : cubeCorners(centre, edge_m)) {
    if (!reachable(chain, corner, R, q_centre, min_height_m, ws)) return false;
  }
  const std::array<Vec3, kIsoPoseCount> poses = testPoses(centre, edge_m);
  for (size_t k = 0; k < poses.size(); ++k) {
    const std::optional<JointVector> q = reachable(chain, poses[k], R, q_centre, min_height_m, ws);
    if (!q) return false;
    q_poses[k] = *q;
  }
  return true;
}

void validate(const Iso9283PlanOptions& o) {
  if (!(std::isfinite(o.rated_load_kg) && o.rated_load_kg >= 0.0)) {
    throw InputError("rated load " + formatShortest(o.rated_load_kg) +
                     " kg; expected a payload >= 0 kg (hint: the robot's rated payload, e.g. 60 "
                     "for an IRB 4400/60; 0 for an unloaded test)");
  }
  if (o.cycles < 2) {
    throw InputError("cycles = " + std::to_string(o.cycles) +
                     "; expected at least 2 (hint: ISO 9283 asks 30; repeatability needs repeats)");
  }
  if (o.centre_candidates < 1 || !(o.max_edge_m > kSmallestEdge_m)) {
    throw InputError("centre candidates " + std::to_string(o.centre_candidates) + ", largest edge " +
                     formatShortest(o.max_edge_m) + " m; expected >= 1 and > 0.01 m");
  }
}

/// The pose list: per load the cycles P1 → P5, then each approach pose from each direction.
std::vector<PlannedMeasurement> isoRows(const Iso9283Plan& plan) {
  std::vector<PlannedMeasurement> rows;
  for (const double load_kg : plan.loads_kg) {
    for (int cycle = 1; cycle <= plan.cycles; ++cycle) {
      for (int pose = 1; pose <= kIsoPoseCount; ++pose) {
        rows.push_back({isoPoseId({pose, 0, cycle}), load_kg,
                        plan.q_pose_rad[static_cast<size_t>(pose - 1)], 0});
      }
    }
    for (const char axis : {'x', 'y', 'z'}) {
      for (int cycle = 1; cycle <= plan.cycles; ++cycle) {
        for (const int pose : kIsoApproachPoses) {
          rows.push_back({isoPoseId({pose, axis, cycle}), load_kg,
                          plan.q_pose_rad[static_cast<size_t>(pose - 1)], 0});
        }
      }
    }
  }
  return rows;
}

}  // namespace

std::string isoPoseId(const IsoPoseId& id) {
  char text[32];
  if (id.approach == 0) {
    std::snprintf(text, sizeof text, "iso-P%d-c%02d", id.pose, id.cycle);
  } else {
    std::snprintf(text, sizeof text, "iso-P%d-%c-c%02d", id.pose, id.approach, id.cycle);
  }
  return text;
}

std::optional<IsoPoseId> parseIsoPoseId(const std::string& pose_id) {
  IsoPoseId id;
  char axis = 0;
  int used = 0;
  if (std::sscanf(pose_id.c_str(), "iso-P%d-c%d%n", &id.pose, &id.cycle, &used) == 2 &&
      used == static_cast<int>(pose_id.size())) {
  } else if (std::sscanf(pose_id.c_str(), "iso-P%d-%c-c%d%n", &id.pose, &axis, &id.cycle,
                         &used) == 3 &&
             used == static_cast<int>(pose_id.size()) && (axis == 'x' || axis == 'y' || axis == 'z')) {
    id.approach = axis;
  } else {
    return std::nullopt;
  }
  if (id.pose < 1 || id.pose > kIsoPoseCount || id.cycle < 1) return std::nullopt;
  return id;
}

std::optional<JointVector> nominalInverse(const KinematicChain& nominal_Base,
                                          const Pose& X_BaseTip_desired,
                                          const JointVector& q_seed_rad) {
  const int n = nominal_Base.dof();
  JointVector q = q_seed_rad;
  clampIntoLimits(nominal_Base, q);
  ChainWorkspace ws;
  Jacobian J(6, n);
  for (int iteration = 0; iteration < kInverseIterations; ++iteration) {
    forwardKinematics(nominal_Base, q, ws);
    const Pose& X = tipPose(ws);
    Vec6 error;
    error.head<3>() = X_BaseTip_desired.translation() - X.translation();
    error.tail<3>() = lie::logSO3(X_BaseTip_desired.linear() * X.linear().transpose());
    if (error.head<3>().norm() < kPositionTolerance_m &&
        error.tail<3>().norm() < kOrientationTolerance_rad) {
      return q;
    }
    tipPointJacobian(nominal_Base, ws, J);
    const Mat6 JJt = J * J.transpose() + kDamping * Mat6::Identity();
    const Vec6 weights = Eigen::LLT<Mat6>(JJt).solve(error);
    JointVector step(n);
    step.noalias() = J.transpose() * weights;
    const double longest = step.cwiseAbs().maxCoeff();
    if (longest > kMaxStep_rad) step *= kMaxStep_rad / longest;
    q += step;
    clampIntoLimits(nominal_Base, q);
  }
  return std::nullopt;
}

Iso9283Plan planIso9283(const KinematicChain& nominal_Base, const Iso9283PlanOptions& options) {
  validate(options);
  const int n = nominal_Base.dof();
  Iso9283Plan plan;
  std::mt19937_64 engine(options.seed);
  ChainWorkspace ws;
  for (int draw = 0; draw < options.centre_candidates; ++draw) {
    JointVector q(n);
    for (int i = 0; i < n; ++i) {
      const auto [lower, upper] = drawRange(nominal_Base.joints()[static_cast<size_t>(i)]);
      q(i) = lower + (upper - lower) * uniform01(engine);
    }
    ++plan.candidates_drawn;
    forwardKinematics(nominal_Base, q, ws);
    if (!linksAboveFloor(ws, n, options.min_link_height_m)) {
      ++plan.candidates_below_floor;
      continue;
    }
    const Vec3 centre = tipPose(ws).translation();
    const Mat3 R = tipPose(ws).linear();
    std::array<JointVector, kIsoPoseCount> q_poses;
    // Only an edge larger than the best so far is worth the bisection.
    const double smallest = std::max(kSmallestEdge_m, plan.edge_m);
    if (!cubeReached(nominal_Base, centre, R, q, smallest, options.min_link_height_m, q_poses)) {
      continue;
    }
    double reached = smallest, missed = options.max_edge_m;
    for (int b = 0; b < kEdgeBisections; ++b) {
      const double edge = 0.5 * (reached + missed);
      std::array<JointVector, kIsoPoseCount> q_try;
      if (cubeReached(nominal_Base, centre, R, q, edge, options.min_link_height_m, q_try)) {
        reached = edge;
        q_poses = q_try;
      } else {
        missed = edge;
      }
    }
    if (reached > plan.edge_m) {
      plan.edge_m = reached;
      plan.p_CentreInBase_m = centre;
      plan.R_BaseTip = R;
      plan.q_pose_rad = q_poses;
    }
  }
  if (plan.edge_m < kSmallestEdge_m) {
    throw InputError("no cube of at least 10 mm is reached with one tool orientation from any of " +
                     std::to_string(plan.candidates_drawn) + " drawn configurations (" +
                     std::to_string(plan.candidates_below_floor) +
                     " with a link below the floor); expected a robot whose joint limits leave a "
                     "working space (hint: draw more with --iso-candidates, check the URDF limits)");
  }
  plan.p_PoseInBase_m = testPoses(plan.p_CentreInBase_m, plan.edge_m);
  plan.cycles = options.cycles;
  plan.loads_kg = {0.0};
  if (options.rated_load_kg > 0.0) {
    plan.loads_kg.push_back(0.1 * options.rated_load_kg);
    plan.loads_kg.push_back(options.rated_load_kg);
  }
  plan.rows = isoRows(plan);
  return plan;
}

}  // namespace stepcal::trainer
