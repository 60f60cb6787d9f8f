// backlash: joint j's lost motion, taken up in the direction of its torque.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [b rad, τ_b N·m]: b tanh(τ_j/τ_b), a sign smoothed over ±τ_b (with no load the joint sits
/// mid-play; τ_b is set from the loads, not fitted).
template <class Double>
struct Backlash {
  static constexpr MechanismKind kKind = MechanismKind::kBacklash;
  static constexpr int kLostMotion = 0, kSmoothingTorque = 1;  ///< parameter indices
  Double* p;
  int order;
  Double& lostMotion_rad() const noexcept { return p[kLostMotion]; }
  Double& smoothingTorque_nm() const noexcept { return p[kSmoothingTorque]; }
};

}  // namespace stepcal::mechanism
