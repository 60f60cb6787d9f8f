// self_weight: the links' weight (families.hpp). With the URDF's masses, the compliance of
// every joint their gravity loads enough is identified from the arm's own weight alone (no
// payload needed); without them, the lumped masses act through a compliance the loads
// identified.
#include "families.hpp"
#include "stepcal/common/mechanisms/self_weight.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// The URDF's masses: the compliances of the joints they load.
void withUrdfMasses(const FamilyContext& c) {
  Family f;
  f.mechanism = blank(MechanismKind::kSelfWeight, c.n);
  f.mechanism.parameters = *c.body_masses;
  f.compliance = gravityLoadedJoints(c.global, c.fit, c.start.theta_rad, *c.body_masses);
  c.recipe.masses = *c.body_masses;
  std::vector<Eigen::Index> columns;
  std::vector<double> steps;
  for (const int joint : f.compliance) {
    ScaledSource source;
    source.kind = ScaledSource::Kind::kGravityTorque;
    columns.push_back(c.sink.feature(joint, std::move(source)));
    steps.push_back(1e-6);  // rad/(N·m): a soft joint
  }
  if (columns.empty()) {
    c.s.untestable.push_back({"self_weight", "no joint's gravity torque varies over these rows"});
  } else {
    c.addGlobal(std::move(f), std::move(columns), std::move(steps));
  }
}

// Lumped masses and first moments, fitted under their prior.
void lumpedMasses(const FamilyContext& c) {
  Family f;
  f.mechanism = blank(MechanismKind::kSelfWeight, c.n);
  PhysicalModel with = c.whole;
  with.mechanisms.push_back(f.mechanism);
  const int index = static_cast<int>(with.mechanisms.size()) - 1;
  std::vector<Eigen::Index> columns;
  std::vector<double> steps;
  for (int i : freeParameters(f.mechanism, false)) {
    f.free.push_back(i);
    const Parameter p{index, i, typicalStep(f.mechanism, i)};
    columns.push_back(c.sink.difference(with, p, 0.0));
    steps.push_back(p.step);
  }
  c.addGlobal(std::move(f), std::move(columns), std::move(steps),
              1.0 / (kSelfWeightPriorSigma * kSelfWeightPriorSigma));
}

}  // namespace

void selfWeightFamilies(const FamilyContext& c) {
  const bool compliant = c.global.compliance_rad_per_nm.size() == c.n &&
                         c.global.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (present(c.global, MechanismKind::kSelfWeight, -1, -1) ||
      !c.wanted(MechanismKind::kSelfWeight)) {
  } else if (c.global.gravity_Tracker.norm() == 0.0) {
    c.s.untestable.push_back({"self_weight", "gravity is unknown (campaign.yaml gravity_in_base)"});
  } else if (c.body_masses) {
    withUrdfMasses(c);
  } else if (!compliant) {
    c.s.untestable.push_back({"self_weight",
                              "no link masses in the URDF, and no joint compliance from loads to "
                              "act on lumped ones"});
  } else {
    lumpedMasses(c);
  }
}

const KindFit& selfWeightFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kSelfWeight};
    f.typical_step = [](const Mechanism&, int index) {  // kg; kg·m
      return index % mechanism::SelfWeight<double>::kPerLink == 0 ? 1.0 : 0.5;
    };
    return f;
  }();
  return fit;
}

const KindSignature& selfWeightSignature() {
  // Each compliant joint's link angle against the torque the weight adds to it.
  static const KindSignature signature{
      MechanismKind::kSelfWeight,
      [](const SignatureContext& c, size_t index, std::vector<EffectSignature>& signatures) {
        const Mechanism& m = c.model.mechanisms[index];
        const Evaluation without_it = c.without(index);
        for (const FoundEffect& e : c.diagnosis.effects) {
          if (e.mechanism.kind != MechanismKind::kSelfWeight) continue;
          for (const int j : e.compliance_joints) {
            EffectSignature s =
                linkAngleSignature(c, m, j, without_it, SignatureVariable::kJointTorque, j,
                                   jointTorques(c.with, &without_it, j));
            curveFromRows(s);
            signatures.push_back(std::move(s));
          }
        }
      }};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
