// Planning a campaign: which poses to measure so that the identification is well conditioned.
//
// Candidates are drawn uniformly within the chain's joint limits (seeded, deterministic) and kept
// when the tracker can see the target: the tip between min_range_m and max_range_m from the
// tracker, every link origin after joint 1 above the floor (base_link's z = 0 plane), and the line
// of sight clear of the arm. The arm is the polyline through the joint frames' origins (base to
// the last joint); the sight line runs from the tracker to the tip, its last tip_exclusion_m left
// out (the wrist and tool around the target are not modelled); it is blocked when it passes
// closer than line_of_sight_clearance_m to the polyline.
//
// Candidates may instead be given (PlanOptions::given_candidates: e.g. the poses of a campaign
// already measured, which the tracker saw): then they are all taken, with no draw and no test.
//
// Each candidate pose is measured unloaded and at every payload of loads_kg. Its identification
// block stacks what steps 1 and 2 fit, each row divided by the tracker's noise: the unloaded
// row's tip position and rotation against the 6(n+1) initial pose parameters (parameterJacobian;
// position rows ṗ = v − p̂ω), and per payload the deflection against the n compliances (tip point
// Jacobian · diag(τ), τ = J_sᵀ W with the payload's weight at its centre of gravity in the
// payload's frame: the F/T sensor's, or the link a payload of known mass hangs from). A robot
// without one is planned unloaded (loads_kg = {0}). Columns are normalised over the candidates (so that millimetres and
// compliances weigh alike) and selection is greedy D-optimal: the pose that most increases
// log det(M + ridge I), M the selected poses' information. The ridge gives the geometry's 2n
// structural redundancies (rank 30 of 42 for six joints) the same constant share whatever is
// chosen. The gain is multiplied by 1 + spread_weight · (share of joints whose angle falls in a
// bin of their range not yet covered), so that, among poses about as informative, those that
// widen every joint's coverage win (what transmission profiles and the GPR are fitted over).
#pragma once

#include <cstdint>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal::trainer {

/// How the poses are chosen among the visible candidates.
enum class PoseSelection {
  kDOptimal,  ///< greedy D-optimal with the spread term (the plan)
  kRandom,    ///< uniformly at random (seeded): the baseline a plan is compared with
};

/// Everything a plan depends on. Bad values throw InputError.
struct PlanOptions {
  int poses = 30;                          ///< N poses to select, ≥ 1
  std::vector<double> loads_kg = {0.0, 20.0, 40.0};  ///< payloads per pose, kg; must hold 0
  Vec3 p_TrackerInBase_m = Vec3(4.0, 0.0, 1.2);  ///< the tracker head in base_link, m
  double min_range_m = 1.5;                ///< nearest tip distance the tracker measures, m
  double max_range_m = 15.0;               ///< farthest, m
  double line_of_sight_clearance_m = 0.15;  ///< sight line to link polyline, at least, m
  double tip_exclusion_m = 0.3;            ///< end of the sight line not checked, m
  double min_link_height_m = 0.1;          ///< link origins after joint 1 above the floor, m
  int candidates = 2000;                   ///< candidate poses drawn, ≥ poses
  /// When not empty, the candidates (pose_id and angles; load_kg ignored), all taken as they are:
  /// no draw, no visibility test (candidates is then unused). Their pose_ids name the plan's
  /// poses. At least poses of them.
  std::vector<PlannedMeasurement> given_candidates;
  /// The payload's centre of gravity in the payload frame (planCampaign's sensor_frame), m.
  Vec3 p_CoGInSensor_m = Vec3::Zero();
  uint64_t seed = 1;                       ///< same seed, same candidates and random choice
  PoseSelection selection = PoseSelection::kDOptimal;
  Vec3 gravity_in_base_m_per_s2 = Vec3(0.0, 0.0, -9.80665);  ///< m/s², base_link axes
  double position_sigma_m = 10e-6;  ///< tracker position noise per axis, 1-σ, m
  /// Tracker orientation noise per axis, 1-σ, rad; 0: a position-only tracker (3D reflector).
  double orientation_sigma_rad = 8.726646259971648e-5;
  double ridge = 1e-3;         ///< added to the normalised information's diagonal
  double spread_weight = 0.2;  ///< weight of new coverage against information
  int spread_bins = 8;         ///< bins per joint range for the coverage
  /// Joints (0-based) whose compliance across the axis (off_axis_compliance) the poses should
  /// identify besides geometry and compliance: each adds its two tilt compliances to the
  /// information, so the plan seeks poses whose payload moment across the joint's axis varies
  /// and moves the tip. Empty: geometry and compliance only.
  std::vector<int> off_axis_joints;
  /// Whether the poses should also identify the tool mount's compliance (tool_mount_compliance):
  /// its three compliances join the information, so the plan seeks poses whose payload force
  /// varies along each of the sensor's axes. Needs a payload link.
  bool tool_mount = false;
  /// A re-check's plan (`stepcal plan --recheck`, trainer/recheck.hpp): the information of what
  /// a re-check fits, the registration (6), the tool (6) and the zeros of joints 2 … n−1, in
  /// place of the whole geometry's 6(n+1) columns; compliance columns at the payloads as ever.
  bool recheck = false;
};

/// A plan: the rows to measure and how it was found.
struct CampaignPlan {
  std::vector<PlannedMeasurement> rows;  ///< unloaded rows of every pose, then each payload's
  int candidates_drawn = 0;  ///< or given (PlanOptions::given_candidates)
  int rejected_range = 0;           ///< tip too near or too far from the tracker
  int rejected_floor = 0;           ///< a link origin below min_link_height_m
  int rejected_line_of_sight = 0;   ///< the arm in the way
  /// log det of the selected poses' normalised information plus the ridge (dimensionless).
  double log_det_information = 0.0;
  /// Per joint, the share of its range's bins the selected poses cover (0–1).
  std::vector<double> joint_coverage;
};

/// Plans options.poses poses for the chain (rooted at base_link) whose attached frame
/// sensor_frame carries the payload (−1: none; then loads_kg must be {0}). Throws InputError on
/// bad options or when fewer visible candidates than poses are found. The same plan whatever the
/// CPU: it first pins Eigen's blocking to the GPR's sizes (Eigen::setCpuCacheSizes, for the whole
/// process, as GaussianProcess::fit does), so no other thread may run Eigen products meanwhile.
CampaignPlan planCampaign(const KinematicChain& nominal_Base, int sensor_frame,
                          const PlanOptions& options);

}  // namespace stepcal::trainer
