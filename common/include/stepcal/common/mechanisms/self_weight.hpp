// self_weight: every link's lumped mass and first moment; the compliance acts on their gravity.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// Per link k = 1..n: [m_k kg, h_k kg·m (3)], h_k = m_k · centre of mass in frame k (the frame
/// after joint k's motion).
template <class Double>
struct SelfWeight {
  static constexpr MechanismKind kKind = MechanismKind::kSelfWeight;
  static constexpr int kPerLink = 4;
  /// Index of link k's mass (k = 1..n); its first moment's x, y, z follow it.
  static constexpr int massIndex(int link) noexcept { return kPerLink * (link - 1); }
  Double* p;
  int order;
  Double& mass_kg(int link) const noexcept { return p[massIndex(link)]; }
  /// Axis 0, 1, 2: x, y, z in frame k.
  Double& firstMoment_kgm(int link, int axis) const noexcept {
    return p[massIndex(link) + 1 + axis];
  }
};

}  // namespace stepcal::mechanism
