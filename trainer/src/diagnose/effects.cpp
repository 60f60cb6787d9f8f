// What each found effect is on the fit rows (search.hpp), for the verdict and the report.
#include <algorithm>
#include <cmath>

#include "profiles.hpp"
#include "search.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Where a torque-deflection mechanism's stiffness changes: its knees, or a nonlinear stiffness's
// fade torque τ₀, N·m (increasing).
std::vector<double> stiffnessChanges(const Mechanism& m) {
  if (m.kind == MechanismKind::kNonlinearStiffness) return {m.parameters[1]};
  std::vector<double> knees;
  if (m.kind == MechanismKind::kTorsionCurve) {
    for (int k = 0; k < m.order; ++k) knees.push_back(m.parameters[3 + 2 * size_t(k)]);
  }
  return knees;
}

// The joint's stiffness in segments (FoundEffect::stiffness_segments): compliance rad/(N·m).
std::vector<FoundEffect::StiffnessSegment> stiffnessSegments(const Mechanism& m,
                                                             double compliance,
                                                             double max_torque_nm) {
  Mechanism stiffening = m;  // lost motion is apart in a catalogue
  if (m.kind != MechanismKind::kNonlinearStiffness) stiffening.parameters[0] = 0.0;
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
