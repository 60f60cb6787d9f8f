#include "stepcal/common/mechanism_accuracy.hpp"

#include <algorithm>
#include <cmath>

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

/// The gate of joint j's transmission profile at q (0 without one): how much of a
/// profile_geometry of joint j the initial poses hold there.
double profileGate(const PhysicalModel& model, int joint, const JointVector& q_rad) noexcept {
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kTransmissionError && m.joint == joint) {
      return coverageGate(m.coverage, q_rad(joint));
    }
  }
  return 0.0;
}

/// A profile_geometry's share, analytic: its parameter 6k + i moves initial pose k by the
/// right-perturbation g δ (the gate g times it, to first order in exp of the gated sum), so its
/// column is g times the identification matrix's (parameterJacobian) at the call's link angles,
/// the tip point's rows ṗ = v − p̂ ω.
void addProfileGeometryCovariance(const PhysicalModel& model, const Mechanism& m,
                                  const JointVector& q_rad, const ChainWorkspace& at_link_angles,
                                  Mat6& covariance) noexcept {
  const double gate = profileGate(model, m.joint, q_rad);
  const int columns = 6 * (model.chain_Tracker.dof() + 1);
  if (gate == 0.0 || static_cast<int>(m.sigma.size()) != columns) return;
  Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6 * (kMaxJoints + 1)> A(6, columns);
  parameterJacobian(model.chain_Tracker, at_link_angles, A);
  A.topRows<3>() -= lie::hat(tipPose(at_link_angles).translation()) * A.bottomRows<3>();
  for (int c = 0; c < columns; ++c) {
    const double sigma = m.sigma[static_cast<size_t>(c)];
    if (!(sigma > 0.0)) continue;
    const Vec6 g = A.col(c) * (gate * sigma);
    covariance.noalias() += g * g.transpose();
  }
}

/// A transmission_error's share, analytic: its coefficient a_k (b_k) moves joint j's link angle
/// by g(q_j) sin(k q_j) (cos) per unit, b(q_j) the vector of these, so the tip by joint j's twist
/// at the tip point times bᵀ δc (first order: the deflection's change with the pose left out, as
/// a profile_geometry's). Its variance at q_j is ‖Fᵀ b‖² with the coefficients' covariance factor
/// F when the model has it, else Σ_i σ_i² b_i² (independent).
void addTransmissionErrorCovariance(const PhysicalModel& model, const Mechanism& m,
                                    const ProfileCovarianceFactor* factor,
                                    const JointVector& q_rad, const ChainWorkspace& at_link_angles,
                                    Mat6& covariance) noexcept {
  const double q = q_rad(m.joint);
  const double gate = coverageGate(m.coverage, q);
  if (gate == 0.0) return;
  const int order = static_cast<int>(std::min(m.sigma.size(), m.parameters.size())) / 2;
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 2 * kMaxHarmonics, 1> basis(2 * order);
  const double sin_q = std::sin(q), cos_q = std::cos(q);
  double sin_kq = sin_q, cos_kq = cos_q;
  for (int k = 0; k < order; ++k) {
    basis(2 * k) = gate * sin_kq;
    basis(2 * k + 1) = gate * cos_kq;
    const double next_sin = sin_kq * cos_q + cos_kq * sin_q;  // harmonics by recurrence
    cos_kq = cos_kq * cos_q - sin_kq * sin_q;
    sin_kq = next_sin;
  }
  double variance = 0.0;
  if (factor != nullptr && factor->factor.rows() == basis.size()) {
    for (Eigen::Index c = 0; c < factor->factor.cols(); ++c) {
      const double u = factor->factor.col(c).dot(basis);
      variance += u * u;
    }
  } else {
    for (int i = 0; i < 2 * order; ++i) {
      const double sigma = m.sigma[static_cast<size_t>(i)];
      variance += sigma * sigma * basis(i) * basis(i);
    }
  }
  if (!(variance > 0.0)) return;
  const Vec6 twist = jointTwistInRoot(model.chain_Tracker, at_link_angles, m.joint + 1);
  Vec6 column;
  column << twist.head<3>() - tipPose(at_link_angles).translation().cross(twist.tail<3>()),
      twist.tail<3>();
  covariance.noalias() += variance * column * column.transpose();
}

/// The factor of mechanism k among profile_factors (ascending), or null.
const ProfileCovarianceFactor* factorOf(const std::vector<ProfileCovarianceFactor>* profile_factors,
                                        size_t k) noexcept {
  if (profile_factors == nullptr) return nullptr;
  for (const ProfileCovarianceFactor& f : *profile_factors) {
    if (f.mechanism == k) return &f;
  }
  return nullptr;
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
                            const std::vector<ProfileCovarianceFactor>* profile_factors,
                            const ChainWorkspace& at_link_angles, const JointVector& q_rad,
                            const Vec6& wrench_Sensor, double temp_c, const PointPayload* payload,
                            MechanismAccuracyWorkspace& ws, Mat6& covariance) noexcept {
  if (!fits(model, ws)) return false;
  ws.first_pass.kept = false;
  for (size_t k = 0; k < model.mechanisms.size(); ++k) {
    const Mechanism& m = model.mechanisms[k];
    if (!movesTheRobot(m)) continue;
    if (m.kind == MechanismKind::kProfileGeometry) {
      addProfileGeometryCovariance(model, m, q_rad, at_link_angles, covariance);
      continue;
    }
    if (m.kind == MechanismKind::kTransmissionError) {
      addTransmissionErrorCovariance(model, m, factorOf(profile_factors, k), q_rad, at_link_angles,
                                     covariance);
      continue;
    }
    Mechanism& moved = ws.perturbed.mechanisms[k];
    const int count = static_cast<int>(std::min(m.sigma.size(), m.parameters.size()));
    for (int i = 0; i < count; ++i) {
      const double sigma = m.sigma[static_cast<size_t>(i)];
      if (!(sigma > 0.0)) continue;
      const double step = kMechanismStep * sigma;
      moved.parameter(i) = m.parameter(i) + step;
      const Pose X_plus = perturbedTip(constants, q_rad, wrench_Sensor, temp_c, payload, ws);
      moved.parameter(i) = m.parameter(i) - step;
      const Pose X_minus = perturbedTip(constants, q_rad, wrench_Sensor, temp_c, payload, ws);
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
