#include "stepcal/common/mechanisms/thermal_expansion.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {

const MechanismTraits& thermalExpansionTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kThermalExpansion, "thermal_expansion"};
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerModel;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = [](int, int) -> std::vector<std::string> {
      return {"expansion_per_k", "reference_temp_c"};
    };
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
