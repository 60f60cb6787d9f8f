#include "stepcal/twin/effects.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <utility>

#include "stepcal/common/error.hpp"

namespace stepcal::twin {

JointCompliance::JointCompliance(std::vector<double> stiffness_nm_per_rad)
    : stiffness_nm_per_rad_(std::move(stiffness_nm_per_rad)) {
  for (size_t i = 0; i < stiffness_nm_per_rad_.size(); ++i) {
    const double k = stiffness_nm_per_rad_[i];
    if (!(std::isfinite(k) && k > 0.0)) {
      throw InputError("stiffness of joint " + std::to_string(i + 1) + " is " +
                       std::to_string(k) +
                       " N·m/rad; expected a finite value > 0 (hint: the paper's IRB4400 values "
                       "are 74226 … 633590 N·m/rad)");
    }
  }
}

void JointCompliance::apply(const JointVector& /*q_cmd_rad*/, const JointVector& tau_nm,
                            JointVector& theta_rad) const {
  STEPCAL_INVARIANT(tau_nm.size() == static_cast<Eigen::Index>(stiffness_nm_per_rad_.size()) &&
                        theta_rad.size() == tau_nm.size(),
                    "compliance: one stiffness per joint");
  for (Eigen::Index i = 0; i < tau_nm.size(); ++i) {
    theta_rad(i) += tau_nm(i) / stiffness_nm_per_rad_[static_cast<size_t>(i)];
  }
}

nlohmann::json JointCompliance::toJson() const {
  return {{"name", name()}, {"stiffness_nm_per_rad", stiffness_nm_per_rad_}};
}

namespace {

/// Names EffectSet::add knows, in the order of its error message.
constexpr const char* kKnownEffects[] = {
    "joint_compliance", "backlash",    "transmission_error", "nonlinear_stiffness",
    "joint_coupling",   "self_weight", "thermal_expansion",  "sensor_bias", "torsion_curve",
    "joint_zero_drift", "registration_drift", "angle_dependent_stiffness", "bearing_tilt",
    "tool_mount_compliance"};

std::string show(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

std::string show(const Vec3& v) {
  return "[" + show(v.x()) + ", " + show(v.y()) + ", " + show(v.z()) + "]";
}

/// Throws unless joint is 1 … dof.
void requireJoint(const std::string& effect, const char* key, int joint, int dof) {
  if (joint < 1 || joint > dof) {
    throw InputError(effect + "." + key + " = " + std::to_string(joint) + "; expected a joint 1 … " +
                     std::to_string(dof));
  }
}

/// Throws unless lower < |value| < upper (lower 0 allows 0 only when allow_zero).
void requireMagnitude(const std::string& effect, const char* key, double value, double upper,
                      bool allow_zero, const char* unit) {
  const bool ok = std::isfinite(value) && std::abs(value) < upper && (allow_zero || value > 0.0);
  if (!ok) {
    throw InputError(effect + "." + key + " = " + show(value) + " " + unit +
                     "; expected a finite value " + (allow_zero ? "with |value| < " : "in (0, ") +
                     show(upper) + (allow_zero ? "" : ")") + " " + unit);
  }
}

/// Throws unless v is finite with |v| < upper.
void requireVectorBelow(const std::string& key, const Vec3& v, double upper, const char* unit) {
  if (!(v.allFinite() && v.norm() < upper)) {
    throw InputError(key + " = " + show(v) + " " + unit + "; expected finite values with norm < " +
                     show(upper) + " " + unit);
  }
}

/// Three numbers [x, y, z] from j[key].
Vec3 vec3FromJson(const nlohmann::json& j, const std::string& effect, const char* key) {
  const nlohmann::json& a = j.at(key);
  if (!a.is_array() || a.size() != 3) {
    throw InputError(effect + "." + key + " = " + a.dump() + "; expected three numbers [x, y, z]");
  }
  return Vec3(a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
}

nlohmann::json vec3ToJson(const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

}  // namespace

Backlash::Backlash(int joint, double lost_motion_rad, int dof)
    : joint_(joint), lost_motion_rad_(lost_motion_rad) {
  requireJoint(name(), "joint", joint, dof);
  requireMagnitude(name(), "lost_motion_rad", lost_motion_rad, 0.01, false, "rad");
}

void Backlash::apply(const JointVector&, const JointVector& tau_nm, JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  theta_rad(j) += lost_motion_rad_ * std::tanh(tau_nm(j) / kSmoothingTorque_nm);
}

nlohmann::json Backlash::toJson() const {
  return {{"name", name()}, {"joint", joint_}, {"lost_motion_rad", lost_motion_rad_}};
}

TransmissionError::TransmissionError(int joint, int harmonic, double sin_rad, double cos_rad,
                                     int dof)
    : joint_(joint), harmonic_(harmonic), sin_rad_(sin_rad), cos_rad_(cos_rad) {
  requireJoint(name(), "joint", joint, dof);
  if (harmonic < 1 || harmonic > 64) {
    throw InputError(name() + ".harmonic = " + std::to_string(harmonic) + "; expected 1 … 64");
  }
  requireMagnitude(name(), "sin_rad", sin_rad, 0.01, true, "rad");
  requireMagnitude(name(), "cos_rad", cos_rad, 0.01, true, "rad");
}

void TransmissionError::apply(const JointVector& q_cmd_rad, const JointVector&,
                              JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  const double angle = harmonic_ * q_cmd_rad(j);
  theta_rad(j) += sin_rad_ * std::sin(angle) + cos_rad_ * std::cos(angle);
}

nlohmann::json TransmissionError::toJson() const {
  return {{"name", name()}, {"joint", joint_}, {"harmonic", harmonic_},
          {"sin_rad", sin_rad_}, {"cos_rad", cos_rad_}};
}

NonlinearStiffness::NonlinearStiffness(int joint, double extra_compliance_rad_per_nm,
                                       double saturation_torque_nm, int dof)
    : joint_(joint),
      extra_compliance_rad_per_nm_(extra_compliance_rad_per_nm),
      saturation_torque_nm_(saturation_torque_nm) {
  requireJoint(name(), "joint", joint, dof);
  requireMagnitude(name(), "extra_compliance_rad_per_nm", extra_compliance_rad_per_nm, 1e-3,
                   false, "rad/(N·m)");
  requireMagnitude(name(), "saturation_torque_nm", saturation_torque_nm, 1e9, false, "N·m");
}

void NonlinearStiffness::apply(const JointVector&, const JointVector& tau_nm,
                               JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  const double tau = tau_nm(j);
  theta_rad(j) += extra_compliance_rad_per_nm_ * tau * saturation_torque_nm_ /
                  (saturation_torque_nm_ + std::abs(tau));
}

nlohmann::json NonlinearStiffness::toJson() const {
  return {{"name", name()},
          {"joint", joint_},
          {"extra_compliance_rad_per_nm", extra_compliance_rad_per_nm_},
          {"saturation_torque_nm", saturation_torque_nm_}};
}

TorsionCurve::TorsionCurve(int joint, double lost_motion_rad,
                           std::vector<double> extra_compliance_rad_per_nm,
                           std::vector<double> segment_end_torque_nm, int dof)
    : joint_(joint),
      lost_motion_rad_(lost_motion_rad),
      extra_compliance_rad_per_nm_(std::move(extra_compliance_rad_per_nm)),
      segment_end_torque_nm_(std::move(segment_end_torque_nm)) {
  requireJoint(name(), "joint", joint, dof);
  requireMagnitude(name(), "lost_motion_rad", lost_motion_rad, 0.01, true, "rad");
  if (lost_motion_rad < 0.0) {
    throw InputError(name() + ".lost_motion_rad = " + show(lost_motion_rad) +
                     " rad; expected a lost motion ≥ 0");
  }
  const size_t segments = extra_compliance_rad_per_nm_.size();
  if (segments < 1 || segments > 2 || segment_end_torque_nm_.size() != segments) {
    throw InputError(name() + " has " + std::to_string(segments) + " extra compliances and " +
                     std::to_string(segment_end_torque_nm_.size()) +
                     " segment end torques; expected one or two of each (K1 up to T1, K2 up to T2)");
  }
  double previous = 0.0;
  for (size_t s = 0; s < segments; ++s) {
    const std::string at = "[" + std::to_string(s) + "]";
    requireMagnitude(name(), ("extra_compliance_rad_per_nm" + at).c_str(),
                     extra_compliance_rad_per_nm_[s], 1e-3, true, "rad/(N·m)");
    if (extra_compliance_rad_per_nm_[s] < 0.0) {
      throw InputError(name() + ".extra_compliance_rad_per_nm" + at + " = " +
                       show(extra_compliance_rad_per_nm_[s]) +
                       " rad/(N·m); expected ≥ 0 (a segment softer than the joint above T2)");
    }
    const double end = segment_end_torque_nm_[s];
    if (!(std::isfinite(end) && end > previous)) {
      throw InputError(name() + ".segment_end_torque_nm" + at + " = " + show(end) +
                       " N·m; expected a finite torque above " + show(previous) + " N·m");
    }
    previous = end;
  }
}

void TorsionCurve::apply(const JointVector&, const JointVector& tau_nm,
                         JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  const double tau = tau_nm(j), magnitude = std::abs(tau);
  double extra = 0.0, from = 0.0;
  for (size_t s = 0; s < extra_compliance_rad_per_nm_.size(); ++s) {
    const double to = segment_end_torque_nm_[s];
    extra += extra_compliance_rad_per_nm_[s] * std::clamp(magnitude - from, 0.0, to - from);
    from = to;
  }
  theta_rad(j) += lost_motion_rad_ * std::tanh(tau / kSmoothingTorque_nm) + std::copysign(extra, tau);
}

nlohmann::json TorsionCurve::toJson() const {
  return {{"name", name()},
          {"joint", joint_},
          {"lost_motion_rad", lost_motion_rad_},
          {"extra_compliance_rad_per_nm", extra_compliance_rad_per_nm_},
          {"segment_end_torque_nm", segment_end_torque_nm_}};
}

AngleDependentStiffness::AngleDependentStiffness(int joint, int harmonic, double amplitude,
                                                 double phase_rad, double stiffness_nm_per_rad,
                                                 int dof)
    : joint_(joint),
      harmonic_(harmonic),
      amplitude_(amplitude),
      phase_rad_(phase_rad),
      stiffness_nm_per_rad_(stiffness_nm_per_rad) {
  requireJoint(name(), "joint", joint, dof);
  if (harmonic < 1 || harmonic > 64) {
    throw InputError(name() + ".harmonic = " + std::to_string(harmonic) +
                     "; expected 1 … 64 (periods per revolution of the joint)");
  }
  if (!(std::isfinite(amplitude) && amplitude > 0.0 && amplitude < 1.0)) {
    throw InputError(name() + ".amplitude = " + show(amplitude) +
                     "; expected a finite value in (0, 1) (the compliance's relative variation)");
  }
  if (!std::isfinite(phase_rad)) {
    throw InputError(name() + ".phase_rad = " + show(phase_rad) + " rad; expected a finite angle");
  }
  if (!(std::isfinite(stiffness_nm_per_rad) && stiffness_nm_per_rad > 0.0)) {
    throw InputError(name() + " of joint " + std::to_string(joint) + ": its stiffness is " +
                     show(stiffness_nm_per_rad) + " N·m/rad; expected a finite value > 0");
  }
}

void AngleDependentStiffness::apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
                                    JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  theta_rad(j) += amplitude_ * std::cos(harmonic_ * q_cmd_rad(j) + phase_rad_) * tau_nm(j) /
                  stiffness_nm_per_rad_;
}

nlohmann::json AngleDependentStiffness::toJson() const {
  return {{"name", name()},           {"joint", joint_},        {"harmonic", harmonic_},
          {"amplitude", amplitude_}, {"phase_rad", phase_rad_}};
}

BearingTilt::BearingTilt(int joint, double compliance_rad_per_nm, int dof)
    : joint_(joint), compliance_rad_per_nm_(compliance_rad_per_nm) {
  requireJoint(name(), "joint", joint, dof);
  if (!(std::isfinite(compliance_rad_per_nm) && compliance_rad_per_nm >= 0.0 &&
        compliance_rad_per_nm < 1e-5)) {
    throw InputError(name() + ".compliance_rad_per_nm = " + show(compliance_rad_per_nm) +
                     " rad/(N·m); expected a finite value in [0, 1e-05) rad/(N·m) (a heavy "
                     "robot's bearing: about 1e-07)");
  }
}

Vec3 BearingTilt::tilt(const Vec3& moment_Joint, const Vec3& axis_Joint) const noexcept {
  return compliance_rad_per_nm_ * (moment_Joint - axis_Joint * axis_Joint.dot(moment_Joint));
}

ToolMountCompliance::ToolMountCompliance(double compliance_m_per_n)
    : compliance_m_per_n_(compliance_m_per_n) {
  if (!(std::isfinite(compliance_m_per_n) && compliance_m_per_n >= 0.0 &&
        compliance_m_per_n < 1e-5)) {
    throw InputError(name() + ".compliance_m_per_n = " + show(compliance_m_per_n) +
                     " m/N; expected a finite value in [0, 1e-05) m/N (a compliant tool mount: "
                     "about 2e-07)");
  }
}

Vec3 ToolMountCompliance::shift(const Vec3& force_Base, const Vec3& z_Base) const noexcept {
  return compliance_m_per_n_ * z_Base.dot(force_Base) * z_Base;
}

nlohmann::json ToolMountCompliance::toJson() const {
  return {{"name", name()}, {"compliance_m_per_n", compliance_m_per_n_}};
}

nlohmann::json BearingTilt::toJson() const {
  return {{"name", name()}, {"joint", joint_}, {"compliance_rad_per_nm", compliance_rad_per_nm_}};
}

JointCoupling::JointCoupling(int from_joint, int to_joint, double ratio, int dof)
    : from_joint_(from_joint), to_joint_(to_joint), ratio_(ratio) {
  requireJoint(name(), "joints[0]", from_joint, dof);
  requireJoint(name(), "joints[1]", to_joint, dof);
  if (from_joint == to_joint) {
    throw InputError(name() + ".joints = [" + std::to_string(from_joint) + ", " +
                     std::to_string(to_joint) + "]; expected two different joints");
  }
  requireMagnitude(name(), "ratio", ratio, 0.01, false, "rad/rad");
}

void JointCoupling::apply(const JointVector& q_cmd_rad, const JointVector&,
                          JointVector& theta_rad) const {
  theta_rad(to_joint_ - 1) += ratio_ * q_cmd_rad(from_joint_ - 1);
}

nlohmann::json JointCoupling::toJson() const {
  return {{"name", name()}, {"joints", {from_joint_, to_joint_}}, {"ratio", ratio_}};
}

SelfWeight::SelfWeight(std::vector<LinkMass> links, int dof) : links_(std::move(links)) {
  if (links_.empty()) {
    throw InputError(name() + ".links is empty; expected at least one {\"link\", \"mass_kg\", "
                     "\"com_m\"}");
  }
  std::set<int> seen;
  for (size_t i = 0; i < links_.size(); ++i) {
    const LinkMass& l = links_[i];
    const std::string key = name() + ".links[" + std::to_string(i) + "].";
    if (l.link < 1 || l.link > dof) {
      throw InputError(key + "link = " + std::to_string(l.link) + "; expected a link 1 … " +
                       std::to_string(dof) + " (the body joint k moves)");
    }
    if (!seen.insert(l.link).second) {
      throw InputError(key + "link = " + std::to_string(l.link) +
                       " appears twice; expected each link at most once");
    }
    if (!(std::isfinite(l.mass_kg) && l.mass_kg > 0.0 && l.mass_kg < 2000.0)) {
      throw InputError(key + "mass_kg = " + show(l.mass_kg) +
                       " kg; expected a finite value in (0, 2000) kg");
    }
    requireVectorBelow(key + "com_m", l.p_ComInLink_m, 5.0, "m");
  }
}

void SelfWeight::addTorques(const ChainWorkspace& ws, const Jacobian& J_s,
                            const Vec3& gravity_in_base, JointVector& tau_nm) const {
  STEPCAL_INVARIANT(J_s.cols() == tau_nm.size() && ws.dof == tau_nm.size(),
                    "self weight: one torque per joint");
  for (const LinkMass& l : links_) {
    // Joints 1 … k carry link k.
    tau_nm.head(l.link) +=
        J_s.leftCols(l.link).transpose() * linkWrench(l, ws, gravity_in_base);
  }
}

Vec6 SelfWeight::wrenchOfLinksFrom(int first_link, const ChainWorkspace& ws,
                                   const Vec3& gravity_in_base) const {
  Vec6 W = Vec6::Zero();
  for (const LinkMass& l : links_) {
    if (l.link >= first_link) W += linkWrench(l, ws, gravity_in_base);
  }
  return W;
}

Vec6 SelfWeight::linkWrench(const LinkMass& l, const ChainWorkspace& ws,
                            const Vec3& gravity_in_base) {
  const Vec3 p_ComInBase = ws.X_RootFrame[static_cast<size_t>(l.link)] * l.p_ComInLink_m;
  Vec6 W;
  W.head<3>() = l.mass_kg * gravity_in_base;
  W.tail<3>() = p_ComInBase.cross(W.head<3>());
  return W;
}

nlohmann::json SelfWeight::toJson() const {
  nlohmann::json links = nlohmann::json::array();
  for (const LinkMass& l : links_) {
    links.push_back(
        {{"link", l.link}, {"mass_kg", l.mass_kg}, {"com_m", vec3ToJson(l.p_ComInLink_m)}});
  }
  return {{"name", name()}, {"links", links}};
}

ThermalExpansion::ThermalExpansion(double expansion_per_k, double reference_temp_c)
    : expansion_per_k_(expansion_per_k), reference_temp_c_(reference_temp_c) {
  requireMagnitude(name(), "expansion_per_k", expansion_per_k, 1e-4, true, "1/K");
  if (!std::isfinite(reference_temp_c)) {
    throw InputError(name() + ".reference_temp_c = " + show(reference_temp_c) +
                     " °C; expected a finite temperature, e.g. 20");
  }
}

double ThermalExpansion::linkLengthScale(double temp_c) const noexcept {
  return std::isnan(temp_c) ? 1.0 : 1.0 + expansion_per_k_ * (temp_c - reference_temp_c_);
}

nlohmann::json ThermalExpansion::toJson() const {
  return {{"name", name()},
          {"expansion_per_k", expansion_per_k_},
          {"reference_temp_c", reference_temp_c_}};
}

SensorBias::SensorBias(const Vec3& force_n, const Vec3& moment_nm) {
  requireVectorBelow(name() + ".force_n", force_n, 500.0, "N");
  requireVectorBelow(name() + ".moment_nm", moment_nm, 100.0, "N·m");
  wrench_Sensor_ << force_n, moment_nm;
}

nlohmann::json SensorBias::toJson() const {
  return {{"name", name()},
          {"force_n", vec3ToJson(wrench_Sensor_.head<3>())},
          {"moment_nm", vec3ToJson(wrench_Sensor_.tail<3>())}};
}

JointZeroDrift::JointZeroDrift(int joint, double drift_rad_per_k, double reference_temp_c, int dof)
    : joint_(joint), drift_rad_per_k_(drift_rad_per_k), reference_temp_c_(reference_temp_c) {
  requireJoint(name(), "joint", joint, dof);
  requireMagnitude(name(), "drift_rad_per_k", drift_rad_per_k, 1e-3, true, "rad/K");
  if (!std::isfinite(reference_temp_c)) {
    throw InputError(name() + ".reference_temp_c = " + show(reference_temp_c) +
                     " °C; expected a finite temperature, e.g. 20");
  }
}

void JointZeroDrift::apply(double temp_c, JointVector& theta_rad) const noexcept {
  if (std::isfinite(temp_c)) theta_rad(joint_ - 1) += drift_rad_per_k_ * (temp_c - reference_temp_c_);
}

nlohmann::json JointZeroDrift::toJson() const {
  return {{"name", name()},
          {"joint", joint_},
          {"drift_rad_per_k", drift_rad_per_k_},
          {"reference_temp_c", reference_temp_c_}};
}

RegistrationDrift::RegistrationDrift(const Vec3& translation_m, const Vec3& rotation_rad,
                                     double settling_rows)
    : settling_rows_(settling_rows) {
  requireVectorBelow(name() + ".translation_m", translation_m, 0.01, "m");
  requireVectorBelow(name() + ".rotation_rad", rotation_rad, 0.01, "rad");
  if (!(std::isfinite(settling_rows) && settling_rows >= 0.0)) {
    throw InputError(name() + ".settling_rows = " + show(settling_rows) +
                     "; expected a finite number of rows ≥ 0 (0: a steady ramp)");
  }
  end_ << translation_m, rotation_rad;
}

Vec6 RegistrationDrift::twist(int64_t seq, int64_t rows) const noexcept {
  const double elapsed = static_cast<double>(seq - 1);
  const double g = settling_rows_ > 0.0 ? 1.0 - std::exp(-elapsed / settling_rows_)
                   : rows > 1           ? elapsed / static_cast<double>(rows - 1)
                                        : 0.0;
  return g * end_;
}

nlohmann::json RegistrationDrift::toJson() const {
  return {{"name", name()},
          {"translation_m", vec3ToJson(end_.head<3>())},
          {"rotation_rad", vec3ToJson(end_.tail<3>())},
          {"settling_rows", settling_rows_}};
}

void EffectSet::add(const nlohmann::json& j, int dof) {
  const std::string name = j.at("name").get<std::string>();
  const auto once = [&name](bool already) {
    if (already) {
      throw InputError(name + " is given twice; expected at most one" +
                       (name == SelfWeight::name() ? " (list every link in its links)" : ""));
    }
  };
  if (name == "backlash") {
    link_angle.push_back(std::make_shared<Backlash>(j.at("joint").get<int>(),
                                                    j.at("lost_motion_rad").get<double>(), dof));
  } else if (name == "transmission_error") {
    link_angle.push_back(std::make_shared<TransmissionError>(
        j.at("joint").get<int>(), j.at("harmonic").get<int>(), j.value("sin_rad", 0.0),
        j.value("cos_rad", 0.0), dof));
  } else if (name == "nonlinear_stiffness") {
    link_angle.push_back(std::make_shared<NonlinearStiffness>(
        j.at("joint").get<int>(), j.at("extra_compliance_rad_per_nm").get<double>(),
        j.at("saturation_torque_nm").get<double>(), dof));
  } else if (name == "torsion_curve") {
    link_angle.push_back(std::make_shared<TorsionCurve>(
        j.at("joint").get<int>(), j.value("lost_motion_rad", 0.0),
        j.at("extra_compliance_rad_per_nm").get<std::vector<double>>(),
        j.at("segment_end_torque_nm").get<std::vector<double>>(), dof));
  } else if (name == "joint_coupling") {
    const auto joints = j.at("joints").get<std::vector<int>>();
    if (joints.size() != 2) {
      throw InputError("joint_coupling.joints has " + std::to_string(joints.size()) +
                       " entries; expected [from_joint, to_joint]");
    }
    link_angle.push_back(
        std::make_shared<JointCoupling>(joints[0], joints[1], j.at("ratio").get<double>(), dof));
  } else if (name == "angle_dependent_stiffness") {
    const int joint = j.at("joint").get<int>();
    link_angle.push_back(std::make_shared<AngleDependentStiffness>(
        joint, j.at("harmonic").get<int>(), j.at("amplitude").get<double>(),
        j.at("phase_rad").get<double>(), jointStiffness(name, joint, dof), dof));
  } else if (name == BearingTilt::name()) {
    const BearingTilt tilt(j.at("joint").get<int>(), j.at("compliance_rad_per_nm").get<double>(),
                           dof);
    for (const BearingTilt& other : bearing_tilt) {
      if (other.joint() == tilt.joint()) {
        throw InputError(name + " of joint " + std::to_string(tilt.joint()) +
                         " is given twice; expected at most one per joint");
      }
    }
    bearing_tilt.push_back(tilt);
    std::sort(bearing_tilt.begin(), bearing_tilt.end(),
              [](const BearingTilt& a, const BearingTilt& b) { return a.joint() < b.joint(); });
  } else if (name == ToolMountCompliance::name()) {
    once(tool_mount.has_value());
    tool_mount.emplace(j.at("compliance_m_per_n").get<double>());
  } else if (name == "joint_compliance") {
    auto stiffness = j.at("stiffness_nm_per_rad").get<std::vector<double>>();
    if (stiffness.size() != static_cast<size_t>(dof)) {
      throw InputError("joint_compliance has " + std::to_string(stiffness.size()) +
                       " stiffness values; expected one per joint, " + std::to_string(dof));
    }
    link_angle.push_back(std::make_shared<JointCompliance>(std::move(stiffness)));
  } else if (name == SelfWeight::name()) {
    once(self_weight.has_value());
    const nlohmann::json& entries = j.at("links");
    if (!entries.is_array()) {
      throw InputError(name + ".links = " + entries.dump() +
                       "; expected an array of {\"link\", \"mass_kg\", \"com_m\"}");
    }
    std::vector<SelfWeight::LinkMass> links;
    for (size_t i = 0; i < entries.size(); ++i) {
      const nlohmann::json& e = entries[i];
      links.push_back({e.at("link").get<int>(), e.at("mass_kg").get<double>(),
                       vec3FromJson(e, name + ".links[" + std::to_string(i) + "]", "com_m")});
    }
    self_weight.emplace(std::move(links), dof);
  } else if (name == ThermalExpansion::name()) {
    once(thermal_expansion.has_value());
    thermal_expansion.emplace(j.at("expansion_per_k").get<double>(),
                              j.at("reference_temp_c").get<double>());
  } else if (name == SensorBias::name()) {
    once(sensor_bias.has_value());
    sensor_bias.emplace(vec3FromJson(j, name, "force_n"), vec3FromJson(j, name, "moment_nm"));
  } else if (name == JointZeroDrift::name()) {
    JointZeroDrift drift(j.at("joint").get<int>(), j.at("drift_rad_per_k").get<double>(),
                         j.at("reference_temp_c").get<double>(), dof);
    for (const JointZeroDrift& other : zero_drift) {
      if (other.joint() == drift.joint()) {
        throw InputError(name + " of joint " + std::to_string(drift.joint()) +
                         " is given twice; expected at most one per joint");
      }
    }
    zero_drift.push_back(drift);
  } else if (name == RegistrationDrift::name()) {
    once(registration_drift.has_value());
    registration_drift.emplace(vec3FromJson(j, name, "translation_m"),
                               vec3FromJson(j, name, "rotation_rad"), j.value("settling_rows", 0.0));
  } else {
    std::string known;
    for (const char* k : kKnownEffects) known += std::string(known.empty() ? "" : ", ") + k;
    throw InputError("unknown effect '" + name + "'; expected one of " + known);
  }
}

nlohmann::json EffectSet::toJson() const {
  nlohmann::json all = nlohmann::json::array();
  for (const auto& e : link_angle) all.push_back(e->toJson());
  for (const BearingTilt& t : bearing_tilt) all.push_back(t.toJson());
  if (tool_mount) all.push_back(tool_mount->toJson());
  if (self_weight) all.push_back(self_weight->toJson());
  if (thermal_expansion) all.push_back(thermal_expansion->toJson());
  if (sensor_bias) all.push_back(sensor_bias->toJson());
  for (const JointZeroDrift& d : zero_drift) all.push_back(d.toJson());
  if (registration_drift) all.push_back(registration_drift->toJson());
  return all;
}

double EffectSet::jointStiffness(const std::string& effect, int joint, int dof) const {
  requireJoint(effect, "joint", joint, dof);
  for (const auto& e : link_angle) {
    if (const auto* compliance = dynamic_cast<const JointCompliance*>(e.get())) {
      return compliance->stiffness().at(static_cast<size_t>(joint - 1));
    }
  }
  throw InputError(effect + " of joint " + std::to_string(joint) +
                   " varies the joint's stiffness, but the twin has no joint_compliance; "
                   "expected the joints' compliance on (TwinOptions.compliance)");
}

double EffectSet::linkLengthScale(double temp_c) const noexcept {
  return thermal_expansion ? thermal_expansion->linkLengthScale(temp_c) : 1.0;
}

Vec6 EffectSet::sensorBias_Sensor() const noexcept {
  return sensor_bias ? sensor_bias->wrench_Sensor() : Vec6::Zero();
}

}  // namespace stepcal::twin
