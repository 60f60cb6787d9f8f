// Partial-residual plots of the found effects (diagnose.hpp EffectSignature): each effect's
// value per fit row from the extended model with and without it, and the residual along it.
// Each kind draws its own (families.hpp KindSignature, in families/<kind>.cpp).
#include "signatures.hpp"

#include <algorithm>
#include <numeric>

#include "families/families.hpp"

namespace stepcal::trainer {
namespace diagnosis {

// Most curve points taken from the rows (a curve sampled at the rows, sorted by x).
constexpr size_t kRowCurvePoints = 400;
// A row's direction weaker than this fraction of the median says little about the effect.
constexpr double kLeverageFraction = 0.25;

Evaluation SignatureContext::without(size_t index) const {
  PhysicalModel out = model;
  out.mechanisms.erase(out.mechanisms.begin() + static_cast<std::ptrdiff_t>(index));
  return evaluate(out, fit);
}

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

EffectSignature linkAngleSignature(const SignatureContext& c, const Mechanism& m, int joint,
                                   const Evaluation& without_it, SignatureVariable variable,
                                   int variable_joint, const std::vector<double>& x) {
  EffectSignature s;
  s.mechanism = m;
  s.joint = joint;
  s.variable = variable;
  s.variable_joint = variable_joint;
  s.response = SignatureResponse::kLinkAngle;
  std::vector<double> effect;
  for (size_t i = 0; i < c.fit.rows.size(); ++i) {
    effect.push_back(c.with.theta_rad[i](joint) - without_it.theta_rad[i](joint));
  }
  fillPoints(c.fit, c.with.r, c.link_angle_columns.col(joint), x, effect, s);
  return s;
}

std::vector<double> jointAngles(const FitRows& fit, int joint) {
  std::vector<double> q;
  for (const Measurement* row : fit.rows) q.push_back(row->q_rad(joint));
  return q;
}

std::vector<double> jointTorques(const Evaluation& with, const Evaluation* without_it, int joint) {
  std::vector<double> tau;
  for (size_t i = 0; i < with.tau_nm.size(); ++i) {
    tau.push_back(with.tau_nm[i](joint) - (without_it ? without_it->tau_nm[i](joint) : 0.0));
  }
  return tau;
}

namespace {

/// The extended model as its fit rows were measured: a registration drift found goes back in
/// with the tracker frame it was fitted in (the model file's is the tracker as it last stood),
/// and each later campaign's rows go through its own station, tool and joint zeros.
PhysicalModel modelAsMeasured(const Diagnosis& diagnosis) {
  PhysicalModel model = physicalModelOf(diagnosis.extended_model);
  for (const FoundEffect& e : diagnosis.effects) {
    if (e.mechanism.kind != MechanismKind::kRegistrationDrift) continue;
    const Pose X_LastFitted = X_FittedLast(e.mechanism).inverse();
    model.chain_Tracker.setInitialPose(0, X_LastFitted * model.chain_Tracker.initialPose(0));
    model.gravity_Tracker = X_LastFitted.linear() * model.gravity_Tracker;
    model.mechanisms.push_back(e.mechanism);
  }
  for (const DiagnosedCampaign& c : diagnosis.campaigns) {
    if (!c.frames.parameters.empty()) model.mechanisms.push_back(c.frames);
  }
  for (const FoundEffect& e : diagnosis.effects) {
    if (e.mechanism.kind == MechanismKind::kCampaignJointZero) model.mechanisms.push_back(e.mechanism);
  }
  return model;
}

}  // namespace
}  // namespace diagnosis

std::vector<EffectSignature> effectSignatures(const Campaign& campaign, const Diagnosis& diagnosis,
                                              const DiagnoseOptions& options) {
  const PhysicalModel model = diagnosis::modelAsMeasured(diagnosis);
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) {
    if (row.set != RowSet::kValidation) rows.push_back(&row);
  }
  const diagnosis::FitRows fit = diagnosis::makeFitRows(rows, campaign.tracker, options.folds);
  const diagnosis::Evaluation with = diagnosis::evaluate(model, fit);
  const Eigen::MatrixXd link_angle = diagnosis::linearise(model, fit, with.r).link_angle;
  const diagnosis::SignatureContext context{diagnosis, model, fit, with, link_angle};

  std::vector<EffectSignature> signatures;
  for (size_t k = 0; k < model.mechanisms.size(); ++k) {
    // Kinds without one are constants of a campaign, not a model's.
    const diagnosis::KindSignature* kind = diagnosis::findKindSignature(model.mechanisms[k].kind);
    if (kind != nullptr) kind->append(context, k, signatures);
  }
  return signatures;
}

}  // namespace stepcal::trainer
