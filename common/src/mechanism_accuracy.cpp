#include "stepcal/common/mechanism_accuracy.hpp"

#include <algorithm>

#include "stepcal/common/lie.hpp"

namespace stepcal {
namespace {

bool movesTheRobot(const Mechanism& m) noexcept { return !isMeasurementOnly(m.kind); }

/// Whether ws.perturbed holds the model's mechanisms with the same parameter counts.
bool fits(const PhysicalModel& model, const MechanismAccuracyWorkspace& ws) noexcept {
  if (ws.perturbed.mechanisms.size() != model.mechanisms.size()) return false;
  for (size_t k = 0; k < model.mechanisms.size(); ++k) {
    if (ws.perturbed.mechanisms[k].parameters.size() != model.mechanisms[k].parameters.size()) {
      return false;
    }
  }
  return ws.link_rad.size() == model.chain_Tracker.dof();
}

/// The perturbed model's tip at the call's terms.
Pose perturbedTip(const PhysicalConstants* constants, const JointVector& q_rad,
                  const Vec6& wrench_Sensor, double temp_c, const PointPayload* payload,
                  MechanismAccuracyWorkspace& ws) noexcept {
  FixedPointStart start;
  start.first_pass = &ws.first_pass;
  PhysicalEvaluation how;
  how.constants = constants;
  how.start = &start;
  how.payload = payload;
  physicalLinkAngles(ws.perturbed, q_rad, wrench_Sensor, temp_c,
                     {ws.chain, ws.link_rad, ws.torque_nm}, how);
  return tipPose(ws.chain);
}

}  // namespace

MechanismAccuracyWorkspace makeMechanismAccuracyWorkspace(const PhysicalModel& model) {
  MechanismAccuracyWorkspace ws;
  ws.perturbed = model;
  const int n = model.chain_Tracker.dof();
  ws.link_rad.setZero(n);
  ws.torque_nm.setZero(n);
  return ws;
}

bool hasMechanismUncertainty(const PhysicalModel& model) noexcept {
  for (const Mechanism& m : model.mechanisms) {
    if (!movesTheRobot(m)) continue;
    for (double s : m.sigma) {
      if (s > 0.0) return true;
    }
  }
  return false;
}

bool addMechanismCovariance(const PhysicalModel& model, const PhysicalConstants* constants,
                            const JointVector& q_rad, const Vec6& wrench_Sensor, double temp_c,
                            const PointPayload* payload, MechanismAccuracyWorkspace& ws,
                            Mat6& covariance) noexcept {
  if (!fits(model, ws)) return false;
  ws.first_pass.kept = false;
  for (size_t k = 0; k < model.mechanisms.size(); ++k) {
    const Mechanism& m = model.mechanisms[k];
    if (!movesTheRobot(m)) continue;
    const PhysicalConstants* unchanged =
        m.kind == MechanismKind::kProfileGeometry ? nullptr : constants;
    Mechanism& moved = ws.perturbed.mechanisms[k];
    const int count = static_cast<int>(std::min(m.sigma.size(), m.parameters.size()));
    for (int i = 0; i < count; ++i) {
      const double sigma = m.sigma[static_cast<size_t>(i)];
      if (!(sigma > 0.0)) continue;
      const double step = kMechanismStep * sigma;
      moved.parameter(i) = m.parameter(i) + step;
      const Pose X_plus = perturbedTip(unchanged, q_rad, wrench_Sensor, temp_c, payload, ws);
      moved.parameter(i) = m.parameter(i) - step;
      const Pose X_minus = perturbedTip(unchanged, q_rad, wrench_Sensor, temp_c, payload, ws);
      moved.parameter(i) = m.parameter(i);
      Vec6 g;
      g << X_plus.translation() - X_minus.translation(),
          lie::logSO3(X_plus.linear() * X_minus.linear().transpose());
      g /= 2.0 * kMechanismStep;
      covariance.noalias() += g * g.transpose();
    }
  }
  return true;
}

}  // namespace stepcal
