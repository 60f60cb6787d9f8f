// A calibration outcome as one self-contained HTML page with SVG figures (mm and degrees).
#pragma once

#include <string>

#include "stepcal/common/campaign.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::report {

/// A self-contained HTML page (inline SVG, one inline script that checks the charts, no external
/// files; html/page.hpp) with the calibration's figures and tables.
/// Figures after Tang et al. 2024: step 1 convergence (Fig. 5), per-point errors on the unloaded
/// (Fig. 6) and on each loaded validation set (Fig. 9, 10), mean error against load, the
/// stiffness check (Fig. 7); then the error's distribution per load and method, where in the
/// workspace it lives, the joint angles the model was fitted on against those it is validated at;
/// tables of K_θ, GPR hyperparameters and every method's accuracy.
/// outcome.row_errors must be aligned with campaign.rows (as calibrateCampaign makes them).
std::string htmlReport(const Campaign& campaign, const trainer::CalibrationOutcome& outcome);

/// A diagnosis as one self-contained HTML page: the effects found, each one's signature
/// (trainer::effectSignatures: a partial-residual plot against its own variable with the fitted
/// curve), the fit rows' position error against the telling variables (before and after the
/// extension), each round's best candidates as horizontal bars with the chosen one marked, the
/// gain table.
std::string diagnosisHtml(const Campaign& campaign, const trainer::Diagnosis& diagnosis);

}  // namespace stepcal::report
