// thermal_expansion: the links' lengths × (1 + α (T − T_ref)).
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [α 1/K, T_ref °C].
template <class Double>
struct ThermalExpansion {
  static constexpr MechanismKind kKind = MechanismKind::kThermalExpansion;
  static constexpr int kExpansion = 0, kReferenceTemp = 1;
  Double* p;
  int order;
  Double& expansion_per_k() const noexcept { return p[kExpansion]; }
  Double& referenceTemp_c() const noexcept { return p[kReferenceTemp]; }
};

}  // namespace stepcal::mechanism
