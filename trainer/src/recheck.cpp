// The re-check (recheck.hpp): Gauss–Newton on the tracker registration, the tool and the joint
// zeros of a stored model, on a short campaign; every other parameter of the model kept.
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

/// The parameters fitted: registration (6), tool translation (3) and rotation (3), joint zeros.
struct Unknowns {
  bool registration = false, tool_translation = false, tool_rotation = false;
  std::vector<int> joints;
  int count() const {
    return (registration ? 6 : 0) + (tool_translation ? 3 : 0) + (tool_rotation ? 3 : 0) +
           static_cast<int>(joints.size());
  }
};

/// The fitted parameters' columns of the initial-pose linearisation G (count × 6(n+1)).
Eigen::MatrixXd columnsOf(const Eigen::MatrixXd& G, const Unknowns& u,
                          const KinematicChain& chain) {
  const int n = chain.dof();
  Eigen::MatrixXd A(G.rows(), u.count());
  int c = 0;
  if (u.registration) A.middleCols(c, 6) = G.leftCols(6), c += 6;
  if (u.tool_translation) A.middleCols(c, 3) = G.middleCols(6 * n, 3), c += 3;
  if (u.tool_rotation) A.middleCols(c, 3) = G.middleCols(6 * n + 3, 3), c += 3;
  for (int j : u.joints) {
    A.col(c++) = G.middleCols(6 * j, 6) * chain.joints()[static_cast<size_t>(j)].twist_Local;
  }
  return A;
}

/// The initial-pose correction (6(n+1), KinematicChain::corrected) of a step x of the unknowns.
Eigen::VectorXd correctionOf(const Eigen::VectorXd& x, const Unknowns& u,
                             const KinematicChain& chain) {
  const int n = chain.dof();
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(6 * (n + 1));
  int c = 0;
  if (u.registration) delta.head(6) = x.segment(c, 6), c += 6;
  if (u.tool_translation) delta.segment(6 * n, 3) = x.segment(c, 3), c += 3;
  if (u.tool_rotation) delta.segment(6 * n + 3, 3) = x.segment(c, 3), c += 3;
  for (int j : u.joints)
    delta.segment(6 * j, 6) += x(c++) * chain.joints()[static_cast<size_t>(j)].twist_Local;
  return delta;
}

struct Fitted {
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
    const Eigen::MatrixXd A =
        columnsOf(diagnosis::linearise(model, fit, r).geometry, u, model.chain_Tracker);
    const SvdSolution s = solveTruncated(A, r, kRankTolerance);
    const double cost = r.squaredNorm();
    bool improved = false;
    for (double fraction = 1.0; fraction > 1e-3; fraction *= 0.5) {
      PhysicalModel moved = model;
      moved.chain_Tracker =
          model.chain_Tracker.corrected(correctionOf(fraction * s.x, u, model.chain_Tracker));
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
    const Eigen::MatrixXd A =
        columnsOf(diagnosis::linearise(model, fit, r).geometry, u, model.chain_Tracker);
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
  out.model = std::move(model);
  return out;
}

double meanError(const PhysicalModel& model, const FitRows& rows) {
  if (rows.rows.empty()) return 0.0;
  return diagnosis::sessionMeanErrors(diagnosis::residuals(model, rows), rows, 1)[0];
}

/// The stored model with the fitted chain: registration and tool as refitted, zeros folded in.
CalibratedModel updatedModel(const CalibratedModel& model, const KinematicChain& fitted,
                             bool registration) {
  CalibratedModel out = model;
  if (registration) {
    out.X_TrackerBase = Pose(fitted.initialPose(0) * model.chain_Tracker.initialPose(0).inverse() *
                             model.X_TrackerBase);
  }
  out.chain_Tracker = fitted;
  return out;
}

std::vector<const Measurement*> rowsWhere(const Campaign& c, bool validation) {
  std::vector<const Measurement*> out;
  for (const Measurement& row : c.rows) {
    if ((row.set == RowSet::kValidation) == validation) out.push_back(&row);
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
  const Fitted full = fitUnknowns(stored, fit, all);

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
  out.updated = updatedModel(model, full.model.chain_Tracker, frames.registration);
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
  const bool changed = !out.empty() || result.tool_changed;
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
  std::snprintf(line, sizeof line,
                "fit rows (%d): %.4f mm with the tracker%s refitted, %.4f mm with the zeros too\n",
                result.fit_rows, result.fit_error_frames_only_m * 1e3,
                result.tool_fitted ? " and tool" : "", result.fit_error_after_m * 1e3);
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
