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

}  // namespace stepcal::trainer::diagnosis
