// The test of ISO 9283 (pose characteristics) laid out for a robot: `stepcal plan --iso9283`.
//
// The cube: edges parallel to base_link's axes, the largest the robot reaches with one tool
// orientation at all of its 8 corners and test poses (within the joint limits, every link origin
// after joint 1 above the floor). Candidate centres are tip positions of joint configurations
// drawn uniformly in the limits (seeded); at each, the edge is found by bisection, every point
// solved by the numeric inverse (damped Gauss–Newton on the nominal chain, from the centre's
// joints; the tip point Jacobian's smallest singular value at least 0.01, the runtime's
// NEAR_SINGULAR threshold). The tool keeps the centre configuration's orientation at every pose.
//
// The test poses lie in the cube's diagonal plane through its two edges parallel to base y (the
// plane x − x_c = z − z_c): P1 at the centre, P2…P5 on the plane's diagonals at 10 % of the
// diagonal's length from its corners, P_k = P1 + 0.8 (C_k − P1): P2 at (−,−,−), P3 (−,+,−),
// P4 (+,+,+), P5 (+,−,+) of the cube's half edge.
//
// The rows (a pose list, readPoseList): at each load, `cycles` cycles P1 → P5 (pose accuracy
// AP and repeatability RP, distance accuracy AD and RD between P2 and P4 of one cycle), then the
// multi-directional test: P1, P2 and P4 approached moving along +x, +y and +z of base_link,
// `cycles` cycles each (vAP). The direction and the cycle are in the pose_id (isoPoseId); the
// approach itself (a via-point 0.1 m back along the direction) is the robot program's.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal::trainer {

/// The five test poses of ISO 9283.
inline constexpr int kIsoPoseCount = 5;
/// The poses approached from three directions for the multi-directional variation (P1, P2, P4).
inline constexpr std::array<int, 3> kIsoApproachPoses = {1, 2, 4};
/// The via-point's distance back along the approach direction, m (described, not measured).
inline constexpr double kIsoApproachDistance_m = 0.1;

/// What a pose_id of an ISO plan says: pose k (1–5), approach axis ('x', 'y', 'z' moving along
/// its + direction; 0 for the cycle P1 → P5) and cycle (1 …).
struct IsoPoseId {
  int pose = 0;
  char approach = 0;
  int cycle = 0;
};

/// "iso-P<k>-c<cc>" or "iso-P<k>-<axis>-c<cc>".
std::string isoPoseId(const IsoPoseId& id);
/// The parts of an ISO pose_id; nullopt for any other pose_id.
std::optional<IsoPoseId> parseIsoPoseId(const std::string& pose_id);

struct Iso9283PlanOptions {
  /// The robot's rated payload, kg: the test runs at it and at 10 % of it (and unloaded, the row
  /// every pose of a pose list has). 0: unloaded only.
  double rated_load_kg = 0.0;
  int cycles = 30;             ///< cycles per pose and per approach direction, ≥ 2
  int centre_candidates = 300;  ///< joint configurations drawn as candidate centres, ≥ 1
  uint64_t seed = 1;
  double min_link_height_m = 0.1;  ///< link origins after joint 1 above the floor, m
  double max_edge_m = 2.0;         ///< the bisection's upper end, m
};

struct Iso9283Plan {
  Vec3 p_CentreInBase_m = Vec3::Zero();  ///< the cube's centre (P1), base_link, m
  double edge_m = 0.0;                    ///< the cube's edge, m
  Mat3 R_BaseTip = Mat3::Identity();      ///< the tool orientation held at every pose
  std::array<Vec3, kIsoPoseCount> p_PoseInBase_m;  ///< P1 … P5, base_link, m
  std::array<JointVector, kIsoPoseCount> q_pose_rad;  ///< their joint targets, rad
  std::vector<double> loads_kg;            ///< 0, then 10 % of rated and rated (when > 0)
  int cycles = 0;
  int candidates_drawn = 0;                ///< configurations drawn as centres
  int candidates_below_floor = 0;          ///< of them with a link below the floor
  std::vector<PlannedMeasurement> rows;    ///< the pose list
};

/// Numeric inverse of the nominal chain: joints that put its tip at X_BaseTip_desired, damped
/// Gauss–Newton from q_seed_rad within the joint limits; nullopt when it does not converge to
/// 1e-7 m and 1e-6 rad.
std::optional<JointVector> nominalInverse(const KinematicChain& nominal_Base,
                                          const Pose& X_BaseTip_desired,
                                          const JointVector& q_seed_rad);

/// Lays out the test for the chain (rooted at base_link). Throws InputError on bad options or
/// when no candidate centre holds a cube of at least 10 mm.
Iso9283Plan planIso9283(const KinematicChain& nominal_Base, const Iso9283PlanOptions& options);

}  // namespace stepcal::trainer
