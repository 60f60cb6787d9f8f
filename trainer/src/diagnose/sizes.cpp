// The size of each found cause in the final fit (sizes.hpp).
#include "sizes.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "chunked_gram.hpp"
#include "profiles.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Eigenvalues of an information matrix normalised to a unit diagonal below this are numerically
// zero (the geometry's gauge directions, docs/method.md, step 1: rank 30 of 42).
constexpr double kRelativeEigenTolerance = 1e-12;

Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& symmetric, int* rank = nullptr) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(symmetric);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double cutoff = kRelativeEigenTolerance * std::max(lambda.maxCoeff(), 1.0);
  Eigen::VectorXd inverse = Eigen::VectorXd::Zero(lambda.size());
  int kept = 0;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    if (lambda(i) > cutoff && lambda(i) > 0.0) {
      inverse(i) = 1.0 / lambda(i);
      ++kept;
    }
  }
  if (rank) *rank = kept;
  return eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
}

// χ² of the parameters in columns M over the directions the data determine. H: the model's
// information with its ridges and priors (AᵀA + R), normalised to a unit diagonal; ridge: R's
// diagonal and value: the parameters, normalised alike.
CauseSize sizeOf(const std::vector<Eigen::Index>& M, const Eigen::MatrixXd& H,
                 const Eigen::VectorXd& ridge, const Eigen::VectorXd& value, double variance) {
  CauseSize size;
  if (M.empty()) return size;
  std::vector<Eigen::Index> O;
  for (Eigen::Index c = 0; c < H.cols(); ++c) {
    if (std::find(M.begin(), M.end(), c) == M.end()) O.push_back(c);
  }
  // What the rows say of M once every other parameter is fitted with it (with their ridges and
  // priors): the Schur complement of the rest, without M's own prior.
  Eigen::MatrixXd information = H(M, M);
  information.diagonal() -= ridge(M);
  information -= H(M, O) * pseudoInverse(H(O, O)) * H(O, M);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(information);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const Eigen::VectorXd p = value(M);
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    const Eigen::VectorXd v = eig.eigenvectors().col(i);
    const double prior = v.dot(ridge(M).asDiagonal() * v);
    if (!(lambda(i) > kRelativeEigenTolerance) || lambda(i) <= prior) continue;
    const double along = v.dot(p);
    size.chi2 += lambda(i) * along * along / variance;
    ++size.dof;
  }
  return size;
}

}  // namespace

std::vector<CauseSize> causeSizes(const DiagnosisModel& model, const FitRows& fit,
                                  const Diagnosis& d, size_t base_globals, size_t base_profiles) {
  const PhysicalModel whole = model.combined();
  const Eigen::VectorXd r = residuals(whole, fit);
  const std::vector<Parameter> params = globalParameters(model);
  const Eigen::Index geometry = 6 * (whole.chain_Tracker.dof() + 1);
  Eigen::Index width = geometry + static_cast<Eigen::Index>(params.size());
  for (const Profile& p : model.profiles) width += 2 * p.mechanism.order;

  // The model's columns (geometry, global parameters, every profile's coefficients), as the
  // joint fit holds them, with their ridges and values.
  Eigen::VectorXd ridge = Eigen::VectorXd::Zero(width), value = Eigen::VectorXd::Zero(width);
  for (size_t c = 0; c < params.size(); ++c) {
    const Parameter& p = params[c];
    const Eigen::Index column = geometry + static_cast<Eigen::Index>(c);
    if (p.mechanism < 0) {
      value(column) = model.global.compliance_rad_per_nm(p.index);
      continue;
    }
    const Mechanism& m = model.global.mechanisms[static_cast<size_t>(p.mechanism)];
    value(column) = m.parameter(p.index);
    if (m.kind == MechanismKind::kSelfWeight && !model.masses_from_urdf) {
      ridge(column) = 1.0 / (kSelfWeightPriorSigma * kSelfWeightPriorSigma);
    }
  }
  Eigen::Index at = geometry + static_cast<Eigen::Index>(params.size());
  for (const Profile& p : model.profiles) {
    const Mechanism& m = p.mechanism;
    const Eigen::Index w = 2 * m.order;
    for (Eigen::Index k = 0; k < w; ++k) {
      ridge(at + k) = p.ridge;
      value(at + k) = m.parameter(static_cast<int>(k));
    }
    at += w;
  }
  // The model's columns chunk by chunk of rows, never held whole.
  const auto rowsOfA = [&](size_t begin, size_t end) {
    const Eigen::VectorXd r_chunk = equationsOf(r, fit, begin, end);
    const Linearisation lin = linearise(whole, fit, begin, end, r_chunk);
    Eigen::MatrixXd A(r_chunk.size(), width);
    A.leftCols(geometry) = lin.geometry;
    A.middleCols(geometry, static_cast<Eigen::Index>(params.size())) =
        parameterColumns(whole, params, fit, begin, end, r_chunk);
    A.rightCols(width - geometry - static_cast<Eigen::Index>(params.size())) =
        profilesColumns(model.profiles, lin.link_angle, fit, begin, end);
    return A;
  };

  // Normalised to a unit diagonal, ridges and priors in (1 for a column nothing sees), so the
  // tolerance means the same for every column and a prior on a column the rows barely see
  // cannot dwarf the rest.
  Eigen::MatrixXd H = chunkedGram(fit, width, r, rowsOfA).H;
  H.diagonal() += ridge;
  const Eigen::VectorXd scale =
      H.diagonal().unaryExpr([](double h) { return h > 0.0 ? std::sqrt(h) : 1.0; });
  const Eigen::VectorXd inverse_scale = scale.cwiseInverse();
  H = inverse_scale.asDiagonal() * H * inverse_scale.asDiagonal();
  const Eigen::VectorXd ridge_n = ridge.cwiseProduct(inverse_scale).cwiseProduct(inverse_scale);
  int rank = 0;
  pseudoInverse(H, &rank);
  const double variance = std::max(r.squaredNorm() / std::max(1, fit.count - rank), 1e-300);
  const Eigen::VectorXd value_n = value.cwiseProduct(scale);

  std::vector<CauseSize> sizes;
  size_t next_global = base_globals, next_profile = base_profiles;
  for (const FoundEffect& effect : d.effects) {
    if (effect.mechanism.kind == MechanismKind::kTransmissionError) {
      const Profile& p = model.profiles[next_profile++];
      sizes.push_back({p.size_chi2, 2 * p.mechanism.order});
      continue;
    }
    const int k = static_cast<int>(next_global++);
    const Mechanism& m = model.global.mechanisms[static_cast<size_t>(k)];
    const bool urdf_self_weight = m.kind == MechanismKind::kSelfWeight && model.masses_from_urdf;
    std::vector<Eigen::Index> M;
    for (size_t c = 0; c < params.size(); ++c) {
      const Parameter& p = params[c];
      const bool frees = urdf_self_weight && p.mechanism < 0 &&
                         std::find(effect.compliance_joints.begin(), effect.compliance_joints.end(),
                                   p.index) != effect.compliance_joints.end();
      if (p.mechanism == k || frees) M.push_back(geometry + static_cast<Eigen::Index>(c));
    }
    CauseSize size = sizeOf(M, H, ridge_n, value_n, variance);
    const std::vector<PhysicalBound> bounds = physicalBounds(m, model.global.chain_Tracker);
    const auto held = [&m](const PhysicalBound& b) { return b.value(m) <= b.tolerance; };
    size.on_bound = !urdf_self_weight && std::any_of(bounds.begin(), bounds.end(), held);
    size.variance = variance;
    sizes.push_back(size);
  }
  return sizes;
}

}  // namespace stepcal::trainer::diagnosis
