// The extended model and its gain on the validation rows (search.hpp).
#include <chrono>

#include "search.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<Measurement> validationRows(const Campaign& campaign) {
  std::vector<Measurement> rows;
  for (const Measurement& m : campaign.rows) {
    if (m.set == RowSet::kValidation) rows.push_back(m);
  }
  return rows;
}

}  // namespace

void extendAndEvaluate(const Campaign& campaign, const CalibratedModel& model,
                       const PhysicalModel& extended_physical, Search& search) {
  const DiagnoseOptions& options = search.options;
  Diagnosis& d = search.d;
  const int n = extended_physical.chain_Tracker.dof();
  auto clock = std::chrono::steady_clock::now();
  CalibratedModel& ext = d.extended_model;
  ext = model;
  ext.chain_Tracker = extended_physical.chain_Tracker;
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
  const std::vector<Measurement> validation = validationRows(campaign);
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
