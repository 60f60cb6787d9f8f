#include "stepcal/common/mechanisms.hpp"

#include <algorithm>
#include <array>
#include <type_traits>
#include <cmath>
#include <cstdio>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal {
namespace {

constexpr MechanismKind kAllKinds[] = {
    MechanismKind::kBacklash,           MechanismKind::kSelfWeight,
    MechanismKind::kTransmissionError,  MechanismKind::kNonlinearStiffness,
    MechanismKind::kThermalExpansion,   MechanismKind::kSensorBias,
    MechanismKind::kJointCoupling,      MechanismKind::kProfileGeometry,
    MechanismKind::kTorsionCurve,       MechanismKind::kJointZeroDrift,
    MechanismKind::kRegistrationDrift,  MechanismKind::kSessionFrames,
    MechanismKind::kCampaignJointZero};

constexpr double kTwoPi = 2.0 * kPi;

bool usesJoint(MechanismKind kind) {
  return kind == MechanismKind::kBacklash || kind == MechanismKind::kTransmissionError ||
         kind == MechanismKind::kNonlinearStiffness || kind == MechanismKind::kJointCoupling ||
         kind == MechanismKind::kProfileGeometry || kind == MechanismKind::kTorsionCurve ||
         kind == MechanismKind::kJointZeroDrift || kind == MechanismKind::kCampaignJointZero;
}

}  // namespace

const char* toString(MechanismKind kind) noexcept {
  switch (kind) {
    case MechanismKind::kBacklash: return "backlash";
    case MechanismKind::kSelfWeight: return "self_weight";
    case MechanismKind::kTransmissionError: return "transmission_error";
    case MechanismKind::kNonlinearStiffness: return "nonlinear_stiffness";
    case MechanismKind::kThermalExpansion: return "thermal_expansion";
    case MechanismKind::kSensorBias: return "sensor_bias";
    case MechanismKind::kJointCoupling: return "joint_coupling";
    case MechanismKind::kProfileGeometry: return "profile_geometry";
    case MechanismKind::kTorsionCurve: return "torsion_curve";
    case MechanismKind::kJointZeroDrift: return "joint_zero_drift";
    case MechanismKind::kRegistrationDrift: return "registration_drift";
    case MechanismKind::kSessionFrames: return "session_frames";
    case MechanismKind::kCampaignJointZero: return "campaign_joint_zero";
  }
  return "unknown";
}

std::optional<MechanismKind> mechanismKindFromString(const std::string& name) {
  for (MechanismKind kind : kAllKinds) {
    if (name == toString(kind)) return kind;
  }
  return std::nullopt;
}

double coverageGate(const AngleCoverage& coverage, double q_rad, double* derivative) noexcept {
  if (derivative) *derivative = 0.0;
  const size_t arcs = coverage.arcs_rad.size() / 2;
  if (arcs == 0) return 1.0;
  // q mod 2π in [0, 2π) by one floor rather than fmod's exact remainder: the two agree to the
  // rounding of 2π's multiple, ~1e-15 rad at the joint ranges robots have.
  double angle = q_rad - kTwoPi * std::floor(q_rad / kTwoPi);
  if (angle >= kTwoPi) angle -= kTwoPi;
  if (angle < 0.0) angle += kTwoPi;
  double best = 0.0, best_slope = 0.0;
  for (size_t a = 0; a < arcs; ++a) {
    const double start = coverage.arcs_rad[2 * a], length = coverage.arcs_rad[2 * a + 1];
    if (length >= kTwoPi) {  // the full turn: no edge
      if (derivative) *derivative = 0.0;
      return 1.0;
    }
    double u = angle - start;  // position inside the arc, [0, 2π)
    if (u < 0.0) u += kTwoPi;
    if (u > length) continue;
    // Distance to the nearer edge, and its slope along q.
    const bool near_start = u < length - u;
    const double d = near_start ? u : length - u;
    const double x = d / coverage.fade_rad;
    if (x >= 1.0) {
      if (derivative) *derivative = 0.0;
      return 1.0;
    }
    const double g = x * x * (3.0 - 2.0 * x);
    if (g > best) {
      best = g;
      best_slope = 6.0 * x * (1.0 - x) / coverage.fade_rad * (near_start ? 1.0 : -1.0);
    }
  }
  if (derivative) *derivative = best_slope;
  return best;
}

std::string coverageProblem(const AngleCoverage& coverage) {
  const std::vector<double>& a = coverage.arcs_rad;
  if (a.empty()) return {};
  if (a.size() % 2 != 0 || a.size() / 2 > static_cast<size_t>(kMaxCoverageArcs)) {
    return "coverage has " + std::to_string(a.size()) +
           " numbers; expected pairs (start, length), at most " +
           std::to_string(kMaxCoverageArcs) + " arcs";
  }
  if (!(std::isfinite(coverage.fade_rad) && coverage.fade_rad > 0.0)) {
    return "coverage fade " + std::to_string(coverage.fade_rad) + " rad; expected > 0";
  }
  for (size_t i = 0; i < a.size(); i += 2) {
    const double start = a[i], length = a[i + 1];
    char line[200];
    if (!(std::isfinite(start) && start >= 0.0 && start < kTwoPi && std::isfinite(length) &&
          length > 0.0 && length <= kTwoPi)) {
      std::snprintf(line, sizeof line,
                    "coverage arc %zu (start %.9g rad, length %.9g rad); expected start in [0, "
                    "2pi), length in (0, 2pi]",
                    i / 2, start, length);
      return line;
    }
    if (i > 0 && !(start >= a[i - 2] + a[i - 1])) {
      std::snprintf(line, sizeof line,
                    "coverage arc %zu starts at %.9g rad, inside the arc before it; expected arcs "
                    "ordered by start, not overlapping",
                    i / 2, start);
      return line;
    }
  }
  const size_t last = a.size() - 2;
  if (a.size() > 2 && a[last] + a[last + 1] > a[0] + kTwoPi) {
    return "the last coverage arc wraps over the first; expected arcs not overlapping";
  }
  return {};
}

namespace {

/// Two doubles in one vector register (GCC/Clang vector extension: SSE2 on any x86-64, and the
/// compiler's choice elsewhere).
typedef double Lanes2 __attribute__((vector_size(2 * sizeof(double))));

// Σ_k a_k sin(k q) + b_k cos(k q) of a profile, ungated, and its derivative by q when slope is
// given, from s1 = sin q and c1 = cos q. sin(kq), cos(kq) for k = 1 … 4 by doubling (e^{2iq} =
// e^{iq} e^{iq}, then e^{i(2+j)q} = e^{ijq} e^{2iq}), then by rotations e^{i(k+4)q} = e^{ikq}
// e^{4iq} in two chains of two harmonics (k ≡ 1, 2 and 3, 4 mod 4), each chain's sines, cosines,
// sums and k in one vector register rather than four scalar chains (docs/runtime.md, "The chord
// step and the physical model's hot spots").
double profileSum(const Mechanism& m, double s1, double c1, double* slope_out) noexcept {
  constexpr int kLanes = 2, kChains = 2, kStep = kLanes * kChains;
  double s0[kStep], c0[kStep];
  s0[0] = s1;
  c0[0] = c1;
  for (int have = 1; have < kStep; have *= 2) {  // k = have + 1 … 2·have from k = 1 … have
    const double s_have = s0[have - 1], c_have = c0[have - 1];
    for (int j = 0; j < have; ++j) {
      s0[have + j] = s0[j] * c_have + c0[j] * s_have;
      c0[have + j] = c0[j] * c_have - s0[j] * s_have;
    }
  }
  Lanes2 s[kChains], c[kChains], value[kChains], slope[kChains], k[kChains];
  for (int r = 0; r < kChains; ++r) {
    s[r] = Lanes2{s0[kLanes * r], s0[kLanes * r + 1]};
    c[r] = Lanes2{c0[kLanes * r], c0[kLanes * r + 1]};
    k[r] = Lanes2{kLanes * r + 1.0, kLanes * r + 2.0};
    value[r] = slope[r] = Lanes2{0.0, 0.0};
  }
  const Lanes2 s_step = {s0[kStep - 1], s0[kStep - 1]}, c_step = {c0[kStep - 1], c0[kStep - 1]},
               k_step = {double(kStep), double(kStep)};
  const double* p = m.parameters.data();  // a_1, b_1, a_2, b_2, …
  const int blocks = m.order / kStep;
  for (int block = 0; block < blocks; ++block, p += 2 * kStep) {
    for (int r = 0; r < kChains; ++r) {
      const double* pr = p + 2 * kLanes * r;
      const Lanes2 a = {pr[0], pr[2]}, b = {pr[1], pr[3]};
      value[r] += a * s[r] + b * c[r];
      slope[r] += k[r] * (a * c[r] - b * s[r]);
      const Lanes2 s_next = s[r] * c_step + c[r] * s_step;
      c[r] = c[r] * c_step - s[r] * s_step;
      s[r] = s_next;
      k[r] += k_step;
    }
  }
  double sum = 0.0, sum_slope = 0.0;
  for (int j = 0; j < m.order - blocks * kStep; ++j) {  // the last order mod 4 harmonics
    const int r = j / kLanes, l = j % kLanes;
    const double a = p[2 * j], b = p[2 * j + 1];
    sum += a * s[r][l] + b * c[r][l];
    sum_slope += k[r][l] * (a * c[r][l] - b * s[r][l]);
  }
  const Lanes2 value_sum = value[0] + value[1], slope_sum = slope[0] + slope[1];
  sum += value_sum[0] + value_sum[1];
  sum_slope += slope_sum[0] + slope_sum[1];
  if (slope_out) *slope_out = sum_slope;
  return sum;
}

// The gated offset from a gate and its slope (coverageGate) at an angle of sine s1 and cosine
// c1: gate · sum, and its derivative.
double gatedOffset(const Mechanism& m, double s1, double c1, double gate, double gate_slope,
                   double* derivative) noexcept {
  if (gate == 0.0) {  // outside the coverage, and so is the slope (the gate is C¹)
    if (derivative) *derivative = 0.0;
    return 0.0;
  }
  double slope = 0.0;
  const double sum = profileSum(m, s1, c1, derivative ? &slope : nullptr);
  if (derivative) *derivative = gate * slope + gate_slope * sum;
  return gate * sum;
}

}  // namespace

bool isTorqueDeflection(MechanismKind kind) noexcept {
  return kind == MechanismKind::kBacklash || kind == MechanismKind::kNonlinearStiffness ||
         kind == MechanismKind::kTorsionCurve;
}

namespace {

// The curve as its formula gives it at every torque (torqueDeflection without its τ_lin).
double curveFormula(const Mechanism& m, double tau_nm, double* derivative) noexcept {
  double slope = 0.0, deflection = 0.0;
  // Lost motion b tanh(τ/τ_b), slope (b/τ_b) sech².
  const auto lost = [&](double b, double smoothing) {
    if (smoothing <= 0.0) return;
    const double t = std::tanh(tau_nm / smoothing);
    deflection += b * t;
    slope += b * (1.0 - t * t) / smoothing;
  };
  // Nonlinear stiffness c τ τ₀/(τ₀ + |τ|), slope c τ₀²/(τ₀ + |τ|)².
  const auto fade = [&](double c, double t0) {
    const double d = t0 + std::abs(tau_nm);
    deflection += c * tau_nm * t0 / d;
    slope += c * t0 * t0 / (d * d);
  };
  // A knee c sign(τ) min(|τ|, T), the min smooth: x − w s((x − T)/w) + w s(−T/w) with s the
  // softplus, w = kTorsionKneeWidth T (0 at x = 0, slope 1 − σ((x − T)/w): 1 below T, 0 above).
  const auto knee = [&](double c, double corner) {
    const double w = kTorsionKneeWidth * corner, x = std::abs(tau_nm);
    const auto softplus = [](double z) { return std::max(z, 0.0) + std::log1p(std::exp(-std::abs(z))); };
    const double z = (x - corner) / w;
    const double bent = x - w * softplus(z) + w * softplus(-corner / w);
    deflection += c * std::copysign(bent, tau_nm);
    slope += c / (1.0 + std::exp(z));
  };
  const auto p = [&m](size_t i) { return m.parameters[i]; };
  switch (m.kind) {
    case MechanismKind::kBacklash: lost(p(0), p(1)); break;
    case MechanismKind::kNonlinearStiffness: fade(p(0), p(1)); break;
    case MechanismKind::kTorsionCurve:
      lost(p(0), p(1));
      for (int k = 0; k < m.order; ++k) knee(p(2 + 2 * size_t(k)), p(3 + 2 * size_t(k)));
      break;
    default: break;
  }
  if (derivative) *derivative = slope;
  return deflection;
}

// τ_lin of a curve that has one (nonlinear_stiffness, torsion_curve: the last parameter), else 0.
double linearAbove(const Mechanism& m) noexcept {
  const bool has = m.kind == MechanismKind::kNonlinearStiffness || m.kind == MechanismKind::kTorsionCurve;
  return has ? m.parameters.back() : 0.0;
}

}  // namespace

double torqueDeflection(const Mechanism& m, double tau_nm, double* derivative) noexcept {
  const double limit = linearAbove(m);
  if (!(limit > 0.0 && std::abs(tau_nm) > limit)) return curveFormula(m, tau_nm, derivative);
  // d(±τ_lin) + d'(±τ_lin) (τ ∓ τ_lin)
  const double edge = std::copysign(limit, tau_nm);
  double slope = 0.0;
  const double at_edge = curveFormula(m, edge, &slope);
  if (derivative) *derivative = slope;
  return at_edge + slope * (tau_nm - edge);
}

double transmissionOffset(const Mechanism& m, double q_rad, double* derivative) noexcept {
  double gate_slope = 0.0;
  const double gate = coverageGate(m.coverage, q_rad, derivative ? &gate_slope : nullptr);
  return gatedOffset(m, std::sin(q_rad), std::cos(q_rad), gate, gate_slope, derivative);
}

std::vector<std::string> mechanismParameterNames(MechanismKind kind, int dof, int order) {
  switch (kind) {
    case MechanismKind::kBacklash: return {"lost_motion_rad", "smoothing_torque_nm"};
    case MechanismKind::kSelfWeight: {
      std::vector<std::string> names;
      for (int k = 1; k <= dof; ++k) {
        const std::string link = "link" + std::to_string(k) + "_";
        for (const char* p : {"mass_kg", "first_moment_x_kgm", "first_moment_y_kgm",
                              "first_moment_z_kgm"}) {
          names.push_back(link + p);
        }
      }
      return names;
    }
    case MechanismKind::kTransmissionError: {
      std::vector<std::string> names;
      for (int k = 1; k <= order; ++k) {
        names.push_back("h" + std::to_string(k) + "_sin_rad");
        names.push_back("h" + std::to_string(k) + "_cos_rad");
      }
      return names;
    }
    case MechanismKind::kNonlinearStiffness:
      return {"extra_compliance_rad_per_nm", "saturation_torque_nm", "linear_above_nm"};
    case MechanismKind::kThermalExpansion: return {"expansion_per_k", "reference_temp_c"};
    case MechanismKind::kSensorBias:
      return {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"};
    case MechanismKind::kJointCoupling: return {"ratio"};
    case MechanismKind::kJointZeroDrift: return {"drift_rad_per_k", "reference_temp_c"};
    case MechanismKind::kCampaignJointZero: {
      std::vector<std::string> names;
      for (int k = 1; k <= order; ++k) names.push_back("campaign" + std::to_string(k + 1) + "_rad");
      return names;
    }
    case MechanismKind::kSessionFrames:
      return {"station_x_m",  "station_y_m",  "station_z_m",  "station_rx_rad",
              "station_ry_rad", "station_rz_rad", "tool_x_m",     "tool_y_m",
              "tool_z_m",     "tool_rx_rad",  "tool_ry_rad",  "tool_rz_rad"};
    case MechanismKind::kRegistrationDrift: {
      std::vector<std::string> names = {"first_seq", "last_seq"};
      for (int d = 1; d <= order; ++d) {
        for (const char* p : {"vx_m", "vy_m", "vz_m", "wx_rad", "wy_rad", "wz_rad"}) {
          names.push_back("p" + std::to_string(d) + "_" + p);
        }
      }
      return names;
    }
    case MechanismKind::kTorsionCurve: {
      std::vector<std::string> names = {"lost_motion_rad", "smoothing_torque_nm"};
      for (int k = 1; k <= order; ++k) {
        names.push_back("extra_compliance" + std::to_string(k) + "_rad_per_nm");
        names.push_back("knee_torque" + std::to_string(k) + "_nm");
      }
      names.push_back("linear_above_nm");
      return names;
    }
    case MechanismKind::kProfileGeometry: {
      std::vector<std::string> names;
      for (int k = 0; k <= dof; ++k) {
        const std::string pose = "pose" + std::to_string(k) + "_";
        for (const char* p : {"vx_m", "vy_m", "vz_m", "wx_rad", "wy_rad", "wz_rad"}) {
          names.push_back(pose + p);
        }
      }
      return names;
    }
  }
  return {};
}

std::string mechanismProblem(const Mechanism& m, int dof) {
  bool known = false;
  for (MechanismKind kind : kAllKinds) known = known || kind == m.kind;
  if (!known) {
    return "mechanism kind " + std::to_string(static_cast<uint32_t>(m.kind)) +
           "; expected 1 to 13 (mechanisms.hpp)";
  }
  const std::string what = toString(m.kind);
  const bool order_fits =
      m.kind == MechanismKind::kTransmissionError ? m.order >= 1 && m.order <= kMaxHarmonics
      : m.kind == MechanismKind::kTorsionCurve    ? m.order >= 0 && m.order <= kMaxTorsionTerms
      : m.kind == MechanismKind::kRegistrationDrift ? m.order >= 1 && m.order <= kMaxDriftDegree
      : m.kind == MechanismKind::kSessionFrames || m.kind == MechanismKind::kCampaignJointZero
          ? m.order >= 1
          : m.order == 0;
  if (!order_fits) {
    return what + " order " + std::to_string(m.order) + "; expected 1 to " +
           std::to_string(kMaxHarmonics) + " harmonics for transmission_error, 0 to " +
           std::to_string(kMaxTorsionTerms) + " terms for torsion_curve, 1 to " +
           std::to_string(kMaxDriftDegree) +
           " (degree) for registration_drift, a campaign index ≥ 1 for session_frames, the "
           "campaigns after the first (≥ 1) for campaign_joint_zero, else 0";
  }
  const size_t count = mechanismParameterNames(m.kind, dof, m.order).size();
  if (m.parameters.size() != count || m.sigma.size() != count) {
    return what + " has " + std::to_string(m.parameters.size()) + " parameters and " +
           std::to_string(m.sigma.size()) + " sigmas; expected " + std::to_string(count);
  }
  for (size_t i = 0; i < count; ++i) {
    if (!std::isfinite(m.parameters[i]) || !std::isfinite(m.sigma[i]) || m.sigma[i] < 0.0) {
      return what + " parameter " + std::to_string(i) + " = " + std::to_string(m.parameters[i]) +
             " (σ " + std::to_string(m.sigma[i]) + "); expected finite values, σ ≥ 0";
    }
  }
  if (usesJoint(m.kind) != (m.joint >= 0) || m.joint >= dof) {
    return what + " joint index " + std::to_string(m.joint) + "; expected " +
           (usesJoint(m.kind) ? "0 to " + std::to_string(dof - 1) : std::string("-1 (none)"));
  }
  if ((m.kind == MechanismKind::kJointCoupling) !=
          (m.source_joint >= 0 && m.source_joint < dof) ||
      (m.kind == MechanismKind::kJointCoupling && m.source_joint == m.joint) ||
      (m.kind != MechanismKind::kJointCoupling && m.source_joint != -1)) {
    return what + " source joint index " + std::to_string(m.source_joint) +
           "; expected a joint other than the moved one for joint_coupling, else -1";
  }
  if (m.kind != MechanismKind::kTransmissionError && !m.coverage.arcs_rad.empty()) {
    return what + " has a joint-angle coverage; expected one only for transmission_error";
  }
  if (const std::string problem = coverageProblem(m.coverage); !problem.empty()) {
    return what + " " + problem;
  }
  if ((m.kind == MechanismKind::kNonlinearStiffness || m.kind == MechanismKind::kBacklash) &&
      !(m.parameters[1] > 0.0)) {
    return what + " " + mechanismParameterNames(m.kind, dof)[1] + " = " +
           std::to_string(m.parameters[1]) + "; expected > 0";
  }
  if ((m.kind == MechanismKind::kNonlinearStiffness || m.kind == MechanismKind::kTorsionCurve) &&
      !(m.parameters.back() >= 0.0)) {
    return what + " linear_above_nm = " + std::to_string(m.parameters.back()) +
           "; expected ≥ 0 (0: the curve's formula at every torque)";
  }
  if (m.kind == MechanismKind::kRegistrationDrift && !(m.parameters[1] > m.parameters[0])) {
    return what + " last_seq = " + std::to_string(m.parameters[1]) + " with first_seq = " +
           std::to_string(m.parameters[0]) + "; expected last_seq > first_seq";
  }
  if (m.kind == MechanismKind::kTorsionCurve) {
    if (m.parameters[1] < 0.0 || (m.parameters[1] == 0.0 && m.parameters[0] != 0.0)) {
      return what + " smoothing_torque_nm = " + std::to_string(m.parameters[1]) +
             " with lost_motion_rad = " + std::to_string(m.parameters[0]) +
             "; expected > 0, or 0 with no lost motion";
    }
    if (m.parameters[1] == 0.0 && m.order == 0) {
      return what + " has neither lost motion nor a stiffening term; expected at least one";
    }
    double previous = 0.0;
    for (int k = 1; k <= m.order; ++k) {
      const double fade = m.parameters[1 + 2 * size_t(k)];
      if (!(fade > previous)) {
        return what + " knee_torque" + std::to_string(k) + "_nm = " + std::to_string(fade) +
               "; expected > 0 and above the term before it";
      }
      previous = fade;
    }
  }
  return {};
}

std::string describe(const Mechanism& m) {
  std::string s = toString(m.kind);
  switch (m.kind) {
    case MechanismKind::kBacklash:
    case MechanismKind::kNonlinearStiffness:
    case MechanismKind::kProfileGeometry:
    case MechanismKind::kTorsionCurve:
    case MechanismKind::kJointZeroDrift:
    case MechanismKind::kCampaignJointZero:
      return s + " (joint " + std::to_string(m.joint + 1) + ")";
    case MechanismKind::kRegistrationDrift: {
      static const char* const kDegrees[] = {"", "linear", "quadratic", "cubic"};
      return s + " (" +
             (m.order < 4 ? std::string(kDegrees[m.order]) : "degree " + std::to_string(m.order)) +
             " in time order)";
    }
    case MechanismKind::kSessionFrames:
      return s + " (campaign " + std::to_string(m.order + 1) + ")";
    case MechanismKind::kTransmissionError:
      return s + " (joint " + std::to_string(m.joint + 1) + ", " + std::to_string(m.order) +
             (m.order == 1 ? " harmonic)" : " harmonics)");
    case MechanismKind::kJointCoupling:
      return s + " (joint " + std::to_string(m.source_joint + 1) + " -> joint " +
             std::to_string(m.joint + 1) + ")";
    default: return s;
  }
}

double PhysicalModel::linkLengthScale(double temp_c) const noexcept {
  if (!std::isfinite(temp_c)) return 1.0;
  double scale = 1.0;
  for (const Mechanism& m : mechanisms) {
    if (m.kind == MechanismKind::kThermalExpansion) {
      scale *= 1.0 + m.parameters[0] * (temp_c - m.parameters[1]);
    }
  }
  return scale;
}

bool isMeasurementOnly(MechanismKind kind) noexcept {
  return kind == MechanismKind::kRegistrationDrift || kind == MechanismKind::kSessionFrames ||
         kind == MechanismKind::kCampaignJointZero;
}

StationAndTool stationAndTool(const Mechanism& frames) noexcept {
  const auto pose = [&](size_t first) {
    const double* p = frames.parameters.data() + first;
    Pose X = Pose::Identity();
    X.linear() = lie::expSO3(Vec3(p[3], p[4], p[5]));
    X.translation() = Vec3(p[0], p[1], p[2]);
    return X;
  };
  return {pose(0), pose(6)};
}

std::vector<double> stationAndToolParameters(const Pose& X_Station, const Pose& X_Tool) {
  std::vector<double> p;
  for (const Pose* X : {&X_Station, &X_Tool}) {
    const Vec3 r = lie::logSO3(X->linear());
    p.insert(p.end(), {X->translation().x(), X->translation().y(), X->translation().z(), r.x(),
                       r.y(), r.z()});
  }
  return p;
}

double legendrePolynomial(int degree, double s) noexcept {
  // (d + 1) P_{d+1} = (2d + 1) s P_d − d P_{d−1}, from P_0 = 1, P_1 = s.
  double previous = 1.0, current = s;
  if (degree == 0) return previous;
  for (int d = 1; d < degree; ++d) {
    const double next = ((2 * d + 1) * s * current - d * previous) / (d + 1);
    previous = current;
    current = next;
  }
  return current;
}

Vec6 registrationDrift(const Mechanism& drift, double seq) noexcept {
  const double first = drift.parameters[0], last = drift.parameters[1];
  // Outside the span it was fitted on, the drift holds its value at the nearer end: a
  // polynomial is not extrapolated.
  const double s = std::clamp(2.0 * (seq - first) / (last - first) - 1.0, -1.0, 1.0);
  Vec6 xi = Vec6::Zero();
  for (int d = 1; d <= drift.order; ++d) {
    xi += legendrePolynomial(d, s) * Eigen::Map<const Vec6>(drift.parameters.data() + 2 + 6 * (d - 1));
  }
  return xi;
}

bool PhysicalModel::has(MechanismKind kind) const noexcept {
  for (const Mechanism& m : mechanisms) {
    if (m.kind == kind) return true;
  }
  return false;
}

uint32_t jointsOutsideCoverage(const PhysicalModel& model, const JointVector& q_rad) noexcept {
  uint32_t outside = 0;
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kTransmissionError && m.joint < q_rad.size() &&
        coverageGate(m.coverage, q_rad(m.joint)) < 1.0) {
      outside |= 1u << m.joint;
    }
  }
  return outside;
}

void selfWeightTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                       const Vec3& gravity_Root, const std::vector<double>& parameters,
                       JointVector& tau_nm) noexcept {
  const int n = chain.dof();
  tau_nm.setZero(n);
  // Suffix sums: joint j carries the weight of links j … n. W = (f, m about the root origin).
  Vec6 W_distal = Vec6::Zero();
  for (int k = n; k >= 1; --k) {
    const Pose& X = ws.X_RootFrame[static_cast<size_t>(k)];
    const double mass = parameters[static_cast<size_t>(4 * (k - 1))];
    const Vec3 h(parameters[static_cast<size_t>(4 * (k - 1) + 1)],
                 parameters[static_cast<size_t>(4 * (k - 1) + 2)],
                 parameters[static_cast<size_t>(4 * (k - 1) + 3)]);
    const Vec3 first_moment_Root = X.linear() * h + mass * X.translation();
    W_distal.head<3>() += mass * gravity_Root;
    W_distal.tail<3>() += first_moment_Root.cross(gravity_Root);
    tau_nm(k - 1) = jointTwistInRoot(chain, ws, k).dot(W_distal);
  }
}

namespace {

/// The joint torques of a payload's weight at the pose in ws, N·m: every joint carries it, its
/// weight at its centre of gravity (root axes).
void payloadTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                                      const Vec3& gravity_Root, const PointPayload& payload,
                                      JointVector& tau_nm) noexcept {
  const int n = chain.dof();
  Vec6 W_Root;
  W_Root.head<3>() = payload.mass_kg * gravity_Root;
  W_Root.tail<3>() =
      (ws.X_RootFrame[static_cast<size_t>(n)] * payload.p_CoGInLast_m).cross(W_Root.head<3>());
  for (int k = 1; k <= n; ++k) tau_nm(k - 1) = jointTwistInRoot(chain, ws, k).dot(W_Root);
}

/// δ = Σ_j g_j δ_j of the profiles' geometry (6(n+1) entries; mechanisms.hpp) at the gates g per
/// joint (a joint without a profile has g 0); false when no profile moves the poses.
bool profileGeometryDelta(const PhysicalModel& model, const std::array<double, kMaxJoints>& gate,
                          std::array<double, 6 * (kMaxJoints + 1)>& delta) noexcept {
  delta.fill(0.0);
  bool corrected = false;
  for (const Mechanism& m : model.mechanisms) {
    const double g = m.kind == MechanismKind::kProfileGeometry ? gate[static_cast<size_t>(m.joint)] : 0.0;
    if (g == 0.0) continue;
    for (size_t i = 0; i < m.parameters.size(); ++i) delta[i] += g * m.parameters[i];
    corrected = true;
  }
  return corrected;
}

}  // namespace

PhysicalConstants physicalConstants(const PhysicalModel& model) noexcept {
  PhysicalConstants constants;
  std::array<double, kMaxJoints> open_gate{};
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kTransmissionError) open_gate[static_cast<size_t>(m.joint)] = 1.0;
  }
  std::array<double, 6 * (kMaxJoints + 1)> delta;
  constants.has_open_geometry = profileGeometryDelta(model, open_gate, delta);
  for (int k = 0; k <= model.chain_Tracker.dof(); ++k) {
    constants.exp_open_geometry[static_cast<size_t>(k)] =
        constants.has_open_geometry ? lie::expSE3(Eigen::Map<const Vec6>(delta.data() + 6 * k))
                                    : Pose::Identity();
  }
  evaluateInitialPoses(model.chain_Tracker, 1.0,
                       constants.has_open_geometry ? &constants.exp_open_geometry : nullptr,
                       constants.initial_open);
  return constants;
}

bool physicalLinkAngles(const PhysicalModel& model, const JointVector& q_rad,
                        const Vec6& wrench_Sensor, double temp_c, ChainWorkspace& ws,
                        JointVector& theta_rad, JointVector& tau_nm,
                        JointVector* profile_slope, const PhysicalConstants* constants,
                        const FixedPointStart* start, const PointPayload* payload) noexcept {
  const KinematicChain& chain = model.chain_Tracker;
  const int n = chain.dof();
  // The wrench's torques: a measured wrench needs the sensor's frame, a payload none.
  const bool has_sensor = payload == nullptr && model.sensor_frame >= 0 &&
                          model.sensor_frame < static_cast<int>(chain.frames().size());
  const bool has_payload = payload != nullptr && payload->mass_kg != 0.0;
  if (q_rad.size() != n || model.compliance_rad_per_nm.size() != n) return false;

  JointVector theta0 = q_rad;
  if (profile_slope) profile_slope->setZero(n);
  FirstPass* const first = start != nullptr ? start->first_pass : nullptr;
  const bool keep = first != nullptr && !first->kept;
  // sin and cos of q serve the profiles and, shifted by θ₀ − q (~1e-4 rad), θ₀'s own.
  JointTrig trig_q;
  if (first != nullptr && first->kept && first->q_rad == q_rad) {
    trig_q = first->trig_q;
  } else {
    jointTrig(q_rad, trig_q);
  }
  Vec6 wrench = wrench_Sensor;
  const Mechanism* self_weight = nullptr;
  // Each profile's gate once: it switches the profile and its share of the geometry.
  std::array<double, kMaxJoints> gate{};
  bool gates_open = true;  // every transmission_error's gate is 1
  for (const Mechanism& m : model.mechanisms) {
    const auto p = [&m](size_t i) { return m.parameters[i]; };
    if (m.kind == MechanismKind::kJointCoupling) {
      theta0(m.joint) += p(0) * q_rad(m.source_joint);
    } else if (m.kind == MechanismKind::kJointZeroDrift) {
      if (std::isfinite(temp_c)) theta0(m.joint) += p(0) * (temp_c - p(1));
    } else if (m.kind == MechanismKind::kTransmissionError) {
      const double q = q_rad(m.joint);
      double gate_slope = 0.0, slope = 0.0;
      gate[static_cast<size_t>(m.joint)] =
          coverageGate(m.coverage, q, profile_slope ? &gate_slope : nullptr);
      gates_open = gates_open && gate[static_cast<size_t>(m.joint)] == 1.0;
      theta0(m.joint) += gatedOffset(m, trig_q.sin(m.joint), trig_q.cos(m.joint),
                                     gate[static_cast<size_t>(m.joint)], gate_slope,
                                     profile_slope ? &slope : nullptr);
      if (profile_slope) (*profile_slope)(m.joint) += slope;
    } else if (m.kind == MechanismKind::kSensorBias) {
      for (int i = 0; i < 6; ++i) wrench(i) -= p(static_cast<size_t>(i));
    } else if (m.kind == MechanismKind::kSelfWeight) {
      self_weight = &m;
    }
  }
  // The initial poses once per call: the thermal scale and the profiles' geometry hold for
  // every pass of the fixed point. With every gate open, from the constants.
  const double link_length_scale = model.linkLengthScale(temp_c);
  InitialPoses initial_here;
  const InitialPoses* initial = &initial_here;
  if (constants != nullptr && gates_open) {
    if (link_length_scale == 1.0) {
      initial = &constants->initial_open;
    } else {
      evaluateInitialPoses(chain, link_length_scale,
                           constants->has_open_geometry ? &constants->exp_open_geometry : nullptr,
                           initial_here);
    }
  } else {
    std::array<double, 6 * (kMaxJoints + 1)> delta;
    const bool corrected = profileGeometryDelta(model, gate, delta);
    evaluateInitialPoses(chain, link_length_scale, corrected ? delta.data() : nullptr,
                         initial_here);
  }
  Jacobian J;
  JointVector tau_self;
  // θ = θ₀ + Δθ(τ): the compliance, plus each joint's torque-deflection mechanism.
  const auto deflect = [&](const JointVector& tau) {
    theta_rad = theta0 + model.compliance_rad_per_nm.cwiseProduct(tau);
    for (const Mechanism& m : model.mechanisms) {
      if (isTorqueDeflection(m.kind)) theta_rad(m.joint) += torqueDeflection(m, tau(m.joint));
    }
  };
  // Without a wrench or self weight every torque is zero and θ = θ₀: no passes. The passes move
  // θ by the deflection only (~1e-3 rad): sin and cos of θ₀ once, then by the angle sum.
  const bool loaded = has_sensor || has_payload || self_weight != nullptr;
  const int passes = !loaded ? 0 : start != nullptr ? start->passes : kFixedPointPasses;
  theta_rad = theta0;
  if (loaded && start != nullptr && start->deflection_rad != nullptr) {
    theta_rad += *start->deflection_rad;
  }
  tau_nm.setZero(n);
  // The frames at θ₀ another evaluation kept, where they are this one's.
  const bool reuse = first != nullptr && first->kept && first->q_rad == q_rad &&
                     first->theta0_rad == theta0 &&
                     std::equal(initial->begin(), initial->begin() + n + 1, first->initial.begin(),
                                [](const Pose& a, const Pose& b) { return a.matrix() == b.matrix(); });
  JointTrig trig0, trig;
  if (reuse) {
    trig0 = first->trig0;
  } else {
    shiftedJointTrig(trig_q, q_rad, theta0 - q_rad, trig0);
  }
  bool at_theta0 = false;      // ws holds the frames at θ₀
  bool kept_frames = false;    // and first keeps them
  const auto evaluate = [&] {
    at_theta0 = theta_rad == theta0;
    if (!at_theta0) {
      shiftedJointTrig(trig0, theta0, theta_rad - theta0, trig);
      forwardKinematics(chain, theta_rad, ws, *initial, &trig);
    } else if (reuse) {
      ws = first->ws;
    } else {
      forwardKinematics(chain, theta_rad, ws, *initial, &trig0);
      if (keep && !kept_frames) {
        first->ws = ws;
        kept_frames = true;
      }
    }
  };
  const auto jacobian = [&] {
    if (at_theta0 && reuse && first->has_J) {
      J = first->J;
      return;
    }
    spatialJacobian(chain, ws, J);
    if (at_theta0 && keep) {
      first->J = J;
      first->has_J = true;
    }
  };
  // The passes, with a payload's torques or without (a loop of its own each, so that the usual
  // one, a measured wrench or none, is compiled as it was).
  const auto runPasses = [&](auto with_payload) {
    for (int pass = 0; pass < passes; ++pass) {
      evaluate();
      tau_nm.setZero(n);
      if (has_sensor) {
        jacobian();
        tau_nm = jointTorques(J, wrenchInRoot(framePose(chain, ws, model.sensor_frame), wrench));
      }
      if constexpr (decltype(with_payload)::value) {
        payloadTorques(chain, ws, model.gravity_Tracker, *payload, tau_nm);
      }
      if (self_weight != nullptr) {
        selfWeightTorques(chain, ws, model.gravity_Tracker, self_weight->parameters, tau_self);
        tau_nm += tau_self;
      }
      deflect(tau_nm);
    }
  };
  if (has_payload) {
    runPasses(std::true_type{});
  } else {
    runPasses(std::false_type{});
  }
  evaluate();
  if (start != nullptr && start->deflection_out_rad != nullptr) {
    *start->deflection_out_rad = theta_rad - theta0;
  }
  if (kept_frames) {
    first->q_rad = q_rad;
    first->theta0_rad = theta0;
    std::copy(initial->begin(), initial->begin() + n + 1, first->initial.begin());
    first->trig_q = trig_q;
    first->trig0 = trig0;
    first->kept = true;
  }
  return true;
}

}  // namespace stepcal
