// The corrected inverse seeded by the nominal closed form, in a requested branch.
//
// A controller's program names its target's configuration (KUKA S/T, ABB confdata, Fanuc CONFIG,
// a UR's joint list), not joints near the answer. The nominal chain's closed-form inverse
// (common/closed_form_ik.hpp, RuntimeModel::nominal_inverse) gives the joints at which the
// NOMINAL robot reaches the desired pose in that branch; the real robot there is off by the
// calibration's millimetres (and, with a nominal target frame off by a degree, by that much in
// orientation). Two rounds of a fixed point on the calibrated geometry (chain_Tracker: one
// forward kinematics and one closed form each; no compliance, no GPR) take the seed to what the
// geometry alone leaves: the deflection and the residual twist, a fraction of a millimetre, so
// solveInverse started there needs few steps and stays in the branch. Allocation-free, noexcept,
// as the calls of corrector.hpp.
#pragma once

#include "stepcal/common/closed_form_ik.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::runtime {

/// The seed [rad] for the desired target pose in the tracker frame (ws.chain is scratch), in
/// branch, each joint the whole turn nearest q_near_rad (ClosedFormInverse::solveNearest: within
/// the limits or not, solveInverse clamps it; q_near also gives a singularity's free joint). q_seed_rad is written when the status is kOk, kSingular or
/// kBeyondLimits; kNoClosedForm for an arm the closed form does not solve (then seed otherwise).
ClosedFormStatus closedFormSeed(const RuntimeModel& model, Workspace& ws,
                                const Pose& X_TrackerTip_desired, ArmBranch branch,
                                const JointVector& q_near_rad, JointVector& q_seed_rad) noexcept;
/// The same for a TCP pose in a call's terms (frame, tool from the target or the flange, hung
/// from the calibrated target as correctForward hangs it). kBadRequest for terms that do not
/// hold (a flange the model lacks, non-finite poses).
ClosedFormStatus closedFormSeed(const RuntimeModel& model, Workspace& ws,
                                const Pose& X_FrameTcp_desired, const CallTerms& terms,
                                ArmBranch branch, const JointVector& q_near_rad,
                                JointVector& q_seed_rad) noexcept;

/// solveInverse from the closed-form seed of branch, with options.twist_at_seed (from q_near_rad
/// and the options as given where the closed form gives no seed: an arm of another layout, or a
/// pose the nominal arm cannot reach in that branch). The
/// answer's branch is model.nominal_inverse.branchOf(result.q_target_rad): the seed's, unless
/// the correction crosses a singularity.
InverseResult solveInverseInBranch(const RuntimeModel& model, Workspace& ws,
                                   const Pose& X_TrackerTip_desired, const Vec6& wrench_Sensor,
                                   double temp_c, ArmBranch branch, const JointVector& q_near_rad,
                                   Clock::time_point deadline,
                                   const InverseOptions& options = {}) noexcept;
/// The same in a call's terms.
InverseResult solveInverseInBranch(const RuntimeModel& model, Workspace& ws,
                                   const Pose& X_FrameTcp_desired, const CallTerms& terms,
                                   double temp_c, ArmBranch branch, const JointVector& q_near_rad,
                                   Clock::time_point deadline,
                                   const InverseOptions& options = {}) noexcept;

}  // namespace stepcal::runtime
