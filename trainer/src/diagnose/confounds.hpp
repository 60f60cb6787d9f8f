// Confounds of the time-order families (internal to stepcal::trainer): the variables that move
// with a family's driver (the time order for registration_drift, temp_c for joint_zero_drift),
// the nuisance columns that re-make the family as a function of each, and the held-out test that
// keeps a family from being named when the rows cannot tell it from one of them.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

struct Scored;

/// A variable of the fit rows as a time-order family's stand-in: its values and the functions
/// of it that a nuisance column takes (each level but the first when it has at most 8 distinct
/// values, a load's blocks; else P_1..P_3 of it mapped from its range onto [−1, 1]).
struct ConfounderVariable {
  std::string name;
  std::vector<double> values;  ///< per fit row; NaN: not known there (every function 0)
  std::vector<double> levels;  ///< its distinct values, ascending, when few; else empty
  double lo = 0.0, hi = 0.0;   ///< its range over the rows where known
  int functions() const;
  /// Function k (0 … functions() − 1) at fit row i.
  double function(int k, size_t row) const;
};
using ConfounderPtr = std::shared_ptr<const ConfounderVariable>;

/// The candidate confounders of the fit rows: load_kg, temp_c, each joint's angle (q_j_deg) and
/// torque in the model the round starts from (tau_j_nm), the wrench's components in sensor axes
/// where any row has one (fx_n … mz_nm), and seq; a variable constant over the rows is left out.
std::vector<ConfounderPtr> confounderVariables(const FitRows& fit, const Evaluation& start);

/// Multiple correlation R of the driver (per fit row, NaN: left out) with the variable's
/// functions, 0 … 1: how far the variable moves with it.
double driverCorrelation(const std::vector<double>& driver, const ConfounderVariable& variable);

/// The variables other than the driver that move with it (R ≥ 0.3), with their R: the six that
/// move most, largest R first.
struct Confounder {
  ConfounderPtr variable;
  double r = 0.0;
};
std::vector<Confounder> confoundersOf(const std::vector<ConfounderPtr>& variables,
                                      const std::string& driver);

/// Each significant time-order family of a round scored again beside each of its confounders
/// (their nuisance columns in the model): the ones the rows cannot tell apart from one lose
/// their significance (a flag cleared in scored). Every test is appended to tests.
void testConfounds(std::vector<Scored>& scored, const CrossValidation& cv,
                   const std::function<bool(const CandidateScore&)>& is_significant, int round,
                   std::vector<ConfoundTest>& tests);

}  // namespace stepcal::trainer::diagnosis
