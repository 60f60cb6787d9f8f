// The fits of the diagnosis's whole model that every phase uses: the global refit under its
// physics' signs, the joint fit of everything linearised at a screening, and the screening
// itself (internal to stepcal::trainer).
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "candidates.hpp"
#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// Index in d.effects of the k-th global cause found (effects other than profiles are the global
/// mechanisms found, in the same order).
size_t globalEffect(const Diagnosis& d, size_t k);

/// Whether a found mechanism's sign-constrained parameter (lost motion, extra compliance) is
/// negative.
bool wrongSign(const Mechanism& m);

/// The global part refitted under its physics' signs (refitGlobal's bounds): a compliance the
/// rows push below zero is held there for good, a mechanism found here (index ≥ base_globals)
/// whose lost motion or extra compliance they push below zero is dropped (with its effect; from
/// a torsion curve just those parts), and the refit repeats. Says what it did in d.changes.
/// hold_profiles: the profiles stay in the model at their values (else the global part is
/// fitted alone).
void refitPhysical(DiagnosisModel& model, const FitRows& fit, const DiagnoseOptions& options,
                   size_t base_globals, JointVector& compliance_sigma, Diagnosis& d,
                   bool hold_profiles = false);

/// The whole model fitted jointly, linearised where the screening was built: every current
/// column (geometry, global parameters, profiles) in one least-squares problem, the ridges on
/// their values (model_fits.cpp says why). Applied to the model, with the screening's values and
/// the Grams' r0 moved to it; the global parameters get their σ from it (compliance_sigma: n
/// entries), the profiles their σ and shares of the geometry. A curve's shape (isShape) stays as
/// the global refit left it, with that refit's σ.
void jointStep(DiagnosisModel& model, Screening& sc, FoldGrams& grams, const FitRows& fit,
               Eigen::Index geometry, JointVector& compliance_sigma);

/// The screening of the families scope tries and its Grams, built at the model as it stands and
/// moved to its joint fit (jointStep) when it has profiles.
void buildScreening(DiagnosisModel& model, const FitRows& fit, const DiagnoseOptions& options,
                    const std::optional<std::vector<double>>& body_masses, Screening& sc,
                    std::unique_ptr<FoldGrams>& grams, JointVector& compliance_sigma,
                    const ScreeningScope& scope = {});

}  // namespace stepcal::trainer::diagnosis
