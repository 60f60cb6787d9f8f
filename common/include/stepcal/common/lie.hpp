// Lie-group maps on SO(3) and SE(3).
//
// Twists are ordered ξ = (v, ω) ∈ R^6 as in docs/method.md eq. (3): translation first, rotation last.
// Wrenches pair with twists as W = (f, m). Every map is exact to round-off on its whole domain:
// small angles use Taylor series, rotations near π use the symmetric part of R.
#pragma once

#include "stepcal/common/types.hpp"

namespace stepcal::lie {

/// Skew-symmetric matrix ŵ with ŵ x = w × x. (docs/method.md eq. 4)
Mat3 hat(const Vec3& w) noexcept;
/// Inverse of hat: the vector of a skew-symmetric matrix (antisymmetric part only).
Vec3 vee(const Mat3& W) noexcept;
/// 4×4 matrix ξ̂ = [ŵ v; 0 0] of a twist ξ = (v, ω). (docs/method.md eq. 3)
Eigen::Matrix4d hat6(const Vec6& xi) noexcept;
/// Inverse of hat6.
Vec6 vee6(const Eigen::Matrix4d& Xi) noexcept;

/// Rodrigues' formula: exp(ŵ) ∈ SO(3), w in rad.
Mat3 expSO3(const Vec3& w) noexcept;
/// Principal logarithm of a rotation, |result| ∈ [0, π] rad; robust at 0 and at π.
Vec3 logSO3(const Mat3& R) noexcept;
/// exp(ξ̂) ∈ SE(3) for ξ = (v [m], ω [rad]).
Pose expSE3(const Vec6& xi) noexcept;
/// Principal logarithm log(T)^∨ = (v [m], ω [rad]).
Vec6 logSE3(const Pose& T) noexcept;

/// Adjoint Ad_T = [R p̂R; 0 R] mapping twists in frame B to frame A for T = X_AB.
Mat6 adjoint(const Pose& T) noexcept;
/// Ad_T ξ without forming Ad_T: (R v + p × R ω, R ω) for ξ = (v, ω).
inline Vec6 adjointTimes(const Pose& T, const Vec6& xi) noexcept {
  const Vec3 w = T.linear() * xi.tail<3>();
  Vec6 out;
  out.head<3>() = T.linear() * xi.head<3>() + T.translation().cross(w);
  out.tail<3>() = w;
  return out;
}

/// Left Jacobian of SO(3): d/dε exp(w + ε) = exp(Jl(w) ε) exp(w) to first order.
Mat3 leftJacobianSO3(const Vec3& w) noexcept;
/// Inverse of the left Jacobian of SO(3).
Mat3 leftJacobianInverseSO3(const Vec3& w) noexcept;
/// Right Jacobian of SO(3): exp(w + ε) = exp(w) exp(Jr(w) ε); Jr(w) = Jl(−w).
Mat3 rightJacobianSO3(const Vec3& w) noexcept;
/// Inverse of the right Jacobian of SO(3).
Mat3 rightJacobianInverseSO3(const Vec3& w) noexcept;

/// Rotation angle between two rotations, rad: ‖log(R_aᵀ R_b)^∨‖ (docs/method.md eq. 11 summand).
double angleBetween(const Mat3& R_a, const Mat3& R_b) noexcept;

/// Projects a near-rotation matrix onto SO(3) (closest in Frobenius norm).
Mat3 projectToSO3(const Mat3& M) noexcept;

/// Rotation from URDF roll-pitch-yaw: R = Rz(yaw) · Ry(pitch) · Rx(roll), rad.
Mat3 rotationFromRpy(double roll, double pitch, double yaw) noexcept;
/// Inverse of rotationFromRpy, pitch in [−π/2, π/2]; the angles give R back to rounding, near
/// gimbal lock too (there roll and yaw share what only their sum or difference fixes).
Vec3 rpyFromRotation(const Mat3& R) noexcept;

}  // namespace stepcal::lie
