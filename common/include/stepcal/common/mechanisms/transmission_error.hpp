// transmission_error: joint j's link angle moves by a profile of its commanded angle.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [a_1 rad, b_1 rad, …, a_order rad, b_order rad]: the link angle moves by
/// g(q_j) Σ_k a_k sin(k q_j) + b_k cos(k q_j), q_j the commanded angle, g the gate of its
/// coverage (transmissionOffset).
template <class Double>
struct TransmissionError {
  static constexpr MechanismKind kKind = MechanismKind::kTransmissionError;
  /// Index of harmonic k's sine coefficient (k = 1..order); its cosine's follows it.
  static constexpr int sinIndex(int harmonic) noexcept { return 2 * (harmonic - 1); }
  Double* p;
  int order;
  Double& sin_rad(int harmonic) const noexcept { return p[sinIndex(harmonic)]; }
  Double& cos_rad(int harmonic) const noexcept { return p[sinIndex(harmonic) + 1]; }
};

}  // namespace stepcal::mechanism
