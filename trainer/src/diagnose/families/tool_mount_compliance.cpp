// tool_mount_compliance: the tool shifting on its mount under the load's force (families.hpp).
// One family, its three compliances (along the mount's x, y, z) as finite-difference columns of
// the whole model (the shift acts on the tip inside the model's evaluation, not on a link
// angle); each is a size of its own, bounded at zero, and an axis the rows do not excite stays
// there.
#include <algorithm>
#include <cmath>

#include "families.hpp"
#include "stepcal/common/mechanisms/sensor_bias.hpp"
#include "stepcal/common/mechanisms/tool_mount_compliance.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

using Mount = mechanism::ToolMountCompliance<double>;

// m/N: a mount 5e6 N/m stiff, which a 55 kg payload's weight shifts by ~0.1 mm.
constexpr double kTypicalMountCompliance = 2e-7;

bool anyLoadedRow(const FitRows& fit) {
  for (const Measurement* row : fit.rows) {
    if (row->has_wrench && row->wrenchOrZero().head<3>().norm() > 0.0) return true;
  }
  return false;
}

}  // namespace

void toolMountComplianceFamilies(const FamilyContext& c) {
  if (present(c.global, MechanismKind::kToolMountCompliance, -1, -1) ||
      !c.wanted(MechanismKind::kToolMountCompliance)) {
    return;
  }
  if (c.global.sensor_frame < 0 || !anyLoadedRow(c.fit)) {
    if (c.scope.only == nullptr) {  // once, in a whole round's screening
      c.s.untestable.push_back(
          {"tool_mount_compliance", "no F/T sensor frame or no loaded row: no force on the mount"});
    }
    return;
  }
  Family f;
  f.mechanism = blank(MechanismKind::kToolMountCompliance, c.n);
  PhysicalModel with = c.whole;
  with.mechanisms.push_back(f.mechanism);
  const int index = static_cast<int>(with.mechanisms.size()) - 1;
  std::vector<Eigen::Index> columns;
  std::vector<double> steps;
  for (int i : {Mount::kAlongX, Mount::kAlongY, Mount::kAlongZ}) {
    f.free.push_back(i);
    const Parameter p{index, i, kTypicalMountCompliance};
    columns.push_back(c.sink.difference(with, p, 0.0));
    steps.push_back(p.step);
  }
  c.addGlobal(std::move(f), std::move(columns), std::move(steps));
}

const KindFit& toolMountComplianceFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kToolMountCompliance};
    f.typical_step = [](const Mechanism&, int) { return kTypicalMountCompliance; };
    // All three are compliances: a mount that moves against the force is no spring.
    f.sign_constrained = [](const Mechanism&) {
      return std::vector<int>{Mount::kAlongX, Mount::kAlongY, Mount::kAlongZ};
    };
    // An axis held at zero is a stiff axis, not a wrong sign: the others are kept.
    f.parts_independent = true;
    return f;
  }();
  return fit;
}

namespace {

// Relative step of a compliance for the residual's direction per unit shift.
constexpr double kSignatureStep = 0.01;

/// Per fit row, the load's force in the mount's axes (the sensor's), N: the measured wrench's
/// less the model's sensor bias.
std::vector<Vec3> rowForces(const SignatureContext& c) {
  Vec6 bias = Vec6::Zero();
  for (const Mechanism& other : c.model.mechanisms) {
    if (other.kind == MechanismKind::kSensorBias) {
      bias = view<mechanism::SensorBias>(other).wrench();
    }
  }
  std::vector<Vec3> forces;
  for (const Measurement* row : c.fit.rows) {
    forces.emplace_back(row->has_wrench ? Vec3((row->wrench_Sensor - bias).head<3>())
                                        : Vec3::Zero());
  }
  return forces;
}

/// The tool's shift along each axis with a compliance against the force along it: the
/// residual's direction per unit shift from a small step of that compliance, divided row by
/// row by the force (a row without one says nothing of the shift and is left out).
void toolMountComplianceSignatures(const SignatureContext& c, size_t index,
                                   std::vector<EffectSignature>& signatures) {
  const Mechanism& m = c.model.mechanisms[index];
  const std::vector<Vec3> forces = rowForces(c);
  double largest = 0.0;
  for (const Vec3& force : forces) largest = std::max(largest, force.cwiseAbs().maxCoeff());
  for (int d = 0; d < 3; ++d) {
    const double compliance = m.parameter(d);
    if (!(compliance > 0.0)) continue;
    PhysicalModel stepped = c.model;
    stepped.mechanisms[index].parameter(d) = compliance * (1.0 + kSignatureStep);
    Eigen::VectorXd direction =
        (c.with.r - evaluate(stepped, c.fit).r) / (kSignatureStep * compliance);
    std::vector<double> x, effect;
    for (size_t i = 0; i < c.fit.rows.size(); ++i) {
      const double force = forces[i](d);
      x.push_back(force);
      effect.push_back(compliance * force);
      auto row = direction.segment(c.fit.start[i], c.fit.equations(i));
      if (std::abs(force) > 1e-6 * largest) {
        row /= force;
      } else {
        row.setZero();
      }
    }
    EffectSignature s;
    s.mechanism = m;
    s.variable = SignatureVariable::kForceAlongMountAxis;
    s.response = SignatureResponse::kToolShift;
    s.direction = d;
    fillPoints(c.fit, c.with.r, direction, x, effect, s);
    curveFromRows(s);
    signatures.push_back(std::move(s));
  }
}

}  // namespace

const KindSignature& toolMountComplianceSignature() {
  static const KindSignature signature{MechanismKind::kToolMountCompliance,
                                       toolMountComplianceSignatures};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
