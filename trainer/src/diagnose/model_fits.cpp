// The fits of the diagnosis's whole model (model_fits.hpp).
#include "model_fits.hpp"

#include <algorithm>

#include "families/families.hpp"
#include "profiles.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"

namespace stepcal::trainer::diagnosis {

size_t globalEffect(const Diagnosis& d, size_t k) {
  size_t global_index = 0;
  for (size_t e = 0; e < d.effects.size(); ++e) {
    if (d.effects[e].mechanism.kind == MechanismKind::kTransmissionError) continue;
    if (global_index++ == k) return e;
  }
  STEPCAL_INVARIANT(false, "every global mechanism found has its effect");
  return d.effects.size();
}

bool wrongSign(const Mechanism& m) {
  const std::vector<int> constrained = signConstrained(m);
  return std::any_of(constrained.begin(), constrained.end(),
                     [&m](int i) { return m.parameter(i) < 0.0; });
}

namespace {

// A parameter held at zero that is its direction's size (KindFit::parts_independent), the
// mechanism's other sizes not all held with it: a result, not a wrong sign.
bool heldAsSize(const GlobalFit& refit, const PhysicalModel& global, const Parameter& p) {
  const Mechanism& m = global.mechanisms[static_cast<size_t>(p.mechanism)];
  const KindFit* fit = findKindFit(m.kind);
  if (fit == nullptr || !fit->parts_independent) return false;
  const size_t held = static_cast<size_t>(
      std::count_if(refit.held.begin(), refit.held.end(), [&p](const HeldAtBound& h) {
        return h.parameter.mechanism == p.mechanism;
      }));
  return held < signConstrained(m).size();
}

}  // namespace

void refitPhysical(DiagnosisModel& model, const FitRows& fit, const DiagnoseOptions& options,
                   size_t base_globals, JointVector& compliance_sigma, Diagnosis& d,
                   bool hold_profiles) {
  for (;;) {
    const GlobalFit refit =
        refitGlobal(model, fit, options.refit_iterations, hold_profiles);
    const HeldAtBound* compliance = nullptr;  // the last joint's, one per pass
    size_t dropped = model.global.mechanisms.size();
    std::vector<int> held_parts;  // of the mechanism to drop
    for (const HeldAtBound& h : refit.held) {
      const Parameter& p = h.parameter;
      if (p.mechanism < 0) {
        compliance = &h;
      } else if (static_cast<size_t>(p.mechanism) >= base_globals &&
                 !heldAsSize(refit, model.global, p)) {
        if (dropped != static_cast<size_t>(p.mechanism)) held_parts.clear();
        dropped = static_cast<size_t>(p.mechanism);
        held_parts.push_back(p.index);
      }
    }
    if (compliance != nullptr) {
      const int joint = compliance->parameter.index;
      ModelChange change;
      change.kind = ModelChange::Kind::kComplianceHeldAtZero;
      change.joint = joint;
      change.compliance_rad_per_nm = compliance->unbounded;
      d.changes.push_back(change);
      compliance_sigma(joint) = 0.0;
      model.compliance_free[static_cast<size_t>(joint)] = false;
      continue;
    }
    if (dropped == model.global.mechanisms.size()) return;
    globalSigma(model, fit, compliance_sigma);  // the change records the mechanism as refitted
    if (Mechanism& m = model.global.mechanisms[dropped]; m.kind == MechanismKind::kTorsionCurve) {
      // A curve loses its parts held at zero and keeps the rest, if any.
      const auto held = [&](int index) {
        return std::find(held_parts.begin(), held_parts.end(), index) != held_parts.end();
      };
      using Curve = mechanism::TorsionCurve<double>;
      Mechanism kept = m;
      if (held(Curve::kLostMotion)) {
        const Curve curve = view<mechanism::TorsionCurve>(kept);
        curve.lostMotion_rad() = curve.smoothingTorque_nm() = 0.0;
        kept.sigma[Curve::kLostMotion] = kept.sigma[Curve::kSmoothingTorque] = 0.0;
      }
      for (int term = kept.order; term >= 1; --term) {
        const int first = Curve::complianceIndex(term);  // the term's compliance and knee
        if (!held(first)) continue;
        kept.parameters.erase(kept.parameters.begin() + first, kept.parameters.begin() + first + 2);
        kept.sigma.erase(kept.sigma.begin() + first, kept.sigma.begin() + first + 2);
        --kept.order;
      }
      if (view<mechanism::TorsionCurve>(kept).smoothingTorque_nm() > 0.0 || kept.order > 0) {
        ModelChange change;
        change.kind = ModelChange::Kind::kPartDroppedWrongSign;
        change.mechanism = m;
        change.kept = simplestTorqueDeflection(kept);
        m = change.kept;
        d.changes.push_back(std::move(change));
        continue;
      }
    }
    ModelChange change;
    change.kind = ModelChange::Kind::kDroppedWrongSign;
    change.mechanism = model.global.mechanisms[dropped];
    d.changes.push_back(std::move(change));
    d.effects.erase(d.effects.begin() + static_cast<long>(globalEffect(d, dropped - base_globals)));
    model.global.mechanisms.erase(model.global.mechanisms.begin() + static_cast<long>(dropped));
  }
}

// The whole model fitted jointly, linearised where the screening was built: every current
// column (geometry, global parameters, profiles) in one least-squares problem, the ridges on
// their values, so what a global cause and a profile share goes to the one without a ridge (the
// global cause: physics that holds everywhere). Alternating the two fits converges there only
// slowly where they share much (a lumped self weight and a shoulder profile over a narrow arc).
// Applied to the model, with r0 and the screening's values moved to it; the global parameters get
// their σ from it (compliance_sigma: n entries), the profiles their σ and shares of the geometry
// (storeStage2), the global geometry what is left of its change.
void jointStep(DiagnosisModel& model, Screening& sc, FoldGrams& grams, const FitRows& fit,
               Eigen::Index geometry, JointVector& compliance_sigma) {
  const std::vector<Parameter> params = globalParameters(model);
  STEPCAL_INVARIANT(sc.stage1.size() == static_cast<size_t>(geometry) + params.size(),
                    "stage 1 holds the geometry and every global parameter");
  // Stage 1, then the profiles' columns; a curve's shape (a fade or knee torque) is left where
  // the global refit put it: the linear step has no line search, and where its compliance is
  // small the shape's column is too (on seed 38 of the stress run it put a knee at −8 N·m).
  std::vector<Eigen::Index> all = sc.stage1;
  all.insert(all.end(), sc.stage2.begin() + geometry, sc.stage2.end());
  std::vector<Eigen::Index> columns, solved;  // solved: each column's place in all
  for (size_t k = 0; k < all.size(); ++k) {
    const Eigen::Index c = static_cast<Eigen::Index>(k) - geometry;
    if (c >= 0 && static_cast<size_t>(c) < params.size() && isShape(model.global, params[static_cast<size_t>(c)])) {
      continue;
    }
    columns.push_back(all[k]);
    solved.push_back(static_cast<Eigen::Index>(k));
  }
  // The shape keeps the σ of the refit that moved it last.
  if (columns.size() < all.size()) globalSigma(model, fit, compliance_sigma);
  const CrossValidation cv(grams, fit, sc.stage1, sc.stage2, sc.ridge, sc.current);
  const CrossValidation::JointFit joint = cv.jointFit(columns);
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(all.size()));
  Eigen::VectorXd unit_variance = Eigen::VectorXd::Constant(delta.size(), -1.0);  // −1: not fitted
  for (size_t k = 0; k < solved.size(); ++k) {
    delta(solved[k]) = joint.change(static_cast<Eigen::Index>(k));
    unit_variance(solved[k]) = joint.unit_variance(static_cast<Eigen::Index>(k));
  }
  Eigen::VectorXd moved = Eigen::VectorXd::Zero(sc.current.size());
  for (size_t k = 0; k < all.size(); ++k) moved(all[k]) = -delta(static_cast<Eigen::Index>(k));

  for (size_t c = 0; c < params.size(); ++c) {
    const Eigen::Index k = geometry + static_cast<Eigen::Index>(c);
    if (unit_variance(k) < 0.0) continue;
    shift(model.global, params[c], delta(k));
    const double sigma = std::sqrt(joint.variance * unit_variance(k));
    if (params[c].mechanism < 0) {
      compliance_sigma(params[c].index) = sigma;
    } else {
      model.global.mechanisms[static_cast<size_t>(params[c].mechanism)]
          .sigma[static_cast<size_t>(params[c].index)] = sigma;
    }
  }
  Eigen::VectorXd old_share = Eigen::VectorXd::Zero(geometry);
  for (const Profile& p : model.profiles) {
    if (p.geometry.size() == geometry) old_share += p.geometry;
  }
  const Eigen::Index width = static_cast<Eigen::Index>(sc.stage2.size());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(width);
  const Eigen::Index first_profile = static_cast<Eigen::Index>(sc.stage1.size());
  for (Eigen::Index c = geometry; c < width; ++c) {
    x(c) = sc.current(sc.stage2[static_cast<size_t>(c)]) + delta(first_profile + c - geometry);
  }
  Eigen::MatrixXd H = grams.G[static_cast<size_t>(fit.folds)](sc.stage2, sc.stage2);
  H.diagonal() += sc.ridge(sc.stage2);
  storeStage2(model, H, x, joint.variance);
  Eigen::VectorXd new_share = Eigen::VectorXd::Zero(geometry);
  for (const Profile& p : model.profiles) new_share += p.geometry;
  model.global.chain_Tracker =
      model.global.chain_Tracker.corrected(delta.head(geometry) + old_share - new_share);

  for (size_t c = 0; c < params.size(); ++c) {
    sc.current(sc.stage1[static_cast<size_t>(geometry) + c]) += delta(geometry + static_cast<Eigen::Index>(c));
  }
  setStage2(sc, model, geometry);
  grams.takeOut(moved);
  model.sigma_pending.reset();
}

void buildScreening(DiagnosisModel& model, const FitRows& fit, const DiagnoseOptions& options,
                    const std::optional<std::vector<double>>& body_masses, Screening& sc,
                    std::unique_ptr<FoldGrams>& grams, JointVector& compliance_sigma,
                    const ScreeningScope& scope) {
  grams.reset();  // the Grams it replaces go first: at most one screening matrix is held
  const Eigen::Index geometry = 6 * (model.global.chain_Tracker.dof() + 1);
  Eigen::VectorXd r0;
  {
    Evaluation start = evaluate(model.combined(), fit);
    sc = screening(model, fit, start, options, body_masses, scope);
    r0 = std::move(start.r);
  }  // its link angles and torques go before the Grams are made
  grams = std::make_unique<FoldGrams>(std::move(sc.columns), std::move(r0), fit);
  sc.columns = ScreeningColumns();
  completeScreening(sc, *grams, geometry);
  if (!model.profiles.empty()) jointStep(model, sc, *grams, fit, geometry, compliance_sigma);
}

}  // namespace stepcal::trainer::diagnosis
