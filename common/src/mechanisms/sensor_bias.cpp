#include "stepcal/common/mechanisms/sensor_bias.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {

const MechanismTraits& sensorBiasTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kSensorBias, "sensor_bias"};
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerModel;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = [](int, int) -> std::vector<std::string> {
      return {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"};
    };
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
