// joint_zero_drift: a joint's zero moving with temperature (families.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "../confounds.hpp"
#include "families.hpp"
#include "stepcal/common/mechanisms/joint_zero_drift.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// A joint's zero drift with temperature is tried where temp_c varies by more than a sensor's
// step (0.1 °C): the coefficient is free, so any spread the sensor resolves can show it.
constexpr double kMinZeroDriftSpreadC = 0.1;

}  // namespace

void jointZeroDriftFamilies(const FamilyContext& c) {
  const RowTemperatures temps = rowTemperatures(c.fit);
  // What moves with the temperature: each re-makes the zero drift as a function of itself
  // (confounds.hpp). Not the time order: a zero that follows the time rather than the
  // temperature is still that joint's zero, the robot's either way (a load block, a grid's loop
  // or a torque is another cause).
  std::vector<Confounder> moving;
  if (!temps.few && temps.spread_c >= kMinZeroDriftSpreadC) {
    moving = confoundersOf(confounderVariables(c.fit, c.start), "temp_c");
    moving.erase(std::remove_if(moving.begin(), moving.end(),
                                [](const Confounder& m) { return m.variable->name == "seq"; }),
                 moving.end());
  }
  for (int j = 0; j < c.n; ++j) {
    if (present(c.global, MechanismKind::kJointZeroDrift, j, -1) ||
        !c.wanted(MechanismKind::kJointZeroDrift, j)) {
      continue;
    }
    const std::string name = "joint_zero_drift (joint " + std::to_string(j + 1) + ")";
    if (temps.few) {
      c.s.untestable.push_back({name, "fewer than half the fit rows have temp_c"});
      continue;
    }
    if (temps.spread_c < kMinZeroDriftSpreadC) {
      char reason[120];
      std::snprintf(reason, sizeof reason,
                    "temp_c varies by less than %.2f °C (standard deviation %.3f °C)",
                    kMinZeroDriftSpreadC, temps.spread_c);
      c.s.untestable.push_back({name, reason});
      continue;
    }
    Family f;
    f.mechanism = blank(MechanismKind::kJointZeroDrift, c.n, j);
    view<mechanism::JointZeroDrift>(f.mechanism).referenceTemp_c() = temps.mean_c;
    f.free = {mechanism::JointZeroDrift<double>::kDriftRate};
    f.driver = "temp_c";
    for (const Confounder& m : moving) {
      Family::Confound confound{m.variable->name, m.r, {}};
      for (int k = 0; k < m.variable->functions(); ++k) {
        ScaledSource nuisance;
        nuisance.kind = ScaledSource::Kind::kConfounder;
        nuisance.variable = m.variable;
        nuisance.function = k;
        confound.columns.push_back(c.sink.feature(j, std::move(nuisance)));
      }
      f.confounds.push_back(std::move(confound));
    }
    ScaledSource source;
    source.kind = ScaledSource::Kind::kTemperature;
    source.reference_c = temps.mean_c;
    // A step that moves the joint by ~1e-4 rad over the rows' spread of temperature.
    c.addGlobal(std::move(f), {c.sink.feature(j, std::move(source))}, {1e-4 / temps.spread_c});
  }
}

const KindFit& jointZeroDriftFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kJointZeroDrift};
    f.typical_step = [](const Mechanism&, int) { return 1e-5; };  // rad/K
    // The reference temperature is chosen: the rows' mean.
    f.free_parameters = [](const Mechanism&) {
      return std::vector<int>{mechanism::JointZeroDrift<double>::kDriftRate};
    };
    return f;
  }();
  return fit;
}

namespace {

/// A joint's zero follows the temperature (rows without one: no drift, no point).
void jointZeroDriftSignatures(const SignatureContext& c, size_t index,
                              std::vector<EffectSignature>& signatures) {
  const Mechanism& m = c.model.mechanisms[index];
  std::vector<double> temps;
  for (const Measurement* row : c.fit.rows) temps.push_back(rowTemperature(*row));
  EffectSignature s = linkAngleSignature(c, m, m.joint, c.without(index),
                                         SignatureVariable::kTemperature, -1, temps);
  for (size_t i = s.x.size(); i-- > 0;) {
    if (std::isfinite(s.x[i])) continue;
    s.x.erase(s.x.begin() + static_cast<std::ptrdiff_t>(i));
    s.effect.erase(s.effect.begin() + static_cast<std::ptrdiff_t>(i));
    s.partial_residual.erase(s.partial_residual.begin() + static_cast<std::ptrdiff_t>(i));
    ++s.rows_left_out;
  }
  curveFromRows(s);
  signatures.push_back(std::move(s));
}

}  // namespace

const KindSignature& jointZeroDriftSignature() {
  static const KindSignature signature{MechanismKind::kJointZeroDrift, jointZeroDriftSignatures};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
