// thermal_expansion: the links' lengths with temperature (families.hpp).
#include <cstdio>

#include "families.hpp"
#include "stepcal/common/mechanisms/thermal_expansion.hpp"

namespace stepcal::trainer::diagnosis {

void thermalExpansionFamilies(const FamilyContext& c) {
  if (present(c.global, MechanismKind::kThermalExpansion, -1, -1) ||
      !c.wanted(MechanismKind::kThermalExpansion)) {
    return;
  }
  const RowTemperatures temps = rowTemperatures(c.fit);
  if (temps.few) {
    c.s.untestable.push_back({"thermal_expansion", "fewer than half the fit rows have temp_c"});
  } else if (temps.spread_c < 0.5) {
    char reason[120];
    std::snprintf(reason, sizeof reason,
                  "temp_c varies by less than 0.5 °C (standard deviation %.2f °C)", temps.spread_c);
    c.s.untestable.push_back({"thermal_expansion", reason});
  } else {
    using Expansion = mechanism::ThermalExpansion<double>;
    Family f;
    f.mechanism = blank(MechanismKind::kThermalExpansion, c.n);
    view<mechanism::ThermalExpansion>(f.mechanism).referenceTemp_c() = temps.mean_c;
    f.free = {Expansion::kExpansion};
    PhysicalModel with = c.whole;
    with.mechanisms.push_back(f.mechanism);
    const Parameter p{static_cast<int>(with.mechanisms.size()) - 1, Expansion::kExpansion, 1e-5};
    c.addGlobal(std::move(f), {c.sink.difference(with, p, 0.0)}, {p.step});
  }
}

const KindFit& thermalExpansionFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kThermalExpansion};
    f.typical_step = [](const Mechanism&, int) { return 1e-5; };
    // The reference temperature is chosen: the rows' mean.
    f.free_parameters = [](const Mechanism&) {
      return std::vector<int>{mechanism::ThermalExpansion<double>::kExpansion};
    };
    return f;
  }();
  return fit;
}

namespace {

/// The length scale against the rows' temperatures. The tip's motion per unit of length scale:
/// lowering T_ref by Δ raises the scale by α Δ at every row, and the residual (measured −
/// modelled) falls by that motion times α Δ.
void thermalExpansionSignatures(const SignatureContext& c, size_t index,
                                std::vector<EffectSignature>& signatures) {
  const Mechanism& m = c.model.mechanisms[index];
  const double alpha = view<mechanism::ThermalExpansion>(m).expansion_per_k();
  if (!(alpha != 0.0)) return;
  constexpr double kScaleStep = 1e-6;
  PhysicalModel shifted = c.model;
  view<mechanism::ThermalExpansion>(shifted.mechanisms[index]).referenceTemp_c() -=
      kScaleStep / alpha;
  const Eigen::VectorXd direction = (c.with.r - residuals(shifted, c.fit)) / kScaleStep;
  EffectSignature s;
  s.mechanism = m;
  s.variable = SignatureVariable::kTemperature;
  s.response = SignatureResponse::kLengthScale;
  std::vector<double> x, effect;
  for (const Measurement* row : c.fit.rows) {
    x.push_back(rowTemperature(*row));
    effect.push_back(c.model.linkLengthScale(x.back()) - 1.0);
  }
  fillPoints(c.fit, c.with.r, direction, x, effect, s);
  curveFromRows(s);
  signatures.push_back(std::move(s));
}

}  // namespace

const KindSignature& thermalExpansionSignature() {
  static const KindSignature signature{MechanismKind::kThermalExpansion,
                                       thermalExpansionSignatures};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
