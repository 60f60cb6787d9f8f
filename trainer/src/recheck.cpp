// The re-check (recheck.hpp): Gauss–Newton on the tracker registration, the tool, the joint
// zeros and (on rows at two loads or more) the joint compliances of a stored model, on a short
// campaign; every other parameter of the model kept.
//
// A joint's zero moves its initial pose by exp(s_j δ_j) (T(0)·exp(s δ)·exp(s θ) =
// T(0)·exp(s(θ+δ))), so its column is the initial-pose columns of its block times its twist s_j,
// and the update is folded into the chain exactly. The first joint's zero is a turn of the whole
// robot about its first axis, which a new registration takes up; the last joint's is a turn of the
// tool about the last axis, which a new tool takes up: each is fitted only when the other is kept.
#include "stepcal/trainer/recheck.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include <Eigen/SVD>

#include "diagnose/fit_rows.hpp"
#include "diagnose/session_frames.hpp"
#include "least_squares.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/trainer/registration.hpp"

namespace stepcal::trainer {
namespace {

using diagnosis::FitRows;

constexpr double kRankTolerance = 1e-9;
constexpr int kIterations = 20;
/// A tool whose 1-σ exceeds ten times a change worth acting on is not determined by the poses.
constexpr double kUndeterminedTool_m = 10.0 * kNegligibleToolChange_m;

/// The parameters fitted: registration (6), tool translation (3) and rotation (3), joint zeros,
/// joint compliances (rad/(N·m)).
struct Unknowns {
  bool registration = false, tool_translation = false, tool_rotation = false;
  std::vector<int> joints, compliances;
  int firstCompliance() const {
    return (registration ? 6 : 0) + (tool_translation ? 3 : 0) + (tool_rotation ? 3 : 0) +
           static_cast<int>(joints.size());
  }
  int count() const { return firstCompliance() + static_cast<int>(compliances.size()); }
};

/// The fitted parameters' columns (count × u.count()) at the model: the initial-pose ones of
/// its linearisation, and a compliance's, the link angle's column times the row's torque
/// (θ = q + C τ).
Eigen::MatrixXd columnsOf(const PhysicalModel& model, const FitRows& fit, const Unknowns& u) {
  const KinematicChain& chain = model.chain_Tracker;
  const int n = chain.dof();
  const diagnosis::Evaluation e = diagnosis::evaluate(model, fit);
  const diagnosis::Linearisation lin = diagnosis::linearise(model, fit, e.r);
  const Eigen::MatrixXd& G = lin.geometry;
  Eigen::MatrixXd A(G.rows(), u.count());
  int c = 0;
  if (u.registration) A.middleCols(c, 6) = G.leftCols(6), c += 6;
  if (u.tool_translation) A.middleCols(c, 3) = G.middleCols(6 * n, 3), c += 3;
  if (u.tool_rotation) A.middleCols(c, 3) = G.middleCols(6 * n + 3, 3), c += 3;
  for (int j : u.joints) {
    A.col(c++) = G.middleCols(6 * j, 6) * chain.joints()[static_cast<size_t>(j)].twist_Local;
  }
  for (int j : u.compliances) {
    for (size_t row = 0; row < fit.rows.size(); ++row) {
      const Eigen::Index first = diagnosis::equationOf(fit, row);
      const Eigen::Index count = diagnosis::equationOf(fit, row + 1) - first;
      A.block(first, c, count, 1) = lin.link_angle.block(first, j, count, 1) * e.tau_nm[row](j);
    }
    ++c;
  }
  return A;
}

/// The model moved by a step x of the unknowns: the initial-pose correction
/// (KinematicChain::corrected; exact for the zeros) and the compliances' change.
PhysicalModel steppedModel(const PhysicalModel& model, const Eigen::VectorXd& x,
                           const Unknowns& u) {
  const KinematicChain& chain = model.chain_Tracker;
  const int n = chain.dof();
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(6 * (n + 1));
  int c = 0;
  if (u.registration) delta.head(6) = x.segment(c, 6), c += 6;
  if (u.tool_translation) delta.segment(6 * n, 3) = x.segment(c, 3), c += 3;
  if (u.tool_rotation) delta.segment(6 * n + 3, 3) = x.segment(c, 3), c += 3;
  for (int j : u.joints)
    delta.segment(6 * j, 6) += x(c++) * chain.joints()[static_cast<size_t>(j)].twist_Local;
  PhysicalModel out = model;
  out.chain_Tracker = chain.corrected(delta);
  for (int j : u.compliances) out.compliance_rad_per_nm(j) += x(c++);
  return out;
}

struct Fitted {
  Unknowns unknowns;
  PhysicalModel model;
  Eigen::VectorXd x;           ///< the unknowns' total step (exact for the zeros)
  Eigen::MatrixXd covariance;  ///< of x, scaled by the reduced χ² when above 1
  double chi2_reduced = 0.0;
  double mean_error_m = 0.0;
};

Fitted fitUnknowns(PhysicalModel model, const FitRows& fit, const Unknowns& u) {
  const int p = u.count();
  if (u.registration) diagnosis::registerInClosedForm(model, fit);
  Eigen::VectorXd r = diagnosis::residuals(model, fit);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(p);
  for (int it = 0; it < kIterations && p > 0; ++it) {
    const Eigen::MatrixXd A = columnsOf(model, fit, u);
    const SvdSolution s = solveTruncated(A, r, kRankTolerance);
    const double cost = r.squaredNorm();
    bool improved = false;
    for (double fraction = 1.0; fraction > 1e-3; fraction *= 0.5) {
      PhysicalModel moved = steppedModel(model, fraction * s.x, u);
      Eigen::VectorXd r_moved = diagnosis::residuals(moved, fit);
      if (r_moved.squaredNorm() < cost) {
        improved = cost - r_moved.squaredNorm() > 1e-12 * cost;
        model = std::move(moved);
        r = std::move(r_moved);
        x += fraction * s.x;
        break;
      }
    }
    if (!improved) break;
  }
  Fitted out;
  const Eigen::Index dof = std::max<Eigen::Index>(1, fit.count - p);
  out.chi2_reduced = r.squaredNorm() / static_cast<double>(dof);
  out.covariance = Eigen::MatrixXd::Zero(p, p);
  if (p > 0) {
    const Eigen::MatrixXd A = columnsOf(model, fit, u);
    const Eigen::VectorXd scale = A.colwise().norm().cwiseMax(1e-300).transpose();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A * scale.cwiseInverse().asDiagonal(),
                                                Eigen::ComputeThinV);
    const Eigen::VectorXd sv = svd.singularValues();
    Eigen::VectorXd inv2 = Eigen::VectorXd::Zero(sv.size());
    for (Eigen::Index i = 0; i < sv.size(); ++i) {
      if (sv(i) > kRankTolerance * sv(0)) inv2(i) = 1.0 / (sv(i) * sv(i));
    }
    out.covariance = scale.cwiseInverse().asDiagonal() * svd.matrixV() * inv2.asDiagonal() *
                     svd.matrixV().transpose() * scale.cwiseInverse().asDiagonal() *
                     std::max(1.0, out.chi2_reduced);
  }
  out.mean_error_m = diagnosis::sessionMeanErrors(r, fit, 1)[0];
  out.x = x;
  out.unknowns = u;
  out.model = std::move(model);
  return out;
}

double meanError(const PhysicalModel& model, const FitRows& rows) {
  if (rows.rows.empty()) return 0.0;
  return diagnosis::sessionMeanErrors(diagnosis::residuals(model, rows), rows, 1)[0];
}

/// The stored model with the fitted chain (registration and tool as refitted, zeros folded in)
/// and the fitted compliances.
CalibratedModel updatedModel(const CalibratedModel& model, const PhysicalModel& fitted_model,
                             bool registration) {
  const KinematicChain& fitted = fitted_model.chain_Tracker;
  CalibratedModel out = model;
  if (registration) {
    out.X_TrackerBase = Pose(fitted.initialPose(0) * model.chain_Tracker.initialPose(0).inverse() *
                             model.X_TrackerBase);
  }
  out.chain_Tracker = fitted;
  if (out.compliance_rad_per_nm.size() > 0) {
    out.compliance_rad_per_nm = fitted_model.compliance_rad_per_nm;
  }
  return out;
}

/// Why these fit rows cannot test the model's compliances, or empty when they can: a compliance
/// needs the model's compliance step and the rows' wrenches at two loads or more.
std::string whyComplianceIsNotTested(const CalibratedModel& model,
                                     const std::vector<const Measurement*>& rows) {
  if (model.compliance_rad_per_nm.size() == 0) return "the model has no compliance step";
  std::set<double> loads_kg;
  bool wrench = false;
  for (const Measurement* row : rows) {
    loads_kg.insert(row->load_kg);
    wrench = wrench || row->has_wrench;
  }
  if (!wrench || loads_kg.size() < 2) {
    return "the rows are at one load (re-check at two or three: stepcal plan --recheck MODEL "
           "--loads 0,40)";
  }
  return "";
}

/// Each joint's torque span (max − min) over the fit rows, at the stored model.
JointVector torqueSpans(const PhysicalModel& model, const FitRows& fit) {
  const diagnosis::Evaluation e = diagnosis::evaluate(model, fit);
  JointVector low = e.tau_nm.front(), high = e.tau_nm.front();
  for (const JointVector& tau : e.tau_nm) low = low.cwiseMin(tau), high = high.cwiseMax(tau);
  return high - low;
}

/// A relative 1-σ above this: the compliance is not determined by the rows (not reported, not
/// updated).
constexpr double kUndeterminedComplianceRelative = 0.25;

/// The compliances of the joints whose torque spans kMinimumTorqueSpan_nm, fitted with the rest
/// of `base`; a joint its fit leaves undetermined is dropped and the rest fitted again.
Fitted fitWithCompliances(const PhysicalModel& stored, const FitRows& fit, Unknowns u,
                          const JointVector& spans_nm) {
  for (int j = 0; j < spans_nm.size(); ++j) {
    if (spans_nm(j) >= kMinimumTorqueSpan_nm) u.compliances.push_back(j);
  }
  Fitted fitted = fitUnknowns(stored, fit, u);
  std::vector<int> determined;
  for (size_t k = 0; k < u.compliances.size(); ++k) {
    const int j = u.compliances[k], c = u.firstCompliance() + static_cast<int>(k);
    const double sigma = std::sqrt(std::max(0.0, fitted.covariance(c, c)));
    if (sigma <= kUndeterminedComplianceRelative * stored.compliance_rad_per_nm(j))
      determined.push_back(j);
  }
  if (determined.size() == u.compliances.size()) return fitted;
  u.compliances = determined;
  return fitUnknowns(stored, fit, u);
}

/// The tested compliances' changes (x's compliance entries) and every joint's torque span.
std::vector<ComplianceChange> complianceChanges(const PhysicalModel& stored, const Fitted& full,
                                                const Unknowns& u, const JointVector& spans_nm) {
  std::vector<ComplianceChange> out;
  for (int j = 0; j < spans_nm.size(); ++j) {
    ComplianceChange change;
    change.joint = j;
    change.torque_span_nm = spans_nm(j);
    change.stored_rad_per_nm = stored.compliance_rad_per_nm(j);
    out.push_back(change);
  }
  for (size_t k = 0; k < u.compliances.size(); ++k) {
    ComplianceChange& change = out[static_cast<size_t>(u.compliances[k])];
    const int c = u.firstCompliance() + static_cast<int>(k);
    change.tested = true;
    change.delta_rad_per_nm = full.x(c);
    change.sigma_rad_per_nm = std::sqrt(std::max(0.0, full.covariance(c, c)));
    change.changed = std::abs(change.delta_rad_per_nm) > 3.0 * change.sigma_rad_per_nm &&
                     std::abs(change.delta_rad_per_nm) >
                         kNegligibleComplianceChange * change.stored_rad_per_nm;
  }
  return out;
}

std::vector<const Measurement*> rowsWhere(const Campaign& c, bool validation) {
  std::vector<const Measurement*> out;
  for (const Measurement& row : c.rows) {
    if ((row.set == RowSet::kValidation) == validation) out.push_back(&row);
  }
  return out;
}

/// "2, 3" → "joint 2" / "joints 2, 3".
std::string jointsNamed(const std::string& list) {
  return (list.find(',') == std::string::npos ? "joint " : "joints ") + list;
}

/// The compliances' lines of the verdict: each changed one with its 1-σ, the unchanged, the not
/// identifiable and why; or why compliance was not tested.
std::string complianceVerdict(const RecheckResult& result) {
  if (!result.compliance_tested) return "compliance not tested: " + result.compliance_not_tested + "\n";
  std::string out, unchanged, flat, undetermined;
  char line[256];
  for (const ComplianceChange& c : result.compliances) {
    const std::string name = std::to_string(c.joint + 1);
    if (c.tested && c.changed) {
      std::snprintf(line, sizeof line,
                    "joint %d's compliance changed: %+.1f %% ± %.1f %% (%.4f -> %.4f "
                    "urad/(N m))\n",
                    c.joint + 1, 100.0 * c.delta_rad_per_nm / c.stored_rad_per_nm,
                    100.0 * c.sigma_rad_per_nm / c.stored_rad_per_nm, c.stored_rad_per_nm * 1e6,
                    (c.stored_rad_per_nm + c.delta_rad_per_nm) * 1e6);
      out += line;
    } else if (c.tested) {
      unchanged += (unchanged.empty() ? "" : ", ") + name;
    } else if (c.torque_span_nm < kMinimumTorqueSpan_nm) {
      flat += (flat.empty() ? "" : ", ") + name;
    } else {
      undetermined += (undetermined.empty() ? "" : ", ") + name;
    }
  }
  if (!unchanged.empty()) {
    out += (out.empty() ? "compliances unchanged (" : "other compliances unchanged (") +
           jointsNamed(unchanged) + ": within 3 sigma or below " +
           std::to_string(static_cast<int>(kNegligibleComplianceChange * 100)) + " %)\n";
  }
  if (!flat.empty()) {
    out += "compliance of " + jointsNamed(flat) +
           " not identifiable: the torque varies less than " +
           std::to_string(static_cast<int>(kMinimumTorqueSpan_nm)) + " N m across the rows\n";
  }
  if (!undetermined.empty()) {
    out += "compliance of " + jointsNamed(undetermined) +
           " not identifiable: these poses and loads leave it above " +
           std::to_string(static_cast<int>(kUndeterminedComplianceRelative * 100)) +
           " % 1-sigma\n";
  }
  return out;
}

}  // namespace

RecheckResult recheckModel(const CalibratedModel& model, const Campaign& campaign,
                           const RecheckOptions& options) {
  const int n = model.chain_Tracker.dof();
  requireCampaignOfModelRobot(model, campaign, "");
  diagnosis::requireJointCount(campaign, n);
  const std::vector<const Measurement*> fit_rows = rowsWhere(campaign, false);
  const std::vector<const Measurement*> validation_rows = rowsWhere(campaign, true);
  const FitRows fit = diagnosis::makeFitRows(fit_rows, campaign.tracker, 1);
  const FitRows validation = diagnosis::makeFitRows(validation_rows, campaign.tracker, 1);
  const bool orientation = std::any_of(fit_rows.begin(), fit_rows.end(),
                                       [](const Measurement* r) { return r->has_orientation; });

  Unknowns frames;
  frames.registration = !options.keep_registration;
  frames.tool_translation = !options.keep_tool;
  frames.tool_rotation = !options.keep_tool && orientation;
  Unknowns all = frames;
  for (int j = 0; j < n; ++j) {
    if ((j == 0 && frames.registration) || (j == n - 1 && frames.tool_translation)) continue;
    all.joints.push_back(j);
  }
  if (fit.count <= all.count()) {
    throw InputError("has " + std::to_string(fit_rows.size()) + " fit rows (" +
                         std::to_string(fit.count) + " equations) for " +
                         std::to_string(all.count()) +
                         " unknowns (registration, tool, joint zeros); expected more rows: about "
                         "twenty poses (stepcal plan --recheck)",
                     campaign.directory);
  }
  const PhysicalModel stored = physicalModelOf(model);
  const Fitted frames_only = fitUnknowns(stored, fit, frames);
  const std::string compliance_not_tested = whyComplianceIsNotTested(model, fit_rows);
  const JointVector spans_nm = torqueSpans(stored, fit);
  const Fitted full = compliance_not_tested.empty()
                          ? fitWithCompliances(stored, fit, all, spans_nm)
                          : fitUnknowns(stored, fit, all);

  RecheckResult out;
  out.fit_rows = static_cast<int>(fit_rows.size());
  out.validation_rows = static_cast<int>(validation_rows.size());
  out.registration_fitted = frames.registration;
  out.tool_fitted = frames.tool_translation;
  out.chi2_reduced = full.chi2_reduced;
  out.fit_error_frames_only_m = frames_only.mean_error_m;
  out.fit_error_after_m = full.mean_error_m;
  out.validation_error_frames_only_m = meanError(frames_only.model, validation);
  out.validation_error_after_m = meanError(full.model, validation);
  const int first_zero = all.count() - static_cast<int>(all.joints.size());
  for (int j = 0; j < n; ++j) out.zeros.push_back({j, false, 0.0, 0.0, false});
  for (size_t k = 0; k < all.joints.size(); ++k) {
    ZeroChange& z = out.zeros[static_cast<size_t>(all.joints[k])];
    const int c = first_zero + static_cast<int>(k);
    z.fitted = true;
    z.delta_rad = full.x(c);
    z.sigma_rad = std::sqrt(std::max(0.0, full.covariance(c, c)));
    z.changed = std::abs(z.delta_rad) > 3.0 * z.sigma_rad &&
                std::abs(z.delta_rad) > kNegligibleZeroChange_rad;
  }
  if (out.tool_fitted) {
    const Pose moved =
        model.chain_Tracker.initialPose(n).inverse() * full.model.chain_Tracker.initialPose(n);
    out.tool_translation_m = moved.translation();
    const int c = frames.registration ? 6 : 0;
    out.tool_translation_sigma_m =
        std::sqrt(std::max(0.0, full.covariance.block(c, c, 3, 3).diagonal().maxCoeff()));
    out.tool_changed = out.tool_translation_m.norm() > 3.0 * out.tool_translation_sigma_m &&
                       out.tool_translation_m.norm() > kNegligibleToolChange_m;
  }
  out.compliance_tested = compliance_not_tested.empty();
  out.compliance_not_tested = compliance_not_tested;
  if (out.compliance_tested) {
    out.compliances = complianceChanges(stored, full, full.unknowns, spans_nm);
  }
  out.updated = updatedModel(model, full.model, frames.registration);
  return out;
}

std::string recheckVerdict(const RecheckResult& result) {
  std::string out;
  char line[256];
  std::string unchanged, unseen;
  for (const ZeroChange& z : result.zeros) {
    const std::string name = std::to_string(z.joint + 1);
    if (!z.fitted) {
      unseen += (unseen.empty() ? "" : ", ") + name;
    } else if (z.changed) {
      std::snprintf(line, sizeof line,
                    "joint %d re-mastered: %+.3f mrad ± %.3f (the link angle is now the reading "
                    "%+.3f mrad)\n",
                    z.joint + 1, z.delta_rad * 1e3, z.sigma_rad * 1e3, z.delta_rad * 1e3);
      out += line;
    } else {
      unchanged += (unchanged.empty() ? "" : ", ") + name;
    }
  }
  const bool changed =
      !out.empty() || result.tool_changed ||
      std::any_of(result.compliances.begin(), result.compliances.end(),
                  [](const ComplianceChange& c) { return c.changed; });
  const bool tool_undetermined =
      result.tool_fitted && result.tool_translation_sigma_m > kUndeterminedTool_m;
  if (tool_undetermined) {
    std::snprintf(line, sizeof line,
                  "tool not determined by these poses (1-sigma %.3f mm: their orientations vary "
                  "too little): re-check with --keep-tool, or with poses of varied orientation\n",
                  result.tool_translation_sigma_m * 1e3);
    out += line;
  } else if (result.tool_fitted) {
    std::snprintf(
        line, sizeof line,
        "tool %s: moved %.3f mm ± %.3f (x %+.3f, y %+.3f, z %+.3f mm in the tool frame)\n",
        result.tool_changed ? "changed" : "unchanged", result.tool_translation_m.norm() * 1e3,
        result.tool_translation_sigma_m * 1e3, result.tool_translation_m.x() * 1e3,
        result.tool_translation_m.y() * 1e3, result.tool_translation_m.z() * 1e3);
    out += line;
  }
  if (!unchanged.empty()) {
    out += (unchanged.find(',') == std::string::npos ? "joint " : "joints ") + unchanged +
           ": zero unchanged (within 3 sigma or below " +
           std::to_string(static_cast<int>(kNegligibleZeroChange_rad * 1e6)) + " urad)\n";
  }
  if (!unseen.empty()) {
    out += (unseen.find(',') == std::string::npos ? "joint " : "joints ") + unseen +
           ": zero not seen (a refitted " +
           std::string(result.registration_fitted && result.tool_fitted ? "registration or tool"
                       : result.registration_fitted                     ? "registration"
                                                                        : "tool") +
           " takes it up; --keep-registration, --keep-tool when the tracker or the tool has not "
           "moved)\n";
  }
  out += complianceVerdict(result);
  std::snprintf(line, sizeof line,
                "fit rows (%d): %.4f mm with the tracker%s refitted, %.4f mm with the zeros%s "
                "too\n",
                result.fit_rows, result.fit_error_frames_only_m * 1e3,
                result.tool_fitted ? " and tool" : "", result.fit_error_after_m * 1e3,
                result.compliance_tested ? " and compliances" : "");
  out += line;
  if (result.validation_rows > 0) {
    std::snprintf(line, sizeof line,
                  "validation rows (%d): %.4f mm before, %.4f mm after the update\n",
                  result.validation_rows, result.validation_error_frames_only_m * 1e3,
                  result.validation_error_after_m * 1e3);
    out += line;
  }
  out += changed             ? "nothing else changed\n"
         : tool_undetermined ? "no joint zero changed (the tool is not determined: see above)\n"
                             : "nothing changed: the stored model holds\n";
  return out;
}

}  // namespace stepcal::trainer
