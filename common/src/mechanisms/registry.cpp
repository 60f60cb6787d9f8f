// The registry of mechanism kinds: one line per kind, its traits in its own file.
#include "kinds.hpp"

// A kind's line: its traits' function (defined in its own file) and its place in the table, at
// the index of its MechanismKind value less one.
namespace stepcal::mechanism {
const MechanismTraits& backlashTraits();            // 1
const MechanismTraits& selfWeightTraits();          // 2
const MechanismTraits& transmissionErrorTraits();   // 3
const MechanismTraits& nonlinearStiffnessTraits();  // 4
const MechanismTraits& thermalExpansionTraits();    // 5
const MechanismTraits& sensorBiasTraits();          // 6
const MechanismTraits& jointCouplingTraits();       // 7
const MechanismTraits& profileGeometryTraits();     // 8
const MechanismTraits& torsionCurveTraits();        // 9
const MechanismTraits& jointZeroDriftTraits();      // 10
const MechanismTraits& registrationDriftTraits();   // 11
const MechanismTraits& sessionFramesTraits();       // 12
const MechanismTraits& campaignJointZeroTraits();   // 13
const MechanismTraits& offAxisComplianceTraits();   // 14
const MechanismTraits& toolMountComplianceTraits();  // 15
}  // namespace stepcal::mechanism

namespace stepcal {

const std::vector<const MechanismTraits*>& mechanismRegistry() {
  using namespace mechanism;
  static const std::vector<const MechanismTraits*> registry = {
      &backlashTraits(),          &selfWeightTraits(),         &transmissionErrorTraits(),
      &nonlinearStiffnessTraits(), &thermalExpansionTraits(),  &sensorBiasTraits(),
      &jointCouplingTraits(),     &profileGeometryTraits(),    &torsionCurveTraits(),
      &jointZeroDriftTraits(),    &registrationDriftTraits(),  &sessionFramesTraits(),
      &campaignJointZeroTraits(), &offAxisComplianceTraits(),  &toolMountComplianceTraits(),
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
