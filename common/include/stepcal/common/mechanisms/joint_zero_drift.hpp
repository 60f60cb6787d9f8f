// joint_zero_drift: joint j's zero moves with temperature.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [k rad/K, T_ref °C]: the link angle moves by k (T − T_ref) where the temperature is known
/// (warm-up, a motor's or gearbox's heat).
template <class Double>
struct JointZeroDrift {
  static constexpr MechanismKind kKind = MechanismKind::kJointZeroDrift;
  static constexpr int kDriftRate = 0, kReferenceTemp = 1;
  Double* p;
  int order;
  Double& driftRate_rad_per_k() const noexcept { return p[kDriftRate]; }
  Double& referenceTemp_c() const noexcept { return p[kReferenceTemp]; }
};

}  // namespace stepcal::mechanism
