// tool_mount_compliance: the compliance beyond the last joint: the tool's mount (an F/T sensor,
// a tool changer) gives under the load's force, shifting the tool without turning it, a spring
// in series with the arm that no joint's frame has.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [c_x m/N, c_y m/N, c_z m/N], all ≥ 0: the tip (the tool, everything past the mount) moves by
/// δ = R_RootMount · diag(c_x, c_y, c_z) · F_Mount, F_Mount the load's force (the measured
/// wrench's, less any sensor bias, or a payload's weight) in the mount's axes: the sensor frame's
/// when the model has one, else the last joint's frame (the flange). One per model.
template <class Double>
struct ToolMountCompliance {
  static constexpr MechanismKind kKind = MechanismKind::kToolMountCompliance;
  static constexpr int kAlongX = 0, kAlongY = 1, kAlongZ = 2;
  Double* p;
  int order;
  Double& alongX_m_per_n() const noexcept { return p[kAlongX]; }
  Double& alongY_m_per_n() const noexcept { return p[kAlongY]; }
  Double& alongZ_m_per_n() const noexcept { return p[kAlongZ]; }
};

/// The tool's shift δ (m, the mount's axes) under the force force_Mount_N (N, the same axes).
/// Allocation-free.
Vec3 toolShift_m(const Mechanism& m, const Vec3& force_Mount_N) noexcept;

}  // namespace stepcal::mechanism
