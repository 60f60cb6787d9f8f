#include "stepcal/common/mechanisms/transmission_error.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

/// Two doubles in one vector register (GCC/Clang vector extension: SSE2 on any x86-64, and the
/// compiler's choice elsewhere).
typedef double Lanes2 __attribute__((vector_size(2 * sizeof(double))));

}  // namespace

// See kinds.hpp. sin(kq), cos(kq) for k = 1 … 4 by doubling (e^{2iq} = e^{iq} e^{iq}, then
// e^{i(2+j)q} = e^{ijq} e^{2iq}), then by rotations e^{i(k+4)q} = e^{ikq} e^{4iq} in two chains
// of two harmonics (k ≡ 1, 2 and 3, 4 mod 4), each chain's sines, cosines, sums and k in one
// vector register rather than four scalar chains (docs/runtime.md, "The chord step and the
// physical model's hot spots").
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
  // a_1, b_1, a_2, b_2, … (TransmissionError's layout), walked in blocks of kStep harmonics.
  const double* p = &view<TransmissionError>(m).sin_rad(1);
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

namespace {

std::vector<std::string> names(int, int order) {
  std::vector<std::string> names;
  for (int k = 1; k <= order; ++k) {
    names.push_back("h" + std::to_string(k) + "_sin_rad");
    names.push_back("h" + std::to_string(k) + "_cos_rad");
  }
  return names;
}

std::string describeSuffix(const Mechanism& m) {
  return " (joint " + std::to_string(m.joint + 1) + ", " + std::to_string(m.order) +
         (m.order == 1 ? " harmonic)" : " harmonics)");
}

}  // namespace

const MechanismTraits& transmissionErrorTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kTransmissionError, "transmission_error"};
    t.uses_joint = true;
    t.has_coverage = true;
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerJoint;
    t.order_fits = [](int order) { return order >= 1 && order <= kMaxHarmonics; };
    t.parameter_names = names;
    t.describe_suffix = describeSuffix;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism

namespace stepcal {

double transmissionOffset(const Mechanism& m, double q_rad, double* derivative) noexcept {
  double gate_slope = 0.0;
  const double gate = coverageGate(m.coverage, q_rad, derivative ? &gate_slope : nullptr);
  return mechanism::gatedOffset(m, std::sin(q_rad), std::cos(q_rad), gate, gate_slope, derivative);
}

}  // namespace stepcal
