// Partial-residual plots of the found effects (diagnose.hpp EffectSignature), internal to
// stepcal::trainer: what a kind's signature (families.hpp KindSignature) is drawn from, and the
// steps the kinds share. effectSignatures (signatures.cpp) walks the model's mechanisms in order.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "fit_rows.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

// Samples of a profile's curve across the rows' range: fine enough for 48 harmonics.
constexpr int kCurveSamples = 600;

/// The extended model at the fit rows: what every kind's signature is drawn from.
struct SignatureContext {
  const Diagnosis& diagnosis;
  const PhysicalModel& model;  ///< the extended model, as its rows were measured
  const FitRows& fit;
  const Evaluation& with;                     ///< the model evaluated at the rows
  const Eigen::MatrixXd& link_angle_columns;  ///< linearise(model, fit, with.r).link_angle

  /// The model without its mechanism at index, evaluated at the rows.
  Evaluation without(size_t index) const;
};

/// Fills x, effect and partial_residual from per-row values and directions (the weighted tip
/// motion per unit of the effect, fit.equations(i) entries from fit.start[i]), leaving out rows
/// of weak direction.
void fillPoints(const FitRows& fit, const Eigen::VectorXd& r, const Eigen::VectorXd& direction,
                const std::vector<double>& x, const std::vector<double>& effect,
                EffectSignature& s);

/// The curve as the effect at the kept rows, in order of x, thinned evenly.
void curveFromRows(EffectSignature& s);

/// The curve as curve(x) at kCurveSamples even steps across the kept rows' x.
template <typename Curve>
void curveSampled(EffectSignature& s, Curve curve) {
  const auto [lo, hi] = std::minmax_element(s.x.begin(), s.x.end());
  for (int i = 0; i < kCurveSamples; ++i) {
    const double x = *lo + (*hi - *lo) * i / (kCurveSamples - 1);
    s.curve_x.push_back(x);
    s.curve_y.push_back(curve(x));
  }
}

/// A link-angle effect on joint `joint` against x (per fit row): its value is the link angle
/// with it minus without it.
EffectSignature linkAngleSignature(const SignatureContext& c, const Mechanism& m, int joint,
                                   const Evaluation& without_it, SignatureVariable variable,
                                   int variable_joint, const std::vector<double>& x);

/// The commanded angles of a joint at the fit rows.
std::vector<double> jointAngles(const FitRows& fit, int joint);

/// Joint torques of the model, or (self weight) what the mechanism adds to them.
std::vector<double> jointTorques(const Evaluation& with, const Evaluation* without_it, int joint);

}  // namespace stepcal::trainer::diagnosis
