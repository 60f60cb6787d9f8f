// A pose as a position and a unit quaternion (w, x, y, z), the form the messages, the correction
// programs, the campaign files and the Python module carry, and back: one converter pair.
// Allocation-free and noexcept (the daemon converts every request and reply).
#pragma once

#include <cmath>

#include "stepcal/common/types.hpp"

namespace stepcal {

/// How far from 1 the norm of a quaternion read from outside may be; it is normalised after.
inline constexpr double kQuaternionNormTolerance = 1e-6;

/// Whether q's norm is 1 within kQuaternionNormTolerance (false when it is NaN).
inline bool isUnitQuaternion(const Eigen::Quaterniond& q) noexcept {
  return std::abs(q.norm() - 1.0) <= kQuaternionNormTolerance;
}

/// X's position (m) into position_m[0..2] and its rotation as a unit quaternion into
/// quaternion_wxyz[0..3], w first.
inline void toPositionQuaternion(const Pose& X, double* position_m,
                                 double* quaternion_wxyz) noexcept {
  const Eigen::Quaterniond q(X.linear());
  for (int k = 0; k < 3; ++k) position_m[k] = X.translation()[k];
  quaternion_wxyz[0] = q.w();
  quaternion_wxyz[1] = q.x();
  quaternion_wxyz[2] = q.y();
  quaternion_wxyz[3] = q.z();
}

/// The pose at p_m (m) rotated by q, normalised here (check a quaternion from outside with
/// isUnitQuaternion first).
inline Pose poseFromPositionQuaternion(const Vec3& p_m, const Eigen::Quaterniond& q) noexcept {
  Pose X = Pose::Identity();
  X.linear() = q.normalized().toRotationMatrix();
  X.translation() = p_m;
  return X;
}

/// The pose at position_m[0..2] (m) rotated by quaternion_wxyz[0..3] (w first), normalised.
inline Pose poseFromPositionQuaternion(const double* position_m,
                                       const double* quaternion_wxyz) noexcept {
  return poseFromPositionQuaternion(
      Vec3(position_m[0], position_m[1], position_m[2]),
      Eigen::Quaterniond(quaternion_wxyz[0], quaternion_wxyz[1], quaternion_wxyz[2],
                         quaternion_wxyz[3]));
}

}  // namespace stepcal
