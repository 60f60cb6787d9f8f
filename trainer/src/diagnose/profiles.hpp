// Transmission profiles: the joint angles they cover, their columns and their joint fit on what
// the global model leaves (internal to stepcal::trainer).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "fit_rows.hpp"
#include "model.hpp"

namespace stepcal::trainer::diagnosis {

/// The arcs of the circle the angles cover [rad]: split wherever consecutive angles (mod 2π) are
/// more than max_gap_rad apart (≥ 2 fade_rad, so that widened arcs do not overlap), each run
/// widened by fade_rad on both sides, so the gate is 1 at every angle given and fades to 0 within
/// fade_rad beyond the outermost ones. The full turn when no gap is that wide.
AngleCoverage coverageOfAngles(std::vector<double> angles_rad, double max_gap_rad,
                               double fade_rad);

/// The gated basis at angle q: out[2(k−1)] = g(q) sin(k q), out[2(k−1)+1] = g(q) cos(k q),
/// k = 1 … order.
void profileFeatures(const AngleCoverage& coverage, int order, double q_rad, double* out);

/// Columns of a profile of `order` harmonics on joint j for fit rows [begin, end): the link-angle
/// column of j (link_angle: those rows' equations × n) times each gated basis function, their
/// equations × 2·order.
Eigen::MatrixXd profileColumns(const Eigen::MatrixXd& link_angle, const FitRows& fit, int joint,
                               const AngleCoverage& coverage, int order, size_t begin,
                               size_t end);

/// Every profile's columns, in the model's order, for fit rows [begin, end) (link_angle: their
/// equations × n): their equations × Σ 2·order.
Eigen::MatrixXd profilesColumns(const std::vector<Profile>& profiles,
                                const Eigen::MatrixXd& link_angle, const FitRows& fit,
                                size_t begin, size_t end);

/// Stores a solved stage 2 in the model's profiles. Stage-2 columns: the geometry's 6(n+1), then
/// each profile's in model order; H their Gram with the ridges, x the coefficients, variance the
/// residual's. Each profile gets its coefficients, σ (from variance · H⁻¹) and size_chi2, and its
/// share of the geometry, δ_j = −H_gg⁻¹ H_gj c_j (model.hpp), with its σ.
void storeStage2(DiagnosisModel& model, const Eigen::MatrixXd& H, const Eigen::VectorXd& x,
                 double variance);

/// Fits every profile of the model jointly with a change of the geometry, with their ridges, on
/// the residual of its global model (which stays as it is), and stores it (storeStage2). The
/// profiles' coverage must hold every fit row.
void fitProfiles(DiagnosisModel& model, const FitRows& fit);

/// RMS over the fit rows of a profile's link-angle offset, gate included, rad.
double profileRms(const Mechanism& profile, const FitRows& fit);

/// A profile's largest harmonic amplitude, rad.
double largestAmplitude(const Mechanism& profile);

/// Whether a profile's single harmonics mean anything: not when its largest amplitude exceeds 3×
/// its RMS over the fit rows (rms_rad), where neighbouring harmonics cancel each other.
bool harmonicsSeparable(const Mechanism& profile, double rms_rad);

/// Per harmonic of a profile, the share of its columns' squared norm that the geometry columns
/// reach (1: a geometric error explains it entirely, 0: orthogonal to every geometric error),
/// both linearised at the model (r: its residual), chunk by chunk of rows.
std::vector<double> geometryShare(const PhysicalModel& model, const Eigen::VectorXd& r,
                                  const Mechanism& profile, const FitRows& fit);

/// The mean squared norm of a profile's columns on the fit rows, linearised at the model (r: its
/// residual): what its relative ridge ρ scales, weighted-residual units per rad².
double profileRidgeScale(const PhysicalModel& model, const Eigen::VectorXd& r,
                         const Mechanism& profile, const FitRows& fit);

}  // namespace stepcal::trainer::diagnosis
