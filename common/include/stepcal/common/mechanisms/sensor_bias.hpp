// sensor_bias: a constant offset of the F/T reading.
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [f N (3), m N·m (3)], sensor_link axes: the reading is the wrench plus this.
template <class Double>
struct SensorBias {
  static constexpr MechanismKind kKind = MechanismKind::kSensorBias;
  Double* p;
  int order;
  /// Component i = 0 … 5 of the bias wrench (force x, y, z, then moment x, y, z).
  Double& wrench(int i) const noexcept { return p[i]; }
  Eigen::Map<const Vec6> wrench() const noexcept { return Eigen::Map<const Vec6>(p); }
};

}  // namespace stepcal::mechanism
