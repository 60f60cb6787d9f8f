// off_axis_compliance: a joint's frame tilting across its axis under the moment it carries
// (families.hpp). One family per joint, its two compliances as finite-difference columns of the
// whole model (the tilt acts inside the fixed point, on the frames, not on a link angle).
#include <cmath>

#include "families.hpp"
#include "stepcal/common/compliance.hpp"
#include "stepcal/common/mechanisms/off_axis_compliance.hpp"
#include "stepcal/common/mechanisms/sensor_bias.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// rad/(N·m): a bearing 5e6 N·m/rad stiff, which a 55 kg payload at ~1.5 m turns by ~1.6e-4 rad.
constexpr double kTypicalTiltCompliance = 2e-7;

bool anyLoadedRow(const FitRows& fit) {
  for (const Measurement* row : fit.rows) {
    if (row->has_wrench && row->wrenchOrZero().head<3>().norm() > 0.0) return true;
  }
  return false;
}

// A neighbour's axis through a joint's origin and across its axis, well beyond a calibrated
// chain's errors (a few tenths of a millimetre and of a milliradian per frame): 5 mm, 10 mrad.
constexpr double kThroughOrigin_m = 5e-3;
constexpr double kAcross = 1e-2;

/// Whether joint j's tilt is its neighbours' compliance: the axes of joints j − 1 and j + 1 both
/// cross j's axis at right angles at j's origin (a spherical wrist's middle joint), so turning
/// j's frame about the directions across its axis is turning about theirs, about the same point,
/// under the same moments.
bool tiltIsNeighboursCompliance(const KinematicChain& chain, int j) {
  const int n = chain.dof();
  if (j == 0 || j == n - 1) return false;
  ChainWorkspace ws;
  forwardKinematics(chain, JointVector::Zero(n), ws);
  const auto axis = [&](int k) -> Vec3 {
    return ws.X_RootFrame[static_cast<size_t>(k + 1)].linear() *
           chain.joints()[static_cast<size_t>(k)].twist_Local.tail<3>();
  };
  const Vec3 origin = ws.X_RootFrame[static_cast<size_t>(j + 1)].translation();
  for (const int k : {j - 1, j + 1}) {
    const Vec3 to_origin = origin - ws.X_RootFrame[static_cast<size_t>(k + 1)].translation();
    const double off_line_m = (to_origin - to_origin.dot(axis(k)) * axis(k)).norm();
    if (off_line_m > kThroughOrigin_m || std::abs(axis(k).dot(axis(j))) > kAcross) return false;
  }
  return true;
}

}  // namespace

void offAxisComplianceFamilies(const FamilyContext& c) {
  if (c.global.sensor_frame < 0 || !anyLoadedRow(c.fit)) {
    if (c.scope.families && c.scope.only == nullptr) {  // once, in a whole round's screening
      c.s.untestable.push_back(
          {"off_axis_compliance", "no F/T sensor frame or no loaded row: no moment to tilt a joint"});
    }
    return;
  }
  for (int j = 0; j < c.n; ++j) {
    if (present(c.global, MechanismKind::kOffAxisCompliance, j, -1) ||
        !c.wanted(MechanismKind::kOffAxisCompliance, j)) {
      continue;
    }
    if (tiltIsNeighboursCompliance(c.global.chain_Tracker, j)) {
      c.s.untestable.push_back(
          {"off_axis_compliance (joint " + std::to_string(j + 1) + ")",
           "its tilt is joints " + std::to_string(j) + " and " + std::to_string(j + 2) +
               "'s compliance: their axes cross its own at right angles at its origin"});
      continue;
    }
    Family f;
    f.mechanism = blank(MechanismKind::kOffAxisCompliance, c.n, j);
    PhysicalModel with = c.whole;
    with.mechanisms.push_back(f.mechanism);
    const int index = static_cast<int>(with.mechanisms.size()) - 1;
    std::vector<Eigen::Index> columns;
    std::vector<double> steps;
    for (int i : {mechanism::OffAxisCompliance<double>::kTiltU,
                  mechanism::OffAxisCompliance<double>::kTiltV}) {
      f.free.push_back(i);
      const Parameter p{index, i, kTypicalTiltCompliance};
      columns.push_back(c.sink.difference(with, p, 0.0));
      steps.push_back(p.step);
    }
    c.addGlobal(std::move(f), std::move(columns), std::move(steps));
  }
}

const KindFit& offAxisComplianceFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kOffAxisCompliance};
    f.typical_step = [](const Mechanism&, int) { return kTypicalTiltCompliance; };
    // Both are compliances: a frame turning against its moment is no bearing.
    f.sign_constrained = [](const Mechanism&) {
      return std::vector<int>{mechanism::OffAxisCompliance<double>::kTiltU,
                              mechanism::OffAxisCompliance<double>::kTiltV};
    };
    // A direction held at zero is a stiff direction, not a wrong sign: the other is kept.
    f.parts_independent = true;
    return f;
  }();
  return fit;
}

namespace {

// Relative step of a compliance for the residual's direction per unit tilt.
constexpr double kSignatureStep = 0.01;

/// Per fit row, the load's moment about the mechanism's joint origin along its two directions
/// across the axis (u·M, v·M), N·m, at the extended model's deflected frames.
std::vector<Eigen::Vector2d> rowMoments(const SignatureContext& c, const Mechanism& m) {
  const PhysicalModel& model = c.model;
  const KinematicChain& chain = model.chain_Tracker;
  Vec6 bias = Vec6::Zero();
  for (const Mechanism& other : model.mechanisms) {
    if (other.kind == MechanismKind::kSensorBias) bias = view<mechanism::SensorBias>(other).wrench();
  }
  const Vec3 axis = chain.joints()[static_cast<size_t>(m.joint)].twist_Local.tail<3>();
  Vec3 u, v;
  mechanism::tiltDirections(axis, u, v);
  const MeasurementFrames frames = measurementFramesOf(model);
  std::vector<Eigen::Vector2d> moments;
  ChainWorkspace ws;
  JointVector theta, tau;
  for (const Measurement* row : c.fit.rows) {
    const Vec6 wrench = row->wrenchOrZero();
    physicalLinkAngles(model, frames.commanded(*row), wrench, rowTemperature(*row),
                       {ws, theta, tau});
    const Vec6 W_Root = wrenchInRoot(framePose(chain, ws, model.sensor_frame), wrench - bias);
    const Pose& X_RootJoint = ws.X_RootFrame[static_cast<size_t>(m.joint + 1)];
    const Vec3 moment_Joint =
        X_RootJoint.linear().transpose() *
        (W_Root.tail<3>() - X_RootJoint.translation().cross(W_Root.head<3>()));
    moments.emplace_back(u.dot(moment_Joint), v.dot(moment_Joint));
  }
  return moments;
}

/// The tilt about each direction with a compliance against the moment about it: the residual's
/// direction per unit tilt from a small step of that compliance, divided row by row by the
/// moment (a row without one says nothing of the tilt and is left out).
void offAxisComplianceSignatures(const SignatureContext& c, size_t index,
                                 std::vector<EffectSignature>& signatures) {
  const Mechanism& m = c.model.mechanisms[index];
  const std::vector<Eigen::Vector2d> moments = rowMoments(c, m);
  double largest = 0.0;
  for (const Eigen::Vector2d& moment : moments) largest = std::max(largest, moment.cwiseAbs().maxCoeff());
  for (int d = 0; d < 2; ++d) {
    const double compliance = m.parameter(d);
    if (!(compliance > 0.0)) continue;
    PhysicalModel stepped = c.model;
    stepped.mechanisms[index].parameter(d) = compliance * (1.0 + kSignatureStep);
    Eigen::VectorXd direction = (c.with.r - evaluate(stepped, c.fit).r) / (kSignatureStep * compliance);
    std::vector<double> x, effect;
    for (size_t i = 0; i < c.fit.rows.size(); ++i) {
      const double moment = moments[i](d);
      x.push_back(moment);
      effect.push_back(compliance * moment);
      auto row = direction.segment(c.fit.start[i], c.fit.equations(i));
      if (std::abs(moment) > 1e-6 * largest) {
        row /= moment;
      } else {
        row.setZero();
      }
    }
    EffectSignature s;
    s.mechanism = m;
    s.joint = m.joint;
    s.variable = SignatureVariable::kMomentAcrossAxis;
    s.variable_joint = m.joint;
    s.response = SignatureResponse::kFrameTilt;
    s.direction = d;
    fillPoints(c.fit, c.with.r, direction, x, effect, s);
    curveFromRows(s);
    signatures.push_back(std::move(s));
  }
}

}  // namespace

const KindSignature& offAxisComplianceSignature() {
  static const KindSignature signature{MechanismKind::kOffAxisCompliance,
                                       offAxisComplianceSignatures};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
