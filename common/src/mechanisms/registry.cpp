// The registry of mechanism kinds: one line per kind, its traits in its own file.
#include "kinds.hpp"

namespace stepcal {

const std::vector<const MechanismTraits*>& mechanismRegistry() {
  using namespace mechanism;
  static const std::vector<const MechanismTraits*> registry = {
      &backlashTraits(),           &selfWeightTraits(),        &transmissionErrorTraits(),
      &nonlinearStiffnessTraits(), &thermalExpansionTraits(),  &sensorBiasTraits(),
      &jointCouplingTraits(),      &profileGeometryTraits(),   &torsionCurveTraits(),
      &jointZeroDriftTraits(),     &registrationDriftTraits(), &sessionFramesTraits(),
      &campaignJointZeroTraits(),
  };
  return registry;
}

const MechanismTraits* findMechanismTraits(MechanismKind kind) noexcept {
  // Kinds are numbered 1, 2, … in registry order (MechanismKind).
  const std::vector<const MechanismTraits*>& registry = mechanismRegistry();
  const auto index = static_cast<size_t>(kind) - 1;
  return index < registry.size() && registry[index]->kind == kind ? registry[index] : nullptr;
}

}  // namespace stepcal

namespace stepcal::mechanism {

std::string jointSuffix(const Mechanism& m) {
  return " (joint " + std::to_string(m.joint + 1) + ")";
}

}  // namespace stepcal::mechanism
