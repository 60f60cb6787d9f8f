#include <algorithm>
#include <cmath>
#include <limits>

#include "../least_squares.hpp"
#include "chunked_gram.hpp"
#include "families/families.hpp"
#include "model.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Singular values below this fraction of the largest are unobservable (as in step 1).
constexpr double kRankTolerance = 1e-9;

bool apply(const PhysicalModel& model, const std::vector<Parameter>& params,
           const Eigen::VectorXd& x, double fraction, PhysicalModel& out) {
  const int geometry = 6 * (model.chain_Tracker.dof() + 1);
  out = model;
  out.chain_Tracker = model.chain_Tracker.corrected(fraction * x.head(geometry));
  for (size_t c = 0; c < params.size(); ++c) {
    shift(out, params[c], fraction * x(geometry + static_cast<Eigen::Index>(c)));
  }
  for (const Mechanism& m : out.mechanisms) {
    if (!mechanismProblem(m, out.chain_Tracker.dof()).empty()) return false;
  }
  return true;
}

// Whether the physics bounds a parameter below by zero: a free compliance, a lost motion or an
// extra compliance (signConstrained).
bool boundedAtZero(const PhysicalModel& model, const Parameter& p) {
  if (p.mechanism < 0) return true;
  const std::vector<int> constrained = signConstrained(model.mechanisms[static_cast<size_t>(p.mechanism)]);
  return std::find(constrained.begin(), constrained.end(), p.index) != constrained.end();
}

double valueOf(const PhysicalModel& model, const Parameter& p) {
  return p.mechanism < 0 ? model.compliance_rad_per_nm(p.index)
                         : model.mechanisms[static_cast<size_t>(p.mechanism)].parameter(p.index);
}

// Lower bounds of a step of the geometry and params: a bounded parameter may fall to zero.
Eigen::VectorXd stepBounds(const PhysicalModel& model, const std::vector<Parameter>& params) {
  const Eigen::Index geometry = 6 * (model.chain_Tracker.dof() + 1);
  Eigen::VectorXd lower = Eigen::VectorXd::Constant(
      geometry + static_cast<Eigen::Index>(params.size()), -std::numeric_limits<double>::infinity());
  for (size_t c = 0; c < params.size(); ++c) {
    if (boundedAtZero(model, params[c])) {
      lower(geometry + static_cast<Eigen::Index>(c)) = -valueOf(model, params[c]);
    }
  }
  return lower;
}

// The mechanisms whose kind bounds combinations of their parameters (KindFit::bounds: a lumped
// self weight's masses and first moments) and that have free parameters in params.
std::vector<size_t> combinationBounded(const PhysicalModel& model,
                                       const std::vector<Parameter>& params) {
  std::vector<size_t> out;
  for (const Parameter& p : params) {
    if (p.mechanism < 0) continue;
    const size_t k = static_cast<size_t>(p.mechanism);
    const KindFit* fit = findKindFit(model.mechanisms[k].kind);
    if (fit == nullptr || fit->bounds == nullptr) continue;
    if (std::find(out.begin(), out.end(), k) == out.end()) out.push_back(k);
  }
  return out;
}

// A step of the geometry and params under the physics' bounds: each bounded parameter's own
// (stepBounds) by solveReducedBounded; with bounds on combinations too (combinationBounded), all
// of them as rows C δ ≥ d (d = −the bound's value now ≤ 0, the model being feasible) by
// solveReducedConstrained, the exact constrained step. at_bound: per variable, whether its own
// bound ends held.
Eigen::VectorXd boundedStep(const TallQr& system, const PhysicalModel& model,
                            const std::vector<Parameter>& params, std::vector<bool>* at_bound) {
  const Eigen::VectorXd lower = stepBounds(model, params);
  const std::vector<size_t> combined = combinationBounded(model, params);
  if (combined.empty()) return solveReducedBounded(system, kRankTolerance, lower, at_bound);
  const Eigen::Index geometry = 6 * (model.chain_Tracker.dof() + 1), p = lower.size();
  std::vector<Eigen::VectorXd> rows;
  std::vector<double> floors;
  std::vector<Eigen::Index> own;  // the variable of each of the first rows
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!std::isfinite(lower(c))) continue;
    rows.push_back(Eigen::VectorXd::Unit(p, c));
    floors.push_back(lower(c));
    own.push_back(c);
  }
  for (size_t k : combined) {
    const Mechanism& m = model.mechanisms[k];
    for (const PhysicalBound& b : findKindFit(m.kind)->bounds(m, model.chain_Tracker)) {
      Eigen::VectorXd row = Eigen::VectorXd::Zero(p);
      for (const auto& [index, coefficient] : b.terms) {
        for (size_t c = 0; c < params.size(); ++c) {
          if (params[c].mechanism == static_cast<int>(k) && params[c].index == index) {
            row(geometry + static_cast<Eigen::Index>(c)) += coefficient;
          }
        }
      }
      rows.push_back(std::move(row));
      floors.push_back(std::min(0.0, -b.value(m)));
    }
  }
  Eigen::MatrixXd C(static_cast<Eigen::Index>(rows.size()), p);
  Eigen::VectorXd d(static_cast<Eigen::Index>(rows.size()));
  for (size_t r = 0; r < rows.size(); ++r) {
    C.row(static_cast<Eigen::Index>(r)) = rows[r].transpose();
    d(static_cast<Eigen::Index>(r)) = floors[r];
  }
  std::vector<bool> active;
  const Eigen::VectorXd x = solveReducedConstrained(system, kRankTolerance, C, d, &active);
  if (at_bound) {
    at_bound->assign(static_cast<size_t>(p), false);
    for (size_t r = 0; r < own.size(); ++r) (*at_bound)[static_cast<size_t>(own[r])] = active[r];
  }
  return x;
}

double priorCost(const DiagnosisModel& model, const PhysicalModel& global) {
  if (model.masses_from_urdf) return 0.0;
  double cost = 0.0;
  for (const Mechanism& m : global.mechanisms) {
    if (m.kind != MechanismKind::kSelfWeight) continue;
    for (double v : m.parameters) cost += (v / kSelfWeightPriorSigma) * (v / kSelfWeightPriorSigma);
  }
  return cost;
}

// The linearised system of the global part (geometry and parameters, then the lumped masses'
// prior rows (value − 0)/σ), reduced chunk by chunk of rows: its Jacobian is never held whole.
TallQr linearSystem(const DiagnosisModel& model, const PhysicalModel& global, const FitRows& fit,
                    const Eigen::VectorXd& r, const std::vector<Parameter>& params) {
  const Eigen::Index geometry = 6 * (global.chain_Tracker.dof() + 1);
  const Eigen::Index p = geometry + static_cast<Eigen::Index>(params.size());
  std::vector<TallQr> slices(kGramSlices, TallQr(p));
  forEachChunk(fit, [&](size_t slice, size_t begin, size_t end) {
    const Eigen::Index first = equationOf(fit, begin), count = equationOf(fit, end) - first;
    const Eigen::VectorXd r_chunk = r.segment(first, count);
    Eigen::MatrixXd A(count, p);
    A.leftCols(geometry) = linearise(global, fit, begin, end, r_chunk).geometry;
    A.rightCols(static_cast<Eigen::Index>(params.size())) =
        parameterColumns(global, params, fit, begin, end, r_chunk);
    slices[slice].add(A, r_chunk);
  });
  TallQr system(p);
  for (const TallQr& slice : slices) system.add(slice);
  if (model.masses_from_urdf) return system;
  for (size_t c = 0; c < params.size(); ++c) {
    const Parameter& q = params[c];
    if (q.mechanism < 0 ||
        global.mechanisms[static_cast<size_t>(q.mechanism)].kind != MechanismKind::kSelfWeight) {
      continue;
    }
    const double value = global.mechanisms[static_cast<size_t>(q.mechanism)].parameter(q.index);
    Eigen::MatrixXd prior = Eigen::MatrixXd::Zero(1, p);
    prior(0, geometry + static_cast<Eigen::Index>(c)) = 1.0 / kSelfWeightPriorSigma;
    system.add(prior, Eigen::VectorXd::Constant(1, -value / kSelfWeightPriorSigma));
  }
  return system;
}

}  // namespace

PhysicalModel DiagnosisModel::combined() const {
  PhysicalModel out = global;
  for (const Profile& p : profiles) out.mechanisms.push_back(p.mechanism);
  for (const Profile& p : profiles) {
    if (p.geometry.size() == 0) continue;
    Mechanism m;
    m.kind = MechanismKind::kProfileGeometry;
    m.joint = p.mechanism.joint;
    m.parameters.assign(p.geometry.data(), p.geometry.data() + p.geometry.size());
    m.sigma.assign(p.geometry_sigma.data(), p.geometry_sigma.data() + p.geometry_sigma.size());
    out.mechanisms.push_back(std::move(m));
  }
  return out;
}

void shift(PhysicalModel& model, const Parameter& p, double delta) {
  if (p.mechanism < 0) {
    model.compliance_rad_per_nm(p.index) += delta;
  } else {
    model.mechanisms[static_cast<size_t>(p.mechanism)].parameter(p.index) += delta;
  }
}

double typicalStep(const Mechanism& m, int index) {
  const KindFit* fit = findKindFit(m.kind);
  return fit != nullptr && fit->typical_step != nullptr ? fit->typical_step(m, index) : 1e-4;
}

bool isShape(const PhysicalModel& model, const Parameter& p) {
  if (p.mechanism < 0) return false;
  const KindFit* fit = findKindFit(model.mechanisms[static_cast<size_t>(p.mechanism)].kind);
  return fit != nullptr && fit->is_shape != nullptr && fit->is_shape(p.index);
}

std::vector<int> signConstrained(const Mechanism& m) {
  const KindFit* fit = findKindFit(m.kind);
  return fit != nullptr && fit->sign_constrained != nullptr ? fit->sign_constrained(m)
                                                            : std::vector<int>{};
}

Mechanism simplestTorqueDeflection(Mechanism m) {
  if (m.kind != MechanismKind::kTorsionCurve || m.order > 0) return m;
  // Lost motion alone, which saturates: a backlash (the curve's first two parameters), no τ_lin.
  m.kind = MechanismKind::kBacklash;
  m.parameters.pop_back();
  m.sigma.pop_back();
  return m;
}

std::vector<int> freeParameters(const Mechanism& m, bool masses_from_urdf) {
  if (m.kind == MechanismKind::kSelfWeight && masses_from_urdf) return {};
  const KindFit* fit = findKindFit(m.kind);
  if (fit != nullptr && fit->free_parameters != nullptr) return fit->free_parameters(m);
  std::vector<int> free;
  for (int i = 0; i < static_cast<int>(m.parameters.size()); ++i) free.push_back(i);
  return free;
}

std::vector<Parameter> globalParameters(const DiagnosisModel& model) {
  std::vector<Parameter> params;
  const JointVector& c = model.global.compliance_rad_per_nm;
  for (int j = 0; j < c.size(); ++j) {
    // Compliance enters linearly (to the fixed point's feedback), so the step's size is free.
    if (model.compliance_free[static_cast<size_t>(j)]) {
      params.push_back({-1, j, std::max(0.01 * c(j), 1e-8)});
    }
  }
  for (size_t k = 0; k < model.global.mechanisms.size(); ++k) {
    const Mechanism& m = model.global.mechanisms[k];
    for (int i : freeParameters(m, model.masses_from_urdf)) {
      params.push_back({static_cast<int>(k), i, typicalStep(m, i)});
    }
  }
  return params;
}

Eigen::MatrixXd parameterColumns(const PhysicalModel& model, const std::vector<Parameter>& params,
                                 const FitRows& fit, size_t begin, size_t end,
                                 const Eigen::VectorXd& r0) {
  std::vector<PhysicalModel> moved(params.size(), model);
  std::vector<const PhysicalModel*> models;
  std::vector<double> steps;
  for (size_t c = 0; c < params.size(); ++c) {
    shift(moved[c], params[c], params[c].step);
    models.push_back(&moved[c]);
    steps.push_back(params[c].step);
  }
  return differenceColumns(models, steps, std::vector<bool>(params.size(), true), fit, begin, end,
                           r0);
}

GlobalFit refitGlobal(DiagnosisModel& model, const FitRows& fit, int iterations,
                      bool hold_profiles) {
  // The global mechanisms come first in combined(), so the parameters index both alike.
  PhysicalModel global = hold_profiles ? model.combined() : model.global;
  // The free parameters as the fit stands: a nonlinear stiffness's τ₀ and a torsion curve's
  // fade torques join once their compliance has moved off zero (the first step fits it).
  const auto parametersNow = [&] {
    DiagnosisModel now = model;
    now.global.mechanisms.assign(global.mechanisms.begin(),
                                 global.mechanisms.begin() +
                                     static_cast<long>(model.global.mechanisms.size()));
    return globalParameters(now);
  };
  // A bounded parameter below zero (a linear joint fit may leave one there) starts at zero.
  for (const Parameter& p : parametersNow()) {
    if (boundedAtZero(global, p) && valueOf(global, p) < 0.0) shift(global, p, -valueOf(global, p));
  }
  // And one breaking a bound on a combination (a lumped mass too small for its first moment) is
  // moved onto it: every bounded step starts feasible.
  for (size_t k : combinationBounded(global, parametersNow())) {
    makeFeasible(global.mechanisms[k], global.chain_Tracker);
  }
  GlobalFit out;
  out.r = residuals(global, fit);
  out.cost = out.r.squaredNorm() + priorCost(model, global);
  for (int it = 0; it < iterations; ++it) {
    const std::vector<Parameter> params = parametersNow();
    const Eigen::VectorXd step =
        boundedStep(linearSystem(model, global, fit, out.r, params), global, params, nullptr);
    bool improved = false;
    for (double fraction = 1.0; fraction > 1e-3; fraction *= 0.5) {
      PhysicalModel candidate;
      if (!apply(global, params, step, fraction, candidate)) continue;
      const Eigen::VectorXd r = residuals(candidate, fit);
      const double cost = r.squaredNorm() + priorCost(model, candidate);
      if (cost < out.cost) {
        // Go on while a step still removes a millionth of the cost (a tiny fraction of the noise).
        improved = out.cost - cost > 1e-6 * out.cost;
        global = std::move(candidate);
        out.r = r;
        out.cost = cost;
        break;
      }
    }
    if (!improved) break;
  }
  // The bounded parameters the rows push below zero: those at zero that the final linearisation's
  // bounded step holds there. Only a bounded step puts one at exactly zero, so without one at zero
  // there is nothing to linearise for.
  const std::vector<Parameter> params = parametersNow();
  bool any_at_zero = false;
  for (const Parameter& p : params) any_at_zero |= boundedAtZero(global, p) && valueOf(global, p) == 0.0;
  if (any_at_zero) {
    const TallQr system = linearSystem(model, global, fit, out.r, params);
    const SvdSolution s = solveReduced(system, kRankTolerance);
    std::vector<bool> at_bound;
    boundedStep(system, global, params, &at_bound);
    const int geometry = 6 * (global.chain_Tracker.dof() + 1);
    for (size_t c = 0; c < params.size(); ++c) {
      const Eigen::Index col = geometry + static_cast<Eigen::Index>(c);
      if (at_bound[static_cast<size_t>(col)] && valueOf(global, params[c]) == 0.0) {
        out.held.push_back({params[c], s.x(col)});
      }
    }
  }
  for (Mechanism& m : global.mechanisms) m.sigma.assign(m.parameters.size(), 0.0);
  global.mechanisms.resize(model.global.mechanisms.size());
  model.global = std::move(global);
  model.sigma_pending = hold_profiles;
  return out;
}

void globalSigma(DiagnosisModel& model, const FitRows& fit, JointVector& compliance_sigma) {
  if (!model.sigma_pending) return;
  PhysicalModel global = *model.sigma_pending ? model.combined() : model.global;
  const Eigen::VectorXd r = residuals(global, fit);
  const double cost = r.squaredNorm() + priorCost(model, global);
  // Covariance of the refit's final linearisation: s² (AᵀA)⁺ in column-normalised coordinates.
  const std::vector<Parameter> params = globalParameters(model);
  const SvdSolution s = solveReduced(linearSystem(model, global, fit, r, params), kRankTolerance);
  const double variance = cost / std::max(1, fit.count - s.rank);
  const int geometry = 6 * (global.chain_Tracker.dof() + 1);
  for (size_t c = 0; c < params.size(); ++c) {
    const Eigen::Index col = geometry + static_cast<Eigen::Index>(c);
    double var_z = 0.0;
    for (int k = 0; k < s.rank; ++k) var_z += std::pow(s.V(col, k) / s.singular_values(k), 2);
    const double sigma = std::sqrt(variance * var_z) / s.column_scale(col);
    const Parameter& p = params[c];
    if (p.mechanism < 0) {
      compliance_sigma(p.index) = sigma;
    } else {
      model.global.mechanisms[static_cast<size_t>(p.mechanism)].sigma[static_cast<size_t>(p.index)] = sigma;
    }
  }
  model.sigma_pending.reset();
}

}  // namespace stepcal::trainer::diagnosis
