// torsion_curve: joint j's lost motion and stiffening terms of its torque, one curve.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [b rad, τ_b N·m, then per term k = 1..order: c_k rad/(N·m), T_k N·m, then τ_lin N·m]:
/// b tanh(τ_j/τ_b) + Σ_k c_k sign(τ_j) min_k(|τ_j|, T_k): lost motion as backlash's (τ_b = 0:
/// none, then b = 0), and per term an extra compliance c_k up to the knee T_k (T_k increasing),
/// its min smooth over kTorsionKneeWidth · T_k (torqueDeflection). With b, c_k ≥ 0 it is odd in
/// τ_j, monotone and stiffening: the joint's compliance is C + c_1 + … + c_order below T_1,
/// C + c_2 + … above it, C above the last knee — a gear catalogue's segments K1, K2, K3 and its
/// lost motion. Up to |τ_j| = τ_lin, carried on above it with its slope there, as
/// nonlinear_stiffness's.
template <class Double>
struct TorsionCurve {
  static constexpr MechanismKind kKind = MechanismKind::kTorsionCurve;
  static constexpr int kLostMotion = 0, kSmoothingTorque = 1;
  /// Index of term k's extra compliance (k = 1..order); its knee torque's follows it.
  static constexpr int complianceIndex(int term) noexcept { return 2 * term; }
  static constexpr int kneeIndex(int term) noexcept { return 2 * term + 1; }
  static constexpr int linearAboveIndex(int order) noexcept { return 2 + 2 * order; }
  Double* p;
  int order;
  Double& lostMotion_rad() const noexcept { return p[kLostMotion]; }
  Double& smoothingTorque_nm() const noexcept { return p[kSmoothingTorque]; }
  Double& extraCompliance_rad_per_nm(int term) const noexcept { return p[complianceIndex(term)]; }
  Double& kneeTorque_nm(int term) const noexcept { return p[kneeIndex(term)]; }
  Double& linearAbove_nm() const noexcept { return p[linearAboveIndex(order)]; }
};

}  // namespace stepcal::mechanism
