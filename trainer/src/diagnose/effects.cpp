// What each found effect is on the fit rows (search.hpp), for the verdict and the report.
#include <algorithm>

#include "profiles.hpp"
#include "search.hpp"

namespace stepcal::trainer::diagnosis {

void describeEffects(Search& search) {
  const FitRows& fit = search.fit;
  const DiagnosisModel& dm = search.model;
  const int n = dm.global.chain_Tracker.dof();
  const Evaluation e = evaluate(dm.global, fit);
  const Linearisation lin = linearise(dm.global, fit, e.r);
  for (FoundEffect& f : search.d.effects) {
    const Mechanism& m = f.mechanism;
    if (m.kind == MechanismKind::kTransmissionError) {
      f.rms_rad = profileRms(m, fit);
      f.largest_amplitude_rad = largestAmplitude(m);
      f.harmonics_separable = harmonicsSeparable(m, f.rms_rad);
      f.geometry_share = geometryShare(
          lin.geometry, profileColumns(lin.link_angle, fit, m.joint, m.coverage, m.order));
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
