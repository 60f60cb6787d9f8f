// joint_coupling: joint j's link angle moving with joint i's commanded angle (families.hpp).
#include "families.hpp"
#include "stepcal/common/mechanisms/joint_coupling.hpp"

namespace stepcal::trainer::diagnosis {

void jointCouplingFamilies(const FamilyContext& c) {
  for (int i = 0; i < c.n; ++i) {
    for (int j = 0; j < c.n; ++j) {
      if (i == j || present(c.global, MechanismKind::kJointCoupling, j, i) ||
          !c.wanted(MechanismKind::kJointCoupling, j, i)) {
        continue;
      }
      Family f;
      f.mechanism = blank(MechanismKind::kJointCoupling, c.n, j, i);
      f.free = {mechanism::JointCoupling<double>::kRatio};
      ScaledSource source;
      source.kind = ScaledSource::Kind::kJointAngle;
      source.source_joint = i;
      c.addGlobal(std::move(f), {c.sink.feature(j, std::move(source))}, {1e-4});
    }
  }
}

const KindSignature& jointCouplingSignature() {
  // A coupling follows the source joint's angle.
  static const KindSignature signature{
      MechanismKind::kJointCoupling,
      [](const SignatureContext& c, size_t index, std::vector<EffectSignature>& signatures) {
        const Mechanism& m = c.model.mechanisms[index];
        EffectSignature s =
            linkAngleSignature(c, m, m.joint, c.without(index), SignatureVariable::kJointAngle,
                               m.source_joint, jointAngles(c.fit, m.source_joint));
        curveFromRows(s);
        signatures.push_back(std::move(s));
      }};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
