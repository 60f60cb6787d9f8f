// What each found effect is on the fit rows (search.hpp), for the verdict and the report.
#include <algorithm>
#include <cmath>

#include "profiles.hpp"
#include "stepcal/common/mechanisms/backlash.hpp"
#include "stepcal/common/mechanisms/nonlinear_stiffness.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"
#include "search.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Where a torque-deflection mechanism's stiffness changes: its knees, or a nonlinear stiffness's
// fade torque τ₀, N·m (increasing).
std::vector<double> stiffnessChanges(const Mechanism& m) {
  if (m.kind == MechanismKind::kNonlinearStiffness) {
    return {view<mechanism::NonlinearStiffness>(m).saturationTorque_nm()};
  }
  std::vector<double> knees;
  if (m.kind == MechanismKind::kTorsionCurve) {
    const mechanism::TorsionCurve<const double> curve = view<mechanism::TorsionCurve>(m);
    for (int term = 1; term <= m.order; ++term) knees.push_back(curve.kneeTorque_nm(term));
  }
  return knees;
}

// The joint's stiffness in segments (FoundEffect::stiffness_segments): compliance rad/(N·m).
std::vector<FoundEffect::StiffnessSegment> stiffnessSegments(const Mechanism& m,
                                                             double compliance,
                                                             double max_torque_nm) {
  Mechanism stiffening = m;  // lost motion is apart in a catalogue
  if (m.kind == MechanismKind::kBacklash) {
    view<mechanism::Backlash>(stiffening).lostMotion_rad() = 0.0;
  }
  if (m.kind == MechanismKind::kTorsionCurve) {
    view<mechanism::TorsionCurve>(stiffening).lostMotion_rad() = 0.0;
  }
  const auto deflection = [&](double tau) { return compliance * tau + torqueDeflection(stiffening, tau); };
  std::vector<double> ends;
  for (double at : stiffnessChanges(m)) {
    if (at < max_torque_nm) ends.push_back(at);
  }
  ends.push_back(max_torque_nm);
  std::vector<FoundEffect::StiffnessSegment> segments;
  double from = 0.0;
  for (double to : ends) {
    const double turn = deflection(to) - deflection(from);
    if (to > from && turn > 0.0) segments.push_back({from, to, (to - from) / turn});
    from = to;
  }
  return segments;
}

// How far a mechanism of the combined model moves the tip on the fit rows: the position part of
// the residual with it against without it (FoundEffect::tip_motion_*).
void tipMotion(const Search& search, const Mechanism& m, const Eigen::VectorXd& r_with,
               FoundEffect& f) {
  const FitRows& fit = search.fit;
  PhysicalModel without_it = search.model.combined();
  auto& mechanisms = without_it.mechanisms;
  for (auto it = mechanisms.begin(); it != mechanisms.end(); ++it) {
    if (it->kind == m.kind && it->joint == m.joint) {
      mechanisms.erase(it);
      break;
    }
  }
  const Eigen::VectorXd r_without = residuals(without_it, fit);
  double sum2 = 0.0;
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    const double motion = (r_with.segment<3>(fit.start[i]) - r_without.segment<3>(fit.start[i])).norm() / fit.w_p;
    sum2 += motion * motion;
    f.tip_motion_max_m = std::max(f.tip_motion_max_m, motion);
  }
  f.tip_motion_rms_m = std::sqrt(sum2 / static_cast<double>(fit.rows.size()));
}

}  // namespace

void describeEffects(Search& search) {
  const FitRows& fit = search.fit;
  const DiagnosisModel& dm = search.model;
  const int n = dm.global.chain_Tracker.dof();
  const Evaluation e = evaluate(dm.global, fit);
  const Evaluation whole = evaluate(dm.combined(), fit);
  for (FoundEffect& f : search.d.effects) {
    const Mechanism& m = f.mechanism;
    if (m.kind == MechanismKind::kTransmissionError) {
      f.rms_rad = profileRms(m, fit);
      f.largest_amplitude_rad = largestAmplitude(m);
      f.harmonics_separable = harmonicsSeparable(m, f.rms_rad);
      f.geometry_share = geometryShare(dm.global, e.r, m, fit);
    } else if (isTorqueDeflection(m.kind)) {
      for (const JointVector& tau : whole.tau_nm) {
        f.max_torque_nm = std::max(f.max_torque_nm, std::abs(tau(m.joint)));
      }
      f.stiffness_segments =
          stiffnessSegments(m, dm.global.compliance_rad_per_nm(m.joint), f.max_torque_nm);
    } else if (m.kind == MechanismKind::kRegistrationDrift ||
               m.kind == MechanismKind::kJointZeroDrift ||
               m.kind == MechanismKind::kCampaignJointZero) {
      tipMotion(search, m, whole.r, f);
    } else if (m.kind == MechanismKind::kSelfWeight && dm.masses_from_urdf) {
      f.gravity_loaded_joints =
          gravityLoadedJoints(dm.global, fit, e.theta_rad, m.parameters, &f.gravity_torque_std_nm);
      for (int j = 0; j < n; ++j) {
        const bool loaded = std::find(f.gravity_loaded_joints.begin(), f.gravity_loaded_joints.end(),
                                      j) != f.gravity_loaded_joints.end();
        if (!loaded && !dm.compliance_free[static_cast<size_t>(j)]) f.weak_gravity_joints.push_back(j);
      }
    }
  }
}

}  // namespace stepcal::trainer::diagnosis
