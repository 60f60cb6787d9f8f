// nonlinear_stiffness: joint j's extra compliance at small torque, fading above τ₀.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [c rad/(N·m), τ₀ N·m, τ_lin N·m]: c τ_j τ₀/(τ₀ + |τ_j|) up to |τ_j| = τ_lin and carried on
/// above it with its slope there (τ_lin: the largest torque it was fitted over; 0: the formula
/// at any torque).
template <class Double>
struct NonlinearStiffness {
  static constexpr MechanismKind kKind = MechanismKind::kNonlinearStiffness;
  static constexpr int kExtraCompliance = 0, kSaturationTorque = 1, kLinearAbove = 2;
  Double* p;
  int order;
  Double& extraCompliance_rad_per_nm() const noexcept { return p[kExtraCompliance]; }
  Double& saturationTorque_nm() const noexcept { return p[kSaturationTorque]; }
  Double& linearAbove_nm() const noexcept { return p[kLinearAbove]; }
};

}  // namespace stepcal::mechanism
