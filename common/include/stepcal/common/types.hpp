// Fixed-size linear-algebra aliases shared by every stepcal module.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace stepcal {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
/// Rigid transform X_AB: maps coordinates in frame B to frame A (Drake monogram).
using Pose = Eigen::Isometry3d;

/// Largest number of revolute joints a chain may have; fixes every hot-path buffer size.
inline constexpr int kMaxJoints = 8;

/// Joint-space vector, heap-free (dynamic size up to kMaxJoints).
using JointVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxJoints, 1>;
/// 6 × n Jacobian, heap-free; columns are twists (v, ω).
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxJoints>;

}  // namespace stepcal
