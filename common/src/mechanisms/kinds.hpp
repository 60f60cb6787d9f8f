// Inside common: the shared pieces of the kinds' text and curves (each kind's traits are in its
// own file, common/src/mechanisms/<kind>.cpp, listed in registry.cpp), and the evaluation
// physicalLinkAngles takes from them.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// " (joint j)", 1-based: describe's suffix of a kind that moves one joint.
std::string jointSuffix(const Mechanism& m);

/// The parts of a torque–deflection curve, each added to a deflection and its slope ∂/∂τ at
/// torque tau_nm (torqueDeflection's shapes).
/// Lost motion b tanh(τ/τ_b), slope (b/τ_b) sech²; none when smoothing ≤ 0.
inline void addLostMotion(double b, double smoothing, double tau_nm, double& deflection,
                          double& slope) noexcept {
  if (smoothing <= 0.0) return;
  const double t = std::tanh(tau_nm / smoothing);
  deflection += b * t;
  slope += b * (1.0 - t * t) / smoothing;
}
/// Nonlinear stiffness c τ τ₀/(τ₀ + |τ|), slope c τ₀²/(τ₀ + |τ|)².
inline void addFade(double c, double t0, double tau_nm, double& deflection,
                    double& slope) noexcept {
  const double d = t0 + std::abs(tau_nm);
  deflection += c * tau_nm * t0 / d;
  slope += c * t0 * t0 / (d * d);
}
/// A knee c sign(τ) min(|τ|, T), the min smooth: x − w s((x − T)/w) + w s(−T/w) with s the
/// softplus, w = kTorsionKneeWidth T (0 at x = 0, slope 1 − σ((x − T)/w): 1 below T, 0 above).
inline void addKnee(double c, double corner, double tau_nm, double& deflection,
                    double& slope) noexcept {
  const double w = kTorsionKneeWidth * corner, x = std::abs(tau_nm);
  const auto softplus = [](double z) {
    return std::max(z, 0.0) + std::log1p(std::exp(-std::abs(z)));
  };
  const double z = (x - corner) / w;
  const double bent = x - w * softplus(z) + w * softplus(-corner / w);
  deflection += c * std::copysign(bent, tau_nm);
  slope += c / (1.0 + std::exp(z));
}

/// Σ_k a_k sin(k q) + b_k cos(k q) of a transmission_error, ungated, and its derivative by q
/// when slope_out is given, from s1 = sin q and c1 = cos q.
double profileSum(const Mechanism& transmission, double s1, double c1, double* slope_out) noexcept;

/// A transmission_error's offset gate · profile at an angle of sine s1 and cosine c1, from its
/// gate and the gate's slope (coverageGate), and its derivative when derivative is given. Inline:
/// physicalLinkAngles adds it to θ₀ as it did when both were one file (the same rounding).
inline double gatedOffset(const Mechanism& transmission, double s1, double c1, double gate,
                          double gate_slope, double* derivative) noexcept {
  if (gate == 0.0) {  // outside the coverage, and so is the slope (the gate is C¹)
    if (derivative) *derivative = 0.0;
    return 0.0;
  }
  double slope = 0.0;
  const double sum = profileSum(transmission, s1, c1, derivative ? &slope : nullptr);
  if (derivative) *derivative = gate * slope + gate_slope * sum;
  return gate * sum;
}

}  // namespace stepcal::mechanism
