// Accuracy of a pose model against measured rows (docs/method.md eq. 11–12).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"

namespace stepcal::trainer {

/// Predicts X_TrackerTip for a measured row.
using PoseModel = std::function<Pose(const Measurement&)>;

/// Error of one row.
struct RowError {
  double position_m = 0.0;
  double orientation_rad = 0.0;  ///< NaN when the row has no orientation
};

/// Summary over a group of rows; orientation over the rows that have one.
struct AccuracySummary {
  std::string method;
  RowSet set = RowSet::kValidation;
  double load_kg = 0.0;
  int rows = 0;
  int rows_with_orientation = 0;
  double mean_position_m = 0.0;      ///< ΔP (eq. 12)
  double rms_position_m = 0.0;
  double max_position_m = 0.0;
  double mean_orientation_rad = 0.0;  ///< ΔR (eq. 11)
  double max_orientation_rad = 0.0;
};

/// Position and rotation error of a predicted pose against a measured row.
RowError rowError(const Pose& X_TrackerTip_predicted, const Measurement& row);

/// Errors of a model on every row, in row order.
std::vector<RowError> rowErrors(const PoseModel& model, const std::vector<Measurement>& rows);

/// Summaries of one method's row errors per (set, load) group, in (set, load) order.
std::vector<AccuracySummary> summarize(const std::string& method,
                                       const std::vector<Measurement>& rows,
                                       const std::vector<RowError>& errors);

/// Summaries of one method per (set, load) group, groups in (set, load) order.
std::vector<AccuracySummary> summarize(const std::string& method, const PoseModel& model,
                                       const std::vector<Measurement>& rows);

/// One method's mean position error over every row of a set, all loads pooled (row-weighted), m;
/// NaN when the summaries hold no such row.
double pooledMeanPosition(const std::vector<AccuracySummary>& summaries, const std::string& method,
                          RowSet set);

/// Mean error that measurement noise alone gives (χ with 3 dof): σ·2·√(2/π), for σ per axis.
double noiseFloorMean(double sigma_per_axis);

/// Raises the factors' measurement noise to a model's residual scatter on rows where larger: the
/// RMS per axis of the position errors (‖e‖² / 3) and of the rotation errors. Given the rows no
/// GPR takes (every fit row when none is taken, the unloaded ones beside a GPR per payload force),
/// what the model leaves there is then part of its stated accuracy (docs/method.md, "The
/// accuracy bound").
void raiseNoiseToResidual(AccuracyFactors& factors, const PoseModel& model,
                          const std::vector<const Measurement*>& rows);

}  // namespace stepcal::trainer
