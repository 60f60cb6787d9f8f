// The residual GP's predictive side (docs/method.md eq. 27, 30, 31); interface in gpr_predictor.hpp.
#include "stepcal/common/gpr_predictor.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <utility>

#include <Eigen/Cholesky>

#include "stepcal/common/error.hpp"

namespace stepcal {
namespace {

std::string shape(Eigen::Index rows, Eigen::Index cols) {
  return std::to_string(rows) + " × " + std::to_string(cols);
}

/// Throws InputError unless `value` is rows × cols with every entry finite.
template <typename Derived>
void requireFinite(const Eigen::DenseBase<Derived>& value, Eigen::Index rows, Eigen::Index cols,
                   const std::string& field) {
  if (value.rows() != rows || value.cols() != cols) {
    throw InputError("GPR " + field + " is " + shape(value.rows(), value.cols()) + "; expected " +
                     shape(rows, cols));
  }
  if (!value.allFinite()) throw InputError("GPR " + field + " has a value that is not finite");
}

/// Throws InputError unless every entry of a (finite) vector of scales is > 0.
void requirePositive(const Eigen::VectorXd& scales, const std::string& field) {
  if (!(scales.array() > 0.0).all()) {
    throw InputError("GPR " + field + " has an entry ≤ 0; expected positive scales");
  }
}

/// The kernel between every training input and one point (docs/method.md eq. 27):
/// k_i = σ_f² exp(−½ ‖z_i − z‖²), z_i the rows of Z; inputs normalised and divided by ℓ.
template <typename Inputs, typename Point, typename Column>
void kernelColumnOf(const Inputs& Z, const Point& z, double signal_variance, Column&& k) {
  k.setZero();
  for (Eigen::Index d = 0; d < Z.cols(); ++d) k.array() += (Z.col(d).array() - z(d)).square();
  k.array() = signal_variance * (-0.5 * k.array()).exp();
}

/// Lowest argument of expInPlace: e^−708 ≈ 3.3e-308 is the last power above the subnormals.
constexpr double kLowestExpArgument = -708.0;

/// x ← e^x for every x in [kLowestExpArgument, 0], within 1 ulp of std::exp (checked over 10⁶
/// arguments): x = n ln 2 + r with n an integer and |r| ≤ ½ ln 2, e^r by its Taylor series to
/// r¹³ (the rest below 4e-18 of it), times 2^n written into the exponent bits. No branch, table
/// or library call, so the compiler vectorises the loop (Eigen's exp divides per element).
void expInPlace(double* x, Eigen::Index count) noexcept {
  constexpr double kLog2e = 1.4426950408889634074;
  constexpr double kLn2High = 6.93147180369123816490e-01;  // 32 bits of ln 2: n · it is exact
  constexpr double kLn2Low = 1.90821492927058770002e-10;   // ln 2 − kLn2High
  constexpr double kRoundShift = 6755399441055744.0;  // 1.5 · 2^52: t + it rounds t, |t| < 2^51
  int64_t shift_bits;
  std::memcpy(&shift_bits, &kRoundShift, sizeof shift_bits);
  for (Eigen::Index i = 0; i < count; ++i) {
    const double v = x[i];
    const double shifted = v * kLog2e + kRoundShift;  // n in its low mantissa bits
    const double n = shifted - kRoundShift;
    const double r = (v - n * kLn2High) - n * kLn2Low;
    double p = 1.0 / 6227020800.0;  // 1/13!, then Horner down to 1/0!
    p = p * r + 1.0 / 479001600.0;
    p = p * r + 1.0 / 39916800.0;
    p = p * r + 1.0 / 3628800.0;
    p = p * r + 1.0 / 362880.0;
    p = p * r + 1.0 / 40320.0;
    p = p * r + 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    p = p * r + 1.0;
    p = p * r + 1.0;
    int64_t n_bits;
    std::memcpy(&n_bits, &shifted, sizeof n_bits);
    const int64_t scale_bits = (n_bits - shift_bits + 1023) * (int64_t{1} << 52);  // 2^n
    double scale;
    std::memcpy(&scale, &scale_bits, sizeof scale);
    x[i] = p * scale;
  }
}

/// Latent predictive std, standardised units (eq. 31): √max(0, σ_f² − vᵀv) with v = L⁻¹ k*,
/// solved in place of k; inverse_diagonal holds 1 / L_jj.
double latentStd(const Eigen::MatrixXd& L, const Eigen::VectorXd& inverse_diagonal,
                 double signal_variance, Eigen::VectorXd& k) noexcept {
  // v = L⁻¹ k in place by column-oriented forward substitution: each step an axpy down one
  // contiguous column of L (vectorised), where row-wise substitution waits on every product; a
  // product by 1 / L_jj rather than a division on that chain of steps.
  const Eigen::Index n = k.size();
  double* v = k.data();
  for (Eigen::Index j = 0; j < n; ++j) {
    const double* column = L.data() + j * L.rows();
    const double v_j = v[j] * inverse_diagonal(j);
    v[j] = v_j;
    for (Eigen::Index i = j + 1; i < n; ++i) v[i] -= v_j * column[i];
  }
  return std::sqrt(std::max(0.0, signal_variance - k.squaredNorm()));
}

/// r rows of Z by farthest-point sampling (Euclidean in Z), from row 0; ties go to the lowest
/// index. Returned ascending.
Eigen::VectorXi farthestPointSubset(const Eigen::MatrixXd& Z, Eigen::Index r) {
  const Eigen::Index m = Z.rows();
  Eigen::VectorXi chosen(r);
  Eigen::VectorXd nearest = Eigen::VectorXd::Constant(m, std::numeric_limits<double>::infinity());
  Eigen::Index next = 0;
  for (Eigen::Index s = 0; s < r; ++s) {
    chosen(s) = static_cast<int>(next);
    nearest = nearest.cwiseMin((Z.rowwise() - Z.row(next)).rowwise().squaredNorm());
    nearest(next) = -1.0;  // never again
    nearest.maxCoeff(&next);  // first maximum
  }
  std::sort(chosen.data(), chosen.data() + r);
  return chosen;
}

}  // namespace

GprPredictor GprPredictor::fromParameters(const GprParameters& parameters) {
  requireFinite(parameters.alpha, parameters.inputs_normalised.rows(),
                parameters.output_mean.size(), "alpha");
  GprPredictor predictor = factorised(parameters);
  predictor.held_out_noise_ = predictor.heldOutNoiseOfAlpha();
  return predictor;
}

GprPredictor GprPredictor::conditioned(GprParameters parameters) {
  GprPredictor predictor = factorised(std::move(parameters));
  Eigen::MatrixXd& L = predictor.cholesky_lower_;
  GprParameters& g = predictor.parameters_;
  g.alpha = L.triangularView<Eigen::Lower>().solve(g.targets_standardised);
  L.triangularView<Eigen::Lower>().transpose().solveInPlace(g.alpha);
  predictor.held_out_noise_ = predictor.heldOutNoiseOfAlpha();
  return predictor;
}

Eigen::VectorXd GprPredictor::heldOutNoiseOfAlpha() const {
  const GprParameters& g = parameters_;
  const Eigen::Index m = g.alpha.rows();
  // diag (K + σ_n² I)⁻¹: the squared column norms of L⁻¹.
  const Eigen::MatrixXd L_inverse = cholesky_lower_.triangularView<Eigen::Lower>().solve(
      Eigen::MatrixXd::Identity(m, m));
  const Eigen::ArrayXd precision = L_inverse.colwise().squaredNorm().transpose().array();
  // Point i predicted from the others: residual α_i / [K⁻¹]_ii, predictive variance
  // 1 / [K⁻¹]_ii, of which all but σ_n² is the latent function's.
  const double latent_variance =
      (precision.inverse() - g.noise_sigma * g.noise_sigma).max(0.0).mean();
  Eigen::VectorXd noise(g.alpha.cols());
  for (Eigen::Index o = 0; o < g.alpha.cols(); ++o) {
    const double residual_variance = (g.alpha.col(o).array() / precision).square().mean();
    noise(o) = std::sqrt(std::max(0.0, residual_variance - latent_variance));
  }
  return noise;
}

GprPredictor GprPredictor::factorised(GprParameters parameters) {
  const GprParameters& g = parameters;
  const Eigen::Index m = g.inputs_normalised.rows(), D = g.inputs_normalised.cols(),
                     P = g.output_mean.size();
  if (m < 1 || D < 1 || P < 1) {
    throw InputError("GPR has m = " + std::to_string(m) + " training points, D = " +
                     std::to_string(D) + " inputs and P = " + std::to_string(P) +
                     " outputs; expected at least one of each");
  }
  requireFinite(g.inputs_normalised, m, D, "inputs_normalised");
  requireFinite(g.input_offset, D, 1, "input_offset");
  requireFinite(g.input_scale, D, 1, "input_scale");
  requireFinite(g.output_mean, P, 1, "output_mean");
  requireFinite(g.output_scale, P, 1, "output_scale");
  requireFinite(g.length_scales, D, 1, "length_scales");
  requireFinite(g.targets_standardised, m, P, "targets_standardised");
  requirePositive(g.input_scale, "input_scale");
  requirePositive(g.output_scale, "output_scale");
  requirePositive(g.length_scales, "length_scales");
  if (!(std::isfinite(g.signal_sigma) && g.signal_sigma > 0.0 && std::isfinite(g.noise_sigma) &&
        g.noise_sigma >= 0.0)) {
    throw InputError("GPR has σ_f = " + std::to_string(g.signal_sigma) + ", σ_n = " +
                     std::to_string(g.noise_sigma) + "; expected finite σ_f > 0 and σ_n ≥ 0");
  }
  if (!(std::isfinite(g.payload_force_reference_n) && g.payload_force_reference_n >= 0.0) ||
      (g.payload_force_reference_n > 0.0 && D < 6)) {
    throw InputError("GPR has payload_force_reference_n = " +
                     std::to_string(g.payload_force_reference_n) + " with " + std::to_string(D) +
                     " inputs; expected 0 (the paper's GPR) or a finite force > 0 N with the "
                     "wrench as the last six inputs");
  }

  GprPredictor predictor;
  predictor.parameters_ = std::move(parameters);
  const GprParameters& p = predictor.parameters_;
  predictor.inverse_length_scales_ = p.length_scales.cwiseInverse();
  const Eigen::MatrixXd Z = p.inputs_normalised * predictor.inverse_length_scales_.asDiagonal();
  // Lower triangle of K + σ_n² I, column by column with the kernel predictions use.
  Eigen::MatrixXd& L = predictor.cholesky_lower_;
  L.setZero(m, m);
  for (Eigen::Index j = 0; j < m; ++j) {
    kernelColumnOf(Z.bottomRows(m - j), Z.row(j), p.signal_sigma * p.signal_sigma,
                   L.col(j).tail(m - j));
    L(j, j) += p.noise_sigma * p.noise_sigma;
  }
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(L);
  if (llt.info() != Eigen::Success || !L.diagonal().allFinite() ||
      !(L.diagonal().array() > 0.0).all()) {
    throw InputError(
        "GPR kernel matrix K + σ_n² I is not positive definite for these inputs and "
        "hyperparameters");
  }
  predictor.cholesky_inverse_diagonal_ = L.diagonal().cwiseInverse();
  // Predictions keep the inputs that vary over the training set; one every training point shares
  // (a wrench that is always zero without an F/T sensor) adds the same (z_d − x_d)² to every
  // squared distance, computed once per query.
  for (Eigen::Index d = 0; d < D; ++d) {
    if ((Z.col(d).array() == Z(0, d)).all()) {
      predictor.constant_dims_.push_back(static_cast<int>(d));
      predictor.constant_values_.push_back(Z(0, d));
    } else {
      predictor.varying_dims_.push_back(static_cast<int>(d));
    }
  }
  predictor.scaled_inputs_ = Z(Eigen::all, predictor.varying_dims_);
  predictor.scaled_input_norms_ = predictor.scaled_inputs_.rowwise().squaredNorm();
  // The subset behind the std bound, factorised with the same kernel code as the full matrix
  // (a principal submatrix of K + σ_n² I: equal to it, bit for bit, when r = m).
  const Eigen::Index r = std::min<Eigen::Index>(m, kMaxBoundSubset);
  predictor.subset_indices_ = farthestPointSubset(Z, r);
  Eigen::MatrixXd Z_subset(r, D);
  for (Eigen::Index s = 0; s < r; ++s) Z_subset.row(s) = Z.row(predictor.subset_indices_(s));
  Eigen::MatrixXd L_S = Eigen::MatrixXd::Zero(r, r);
  for (Eigen::Index j = 0; j < r; ++j) {
    kernelColumnOf(Z_subset.bottomRows(r - j), Z_subset.row(j), p.signal_sigma * p.signal_sigma,
                   L_S.col(j).tail(r - j));
    L_S(j, j) += p.noise_sigma * p.noise_sigma;
  }
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> subset_llt(L_S);
  if (subset_llt.info() != Eigen::Success || !L_S.diagonal().allFinite() ||
      !(L_S.diagonal().array() > 0.0).all()) {
    throw InputError(
        "GPR kernel matrix of the std bound's training subset is not positive definite");
  }
  predictor.subset_cholesky_inverse_ =
      L_S.triangularView<Eigen::Lower>().solve(Eigen::MatrixXd::Identity(r, r));
  return predictor;
}

double GprPredictor::outputGain(const double* x_raw) const noexcept {
  const double reference = parameters_.payload_force_reference_n;
  if (reference == 0.0) return 1.0;
  const double* force = x_raw + inputDim() - 6;
  return std::sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]) / reference;
}

int GprPredictor::inputDim() const noexcept {
  return static_cast<int>(parameters_.inputs_normalised.cols());
}

int GprPredictor::outputDim() const noexcept { return static_cast<int>(parameters_.alpha.cols()); }

int GprPredictor::trainingSize() const noexcept {
  return static_cast<int>(parameters_.inputs_normalised.rows());
}

GprPredictor::Workspace GprPredictor::makeWorkspace() const {
  Workspace workspace;
  workspace.normalised_input.setZero(inputDim());
  workspace.varying_input.setZero(static_cast<Eigen::Index>(varying_dims_.size()));
  workspace.kernel_column.setZero(trainingSize());
  workspace.subset_column.setZero(boundSubsetSize());
  return workspace;
}

void GprPredictor::kernelColumn(const double* x_raw, Workspace& workspace) const noexcept {
  const GprParameters& g = parameters_;
  Eigen::VectorXd& z = workspace.normalised_input;
  for (Eigen::Index d = 0; d < z.size(); ++d) {
    z(d) = (x_raw[d] - g.input_offset(d)) / g.input_scale(d) * inverse_length_scales_(d);
  }
  double z_norm = 0.0;  // ‖z_v‖² over the varying inputs, plus Σ (z_c − x_c)² over the others
  for (size_t v = 0; v < varying_dims_.size(); ++v) {
    const double z_v = z(varying_dims_[v]);
    workspace.varying_input(static_cast<Eigen::Index>(v)) = z_v;
    z_norm += z_v * z_v;
  }
  for (size_t c = 0; c < constant_dims_.size(); ++c) {
    const double d = z(constant_dims_[c]) - constant_values_[c];
    z_norm += d * d;
  }
  Eigen::VectorXd& k = workspace.kernel_column;
  k.noalias() = scaled_inputs_ * workspace.varying_input;
  // Beyond a distance of 37.6 length scales the kernel is taken as σ_f² e^−708 (≈ 3e-308 σ_f²)
  // instead of smaller: nothing any prediction could resolve.
  k.array() = (-0.5 * (scaled_input_norms_.array() + z_norm - 2.0 * k.array()).max(0.0))
                  .max(kLowestExpArgument);
  expInPlace(k.data(), k.size());
  k *= g.signal_sigma * g.signal_sigma;
}

void GprPredictor::meanFromColumn(const Workspace& workspace, double* mean_out) const noexcept {
  const GprParameters& g = parameters_;
  Eigen::Map<Eigen::VectorXd> mean(mean_out, g.alpha.cols());
  mean.noalias() = g.alpha.transpose() * workspace.kernel_column;
  mean.array() = g.output_mean.array() + g.output_scale.array() * mean.array();
}

double GprPredictor::subsetLatentStd(Workspace& workspace) const noexcept {
  Eigen::VectorXd& k_subset = workspace.subset_column;
  for (Eigen::Index s = 0; s < k_subset.size(); ++s) {
    k_subset(s) = workspace.kernel_column(subset_indices_(s));
  }
  // v_S = L_S⁻¹ k_S as one dense matrix–vector product (r ≤ 48: no chain of dependent steps as
  // in a substitution), into the head of the kernel column, which the mean no longer needs.
  auto v = workspace.kernel_column.head(k_subset.size());
  v.noalias() = subset_cholesky_inverse_ * k_subset;
  const double signal_variance = parameters_.signal_sigma * parameters_.signal_sigma;
  return std::sqrt(std::max(0.0, signal_variance - v.squaredNorm()));
}

double GprPredictor::exactLatentStd(Workspace& workspace) const noexcept {
  if (boundSubsetSize() == trainingSize()) return subsetLatentStd(workspace);  // the same GP
  const double signal_variance = parameters_.signal_sigma * parameters_.signal_sigma;
  return latentStd(cholesky_lower_, cholesky_inverse_diagonal_, signal_variance,
                   workspace.kernel_column);
}

void GprPredictor::predictInto(const double* x_raw, double* mean_out, double* std_out,
                               Workspace& workspace) const noexcept {
  const GprParameters& g = parameters_;
  const double gain = outputGain(x_raw);
  if (gain == 0.0) {
    zeroOutputs(mean_out, std_out);
    return;
  }
  kernelColumn(x_raw, workspace);
  meanFromColumn(workspace, mean_out);
  if (std_out != nullptr) {
    const double latent_std = exactLatentStd(workspace);
    for (Eigen::Index o = 0; o < g.alpha.cols(); ++o) std_out[o] = g.output_scale(o) * latent_std;
  }
  applyGain(gain, mean_out, std_out);
}

void GprPredictor::zeroOutputs(double* mean_out, double* std_out) const noexcept {
  for (Eigen::Index o = 0; o < parameters_.alpha.cols(); ++o) {
    mean_out[o] = 0.0;
    if (std_out != nullptr) std_out[o] = 0.0;
  }
}

void GprPredictor::applyGain(double gain, double* mean_out, double* std_out) const noexcept {
  if (parameters_.payload_force_reference_n == 0.0) return;  // the paper's GPR: as computed
  for (Eigen::Index o = 0; o < parameters_.alpha.cols(); ++o) {
    mean_out[o] *= gain;
    if (std_out != nullptr) std_out[o] *= gain;
  }
}

void GprPredictor::predictMeanAndBoundInto(const double* x_raw, double* mean_out,
                                           double* std_bound_out,
                                           Workspace& workspace) const noexcept {
  const GprParameters& g = parameters_;
  const double gain = outputGain(x_raw);
  if (gain == 0.0) {
    zeroOutputs(mean_out, std_bound_out);
    return;
  }
  kernelColumn(x_raw, workspace);
  meanFromColumn(workspace, mean_out);
  if (std_bound_out != nullptr) {
    const double latent_std = subsetLatentStd(workspace);
    for (Eigen::Index o = 0; o < g.alpha.cols(); ++o) {
      std_bound_out[o] = g.output_scale(o) * latent_std;
    }
  }
  applyGain(gain, mean_out, std_bound_out);
}

double GprPredictor::relativeStd(const double* x_raw, Workspace& workspace) const noexcept {
  const GprParameters& g = parameters_;
  const double gain = outputGain(x_raw);
  if (gain == 0.0) return 0.0;
  kernelColumn(x_raw, workspace);
  const double relative = exactLatentStd(workspace) / g.signal_sigma;
  return g.payload_force_reference_n == 0.0 ? relative : gain * relative;
}

double GprPredictor::relativeStdBound(const double* x_raw, Workspace& workspace) const noexcept {
  const double gain = outputGain(x_raw);
  if (gain == 0.0) return 0.0;
  kernelColumn(x_raw, workspace);
  const double relative = subsetLatentStd(workspace) / parameters_.signal_sigma;
  return parameters_.payload_force_reference_n == 0.0 ? relative : gain * relative;
}

void tipTwistFromGprOutput(const GprParameters& gpr, const Mat3& R_TrackerTip, Vec6& twist) noexcept {
  if (gpr.payload_force_reference_n == 0.0) return;
  twist.head<3>() = R_TrackerTip.transpose() * twist.head<3>().eval();
  twist.tail<3>() = R_TrackerTip.transpose() * twist.tail<3>().eval();
}

}  // namespace stepcal
