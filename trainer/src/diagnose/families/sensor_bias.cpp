// sensor_bias: a constant offset of the F/T reading (families.hpp).
#include "families.hpp"

namespace stepcal::trainer::diagnosis {

void sensorBiasFamilies(const FamilyContext& c) {
  const bool compliant = c.global.compliance_rad_per_nm.size() == c.n &&
                         c.global.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (present(c.global, MechanismKind::kSensorBias, -1, -1) ||
      !c.wanted(MechanismKind::kSensorBias)) {
    return;
  }
  if (c.global.sensor_frame < 0 || !compliant) {
    c.s.untestable.push_back({"sensor_bias", "the model has no F/T sensor or no compliance"});
    return;
  }
  Family f;
  f.mechanism = blank(MechanismKind::kSensorBias, c.n);
  PhysicalModel with = c.whole;
  with.mechanisms.push_back(f.mechanism);
  const int index = static_cast<int>(with.mechanisms.size()) - 1;
  std::vector<Eigen::Index> columns;
  std::vector<double> steps;
  for (int i = 0; i < 6; ++i) {  // force, then moment
    f.free.push_back(i);
    const Parameter p{index, i, typicalStep(f.mechanism, i)};
    columns.push_back(c.sink.difference(with, p, 0.0));
    steps.push_back(p.step);
  }
  c.addGlobal(std::move(f), std::move(columns), std::move(steps));
}

const KindFit& sensorBiasFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kSensorBias};
    f.typical_step = [](const Mechanism&, int index) { return index < 3 ? 1.0 : 0.1; };  // N; N·m
    return f;
  }();
  return fit;
}

}  // namespace stepcal::trainer::diagnosis
