// joint_coupling: joint j's link angle moves with joint i's commanded angle.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [c rad/rad]: θ_j += c q_i, i = Mechanism::source_joint.
template <class Double>
struct JointCoupling {
  static constexpr MechanismKind kKind = MechanismKind::kJointCoupling;
  static constexpr int kRatio = 0;
  Double* p;
  int order;
  Double& ratio() const noexcept { return p[kRatio]; }
};

}  // namespace stepcal::mechanism
