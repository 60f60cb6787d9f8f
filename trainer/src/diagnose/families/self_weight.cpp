// self_weight: the links' weight (families.hpp). With the URDF's masses, the compliance of
// every joint their gravity loads enough is identified from the arm's own weight alone (no
// payload needed); without them, the lumped masses act through a compliance the loads
// identified.
#include <algorithm>
#include <cmath>
#include <cstdio>

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

using Links = mechanism::SelfWeight<double>;

// Link k's reach, m: a box around its joint's origin (frame k) as wide as the way to the next
// joint's origin (to the tip for the last link) plus a quarter of the arm's longest link (the
// housings around the axes). Its centre of mass lies in it: |h_a| ≤ m L on each axis.
std::vector<double> linkReaches(const KinematicChain& chain) {
  const int n = chain.dof();
  double longest = 0.0;
  for (int k = 1; k <= n; ++k) longest = std::max(longest, chain.initialPose(k).translation().norm());
  std::vector<double> reach;
  for (int k = 1; k <= n; ++k) {
    reach.push_back(chain.initialPose(k).translation().norm() + 0.25 * longest);
  }
  return reach;
}

// Per link its mass ≥ 0, then per link and axis m L ∓ h_a ≥ 0 (a gram, a gram-metre of rounding).
std::vector<PhysicalBound> linkBounds(const Mechanism& m, const KinematicChain& chain) {
  std::vector<PhysicalBound> bounds;
  const std::vector<double> reach = linkReaches(chain);
  const int n = static_cast<int>(m.parameters.size()) / Links::kPerLink;
  for (int k = 1; k <= n; ++k) {
    const int mass = Links::massIndex(k);
    PhysicalBound b;
    b.terms = {{mass, 1.0}};
    b.tolerance = 1e-3;
    b.broken = [k, mass](const Mechanism& x) {
      char text[80];
      std::snprintf(text, sizeof text, "link %d mass %.3g kg", k, x.parameter(mass));
      return std::string(text);
    };
    bounds.push_back(std::move(b));
  }
  for (int k = 1; k <= n; ++k) {
    const int mass = Links::massIndex(k);
    const double L = reach[static_cast<size_t>(k - 1)];
    for (int axis = 0; axis < 3; ++axis) {
      for (const double sign : {1.0, -1.0}) {
        PhysicalBound b;
        b.terms = {{mass, L}, {mass + 1 + axis, -sign}};
        b.tolerance = 1e-3;
        b.broken = [k, mass, axis, L](const Mechanism& x) {
          char text[160];
          if (x.parameter(mass) <= 0.0) {  // no centre of mass: the mass is what breaks
            std::snprintf(text, sizeof text, "link %d mass %.3g kg with a first moment of %.3g kg·m",
                          k, x.parameter(mass), x.parameter(mass + 1 + axis));
            return std::string(text);
          }
          std::snprintf(text, sizeof text,
                        "link %d centre of mass %.3g m along %c of its frame (%.3g kg·m over "
                        "%.3g kg), beyond its reach %.2g m",
                        k, x.parameter(mass + 1 + axis) / x.parameter(mass),
                        "xyz"[axis], x.parameter(mass + 1 + axis), x.parameter(mass), L);
          return std::string(text);
        };
        bounds.push_back(std::move(b));
      }
    }
  }
  return bounds;
}

// Each link's mass at least zero and at least what its first moment needs within its reach.
void linksFeasible(Mechanism& m, const KinematicChain& chain) {
  const std::vector<double> reach = linkReaches(chain);
  const int n = static_cast<int>(m.parameters.size()) / Links::kPerLink;
  for (int k = 1; k <= n; ++k) {
    double& mass = m.parameter(Links::massIndex(k));
    mass = std::max(mass, 0.0);
    for (int axis = 0; axis < 3; ++axis) {
      mass = std::max(mass, std::abs(m.parameter(Links::massIndex(k) + 1 + axis)) /
                                reach[static_cast<size_t>(k - 1)]);
    }
  }
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
    f.bounds = linkBounds;
    f.make_feasible = linksFeasible;
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
