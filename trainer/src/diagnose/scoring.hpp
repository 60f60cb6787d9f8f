// A round's families scored on held-out poses, and the choice among the significant ones
// (internal to stepcal::trainer).
#pragma once

#include <vector>

#include "candidates.hpp"
#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// One family's best configuration in a round, with its held-out outcome.
struct Scored {
  CandidateScore score;
  CrossValidation::Outcome outcome;
  const Family* family = nullptr;
  double lambda = 0.0;  ///< a profile's absolute ridge
  int spent = 0;        ///< parameters it spends (fitted, and chosen such as τ₀ or knots)
};

/// A global family added to stage 1: its parameters fitted on every row and its held-out
/// comparison with the base model.
Scored scoreGlobal(const Family& family, const CrossValidation& cv,
                   const CrossValidation::Outcome& base, size_t stage1_size);

/// Drops from a family the joints whose compliance it would make negative (fitted on every row):
/// a joint that deflects against its load under the arm's weight is not deflecting under it.
void pruneNegativeCompliance(Family& family, const CrossValidation& cv, size_t stage1_size,
                             const DiagnosisModel& model);

/// A profile family over the grid of orders and ridges, at the simplest configuration the
/// held-out poses do not show to be worse than the best (scoring.cpp says how).
Scored scoreProfile(const Family& family, const CrossValidation& cv,
                    const CrossValidation::Outcome& base, const FoldGrams& grams,
                    const DiagnoseOptions& options, const FitRows& fit);

/// Index in scored of the family a round adds, among the significant ones (physical constants
/// of the arm first; else the largest held-out reduction unless a family spending fewer
/// parameters is not significantly worse).
size_t choose(const std::vector<Scored>& scored, std::vector<size_t> significant);

/// Whether two mechanisms are the same candidate: kind, joint and source joint.
bool sameCandidate(const Mechanism& a, const Mechanism& b);

}  // namespace stepcal::trainer::diagnosis
