#include "stepcal/common/mechanisms.hpp"

#include <cmath>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal {
namespace {

constexpr MechanismKind kAllKinds[] = {
    MechanismKind::kBacklash,           MechanismKind::kSelfWeight,
    MechanismKind::kTransmissionError,  MechanismKind::kNonlinearStiffness,
    MechanismKind::kThermalExpansion,   MechanismKind::kSensorBias,
    MechanismKind::kJointCoupling};

// The fixed point θ = θ₀ + Δθ(τ(θ)) contracts by ~C·m·g·r ≈ 1e-3 per pass; three passes leave
// an error far below a nanoradian (METHOD.md eq. 24 uses two for compliance alone).
constexpr int kFixedPointPasses = 3;

bool usesJoint(MechanismKind kind) {
  return kind == MechanismKind::kBacklash || kind == MechanismKind::kTransmissionError ||
         kind == MechanismKind::kNonlinearStiffness || kind == MechanismKind::kJointCoupling;
}

}  // namespace

const char* toString(MechanismKind kind) noexcept {
  switch (kind) {
    case MechanismKind::kBacklash: return "backlash";
    case MechanismKind::kSelfWeight: return "self_weight";
    case MechanismKind::kTransmissionError: return "transmission_error";
    case MechanismKind::kNonlinearStiffness: return "nonlinear_stiffness";
    case MechanismKind::kThermalExpansion: return "thermal_expansion";
    case MechanismKind::kSensorBias: return "sensor_bias";
    case MechanismKind::kJointCoupling: return "joint_coupling";
  }
  return "unknown";
}

std::optional<MechanismKind> mechanismKindFromString(const std::string& name) {
  for (MechanismKind kind : kAllKinds) {
    if (name == toString(kind)) return kind;
  }
  return std::nullopt;
}

std::vector<std::string> mechanismParameterNames(MechanismKind kind, int dof) {
  switch (kind) {
    case MechanismKind::kBacklash: return {"lost_motion_rad", "smoothing_torque_nm"};
    case MechanismKind::kSelfWeight: {
      std::vector<std::string> names;
      for (int k = 1; k <= dof; ++k) {
        const std::string link = "link" + std::to_string(k) + "_";
        for (const char* p : {"mass_kg", "first_moment_x_kgm", "first_moment_y_kgm",
                              "first_moment_z_kgm"}) {
          names.push_back(link + p);
        }
      }
      return names;
    }
    case MechanismKind::kTransmissionError: return {"sin_rad", "cos_rad"};
    case MechanismKind::kNonlinearStiffness:
      return {"extra_compliance_rad_per_nm", "saturation_torque_nm"};
    case MechanismKind::kThermalExpansion: return {"expansion_per_k", "reference_temp_c"};
    case MechanismKind::kSensorBias:
      return {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"};
    case MechanismKind::kJointCoupling: return {"ratio"};
  }
  return {};
}

std::string mechanismProblem(const Mechanism& m, int dof) {
  bool known = false;
  for (MechanismKind kind : kAllKinds) known = known || kind == m.kind;
  if (!known) {
    return "mechanism kind " + std::to_string(static_cast<uint32_t>(m.kind)) +
           "; expected 1 to 7 (mechanisms.hpp)";
  }
  const std::string what = toString(m.kind);
  const size_t count = mechanismParameterNames(m.kind, dof).size();
  if (m.parameters.size() != count || m.sigma.size() != count) {
    return what + " has " + std::to_string(m.parameters.size()) + " parameters and " +
           std::to_string(m.sigma.size()) + " sigmas; expected " + std::to_string(count);
  }
  for (size_t i = 0; i < count; ++i) {
    if (!std::isfinite(m.parameters[i]) || !std::isfinite(m.sigma[i]) || m.sigma[i] < 0.0) {
      return what + " parameter " + std::to_string(i) + " = " + std::to_string(m.parameters[i]) +
             " (σ " + std::to_string(m.sigma[i]) + "); expected finite values, σ ≥ 0";
    }
  }
  if (usesJoint(m.kind) != (m.joint >= 0) || m.joint >= dof) {
    return what + " joint index " + std::to_string(m.joint) + "; expected " +
           (usesJoint(m.kind) ? "0 to " + std::to_string(dof - 1) : std::string("-1 (none)"));
  }
  if ((m.kind == MechanismKind::kJointCoupling) !=
          (m.source_joint >= 0 && m.source_joint < dof) ||
      (m.kind == MechanismKind::kJointCoupling && m.source_joint == m.joint) ||
      (m.kind != MechanismKind::kJointCoupling && m.source_joint != -1)) {
    return what + " source joint index " + std::to_string(m.source_joint) +
           "; expected a joint other than the moved one for joint_coupling, else -1";
  }
  if ((m.kind == MechanismKind::kTransmissionError) != (m.harmonic >= 1) ||
      m.harmonic > 64) {
    return what + " harmonic " + std::to_string(m.harmonic) +
           "; expected 1 to 64 for transmission_error, else 0";
  }
  if ((m.kind == MechanismKind::kNonlinearStiffness || m.kind == MechanismKind::kBacklash) &&
      !(m.parameters[1] > 0.0)) {
    return what + " " + mechanismParameterNames(m.kind, dof)[1] + " = " +
           std::to_string(m.parameters[1]) + "; expected > 0";
  }
  return {};
}

std::string describe(const Mechanism& m) {
  std::string s = toString(m.kind);
  switch (m.kind) {
    case MechanismKind::kBacklash:
    case MechanismKind::kNonlinearStiffness:
      return s + " (joint " + std::to_string(m.joint + 1) + ")";
    case MechanismKind::kTransmissionError:
      return s + " (joint " + std::to_string(m.joint + 1) + ", harmonic " +
             std::to_string(m.harmonic) + ")";
    case MechanismKind::kJointCoupling:
      return s + " (joint " + std::to_string(m.source_joint + 1) + " -> joint " +
             std::to_string(m.joint + 1) + ")";
    default: return s;
  }
}

double PhysicalModel::linkLengthScale(double temp_c) const noexcept {
  if (!std::isfinite(temp_c)) return 1.0;
  double scale = 1.0;
  for (const Mechanism& m : mechanisms) {
    if (m.kind == MechanismKind::kThermalExpansion) {
      scale *= 1.0 + m.parameters[0] * (temp_c - m.parameters[1]);
    }
  }
  return scale;
}

bool PhysicalModel::has(MechanismKind kind) const noexcept {
  for (const Mechanism& m : mechanisms) {
    if (m.kind == kind) return true;
  }
  return false;
}

void selfWeightTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                       const Vec3& gravity_Root, const std::vector<double>& parameters,
                       JointVector& tau_nm) noexcept {
  const int n = chain.dof();
  tau_nm.setZero(n);
  // Suffix sums: joint j carries the weight of links j … n. W = (f, m about the root origin).
  Vec6 W_distal = Vec6::Zero();
  for (int k = n; k >= 1; --k) {
    const Pose& X = ws.X_RootFrame[static_cast<size_t>(k)];
    const double mass = parameters[static_cast<size_t>(4 * (k - 1))];
    const Vec3 h(parameters[static_cast<size_t>(4 * (k - 1) + 1)],
                 parameters[static_cast<size_t>(4 * (k - 1) + 2)],
                 parameters[static_cast<size_t>(4 * (k - 1) + 3)]);
    const Vec3 first_moment_Root = X.linear() * h + mass * X.translation();
    W_distal.head<3>() += mass * gravity_Root;
    W_distal.tail<3>() += first_moment_Root.cross(gravity_Root);
    const Vec6& s = chain.joints()[static_cast<size_t>(k - 1)].twist_Local;
    tau_nm(k - 1) = (lie::adjoint(X) * s).dot(W_distal);
  }
}

bool physicalLinkAngles(const PhysicalModel& model, const JointVector& q_rad,
                        const Vec6& wrench_Sensor, double temp_c, ChainWorkspace& ws,
                        JointVector& theta_rad, JointVector& tau_nm) noexcept {
  const KinematicChain& chain = model.chain_Tracker;
  const int n = chain.dof();
  const bool has_sensor =
      model.sensor_frame >= 0 && model.sensor_frame < static_cast<int>(chain.frames().size());
  if (q_rad.size() != n || model.compliance_rad_per_nm.size() != n) return false;

  JointVector theta0 = q_rad;
  Vec6 wrench = wrench_Sensor;
  const Mechanism* self_weight = nullptr;
  for (const Mechanism& m : model.mechanisms) {
    const auto p = [&m](size_t i) { return m.parameters[i]; };
    if (m.kind == MechanismKind::kJointCoupling) {
      theta0(m.joint) += p(0) * q_rad(m.source_joint);
    } else if (m.kind == MechanismKind::kTransmissionError) {
      const double angle = m.harmonic * q_rad(m.joint);
      theta0(m.joint) += p(0) * std::sin(angle) + p(1) * std::cos(angle);
    } else if (m.kind == MechanismKind::kSensorBias) {
      for (int i = 0; i < 6; ++i) wrench(i) -= p(static_cast<size_t>(i));
    } else if (m.kind == MechanismKind::kSelfWeight) {
      self_weight = &m;
    }
  }
  const double scale = model.linkLengthScale(temp_c);
  Jacobian J;
  JointVector tau_self;
  theta_rad = theta0;
  tau_nm.setZero(n);
  for (int pass = 0; pass < kFixedPointPasses; ++pass) {
    forwardKinematics(chain, theta_rad, ws, scale);
    spatialJacobian(chain, ws, J);
    tau_nm.setZero(n);
    if (has_sensor) {
      tau_nm = jointTorques(J, wrenchInRoot(framePose(chain, ws, model.sensor_frame), wrench));
    }
    if (self_weight != nullptr) {
      selfWeightTorques(chain, ws, model.gravity_Tracker, self_weight->parameters, tau_self);
      tau_nm += tau_self;
    }
    theta_rad = theta0 + model.compliance_rad_per_nm.cwiseProduct(tau_nm);
    for (const Mechanism& m : model.mechanisms) {
      const double t = m.joint >= 0 ? tau_nm(m.joint) : 0.0;
      if (m.kind == MechanismKind::kBacklash) {
        theta_rad(m.joint) += m.parameters[0] * std::tanh(t / m.parameters[1]);
      } else if (m.kind == MechanismKind::kNonlinearStiffness) {
        const double c = m.parameters[0], t0 = m.parameters[1];
        theta_rad(m.joint) += c * t * t0 / (t0 + std::abs(t));
      }
    }
  }
  forwardKinematics(chain, theta_rad, ws, scale);
  return true;
}

}  // namespace stepcal
