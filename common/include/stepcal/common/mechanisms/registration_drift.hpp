// registration_drift: the tracker's frame moving in time order during a campaign (measurement,
// not robot).
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [first_seq, last_seq, then per degree d = 1..order: ξ_d (v m (3), ω rad (3))]: the tracker's
/// frame at time order seq is exp(ξ̂(s)) times the fitted one, ξ(s) = Σ_d P_d(s) ξ_d, P_d the
/// Legendre polynomials, s = 2 (seq − first_seq)/(last_seq − first_seq) − 1 (tracker axes),
/// held at ±1 outside the span it was fitted on (registrationDrift).
template <class Double>
struct RegistrationDrift {
  static constexpr MechanismKind kKind = MechanismKind::kRegistrationDrift;
  static constexpr int kFirstSeq = 0, kLastSeq = 1;
  /// Index of degree d's twist (d = 1..order; 6 entries).
  static constexpr int termIndex(int degree) noexcept { return 2 + 6 * (degree - 1); }
  Double* p;
  int order;
  Double& firstSeq() const noexcept { return p[kFirstSeq]; }
  Double& lastSeq() const noexcept { return p[kLastSeq]; }
  Eigen::Map<const Vec6> term(int degree) const noexcept {
    return Eigen::Map<const Vec6>(p + termIndex(degree));
  }
};

}  // namespace stepcal::mechanism
