// profile_geometry: joint j's initial-pose corrections that go with its transmission profile.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// Per initial pose k = 0..n: [δ_k (v m (3), ω rad (3))], applied as T_k · exp(g(q_j) δ̂_k), g
/// the gate of joint j's transmission_error.
template <class Double>
struct ProfileGeometry {
  static constexpr MechanismKind kKind = MechanismKind::kProfileGeometry;
  Double* p;
  int order;
  /// Initial pose k's twist δ_k.
  Eigen::Map<const Vec6> poseDelta(int pose) const noexcept {
    return Eigen::Map<const Vec6>(p + 6 * pose);
  }
};

}  // namespace stepcal::mechanism
