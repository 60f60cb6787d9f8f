#include "stepcal/report/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/diagnosis_report.hpp"
#include "stepcal/report/session_report.hpp"
#include "stepcal/report/unexplained_report.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

// NaN (no orientation measured) becomes null in JSON.
nlohmann::json numberOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json summaryJson(const trainer::AccuracySummary& s) {
  return {{"method", s.method},
          {"set", toString(s.set)},
          {"load_kg", s.load_kg},
          {"rows", s.rows},
          {"mean_position_mm", s.mean_position_m * kMmPerM},
          {"rms_position_mm", s.rms_position_m * kMmPerM},
          {"max_position_mm", s.max_position_m * kMmPerM},
          {"mean_orientation_deg", numberOrNull(s.mean_orientation_rad * kDegPerRad)}};
}

std::vector<std::string> methodsOf(const std::vector<trainer::AccuracySummary>& summaries) {
  std::vector<std::string> methods;
  for (const auto& s : summaries) {
    bool seen = false;
    for (const auto& m : methods) seen |= m == s.method;
    if (!seen) methods.push_back(s.method);
  }
  return methods;
}

}  // namespace

SessionSummary sessionSummary(const trainer::CalibrationOutcome& outcome, size_t k) {
  const KinematicChain& mine = outcome.poe.sessions[k].chain_Tracker;
  const KinematicChain& first = outcome.poe.sessions[0].chain_Tracker;
  const int n = mine.dof();
  SessionSummary out;
  out.X_TrackerBase = mine.initialPose(0) * outcome.nominal_Base.initialPose(0).inverse();
  const Pose X_FirstToolMyTool = first.initialPose(n).inverse() * mine.initialPose(n);
  out.tool_offset_m = X_FirstToolMyTool.translation().norm();
  out.tool_angle_rad = lie::logSO3(X_FirstToolMyTool.linear()).norm();
  return out;
}

std::string formatReport(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  std::ostringstream out;
  const trainer::GeometricResult& poe = outcome.poe;
  std::map<std::string, int> per_set;
  for (const Measurement& m : campaign.rows) ++per_set[toString(m.set)];
  out << "campaign " << campaign.directory << ": " << campaign.rows.size() << " rows (";
  bool first = true;
  for (const auto& [set, count] : per_set) {
    out << (first ? "" : ", ") << count << " " << set;
    first = false;
  }
  out << "), " << outcome.nominal_Base.dof() << " joints, tip " << campaign.tip_link << "\n";
  out << format("tracker noise %.4f mm, %.4f deg per axis%s -> noise floor (mean) %.4f mm, %.4f deg\n",
                       campaign.tracker.position_sigma_m * kMmPerM,
                       campaign.tracker.orientation_sigma_rad * kDegPerRad,
                       campaign.tracker.stated ? "" : " (not stated in campaign.yaml; assumed)",
                       outcome.floor_position_m * kMmPerM, outcome.floor_orientation_rad * kDegPerRad);
  out << format(
      "step 1, geometry (local POE): %d rows, %s after %d iterations; rank %d of %d, condition %.3g\n",
      poe.fit_rows, poe.converged ? "converged" : "NOT converged", poe.iterations,
      poe.observability.rank, poe.observability.parameter_count, poe.observability.condition_number);
  out << "  convergence (rms position mm, rms orientation deg):";
  for (const auto& h : poe.history) {
    out << format(" [%d] %.4f %.5f", h.iteration, h.rms_position_m * kMmPerM,
                         h.rms_orientation_rad * kDegPerRad);
  }
  out << "\n  unobservable combinations, kept at their nominal values ("
      << poe.observability.unobservable.size() << "):\n";
  for (const auto& u : poe.observability.unobservable) out << "    - " << u.description << "\n";
  if (!campaign.sessions.empty()) {
    out << campaign.sessions.size()
        << " campaigns of one robot: joint frames and compliance shared, each campaign its own "
           "tracker registration and tool (target):\n";
    for (size_t k = 0; k < campaign.sessions.size(); ++k) {
      const trainer::SessionFrames& frames = poe.sessions[k];
      const SessionSummary summary = sessionSummary(outcome, k);
      const Vec3 p = summary.X_TrackerBase.translation();
      const Vec3 rpy = lie::rpyFromRotation(summary.X_TrackerBase.linear()) * kDegPerRad;
      out << format("  %zu %s: %zu rows, %d fit, rms %.4f mm; base in its tracker (%.4f, %.4f, "
                    "%.4f) m, rpy (%.3f, %.3f, %.3f) deg",
                    k + 1, campaign.sessions[k].directory.c_str(), campaign.sessions[k].row_count,
                    frames.fit_rows, frames.rms_position_m * kMmPerM, p.x(), p.y(), p.z(), rpy.x(),
                    rpy.y(), rpy.z());
      if (k > 0) {
        out << format("; tool %.3f mm, %.4f deg from campaign 1's", summary.tool_offset_m * kMmPerM,
                      summary.tool_angle_rad * kDegPerRad);
      }
      out << "\n";
    }
    out << formatCampaignDifferences(campaign, outcome);
  }

  if (outcome.has_stiffness) {
    out << format("step 2, joint compliance: %d loaded/unloaded pairs, rms fit residual %.4f mm\n",
                         outcome.stiffness.pairs, outcome.stiffness.rms_position_residual_m * kMmPerM);
    out << format("  %-14s %14s %12s %8s %14s\n", "joint", "K (Nm/rad)", "1-sigma", "rel.", "max |tau| Nm");
    for (const auto& j : outcome.stiffness.joints) {
      if (j.excited) {
        out << format("  %-14s %14.0f %12.0f %7.1f%% %14.1f\n", j.joint.c_str(), j.stiffness_nm_per_rad,
                             j.stiffness_sigma_nm_per_rad,
                             100.0 * j.stiffness_sigma_nm_per_rad / j.stiffness_nm_per_rad, j.max_torque_nm);
      } else {
        out << format("  %-14s %14s %12s %8s %14.1f  (too little torque from these loads to identify: taken as rigid)\n",
                             j.joint.c_str(), "-", "-", "-", j.max_torque_nm);
      }
    }
    out << "  check on validation pairs, modelled vs measured deflection (paper: 11.9 / 11.3 / 11.4 % mean):\n";
    for (const auto& v : outcome.stiffness_validation) {
      out << format("    %5.1f kg: %3d pairs, deflection %.3f mm, deviation mean %.1f %%, max %.1f %%\n",
                           v.load_kg, v.pairs, v.mean_deflection_m * kMmPerM, v.mean_deviation_pct,
                           v.max_deviation_pct);
    }
  } else {
    out << "step 2, joint compliance: skipped (no loaded/unloaded stiffness pairs with a sensor_link)\n";
  }
  for (const auto* residual : {&outcome.gpr, &outcome.gpr_baseline}) {
    if (!*residual) continue;
    const auto& r = **residual;
    const auto& h = r.gp.hyperparameters();
    out << format("step 3, GPR on the %s residual: %d %s rows, log marginal likelihood %.1f\n",
                         residual == &outcome.gpr ? (outcome.has_stiffness ? "POE + stiffness" : "POE")
                                                  : "POE (baseline POE + GPR)",
                         r.training_rows, r.training_set.c_str(), r.gp.logMarginalLikelihood());
    out << format("  sigma_n %.4g, sigma_f %.4g (standardised outputs); length scales (normalised inputs):",
                         h.noise_sigma, h.signal_sigma);
    for (Eigen::Index d = 0; d < h.length_scales.size(); ++d) out << format(" %.3g", h.length_scales(d));
    out << "\n  10-fold CV mean squared error per output (mm^2 / deg^2 -> rms):";
    for (Eigen::Index o = 0; o < r.report.cv_mse.size(); ++o) {
      const double unit = o < 3 ? kMmPerM : kDegPerRad;
      out << format(" %.4f", std::sqrt(r.report.cv_mse(o)) * unit);
    }
    out << format("\n  held out, it leaves %.2f of the %.2f uncorrected (per row, squared over "
                  "the tracker's stated noise), signed-rank z %.1f: %s\n",
                  r.cv_error, r.uncorrected_error, r.z_statistic,
                  r.taken ? "taken"
                          : "not taken, it does not predict the residual on rows it was not fitted "
                            "on (the layer is the model under it; the model file holds no GPR)");
  }
  out << format("time: geometry %.3f s, stiffness %.3f s, GPR %.3f s\n", outcome.seconds_geometry,
                       outcome.seconds_stiffness, outcome.seconds_gpr);
  out << "\n" << formatAccuracyTable(outcome.accuracy);
  for (size_t k = 0; k < outcome.session_accuracy.size(); ++k) {
    out << "\ncampaign " << k + 1 << " (" << campaign.sessions[k].directory << ") alone, "
        << formatAccuracyTable(outcome.session_accuracy[k]);
  }
  out << "methods: nominal = nominal URDF, tracker registered (closed form); frames = tracker and "
         "tool frames fitted; poe = every initial pose fitted (step 1); +stiffness = joint compliance "
         "(step 2); +gpr = Gaussian process on the residual (step 3)\n";
  return out.str();
}

std::string formatModel(const CalibratedModel& model, size_t file_bytes) {
  std::ostringstream out;
  const KinematicChain& chain = model.chain_Tracker;
  const auto pose = [](const Pose& X) {
    const Vec3 rpy = lie::rpyFromRotation(X.linear()) * kDegPerRad;
    const Vec3 p = X.translation() * kMmPerM;
    return format("xyz (%.4f, %.4f, %.4f) mm, rpy (%.5f, %.5f, %.5f) deg", p.x(), p.y(), p.z(),
                         rpy.x(), rpy.y(), rpy.z());
  };
  out << format("stepcal model, format version %u, %zu bytes\n", kModelFormatVersion, file_bytes);
  const ModelProvenance& prov = model.provenance;
  out << "provenance: campaign " << prov.campaign_path << " (hash " << prov.campaign_hash << "), trained "
      << prov.created_utc << " by stepcal " << prov.trainer_version << "\n";
  out << "chain: " << chain.dof() << " revolute joints, rooted at the tracker frame\n";
  for (int k = 0; k <= chain.dof(); ++k) {
    const std::string name = k < chain.dof() ? chain.joints()[static_cast<size_t>(k)].name : "tip";
    out << format("  T_{%d,%d}(0) -> %-14s %s\n", k, k + 1, name.c_str(), pose(chain.initialPose(k)).c_str());
  }
  for (const ChainJoint& j : chain.joints()) {
    const Vec6& s = j.twist_Local;
    out << format("  twist %-14s (%.3g, %.3g, %.3g, %.3g, %.3g, %.3g), limits [%.2f, %.2f] deg\n", j.name.c_str(),
                         s(0), s(1), s(2), s(3), s(4), s(5), j.lower_rad * kDegPerRad, j.upper_rad * kDegPerRad);
  }
  const KinematicChain& nominal = model.nominal_Base;
  out << format("nominal chain: %d revolute joints, rooted at the robot base, tool T_{%d,%d}(0) %s\n",
                       nominal.dof(), nominal.dof(), nominal.dof() + 1,
                       pose(nominal.initialPose(nominal.dof())).c_str());
  out << "tracker registration X_TrackerBase: " << pose(model.X_TrackerBase) << "\n";
  for (size_t f = 0; f < chain.frames().size(); ++f) {
    const AttachedFrame& frame = chain.frames()[f];
    out << format("frame %s on chain frame %d: %s%s\n", frame.name.c_str(), frame.parent,
                         pose(frame.X_ParentFrame).c_str(),
                         static_cast<int>(f) == model.sensor_frame ? " (F/T sensor)" : "");
  }
  out << format("gravity in base: (%.5f, %.5f, %.5f) m/s^2\n", model.gravity_Base.x(),
                       model.gravity_Base.y(), model.gravity_Base.z());
  if (model.compliance_rad_per_nm.size() == 0) {
    out << "compliance: none (no step 2)\n";
  } else {
    out << "joint stiffness (Nm/rad, 1-sigma):";
    for (Eigen::Index j = 0; j < model.compliance_rad_per_nm.size(); ++j) {
      const double c = model.compliance_rad_per_nm(j), sc = model.compliance_sigma_rad_per_nm(j);
      out << (c > 0 ? format(" %.0f+-%.0f", 1 / c, sc / (c * c)) : std::string(" rigid"));
    }
    out << "\n";
  }
  if (model.mechanisms.empty()) {
    out << "mechanisms: none (stepcal diagnose adds them)\n";
  }
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kTransmissionError) {
      out << "mechanism " << describe(m) << ": " << transmissionSummary(m) << "\n";
      continue;
    }
    if (m.kind == MechanismKind::kProfileGeometry) {
      out << "mechanism " << describe(m) << ": " << profileGeometrySummary(m) << "\n";
      continue;
    }
    const std::vector<std::string> names =
        mechanismParameterNames(m.kind, model.chain_Tracker.dof(), m.order);
    out << "mechanism " << describe(m) << ":";
    for (size_t i = 0; i < names.size(); ++i) {
      const double value = m.parameter(static_cast<int>(i));
      if (m.kind == MechanismKind::kSelfWeight && value == 0.0) continue;
      out << format(" %s %.5g+-%.2g", names[i].c_str(), value, m.sigma[i]);
    }
    out << "\n";
  }
  if (!model.gpr) {
    out << "GPR: none (no step 3)\n";
  } else {
    const GprParameters& g = *model.gpr;
    out << format("GPR: %ld training points, %ld inputs, %ld outputs; sigma_n %.4g, sigma_f %.4g; length scales:",
                         static_cast<long>(g.inputs_normalised.rows()), static_cast<long>(g.inputs_normalised.cols()),
                         static_cast<long>(g.alpha.cols()), g.noise_sigma, g.signal_sigma);
    for (Eigen::Index d = 0; d < g.length_scales.size(); ++d) out << format(" %.3g", g.length_scales(d));
    if (g.payload_force_reference_n > 0.0) {
      out << format("; the residual per payload force in the tracker's axes, reference %.4g N",
                    g.payload_force_reference_n);
    }
    out << "\n";
  }
  out << "validation figures at training time (mean / max position mm, mean orientation deg):\n";
  for (const ValidationFigure& v : prov.validation) out << formatValidationFigure(v);
  return out.str();
}

std::string formatValidationFigure(const ValidationFigure& v) {
  return format("  %-20s %5.1f kg %4d rows  %8.4f / %8.4f  %.4f\n", v.method.c_str(), v.load_kg, v.rows,
                v.mean_position_m * kMmPerM, v.max_position_m * kMmPerM, v.mean_orientation_rad * kDegPerRad);
}

std::string formatAccuracyTable(const std::vector<trainer::AccuracySummary>& summaries) {
  std::ostringstream out;
  const std::vector<std::string> methods = methodsOf(summaries);
  out << "accuracy: mean / max position error (mm), mean orientation error (deg)\n";
  out << format("%-11s %7s %5s", "set", "load_kg", "rows");
  for (const auto& m : methods) out << format("   %-24s", m.c_str());
  out << "\n";
  std::map<std::pair<int, double>, std::map<std::string, const trainer::AccuracySummary*>> table;
  for (const auto& s : summaries) table[{static_cast<int>(s.set), s.load_kg}][s.method] = &s;
  for (const auto& [key, by_method] : table) {
    const trainer::AccuracySummary* any = by_method.begin()->second;
    out << format("%-11s %7.1f %5d", toString(any->set), any->load_kg, any->rows);
    for (const auto& m : methods) {
      const auto it = by_method.find(m);
      if (it == by_method.end()) {
        out << format("   %-24s", "-");
        continue;
      }
      const auto& s = *it->second;
      out << format("   %7.4f / %7.4f %7.4f", s.mean_position_m * kMmPerM, s.max_position_m * kMmPerM,
                           s.mean_orientation_rad * kDegPerRad);
    }
    out << "\n";
  }
  return out.str();
}

nlohmann::json accuracyJson(const std::vector<trainer::AccuracySummary>& summaries) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& s : summaries) out.push_back(summaryJson(s));
  return out;
}

nlohmann::json reportJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  nlohmann::json validation = nlohmann::json::array(), fit = nlohmann::json::array();
  for (const auto& s : outcome.accuracy) {
    nlohmann::json row = summaryJson(s);
    if (s.set == RowSet::kValidation) {
      row.erase("set");
      validation.push_back(row);
    } else {
      fit.push_back(row);
    }
  }
  const trainer::GeometricResult& poe = outcome.poe;
  nlohmann::json history = nlohmann::json::array();
  for (const auto& h : poe.history) {
    history.push_back({{"iteration", h.iteration},
                       {"rms_position_mm", h.rms_position_m * kMmPerM},
                       {"rms_orientation_deg", h.rms_orientation_rad * kDegPerRad}});
  }
  nlohmann::json unobservable = nlohmann::json::array();
  for (const auto& u : poe.observability.unobservable) {
    unobservable.push_back({{"description", u.description}, {"structural", u.structural}});
  }
  nlohmann::json stiffness = nlohmann::json::array(), stiffness_validation = nlohmann::json::array();
  for (const auto& j : outcome.stiffness.joints) {
    stiffness.push_back({{"joint", j.joint},
                         {"identified", j.excited},
                         {"stiffness_nm_per_rad", j.excited ? nlohmann::json(j.stiffness_nm_per_rad) : nlohmann::json()},
                         {"sigma_nm_per_rad", j.excited ? nlohmann::json(j.stiffness_sigma_nm_per_rad) : nlohmann::json()},
                         {"max_torque_nm", j.max_torque_nm}});
  }
  for (const auto& v : outcome.stiffness_validation) {
    stiffness_validation.push_back({{"load_kg", v.load_kg},
                                    {"pairs", v.pairs},
                                    {"mean_deflection_mm", v.mean_deflection_m * kMmPerM},
                                    {"mean_deviation_pct", v.mean_deviation_pct},
                                    {"max_deviation_pct", v.max_deviation_pct}});
  }
  nlohmann::json gpr = nlohmann::json::array();
  for (const auto* residual : {&outcome.gpr, &outcome.gpr_baseline}) {
    if (!*residual) continue;
    const auto& r = **residual;
    const auto& h = r.gp.hyperparameters();
    nlohmann::json cv = nlohmann::json::array();
    for (Eigen::Index o = 0; o < r.report.cv_mse.size(); ++o) cv.push_back(std::sqrt(r.report.cv_mse(o)) * (o < 3 ? kMmPerM : kDegPerRad));
    gpr.push_back({{"method", residual == &outcome.gpr
                                  ? (outcome.has_stiffness ? trainer::kMethodPoeStiffnessGpr : trainer::kMethodPoeGpr)
                                  : trainer::kMethodPoeGpr},
                   {"training_rows", r.training_rows},
                   {"training_set", r.training_set},
                   {"noise_sigma", h.noise_sigma},
                   {"signal_sigma", h.signal_sigma},
                   {"length_scales", std::vector<double>(h.length_scales.data(), h.length_scales.data() + h.length_scales.size())},
                   {"log_marginal_likelihood", r.gp.logMarginalLikelihood()},
                   {"cv_rms_mm_deg", cv},
                   {"cv_error", r.cv_error},
                   {"uncorrected_error", r.uncorrected_error},
                   {"z_statistic", r.z_statistic},
                   {"taken", r.taken}});
  }
  nlohmann::json sessions = nlohmann::json::array();
  for (size_t k = 0; k < campaign.sessions.size(); ++k) {
    const SessionSummary summary = sessionSummary(outcome, k);
    const trainer::SessionFrames& frames = poe.sessions[k];
    const Vec3 p = summary.X_TrackerBase.translation();
    const Vec3 rpy = lie::rpyFromRotation(summary.X_TrackerBase.linear()) * kDegPerRad;
    nlohmann::json accuracy = nlohmann::json::array();
    for (const auto& a : outcome.session_accuracy[k]) accuracy.push_back(summaryJson(a));
    sessions.push_back({{"campaign", campaign.sessions[k].directory},
                        {"rows", campaign.sessions[k].row_count},
                        {"fit_rows", frames.fit_rows},
                        {"fit_rms_position_mm", frames.rms_position_m * kMmPerM},
                        {"base_in_tracker_m", {p.x(), p.y(), p.z()}},
                        {"base_in_tracker_rpy_deg", {rpy.x(), rpy.y(), rpy.z()}},
                        {"tool_from_first_mm", summary.tool_offset_m * kMmPerM},
                        {"tool_from_first_deg", summary.tool_angle_rad * kDegPerRad},
                        {"accuracy", accuracy}});
  }
  nlohmann::json report = {{"campaign", campaign.directory},
          {"sessions", sessions},
          {"session_differences", sessionDifferencesJson(campaign, outcome)},
          {"stiffness_nm_per_rad", stiffness},
          {"stiffness_validation", stiffness_validation},
          {"gpr", gpr},
          {"seconds", {{"geometry", outcome.seconds_geometry}, {"stiffness", outcome.seconds_stiffness}, {"gpr", outcome.seconds_gpr}}},
          {"rows", campaign.rows.size()},
          {"noise_floor",
           {{"mean_position_mm", outcome.floor_position_m * kMmPerM},
            {"mean_orientation_deg", outcome.floor_orientation_rad * kDegPerRad},
            {"tracker_stated", campaign.tracker.stated}}},
          {"geometry",
           {{"fit_rows", poe.fit_rows},
            {"iterations", poe.iterations},
            {"converged", poe.converged},
            {"rank", poe.observability.rank},
            {"parameters", poe.observability.parameter_count},
            {"condition_number", poe.observability.condition_number},
            {"convergence", history},
            {"unobservable", unobservable}}},
          {"validation", validation},
          {"fit", fit}};
  addCampaignDifferencesJson(campaign, outcome, report);
  // The one line calibrate adds when its residual stands far above the noise (null: none).
  const std::string note = residualNote(campaign, outcome);
  report["residual_note"] = note.empty() ? nlohmann::json(nullptr) : nlohmann::json(note);
  return report;
}

std::string formatPlan(const trainer::CampaignPlan& plan, const trainer::PlanOptions& options) {
  std::ostringstream out;
  const int visible = plan.candidates_drawn - plan.rejected_range - plan.rejected_floor -
                      plan.rejected_line_of_sight;
  const char* selection =
      options.selection == trainer::PoseSelection::kRandom ? "random" : "D-optimal";
  if (!options.given_candidates.empty()) {
    out << format("%d poses (%s) x %zu loads = %zu rows, from %d given candidates (measured "
                  "poses: no visibility test)\n",
                  options.poses, selection, options.loads_kg.size(), plan.rows.size(),
                  plan.candidates_drawn);
  } else {
    out << format("%d poses (%s) x %zu loads = %zu rows, from %d visible of %d candidates "
                  "(%d out of range, %d below the floor, %d with the arm in the line of sight)\n",
                  options.poses, selection, options.loads_kg.size(), plan.rows.size(), visible,
                  plan.candidates_drawn, plan.rejected_range, plan.rejected_floor,
                  plan.rejected_line_of_sight);
  }
  const bool loaded = std::any_of(options.loads_kg.begin(), options.loads_kg.end(),
                                  [](double load_kg) { return load_kg > 0.0; });
  out << format("log det of the normalised information (%s, ridge %g): %.2f\n",
                !options.recheck ? "geometry + compliance"
                : loaded ? "re-check: registration, tool, inner joint zeros, compliances"
                         : "re-check: registration, tool, inner joint zeros",
                options.ridge, plan.log_det_information);
  out << format("joint range covered (share of %d bins):", options.spread_bins);
  for (size_t i = 0; i < plan.joint_coverage.size(); ++i) {
    out << format(" q%zu %.2f", i + 1, plan.joint_coverage[i]);
  }
  out << "\n";
  return out.str();
}

}  // namespace stepcal::report
