#include "stepcal/runtime/closed_form_seed.hpp"

namespace stepcal::runtime {
namespace {

bool seeded(ClosedFormStatus status) noexcept {
  return status == ClosedFormStatus::kOk || status == ClosedFormStatus::kSingular ||
         status == ClosedFormStatus::kBeyondLimits;
}

bool finite(const Pose& X) noexcept { return X.matrix().allFinite(); }

}  // namespace

ClosedFormStatus closedFormSeed(const RuntimeModel& model, const Pose& X_TrackerTip_desired,
                                ArmBranch branch, const JointVector& q_near_rad,
                                JointVector& q_seed_rad) noexcept {
  if (!finite(X_TrackerTip_desired)) return ClosedFormStatus::kBadRequest;
  const Pose X_BaseTip = model.file.X_TrackerBase.inverse() * X_TrackerTip_desired;
  return model.nominal_inverse.solve(X_BaseTip, branch, q_near_rad, q_seed_rad);
}

ClosedFormStatus closedFormSeed(const RuntimeModel& model, const Pose& X_FrameTcp_desired,
                                const CallTerms& terms, ArmBranch branch,
                                const JointVector& q_near_rad, JointVector& q_seed_rad) noexcept {
  const bool from_flange = terms.tool_from == ToolFrom::kFlange;
  if (!finite(X_FrameTcp_desired) || !finite(terms.X_Tool) || !finite(terms.X_BaseUser) ||
      (from_flange && !model.has_flange)) {
    return ClosedFormStatus::kBadRequest;
  }
  // As nominalTcp: X_FrameTcp = X_TrackerFrame⁻¹ X_TrackerBase X_BaseRef X_Tool, the reference
  // the nominal chain's target or its flange (frame n · X_LastFlange_nominal).
  const Pose X_BaseRef = model.file.X_TrackerBase.inverse() *
                         trackerFromFrame(model, terms.frame, terms.X_BaseUser) *
                         X_FrameTcp_desired * terms.X_Tool.inverse();
  const KinematicChain& nominal = model.file.nominal_Base;
  const Pose X_BaseTip =
      from_flange ? Pose(X_BaseRef * model.X_LastFlange_nominal.inverse() *
                         nominal.initialPose(nominal.dof()))
                  : X_BaseRef;
  return model.nominal_inverse.solve(X_BaseTip, branch, q_near_rad, q_seed_rad);
}

InverseResult solveInverseInBranch(const RuntimeModel& model, Workspace& ws,
                                   const Pose& X_TrackerTip_desired, const Vec6& wrench_Sensor,
                                   double temp_c, ArmBranch branch, const JointVector& q_near_rad,
                                   Clock::time_point deadline,
                                   const InverseOptions& options) noexcept {
  JointVector q_seed_rad = q_near_rad;
  if (!seeded(closedFormSeed(model, X_TrackerTip_desired, branch, q_near_rad, q_seed_rad))) {
    q_seed_rad = q_near_rad;
  }
  return solveInverse(model, ws, X_TrackerTip_desired, wrench_Sensor, temp_c, q_seed_rad,
                      deadline, options);
}

InverseResult solveInverseInBranch(const RuntimeModel& model, Workspace& ws,
                                   const Pose& X_FrameTcp_desired, const CallTerms& terms,
                                   double temp_c, ArmBranch branch, const JointVector& q_near_rad,
                                   Clock::time_point deadline,
                                   const InverseOptions& options) noexcept {
  JointVector q_seed_rad = q_near_rad;
  if (!seeded(closedFormSeed(model, X_FrameTcp_desired, terms, branch, q_near_rad, q_seed_rad))) {
    q_seed_rad = q_near_rad;
  }
  return solveInverse(model, ws, X_FrameTcp_desired, terms, temp_c, q_seed_rad, deadline,
                      options);
}

}  // namespace stepcal::runtime
