// Joint compliance (virtual joint method): how the payload's wrench deflects the joints.
//
//   τ = J_sᵀ W_s                     (docs/method.md eq. 13; spatial Jacobian and wrench, root frame)
//   Δθ = C_θ τ,  C_θ = K_θ⁻¹          (eq. 15)
//   T_C1 = T_C(q) · T_STIF = T_C(q + Δθ)   (eq. 24, in its exact form: the link angles move,
//                                           not a linearised tip twist)
// Shared by the trainer and the runtime; allocation-free.
#pragma once

#include "stepcal/common/chain.hpp"

namespace stepcal {

/// Spatial wrench (f [N], m [N·m] about the root origin, root axes) from a wrench measured in
/// a frame whose pose in the root is X_RootSensor. Wrench transform: W_root = Ad_{X_RootSensor⁻¹}ᵀ W.
Vec6 wrenchInRoot(const Pose& X_RootSensor, const Vec6& wrench_Sensor) noexcept;

/// Joint torques τ = J_sᵀ W_root at the workspace's configuration, N·m. J must be the spatial
/// Jacobian there.
JointVector jointTorques(const Jacobian& J_spatial, const Vec6& wrench_Root) noexcept;

/// Link angles under a wrench measured by the sensor (an attached frame of the chain):
/// q_link = q + C_θ τ(q_link), iterated twice from τ(q) (the torque's change with the
/// deflection is second order). Leaves ws evaluated at q_link. Allocation-free; false when
/// sizes disagree.
bool deflectedJointAngles(const KinematicChain& chain, int sensor_frame, const JointVector& q,
                          const Vec6& wrench_Sensor, const JointVector& compliance_rad_per_nm,
                          ChainWorkspace& ws, JointVector& q_link) noexcept;

}  // namespace stepcal
