// Partial-residual plots of the found effects (diagnose.hpp EffectSignature): each effect's
// value per fit row from the extended model with and without it, and the residual along it.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "fit_rows.hpp"
#include "stepcal/common/mechanisms/thermal_expansion.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer {
namespace {

using diagnosis::Evaluation;
using diagnosis::FitRows;

// Samples of a profile's curve across the rows' range: fine enough for 48 harmonics.
constexpr int kCurveSamples = 600;
// Most curve points taken from the rows (a curve sampled at the rows, sorted by x).
constexpr size_t kRowCurvePoints = 400;
// A row's direction weaker than this fraction of the median says little about the effect.
constexpr double kLeverageFraction = 0.25;

/// The model without its mechanism at index.
PhysicalModel without(const PhysicalModel& model, size_t index) {
  PhysicalModel out = model;
  out.mechanisms.erase(out.mechanisms.begin() + static_cast<std::ptrdiff_t>(index));
  return out;
}

/// Fills x, effect and partial_residual from per-row values and directions (the weighted tip
/// motion per unit of the effect, fit.equations(i) entries from fit.start[i]), leaving out rows
/// of weak direction.
void fillPoints(const FitRows& fit, const Eigen::VectorXd& r, const Eigen::VectorXd& direction,
                const std::vector<double>& x, const std::vector<double>& effect,
                EffectSignature& s) {
  const size_t rows = fit.rows.size();
  std::vector<double> norm(rows);
  for (size_t i = 0; i < rows; ++i) {
    norm[i] = direction.segment(fit.start[i], fit.equations(i)).norm();
  }
  std::vector<double> sorted = norm;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(rows / 2), sorted.end());
  const double threshold = kLeverageFraction * sorted[rows / 2];
  for (size_t i = 0; i < rows; ++i) {
    if (!(norm[i] > threshold)) {
      ++s.rows_left_out;
      continue;
    }
    const auto d = direction.segment(fit.start[i], fit.equations(i));
    const auto ri = r.segment(fit.start[i], fit.equations(i));
    s.x.push_back(x[i]);
    s.effect.push_back(effect[i]);
    s.partial_residual.push_back(effect[i] + d.dot(ri) / d.squaredNorm());
  }
}

/// The curve as the effect at the kept rows, in order of x, thinned evenly.
void curveFromRows(EffectSignature& s) {
  std::vector<size_t> order(s.x.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return s.x[a] < s.x[b]; });
  const size_t step = std::max<size_t>(1, order.size() / kRowCurvePoints);
  for (size_t k = 0; k < order.size(); k += step) {
    s.curve_x.push_back(s.x[order[k]]);
    s.curve_y.push_back(s.effect[order[k]]);
  }
  if (!order.empty() && (order.size() - 1) % step != 0) {
    s.curve_x.push_back(s.x[order.back()]);
    s.curve_y.push_back(s.effect[order.back()]);
  }
}

/// A link-angle effect on joint `joint` against x (per fit row): its value is the link angle
/// with it minus without it.
EffectSignature linkAngleSignature(const Mechanism& m, int joint, const FitRows& fit,
                                   const Evaluation& with, const Evaluation& without_it,
                                   const Eigen::MatrixXd& link_angle_columns,
                                   SignatureVariable variable, int variable_joint,
                                   const std::vector<double>& x) {
  EffectSignature s;
  s.mechanism = m;
  s.joint = joint;
  s.variable = variable;
  s.variable_joint = variable_joint;
  s.response = SignatureResponse::kLinkAngle;
  std::vector<double> effect;
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    effect.push_back(with.theta_rad[i](joint) - without_it.theta_rad[i](joint));
  }
  fillPoints(fit, with.r, link_angle_columns.col(joint), x, effect, s);
  return s;
}

std::vector<double> jointAngles(const FitRows& fit, int joint) {
  std::vector<double> q;
  for (const Measurement* row : fit.rows) q.push_back(row->q_rad(joint));
  return q;
}

/// Joint torques of the model, or (self weight) what the mechanism adds to them.
std::vector<double> jointTorques(const Evaluation& with, const Evaluation* without_it, int joint) {
  std::vector<double> tau;
  for (size_t i = 0; i < with.tau_nm.size(); ++i) {
    tau.push_back(with.tau_nm[i](joint) - (without_it ? without_it->tau_nm[i](joint) : 0.0));
  }
  return tau;
}

}  // namespace

std::vector<EffectSignature> effectSignatures(const Campaign& campaign, const Diagnosis& diagnosis,
                                              const DiagnoseOptions& options) {
  // The fit rows are as measured: a registration drift found goes back in with the tracker frame
  // it was fitted in (the model file's is the tracker as it last stood).
  PhysicalModel model = physicalModelOf(diagnosis.extended_model);
  for (const FoundEffect& e : diagnosis.effects) {
    if (e.mechanism.kind != MechanismKind::kRegistrationDrift) continue;
    const Pose X_LastFitted = diagnosis::X_FittedLast(e.mechanism).inverse();
    model.chain_Tracker.setInitialPose(0, X_LastFitted * model.chain_Tracker.initialPose(0));
    model.gravity_Tracker = X_LastFitted.linear() * model.gravity_Tracker;
    model.mechanisms.push_back(e.mechanism);
  }
  // Several campaigns: each later one's rows through its own station, tool and joint zeros.
  for (const DiagnosedCampaign& c : diagnosis.campaigns) {
    if (!c.frames.parameters.empty()) model.mechanisms.push_back(c.frames);
  }
  for (const FoundEffect& e : diagnosis.effects) {
    if (e.mechanism.kind == MechanismKind::kCampaignJointZero) model.mechanisms.push_back(e.mechanism);
  }
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) {
    if (row.set != RowSet::kValidation) rows.push_back(&row);
  }
  const FitRows fit = diagnosis::makeFitRows(rows, campaign.tracker, options.folds);
  const Evaluation with = diagnosis::evaluate(model, fit);
  const Eigen::MatrixXd link_angle = diagnosis::linearise(model, fit, with.r).link_angle;

  std::vector<EffectSignature> signatures;
  for (size_t k = 0; k < model.mechanisms.size(); ++k) {
    const Mechanism& m = model.mechanisms[k];
    switch (m.kind) {
      case MechanismKind::kTransmissionError: {
        EffectSignature s = linkAngleSignature(m, m.joint, fit, with, diagnosis::evaluate(without(model, k), fit),
                                               link_angle, SignatureVariable::kJointAngle, m.joint,
                                               jointAngles(fit, m.joint));
        if (s.x.empty()) break;
        const auto [lo, hi] = std::minmax_element(s.x.begin(), s.x.end());
        for (int i = 0; i < kCurveSamples; ++i) {
          const double q = *lo + (*hi - *lo) * i / (kCurveSamples - 1);
          s.curve_x.push_back(q);
          s.curve_y.push_back(transmissionOffset(m, q));
        }
        signatures.push_back(std::move(s));
        break;
      }
      case MechanismKind::kBacklash:
      case MechanismKind::kNonlinearStiffness:
      case MechanismKind::kTorsionCurve: {
        // The joint's torque–deflection beyond its linear compliance, drawn over the torques the
        // rows span: the curve a gear catalogue gives, less its linear part.
        EffectSignature s = linkAngleSignature(
            m, m.joint, fit, with, diagnosis::evaluate(without(model, k), fit), link_angle,
            SignatureVariable::kJointTorque, m.joint, jointTorques(with, nullptr, m.joint));
        if (s.x.empty()) break;
        const auto [lo, hi] = std::minmax_element(s.x.begin(), s.x.end());
        for (int i = 0; i < kCurveSamples; ++i) {
          const double tau = *lo + (*hi - *lo) * i / (kCurveSamples - 1);
          s.curve_x.push_back(tau);
          s.curve_y.push_back(torqueDeflection(m, tau));
        }
        signatures.push_back(std::move(s));
        break;
      }
      case MechanismKind::kJointCoupling: {
        // A coupling follows the source joint's angle.
        EffectSignature s = linkAngleSignature(
            m, m.joint, fit, with, diagnosis::evaluate(without(model, k), fit), link_angle,
            SignatureVariable::kJointAngle, m.source_joint, jointAngles(fit, m.source_joint));
        curveFromRows(s);
        signatures.push_back(std::move(s));
        break;
      }
      case MechanismKind::kSelfWeight: {
        const Evaluation without_it = diagnosis::evaluate(without(model, k), fit);
        for (const FoundEffect& e : diagnosis.effects) {
          if (e.mechanism.kind != MechanismKind::kSelfWeight) continue;
          for (const int j : e.compliance_joints) {
            EffectSignature s = linkAngleSignature(m, j, fit, with, without_it, link_angle,
                                                   SignatureVariable::kJointTorque, j,
                                                   jointTorques(with, &without_it, j));
            curveFromRows(s);
            signatures.push_back(std::move(s));
          }
        }
        break;
      }
      case MechanismKind::kThermalExpansion: {
        // The tip's motion per unit of length scale: lowering T_ref by Δ raises the scale by α Δ
        // at every row, and the residual (measured − modelled) falls by that motion times α Δ.
        const double alpha = view<mechanism::ThermalExpansion>(m).expansion_per_k();
        if (!(alpha != 0.0)) break;
        constexpr double kScaleStep = 1e-6;
        PhysicalModel shifted = model;
        view<mechanism::ThermalExpansion>(shifted.mechanisms[k]).referenceTemp_c() -=
            kScaleStep / alpha;
        const Eigen::VectorXd direction = (with.r - diagnosis::residuals(shifted, fit)) / kScaleStep;
        EffectSignature s;
        s.mechanism = m;
        s.variable = SignatureVariable::kTemperature;
        s.response = SignatureResponse::kLengthScale;
        std::vector<double> x, effect;
        for (const Measurement* row : fit.rows) {
          x.push_back(rowTemperature(*row));
          effect.push_back(model.linkLengthScale(x.back()) - 1.0);
        }
        fillPoints(fit, with.r, direction, x, effect, s);
        curveFromRows(s);
        signatures.push_back(std::move(s));
        break;
      }
      case MechanismKind::kJointZeroDrift: {
        // A joint's zero follows the temperature (rows without one: no drift, no point).
        std::vector<double> temps;
        for (const Measurement* row : fit.rows) temps.push_back(rowTemperature(*row));
        EffectSignature s = linkAngleSignature(
            m, m.joint, fit, with, diagnosis::evaluate(without(model, k), fit), link_angle,
            SignatureVariable::kTemperature, -1, temps);
        for (size_t i = s.x.size(); i-- > 0;) {
          if (std::isfinite(s.x[i])) continue;
          s.x.erase(s.x.begin() + static_cast<std::ptrdiff_t>(i));
          s.effect.erase(s.effect.begin() + static_cast<std::ptrdiff_t>(i));
          s.partial_residual.erase(s.partial_residual.begin() + static_cast<std::ptrdiff_t>(i));
          ++s.rows_left_out;
        }
        curveFromRows(s);
        signatures.push_back(std::move(s));
        break;
      }
      case MechanismKind::kSensorBias:
      case MechanismKind::kProfileGeometry:
      case MechanismKind::kRegistrationDrift:
      case MechanismKind::kSessionFrames:
      case MechanismKind::kCampaignJointZero: break;  // constants of a campaign, not a model's
    }
  }
  return signatures;
}

}  // namespace stepcal::trainer
