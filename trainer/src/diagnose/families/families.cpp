// The family builders' registry and what they share (families.hpp).
#include "families.hpp"

#include <algorithm>
#include <cmath>

namespace stepcal::trainer::diagnosis {

const std::vector<FamilyBuilder>& familyBuilders() {
  static const std::vector<FamilyBuilder> builders = {
      torqueDeflectionFamilies, jointCouplingFamilies,     selfWeightFamilies,
      sensorBiasFamilies,       thermalExpansionFamilies,  registrationDriftFamilies,
      jointZeroDriftFamilies,   campaignJointZeroFamilies, transmissionErrorFamilies,
      offAxisComplianceFamilies, toolMountComplianceFamilies,
  };
  return builders;
}

const KindFit* findKindFit(MechanismKind kind) {
  static const std::vector<const KindFit*> fits = {
      &backlashFit(),         &nonlinearStiffnessFit(), &torsionCurveFit(),
      &selfWeightFit(),       &sensorBiasFit(),         &thermalExpansionFit(),
      &registrationDriftFit(), &jointZeroDriftFit(),    &sessionFramesFit(),
      &offAxisComplianceFit(),  &toolMountComplianceFit(),
  };
  for (const KindFit* fit : fits) {
    if (fit->kind == kind) return fit;
  }
  return nullptr;
}

const KindSignature* findKindSignature(MechanismKind kind) {
  static const std::vector<const KindSignature*> signatures = {
      &transmissionErrorSignature(), &backlashSignature(),        &nonlinearStiffnessSignature(),
      &torsionCurveSignature(),      &jointCouplingSignature(),   &selfWeightSignature(),
      &thermalExpansionSignature(),  &jointZeroDriftSignature(),   &offAxisComplianceSignature(),
      &toolMountComplianceSignature(),
  };
  for (const KindSignature* signature : signatures) {
    if (signature->kind == kind) return signature;
  }
  return nullptr;
}

bool FamilyContext::wanted(MechanismKind kind, int joint, int source) const {
  return scope.families &&
         (scope.only == nullptr || (scope.only->kind == kind && scope.only->joint == joint &&
                                    scope.only->source_joint == source));
}

void FamilyContext::addGlobal(Family family, std::vector<Eigen::Index> columns,
                              std::vector<double> steps, double column_ridge) const {
  for (Eigen::Index c : columns) sink.ridge[static_cast<size_t>(c)] = column_ridge;
  family.columns = std::move(columns);
  family.steps = std::move(steps);
  family.untestable_before = s.untestable.size();
  family.bounds = physicalBounds(family.mechanism, global.chain_Tracker);
  s.families.push_back(std::move(family));
}

Mechanism blank(MechanismKind kind, int dof, int joint, int source, int order) {
  Mechanism m;
  m.kind = kind;
  m.joint = joint;
  m.source_joint = source;
  m.order = order;
  m.parameters.assign(mechanismParameterNames(kind, dof, order).size(), 0.0);
  m.sigma.assign(m.parameters.size(), 0.0);
  return m;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double stdOf(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  double sum = 0.0, sum2 = 0.0;
  for (double x : v) {
    sum += x;
    sum2 += x * x;
  }
  const double mean = sum / static_cast<double>(v.size());
  return std::sqrt(std::max(0.0, sum2 / static_cast<double>(v.size()) - mean * mean));
}

bool present(const PhysicalModel& model, MechanismKind kind, int joint, int source) {
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind != kind) continue;
    const bool one_per_model =
        kind == MechanismKind::kSelfWeight || kind == MechanismKind::kSensorBias ||
        kind == MechanismKind::kThermalExpansion || kind == MechanismKind::kRegistrationDrift;
    if (one_per_model || (m.joint == joint && m.source_joint == source)) return true;
  }
  return false;
}

RowTemperatures rowTemperatures(const FitRows& fit) {
  std::vector<double> temps;
  for (const Measurement* row : fit.rows) {
    if (row->temp_c) temps.push_back(*row->temp_c);
  }
  RowTemperatures t;
  double mean_temp = 0.0;
  for (double temp : temps) mean_temp += temp;
  t.mean_c = temps.empty() ? 0.0 : mean_temp / static_cast<double>(temps.size());
  t.spread_c = stdOf(temps);
  t.few = temps.size() * 2 < fit.rows.size();
  return t;
}

}  // namespace stepcal::trainer::diagnosis
