#include "stepcal/common/units.hpp"
#include "stepcal/trainer/accuracy.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

#include "stepcal/common/lie.hpp"

namespace stepcal::trainer {

RowError rowError(const Pose& X_TrackerTip_predicted, const Measurement& row) {
  RowError e;
  e.position_m = (X_TrackerTip_predicted.translation() - row.p_TipInTracker_m).norm();
  e.orientation_rad = row.has_orientation
                          ? lie::angleBetween(row.q_TrackerTip.toRotationMatrix(),
                                              X_TrackerTip_predicted.linear())
                          : std::numeric_limits<double>::quiet_NaN();
  return e;
}

std::vector<RowError> rowErrors(const PoseModel& model, const std::vector<Measurement>& rows) {
  std::vector<RowError> errors;
  errors.reserve(rows.size());
  for (const Measurement& row : rows) errors.push_back(rowError(model(row), row));
  return errors;
}

std::vector<AccuracySummary> summarize(const std::string& method, const PoseModel& model,
                                       const std::vector<Measurement>& rows) {
  return summarize(method, rows, rowErrors(model, rows));
}

std::vector<AccuracySummary> summarize(const std::string& method,
                                       const std::vector<Measurement>& rows,
                                       const std::vector<RowError>& errors) {
  std::map<std::pair<int, double>, AccuracySummary> groups;
  for (size_t i = 0; i < rows.size(); ++i) {
    const Measurement& row = rows[i];
    AccuracySummary& g = groups[{static_cast<int>(row.set), row.load_kg}];
    g.method = method;
    g.set = row.set;
    g.load_kg = row.load_kg;
    const RowError& e = errors[i];
    ++g.rows;
    g.mean_position_m += e.position_m;
    g.rms_position_m += e.position_m * e.position_m;
    g.max_position_m = std::max(g.max_position_m, e.position_m);
    if (row.has_orientation) {
      ++g.rows_with_orientation;
      g.mean_orientation_rad += e.orientation_rad;
      g.max_orientation_rad = std::max(g.max_orientation_rad, e.orientation_rad);
    }
  }
  std::vector<AccuracySummary> out;
  for (auto& [key, g] : groups) {
    g.mean_position_m /= g.rows;
    g.rms_position_m = std::sqrt(g.rms_position_m / g.rows);
    g.mean_orientation_rad = g.rows_with_orientation > 0
                                 ? g.mean_orientation_rad / g.rows_with_orientation
                                 : std::numeric_limits<double>::quiet_NaN();
    out.push_back(g);
  }
  return out;
}

double pooledMeanPosition(const std::vector<AccuracySummary>& summaries, const std::string& method,
                          RowSet set) {
  double sum_m = 0.0;
  int rows = 0;
  for (const AccuracySummary& s : summaries) {
    if (s.method != method || s.set != set) continue;
    sum_m += s.mean_position_m * s.rows;
    rows += s.rows;
  }
  return rows > 0 ? sum_m / rows : std::numeric_limits<double>::quiet_NaN();
}

double noiseFloorMean(double sigma_per_axis) {
  return sigma_per_axis * 2.0 * std::sqrt(2.0 / kPi);
}

void raiseNoiseToResidual(AccuracyFactors& factors, const PoseModel& model,
                          const std::vector<const Measurement*>& rows) {
  double sum_p2 = 0.0, sum_r2 = 0.0;
  int oriented = 0;
  for (const Measurement* row : rows) {
    const RowError e = rowError(model(*row), *row);
    sum_p2 += e.position_m * e.position_m;
    if (row->has_orientation) {
      sum_r2 += e.orientation_rad * e.orientation_rad;
      ++oriented;
    }
  }
  if (!rows.empty()) {
    factors.position_noise_m =
        std::max(factors.position_noise_m, std::sqrt(sum_p2 / (3.0 * static_cast<double>(rows.size()))));
  }
  if (oriented > 0) {
    factors.orientation_noise_rad =
        std::max(factors.orientation_noise_rad, std::sqrt(sum_r2 / (3.0 * oriented)));
  }
}

}  // namespace stepcal::trainer
