#include "stepcal/runtime/closed_form_seed.hpp"

namespace stepcal::runtime {
namespace {

bool seeded(ClosedFormStatus status) noexcept {
  return status == ClosedFormStatus::kOk || status == ClosedFormStatus::kSingular ||
         status == ClosedFormStatus::kBeyondLimits;
}

bool finite(const Pose& X) noexcept { return X.matrix().allFinite(); }

/// Rounds of the calibrated geometry's fixed point after the nominal closed form.
constexpr int kGeometryRounds = 1;

}  // namespace

ClosedFormStatus closedFormSeed(const RuntimeModel& model, Workspace& ws,
                                const Pose& X_TrackerTip_desired, ArmBranch branch,
                                const JointVector& q_near_rad, JointVector& q_seed_rad) noexcept {
  if (!finite(X_TrackerTip_desired)) return ClosedFormStatus::kBadRequest;
  const Pose& X_TrackerBase = model.file.X_TrackerBase;
  // The nominal target asked for, in the base frame: the desired one, then moved by what the
  // calibrated geometry adds at the last answer (X_TrackerCmd ← X_desired · X_calibrated⁻¹ ·
  // X_TrackerCmd): a fixed point whose error shrinks by the geometry's change over the move.
  Pose X_BaseCommanded = X_TrackerBase.inverse() * X_TrackerTip_desired;
  ClosedFormStatus status =
      model.nominal_inverse.solveNearest(X_BaseCommanded, branch, q_near_rad, q_seed_rad);
  for (int round = 0; round < kGeometryRounds && seeded(status); ++round) {
    forwardKinematics(model.file.chain_Tracker, q_seed_rad, ws.chain);
    X_BaseCommanded = X_TrackerBase.inverse() * X_TrackerTip_desired *
                      tipPose(ws.chain).inverse() * X_TrackerBase * X_BaseCommanded;
    status = model.nominal_inverse.solveNearest(X_BaseCommanded, branch, q_seed_rad, q_seed_rad);
  }
  return status;
}

ClosedFormStatus closedFormSeed(const RuntimeModel& model, Workspace& ws,
                                const Pose& X_FrameTcp_desired, const CallTerms& terms,
                                ArmBranch branch, const JointVector& q_near_rad,
                                JointVector& q_seed_rad) noexcept {
  const bool from_flange = terms.tool_from == ToolFrom::kFlange;
  if (!finite(X_FrameTcp_desired) || !finite(terms.X_Tool) || !finite(terms.X_BaseUser) ||
      (from_flange && !model.has_flange)) {
    return ClosedFormStatus::kBadRequest;
  }
  // The calibrated target that puts the TCP there (as correctForward hangs the tool from it).
  const Pose X_TipTcp = from_flange ? Pose(model.X_TipFlange * terms.X_Tool) : terms.X_Tool;
  const Pose X_TrackerTip_desired = trackerFromFrame(model, terms.frame, terms.X_BaseUser) *
                                    X_FrameTcp_desired * X_TipTcp.inverse();
  return closedFormSeed(model, ws, X_TrackerTip_desired, branch, q_near_rad, q_seed_rad);
}

InverseResult solveInverseInBranch(const RuntimeModel& model, Workspace& ws,
                                   const Pose& X_TrackerTip_desired, const Vec6& wrench_Sensor,
                                   double temp_c, ArmBranch branch, const JointVector& q_near_rad,
                                   Clock::time_point deadline,
                                   const InverseOptions& options) noexcept {
  JointVector q_seed_rad = q_near_rad;
  InverseOptions seeded_options = options;
  if (seeded(closedFormSeed(model, ws, X_TrackerTip_desired, branch, q_near_rad, q_seed_rad))) {
    seeded_options.twist_at_seed = true;
  } else {
    q_seed_rad = q_near_rad;
  }
  return solveInverse(model, ws, X_TrackerTip_desired, wrench_Sensor, temp_c, q_seed_rad,
                      deadline, seeded_options);
}

InverseResult solveInverseInBranch(const RuntimeModel& model, Workspace& ws,
                                   const Pose& X_FrameTcp_desired, const CallTerms& terms,
                                   double temp_c, ArmBranch branch, const JointVector& q_near_rad,
                                   Clock::time_point deadline,
                                   const InverseOptions& options) noexcept {
  JointVector q_seed_rad = q_near_rad;
  InverseOptions seeded_options = options;
  if (seeded(closedFormSeed(model, ws, X_FrameTcp_desired, terms, branch, q_near_rad, q_seed_rad))) {
    seeded_options.twist_at_seed = true;
  } else {
    q_seed_rad = q_near_rad;
  }
  return solveInverse(model, ws, X_FrameTcp_desired, terms, temp_c, q_seed_rad, deadline,
                      seeded_options);
}

}  // namespace stepcal::runtime
