// A round's families scored on held-out poses, and the choice among the significant ones
// (internal to stepcal::trainer).
#pragma once

#include <functional>
#include <vector>

#include "candidates.hpp"
#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// One family's best configuration in a round, with its held-out outcome (its per-pose errors
/// only where scoreFamilies was asked to keep them: every family's at once would hold a vector
/// per pose each).
struct Scored {
  CandidateScore score;
  CrossValidation::Outcome outcome;
  double total = 0.0;  ///< held-out squared error, Σ of the outcome's per-pose errors
  const Family* family = nullptr;
  double lambda = 0.0;  ///< a profile's absolute ridge
  int spent = 0;        ///< parameters it spends (fitted, and chosen such as τ₀ or knots)
};

/// A scored global family fitted with extra global columns beside it (after its own), within its
/// physics' bounds where its score needed them (score.impossible_unbounded not empty).
CrossValidation::Correction globalBeside(const Scored& scored, const CrossValidation& cv,
                                         const std::vector<Eigen::Index>& extra);

/// Drops from a family the joints whose compliance it would make negative (fitted on every row):
/// a joint that deflects against its load under the arm's weight is not deflecting under it.
void pruneNegativeCompliance(Family& family, const CrossValidation& cv, size_t stage1_size,
                             const DiagnosisModel& model);

/// Configurations a family tries (orders × ridges for a profile, else 1): what a round's
/// family-wise test divides its level by.
int configurations(const Family& family, const DiagnoseOptions& options);

/// Every family scored against the current model (cv's base) on held-out poses, the held-out
/// errors of every configuration from as few passes over the fit rows as the memory for their
/// per-pose errors allows (heldOutBatch). A global family is added to stage 1 with its
/// parameters fitted on every row; a profile is tried over its grid of orders and ridges and
/// scored at the simplest configuration the held-out poses do not show to be worse than the best
/// (scoring.cpp says how). keep(score) says whose per-pose errors to keep (choose() compares
/// them); in the order of families.
std::vector<Scored> scoreFamilies(const std::vector<Family>& families, const CrossValidation& cv,
                                  size_t stage1_size, const FoldGrams& grams,
                                  const DiagnoseOptions& options, const FitRows& fit,
                                  const std::function<bool(const CandidateScore&)>& keep);

/// Index in scored of the family a round adds, among the significant ones (physical constants
/// of the arm first; else the largest held-out reduction unless a family spending fewer
/// parameters is not significantly worse).
size_t choose(const std::vector<Scored>& scored, std::vector<size_t> significant);

/// Whether two mechanisms are the same candidate: kind, joint and source joint.
bool sameCandidate(const Mechanism& a, const Mechanism& b);

}  // namespace stepcal::trainer::diagnosis
