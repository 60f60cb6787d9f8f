// What a model leaves on the fit rows: its size against the tracker noise and its trends in the
// variables a cause could follow (internal to stepcal::trainer).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "fit_rows.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// Per fit row, the variables a residual is tested against: q_j (deg), τ_j (N·m), load_kg,
/// temp_c and seq.
struct Variables {
  std::vector<std::string> names;
  std::vector<std::vector<double>> values;  ///< per variable, per fit row (NaN = absent)
};
Variables trendVariables(const FitRows& fit, const std::vector<JointVector>& tau_nm, int dof);

/// Size of the residual r and its cross-validated cubic trends in each variable (Bonferroni over
/// the variables at family-wise alpha).
ResidualStatistics statistics(const Eigen::VectorXd& r, const FitRows& fit,
                              const Variables& variables, double alpha);

/// What the residual still follows, in words; empty when nothing (no significant trend and the
/// noise ratio within limit).
std::string trendSummary(const ResidualStatistics& s, double limit);

}  // namespace stepcal::trainer::diagnosis
