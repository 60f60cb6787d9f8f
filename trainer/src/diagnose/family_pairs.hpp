// Whether the rows tell the family a round chose from the other significant global families of
// that round (internal to stepcal::trainer): their collinearity on the fit rows and each held
// out beside the other (FamilyPairTest).
#pragma once

#include <functional>
#include <vector>

#include "candidates.hpp"
#include "cross_validation.hpp"
#include "scoring.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// The largest canonical correlation, over the fit rows, of columns a and b of the screening
/// matrix once the columns `model` span are taken out (total Gram of grams), 0 … 1. Columns in
/// both a and b count as the model's: the same parameter is no pair to separate.
double canonicalCorrelation(const FoldGrams& grams, std::vector<Eigen::Index> model,
                            std::vector<Eigen::Index> a, std::vector<Eigen::Index> b);

/// The chosen global family of a round (scored[chosen]) against the other significant global
/// families (the kMostPairs with the largest held-out reduction): ρ of their columns beside the
/// model's (stage 1 and 2 of the round), each held out beside the other at the round's level
/// (passes(p, reduction)). The tests are appended to pairs.
void testFamilyPairs(const std::vector<Scored>& scored, size_t chosen,
                     const std::vector<size_t>& significant, const CrossValidation& cv,
                     const FoldGrams& grams, const Screening& screening,
                     const std::function<bool(double p, double reduction)>& passes, int round,
                     std::vector<FamilyPairTest>& pairs);

}  // namespace stepcal::trainer::diagnosis
