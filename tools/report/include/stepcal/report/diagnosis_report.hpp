// Human-readable and JSON renderings of a diagnosis (mm and degrees at the boundary).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::report {

/// The diagnosis as text: what the physical model gets wrong, the candidates that stood out,
/// the verdict with parameters and 1-σ, the gain per validation load, where the time went.
std::string formatDiagnosis(const trainer::Diagnosis& diagnosis, double seconds_calibrate);

/// The diagnosis as JSON: `verdict` ("found", "none", "unexplained"), `effects` → [{name, joint,
/// joints, order, parameters, uncertainty, cv_gain_mm, z_statistic, p_value, round}] in the order
/// found (joints 1-based). A transmission_error (a profile) has instead of parameters `harmonics`
/// → [{harmonic, sin_rad, cos_rad, sin_sigma_rad, cos_sigma_rad, geometry_share}] (link angle +=
/// sin_rad·sin(k q) + cos_rad·cos(k q), q the recorded joint angle, inside its coverage),
/// `coverage_deg` → [[from, to]], `rms_urad` and `strongest_harmonics`; a self_weight whose masses
/// come from the URDF has `compliance` → [{joint, compliance_rad_per_nm, sigma_rad_per_nm}]; a
/// backlash, nonlinear_stiffness or torsion_curve `max_torque_nm` and `stiffness_segments` →
/// [{from_nm, to_nm, stiffness_nm_per_rad}]; every effect `size_chi2` and `size_dof` (its size
/// in the final fit).
/// Then `candidates` → every family tried with its score, `untestable`, `identifiability`,
/// `extended_gpr` {training_rows, z_statistic, taken},
/// `unexplained_trend`, `unexplained` (unexplainedJson), `residual` {before, after}, `campaigns` (several campaigns diagnosed
/// together; else empty) → [{directory, fit_rows, before_mean_position_mm, after_mean_position_mm,
/// and after the first: station, tool → {translation_mm, translation_sigma_mm, rotation_deg,
/// rotation_sigma_deg}, profile_differences → [{joint, order, ridge, cv_gain_mm,
/// relative_reduction, z_statistic, p_value, significant, rms_difference_urad}]}], `gain` → [{load_kg, rows, before_mean_position_mm,
/// after_mean_position_mm, gpr_mean_position_mm, …}], `timing_s`. Where a joint's profile was
/// told apart from the same profile times the joint's torque: `load_modulated_profiles` →
/// [{joint, order, modulated_order, round, profile_named, torque_std_nm, modulated: {cv_gain_mm,
/// relative_reduction, z_statistic, p_value}, profile: {…}, text}] (absent when there is none).
nlohmann::json diagnosisJson(const trainer::Diagnosis& diagnosis, double seconds_calibrate);

/// A profile told apart from the same profile times its joint's torque, in one line
/// (trainer::LoadModulatedProfile): not named, or named with the modulated part left, and why.
std::string loadModulatedProfileText(const trainer::LoadModulatedProfile& finding);

/// A mechanism's parameters as a JSON object keyed by their names (SI, units in the names).
nlohmann::json parametersJson(const Mechanism& mechanism, const std::vector<double>& values);

/// A found effect's parameters in one line: "name = value ± σ" each (SI); a profile by
/// transmissionSummary, or by its coverage when its harmonics are not separable; self weight with
/// the URDF's masses by those masses.
std::string effectParameterText(const trainer::FoundEffect& effect);

/// The compliance self weight identifies for a joint (0-based), e.g. "joint 2 compliance
/// 1.69e-05 rad/(N·m) ± 1e-06, from the arm's own weight".
std::string selfWeightComplianceText(const trainer::Diagnosis& diagnosis, int joint);

/// A transmission profile in one line: its strongest harmonics (amplitude √(a² + b²), µrad) and
/// the joint angles it covers (deg), e.g. "strongest h8 212, h2 95, h7 60 urad; covers 52..180 deg".
std::string transmissionSummary(const Mechanism& profile);

/// A profile geometry in one line: its largest translation (µm) and rotation (µrad) of an
/// initial pose, e.g. "initial poses moved by up to 41 um, 63 urad where joint 2's profile holds".
std::string profileGeometrySummary(const Mechanism& geometry);

/// A joint's torque–deflection mechanism in a gear catalogue's terms: its stiffness in
/// segments and the torques the rows identify it over, e.g. "stiffness 0..120 N·m 2.1e+06,
/// 120..840 N·m 3.3e+06 N·m/rad (lost motion apart); identified up to 840 N·m, the largest
/// torque on the fit rows". Empty for other effects.
std::string torqueCurveText(const trainer::FoundEffect& effect);

/// A later campaign's station (tool = false) or tool against the first's (session_frames), e.g.
/// "t (-2386.218, -4631.032, 74.971) mm ± 0.023, r (-0.6376, -0.0844, 50.2445) deg ± 0.00048":
/// translation and rotation vector, each with its largest 1-σ.
std::string campaignFrameText(const Mechanism& frames, bool tool);

/// The joint angles a profile covers, deg, e.g. "covers 52..180 deg".
std::string coverageText(const Mechanism& profile);

}  // namespace stepcal::report
