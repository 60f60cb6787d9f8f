// The extended model and its gain on the validation rows (search.hpp).
#include <algorithm>
#include <chrono>

#include "search.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A row as the tracker would have measured it standing as at the last fit row (drift: the found
// model's, or null: the row as measured). Rows after the fit rows are measured there already.
Measurement withoutDrift(Measurement row, const Mechanism* drift) {
  if (drift == nullptr) return row;
  const Pose X_Undrift =
      X_FittedLast(*drift) * lie::expSE3(-registrationDrift(*drift, static_cast<double>(row.seq)));
  row.p_TipInTracker_m = X_Undrift * row.p_TipInTracker_m;
  row.q_TrackerTip = Eigen::Quaterniond(X_Undrift.linear() * row.q_TrackerTip.toRotationMatrix());
  return row;
}

std::vector<Measurement> validationRows(const Campaign& campaign, const Mechanism* drift) {
  std::vector<Measurement> rows;
  for (const Measurement& m : campaign.rows) {
    if (m.set == RowSet::kValidation) rows.push_back(withoutDrift(m, drift));
  }
  return rows;
}

}  // namespace

void extendAndEvaluate(const Campaign& campaign, const CalibratedModel& model,
                       const PhysicalModel& extended_found, Search& search) {
  const DiagnoseOptions& options = search.options;
  Diagnosis& d = search.d;
  // The robot's part of what was found: a drift of the tracker is the campaign's, never a
  // correction. The rows the GPR learns from and the validation rows are judged as the tracker
  // would have measured them had it stood as at the last fit row (withoutDrift).
  const auto measurementOnly = [](const Mechanism& m) { return isMeasurementOnly(m.kind); };
  const auto drift_at = std::find_if(extended_found.mechanisms.begin(),
                                     extended_found.mechanisms.end(), measurementOnly);
  const Mechanism* drift = drift_at != extended_found.mechanisms.end() ? &*drift_at : nullptr;
  PhysicalModel extended_physical = extended_found;
  auto& mechanisms = extended_physical.mechanisms;
  mechanisms.erase(std::remove_if(mechanisms.begin(), mechanisms.end(), measurementOnly),
                   mechanisms.end());
  // The model's tracker frame is the tracker as it last stood (the one a user measures in next),
  // its base unmoved: the tracker registration and the chain's root move together.
  Pose X_TrackerBase = model.X_TrackerBase;
  if (drift != nullptr) {
    const Pose X_Last = X_FittedLast(*drift);
    KinematicChain& chain = extended_physical.chain_Tracker;
    chain.setInitialPose(0, X_Last * chain.initialPose(0));
    extended_physical.gravity_Tracker = X_Last.linear() * extended_physical.gravity_Tracker;
    X_TrackerBase = X_Last * X_TrackerBase;
  }
  const int n = extended_physical.chain_Tracker.dof();
  auto clock = std::chrono::steady_clock::now();
  CalibratedModel& ext = d.extended_model;
  ext = model;
  ext.chain_Tracker = extended_physical.chain_Tracker;
  ext.X_TrackerBase = X_TrackerBase;
  ext.mechanisms = extended_physical.mechanisms;
  const bool any_compliance = extended_physical.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (model.compliance_rad_per_nm.size() == n || any_compliance) {
    ext.compliance_rad_per_nm = extended_physical.compliance_rad_per_nm;
    ext.compliance_sigma_rad_per_nm = search.compliance_sigma;
  }
  std::vector<const Measurement*> gpr_rows = campaign.rowsIn(RowSet::kResidual);
  std::string gpr_set = "residual";
  if (gpr_rows.empty()) {
    gpr_rows = campaign.rowsIn(RowSet::kGeometry);
    gpr_set = "geometry";
  }
  std::vector<Measurement> undrifted;
  if (drift != nullptr) {
    for (const Measurement* row : gpr_rows) undrifted.push_back(withoutDrift(*row, drift));
    for (size_t i = 0; i < undrifted.size(); ++i) gpr_rows[i] = &undrifted[i];
  }
  const PoseModel after = physicalPoseModel(extended_physical);
  const ResidualModel residual =
      fitResidual(after, gpr_rows, gpr_set, campaign.tracker, options.calibration);
  ext.gpr.reset();
  if (residual.taken) ext.gpr = residual.gp.parameters();
  d.extended_gpr_rows = residual.training_rows;
  d.extended_gpr_z = residual.z_statistic;
  d.extended_gpr_taken = residual.taken;
  d.seconds_gpr = secondsSince(clock);

  clock = std::chrono::steady_clock::now();
  const std::vector<Measurement> validation = validationRows(campaign, drift);
  d.validation_rows = static_cast<int>(validation.size());
  d.floor_position_m = noiseFloorMean(campaign.tracker.position_sigma_m);
  if (!validation.empty()) {
    const auto base_layers = modelLayers(model);
    const PoseModel before = physicalPoseModel(physicalModelOf(model));
    const bool has_gpr = model.gpr.has_value();
    d.gpr_method = has_gpr ? base_layers.back().first : "";
    const auto s_before = summarize("before", before, validation);
    const auto s_after = summarize(kMethodExtended, after, validation);
    const auto s_after_gpr =
        summarize(kMethodExtendedGpr, withResidual(after, residual), validation);
    std::vector<AccuracySummary> s_gpr;
    if (has_gpr) s_gpr = summarize(d.gpr_method, base_layers.back().second, validation);
    for (size_t g = 0; g < s_before.size(); ++g) {
      GainRow row;
      row.load_kg = s_before[g].load_kg;
      row.rows = s_before[g].rows;
      row.before = s_before[g];
      row.after = s_after[g];
      row.after_gpr = s_after_gpr[g];
      if (has_gpr) row.gpr = s_gpr[g];
      d.gain.push_back(row);
    }
    ext.provenance.validation.clear();
    for (const auto& [method, layer] : modelLayers(ext)) {
      for (const AccuracySummary& s : summarize(method, layer, validation)) {
        ext.provenance.validation.push_back({s.method, s.load_kg, s.rows, s.mean_position_m,
                                             s.max_position_m, s.mean_orientation_rad});
      }
    }
  }
  d.seconds_evaluation = secondsSince(clock);
}

}  // namespace stepcal::trainer::diagnosis
