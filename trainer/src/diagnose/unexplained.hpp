// The verdict's "unexplained" part (Diagnosis::unexplained): what the extended model leaves
// beyond the tracker noise held out, which variables it follows, and what a free learner over
// physical features removes of it that the catalogue does not (internal to stepcal::trainer).
//
// Every variable is judged held out as a family is (the folds over poses of the fit rows, the
// one-sided signed-rank test of the per-pose reduction of the held-out squared error, Bonferroni
// over the variables tested): the extended model's residual on the fit rows fitted on the
// variable's columns on four folds and judged on the fifth.
#pragma once

#include "search.hpp"

namespace stepcal::trainer::diagnosis {

/// Fills Diagnosis::unexplained for the extended model as fitted (its measurement frames in),
/// after its gain on the validation rows (extendAndEvaluate). noise: the campaign's tracker.
void judgeUnexplained(Search& search, const PhysicalModel& extended, const TrackerNoise& noise);

}  // namespace stepcal::trainer::diagnosis
