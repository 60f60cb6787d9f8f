// off_axis_compliance: a joint's compliance across its axis (bearing tilt, link bending): its
// frame turns by the moment the joint carries about the two directions perpendicular to its
// axis, as the virtual-joint stiffness models of heavy robots have it.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [c_u rad/(N·m), c_v rad/(N·m)], both ≥ 0: joint j's frame (chain frame j, after its motion)
/// turns about its origin by the rotation vector t = c_u (u·M) u + c_v (v·M) v, M the moment of
/// the load (the measured wrench, or a payload's weight) about that origin in the frame's axes,
/// u and v the directions across the axis (tiltDirections). With c_u = c_v = c: t = c M⊥, M
/// with its component along the axis removed. Everything beyond the joint turns with its frame.
template <class Double>
struct OffAxisCompliance {
  static constexpr MechanismKind kKind = MechanismKind::kOffAxisCompliance;
  static constexpr int kTiltU = 0, kTiltV = 1;
  Double* p;
  int order;
  Double& tiltU_rad_per_nm() const noexcept { return p[kTiltU]; }
  Double& tiltV_rad_per_nm() const noexcept { return p[kTiltV]; }
};

/// The two unit directions across a joint's unit axis ω (its frame's axes): u is the frame's
/// coordinate axis least aligned with ω (the first of equals) made orthogonal to ω, v = ω × u.
/// For an axis along ±z: u = x, v = ±y.
void tiltDirections(const Vec3& axis, Vec3& u, Vec3& v) noexcept;

/// The rotation vector t (rad, the joint frame's axes) by which an off_axis_compliance turns its
/// joint's frame under the moment moment_Nm (N·m, the frame's axes, about its origin), the
/// joint's unit axis axis (same axes). Allocation-free.
Vec3 frameTilt_rad(const Mechanism& m, const Vec3& axis, const Vec3& moment_Nm) noexcept;

}  // namespace stepcal::mechanism
