// Human-readable and JSON renderings of a diagnosis (mm and degrees at the boundary).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::cli {

/// The diagnosis as text: what the physical model gets wrong, the candidates that stood out,
/// the verdict with parameters and 1-σ, the gain per validation load, where the time went.
std::string formatDiagnosis(const trainer::Diagnosis& diagnosis, double seconds_calibrate);

/// The diagnosis as JSON: `verdict` ("found", "none", "unexplained"), `effects` → [{name, joint,
/// joints, harmonic, parameters, uncertainty, cv_gain_mm, t_statistic, p_value}] in the order
/// found (joints 1-based), `candidates` → every candidate tried with its score, `untestable`,
/// `unexplained_trend`, `residual` {before, after}, `gain` → [{load_kg, rows,
/// before_mean_position_mm, after_mean_position_mm, gpr_mean_position_mm, …}], `timing_s`.
nlohmann::json diagnosisJson(const trainer::Diagnosis& diagnosis, double seconds_calibrate);

/// A mechanism's parameters as a JSON object keyed by their names (SI, units in the names).
nlohmann::json parametersJson(const Mechanism& mechanism, const std::vector<double>& values);

}  // namespace stepcal::cli
