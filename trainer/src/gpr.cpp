#include "stepcal/trainer/gpr.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <thread>
#include <utility>

#include <Eigen/Cholesky>
#include <LBFGSB.h>

#include "stepcal/common/error.hpp"

namespace stepcal::trainer {
namespace {

constexpr double kLog2Pi = 1.8378770664093454836;  // log(2π)
// Column-block width of the blocked triangular inverse and K⁻¹ product.
constexpr Eigen::Index kBlockWidth = 48;
// Per-sample objective returned to the optimiser where the Cholesky factorisation fails.
constexpr double kFailedObjective = 1e10;
// A column whose sample std is at most this fraction of its largest magnitude is constant.
constexpr double kConstantColumnTolerance = 1e-10;
// fromParts rejects α whose normwise backward error exceeds this.
constexpr double kAlphaBackwardErrorLimit = 1e-8;
// The cache sizes Eigen's matrix products and triangular solves are told, bytes: its own
// fallback values for x86 (see pinEigenBlocking).
constexpr std::ptrdiff_t kPinnedL1CacheBytes = 32 * 1024;
constexpr std::ptrdiff_t kPinnedL2CacheBytes = 256 * 1024;
constexpr std::ptrdiff_t kPinnedL3CacheBytes = 2 * 1024 * 1024;

/// Eigen cuts its matrix products and triangular solves into blocks sized from the CPU's caches
/// (CPUID), and the cut sets the order of the sums: the same fit rounded differently on two
/// CPUs (a host with 48 KiB L1 and qemu's 64 KiB), and a flat likelihood carried those last bits
/// to different hyperparameters. Fixed sizes make every CPU cut alike. Process-wide and kept:
/// later products block alike too, only their speed differs.
void pinEigenBlocking() {
  Eigen::setCpuCacheSizes(kPinnedL1CacheBytes, kPinnedL2CacheBytes, kPinnedL3CacheBytes);
}

/// Lower triangle (with diagonal) of E_ij = exp(−½ ‖z_i − z_j‖²) for scaled inputs Z (m × D).
void fillUnitKernelLower(const Eigen::MatrixXd& Z, Eigen::MatrixXd& E) {
  const Eigen::Index m = Z.rows();
  for (Eigen::Index j = 0; j < m; ++j) {
    auto column = E.col(j).tail(m - j);
    column.setZero();
    for (Eigen::Index d = 0; d < Z.cols(); ++d) {
      column.array() += (Z.col(d).tail(m - j).array() - Z(j, d)).square();
    }
    column.array() = (-0.5 * column.array()).exp();
  }
}

/// Lower triangle of K = σ_f² E + v I from the lower triangle of E (m × m); v is the diagonal
/// variance (σ_n², plus the jitter while fitting).
void fillCovarianceLower(const Eigen::MatrixXd& E, double signal_variance, double diagonal_variance,
                         Eigen::MatrixXd& K) {
  K.triangularView<Eigen::Lower>() = signal_variance * E;
  K.diagonal().array() += diagonal_variance;
}

/// Factorises the lower triangle of K in place into L (L Lᵀ = K); false when K is not
/// numerically positive definite.
bool choleskyInPlace(Eigen::MatrixXd& K) {
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(K);
  return llt.info() == Eigen::Success && K.diagonal().allFinite() &&
         (K.diagonal().array() > 0.0).all();
}

/// Lower triangle of K⁻¹ = L⁻ᵀ L⁻¹ from the Cholesky factor L (lower, m × m), blocked so
/// both the triangular inverse and the product exploit the triangular shapes (≈ m³/3 flops).
/// inverse_factor receives L⁻¹ in its lower triangle.
void inverseFromCholesky(const Eigen::MatrixXd& L, Eigen::MatrixXd& inverse_factor,
                         Eigen::MatrixXd& inverse_lower) {
  const Eigen::Index m = L.rows();
  for (Eigen::Index c0 = 0; c0 < m; c0 += kBlockWidth) {
    const Eigen::Index rows = m - c0, width = std::min(kBlockWidth, rows);
    auto block = inverse_factor.block(c0, c0, rows, width);
    block.setZero();
    block.topRows(width).setIdentity();
    L.block(c0, c0, rows, rows).triangularView<Eigen::Lower>().solveInPlace(block);
  }
  for (Eigen::Index c0 = 0; c0 < m; c0 += kBlockWidth) {
    const Eigen::Index rows = m - c0, width = std::min(kBlockWidth, rows);
    inverse_lower.block(c0, c0, rows, width).noalias() =
        inverse_factor.block(c0, c0, rows, rows).transpose().triangularView<Eigen::Upper>() *
        inverse_factor.block(c0, c0, rows, width);
  }
}

/// −½ Σ_o y_oᵀ α_o − P Σ_i log L_ii − P (m/2) log 2π (docs/method.md eq. 26, summed over outputs).
double logMarginalLikelihoodFromFactor(const Eigen::MatrixXd& L, const Eigen::MatrixXd& Yn,
                                       const Eigen::MatrixXd& alpha) {
  const double outputs = static_cast<double>(Yn.cols());
  const double m = static_cast<double>(Yn.rows());
  return -0.5 * Yn.cwiseProduct(alpha).sum() - outputs * L.diagonal().array().log().sum() -
         0.5 * outputs * m * kLog2Pi;
}

/// Log marginal likelihood and its gradient for fixed training data, with buffers sized once.
class LikelihoodEvaluator {
 public:
  LikelihoodEvaluator(const Eigen::MatrixXd& Xn, const Eigen::MatrixXd& Yn)
      : Xn_(Xn),
        Yn_(Yn),
        scaled_inputs_(Xn.rows(), Xn.cols()),
        unit_kernel_(Xn.rows(), Xn.rows()),
        factor_(Xn.rows(), Xn.rows()),
        inverse_factor_(Xn.rows(), Xn.rows()),
        weights_(Xn.rows(), Xn.rows()),
        alpha_(Xn.rows(), Yn.cols()),
        column_products_(Xn.rows()) {}

  /// L(θ) summed over outputs; gradient (D + 2) receives ∂L/∂θ when given. −∞ on failure.
  double evaluate(const Eigen::VectorXd& log_theta, Eigen::VectorXd* gradient) {
    const Eigen::Index D = Xn_.cols();
    const double signal_variance = std::exp(2.0 * log_theta(D));
    const double noise_variance = std::exp(2.0 * log_theta(D + 1));
    scaled_inputs_ = Xn_ * (-log_theta.head(D)).array().exp().matrix().asDiagonal();
    fillUnitKernelLower(scaled_inputs_, unit_kernel_);
    fillCovarianceLower(unit_kernel_, signal_variance,
                        kGprRelativeJitter * signal_variance + noise_variance, factor_);
    const double failed = -std::numeric_limits<double>::infinity();
    if (gradient) gradient->setZero(D + 2);
    if (!choleskyInPlace(factor_)) return failed;
    alpha_ = factor_.triangularView<Eigen::Lower>().solve(Yn_);
    factor_.triangularView<Eigen::Lower>().transpose().solveInPlace(alpha_);
    const double lml = logMarginalLikelihoodFromFactor(factor_, Yn_, alpha_);
    if (!std::isfinite(lml)) return failed;
    if (gradient) fillGradient(signal_variance, noise_variance, *gradient);
    return lml;
  }

 private:
  // ∂L/∂θ_j = ½ tr(W ∂K/∂θ_j), W = Σ_o α_o α_oᵀ − P K⁻¹ (docs/method.md eq. 26–27), with
  // ∂K/∂log ℓ_d = σ_f² E ⊙ Δ_d²/ℓ_d², ∂K/∂log σ_f = 2 σ_f² (E + ε I), ∂K/∂log σ_n = 2 σ_n² I.
  void fillGradient(double signal_variance, double noise_variance, Eigen::VectorXd& gradient) {
    const Eigen::Index m = Xn_.rows(), D = Xn_.cols();
    inverseFromCholesky(factor_, inverse_factor_, weights_);
    weights_.triangularView<Eigen::Lower>() *= -static_cast<double>(Yn_.cols());
    weights_.selfadjointView<Eigen::Lower>().rankUpdate(alpha_);
    const double trace = weights_.diagonal().sum();
    // Off-diagonal pairs (i > j) counted once; the diagonal does not depend on ℓ.
    double weighted_kernel_sum = 0.0;
    for (Eigen::Index j = 0; j + 1 < m; ++j) {
      const Eigen::Index below = m - j - 1;
      auto products = column_products_.head(below);
      products.array() =
          weights_.col(j).tail(below).array() * unit_kernel_.col(j).tail(below).array();
      weighted_kernel_sum += products.sum();
      for (Eigen::Index d = 0; d < D; ++d) {
        gradient(d) += (products.array() *
                        (scaled_inputs_.col(d).tail(below).array() - scaled_inputs_(j, d)).square())
                           .sum();
      }
    }
    gradient.head(D) *= signal_variance;
    gradient(D) =
        signal_variance * ((1.0 + kGprRelativeJitter) * trace + 2.0 * weighted_kernel_sum);
    gradient(D + 1) = noise_variance * trace;
  }

  const Eigen::MatrixXd& Xn_;
  const Eigen::MatrixXd& Yn_;
  Eigen::MatrixXd scaled_inputs_;    // m × D: x_n / ℓ
  Eigen::MatrixXd unit_kernel_;      // m × m lower: E
  Eigen::MatrixXd factor_;           // m × m lower: L
  Eigen::MatrixXd inverse_factor_;   // m × m lower: L⁻¹
  Eigen::MatrixXd weights_;          // m × m lower: W
  Eigen::MatrixXd alpha_;            // m × P
  Eigen::VectorXd column_products_;  // m
};

/// −L/(m·P) and its gradient for L-BFGS-B (per sample, so tolerances do not depend on m, P);
/// remembers the best point seen so a failed line search loses nothing.
class NegativeLikelihoodObjective {
 public:
  NegativeLikelihoodObjective(LikelihoodEvaluator& evaluator, double samples,
                              double short_length_scale_prior)
      : evaluator_(evaluator),
        samples_(samples),
        log_short_length_scale_(std::log(short_length_scale_prior)) {}

  double operator()(const Eigen::VectorXd& log_theta, Eigen::VectorXd& gradient) {
    ++evaluations_;
    const double lml = evaluator_.evaluate(log_theta, &gradient_);
    double log_posterior = lml;
    // One-sided log-normal prior on the length scales (see GprOptions).
    for (Eigen::Index d = 0; d + 2 < log_theta.size() && gradient_.size() == log_theta.size(); ++d) {
      const double z = log_theta(d) - log_short_length_scale_;
      if (z < 0.0) {
        log_posterior -= 0.5 * z * z;
        gradient_(d) -= z;
      }
    }
    double objective = kFailedObjective;
    if (std::isfinite(log_posterior) && gradient_.allFinite()) {
      objective = -log_posterior / samples_;
      gradient = -gradient_ / samples_;
    } else {
      gradient.setZero(log_theta.size());
    }
    if (evaluations_ == 1) start_lml_ = std::isfinite(lml) ? lml : -kFailedObjective * samples_;
    if (objective < best_objective_) {
      best_objective_ = objective;
      best_lml_ = lml;
      best_log_theta_ = log_theta;
    }
    return objective;
  }

  int evaluations() const { return evaluations_; }
  double startLml() const { return start_lml_; }
  double bestLml() const { return best_lml_; }
  double bestLogPosterior() const { return -best_objective_ * samples_; }
  const Eigen::VectorXd& bestLogTheta() const { return best_log_theta_; }

 private:
  LikelihoodEvaluator& evaluator_;
  double samples_;
  double log_short_length_scale_;
  Eigen::VectorXd gradient_;
  int evaluations_ = 0;
  double start_lml_ = 0.0;
  double best_lml_ = 0.0;
  double best_objective_ = std::numeric_limits<double>::infinity();
  Eigen::VectorXd best_log_theta_;
};

/// Maximises the log marginal likelihood (plus the length-scale prior) from one start inside
/// [lower, upper] (log θ).
GprRestart optimiseFrom(const Eigen::MatrixXd& Xn, const Eigen::MatrixXd& Yn,
                        const Eigen::VectorXd& start, const Eigen::VectorXd& lower,
                        const Eigen::VectorXd& upper, int max_iterations, double short_length_scale_prior) {
  LikelihoodEvaluator evaluator(Xn, Yn);
  NegativeLikelihoodObjective objective(evaluator, static_cast<double>(Yn.size()),
                                        short_length_scale_prior);
  LBFGSpp::LBFGSBParam<double> param;
  param.m = 10;          // correction pairs: about as many as hyperparameters for D = 12
  param.epsilon = 1e-4;  // ∞-norm of the projected per-sample gradient: |∂L/∂θ| ≤ 1e-4·m·P
  param.epsilon_rel = 0.0;
  param.past = 1;
  param.delta = 1e-8;  // or the per-sample objective changed by < 1e-8 in one iteration
  param.max_iterations = std::max(1, max_iterations);
  LBFGSpp::LBFGSBSolver<double> solver(param);

  GprRestart restart;
  restart.start_log_theta = start;
  Eigen::VectorXd log_theta = start;
  double value = 0.0;
  try {
    restart.iterations = solver.minimize(objective, log_theta, value, lower, upper);
  } catch (const std::runtime_error&) {
    restart.stopped_by_line_search = true;  // line search could not improve: keep the best seen
  } catch (const std::logic_error&) {
    restart.stopped_by_line_search = true;  // search direction not downhill (round-off)
  }
  restart.evaluations = objective.evaluations();
  restart.start_lml = objective.startLml();
  restart.final_lml = objective.bestLml();
  restart.final_log_posterior = objective.bestLogPosterior();
  restart.final_log_theta = objective.bestLogTheta();
  return restart;
}

void requireFiniteData(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y) {
  if (X.rows() < 1 || X.cols() < 1 || Y.cols() < 1) {
    throw InputError("GPR needs at least one training point, input and output; got " +
                     std::to_string(X.rows()) + " × " + std::to_string(X.cols()) + " inputs and " +
                     std::to_string(Y.cols()) + " outputs");
  }
  if (Y.rows() != X.rows()) {
    throw InputError("GPR inputs have " + std::to_string(X.rows()) + " rows but outputs have " +
                     std::to_string(Y.rows()));
  }
  if (!X.allFinite() || !Y.allFinite()) throw InputError("GPR training data are not finite");
}

void requireValidScaling(const GprScaling& s, Eigen::Index D, Eigen::Index P) {
  if (s.input_offset.size() != D || s.input_scale.size() != D || s.output_mean.size() != P ||
      s.output_scale.size() != P) {
    throw InputError("GPR scaling sizes do not match " + std::to_string(D) + " inputs and " +
                     std::to_string(P) + " outputs");
  }
  const bool finite = s.input_offset.allFinite() && s.input_scale.allFinite() &&
                      s.output_mean.allFinite() && s.output_scale.allFinite();
  if (!finite || (s.input_scale.array() <= 0.0).any() || (s.output_scale.array() <= 0.0).any()) {
    throw InputError("GPR scaling must be finite with positive scales");
  }
}

void requireValidHyperparameters(const GprHyperparameters& h, Eigen::Index D) {
  if (h.length_scales.size() != D) {
    throw InputError("GPR has " + std::to_string(h.length_scales.size()) + " length scales for " +
                     std::to_string(D) + " inputs");
  }
  const bool valid = h.length_scales.allFinite() && (h.length_scales.array() > 0.0).all() &&
                     std::isfinite(h.signal_sigma) && h.signal_sigma > 0.0 &&
                     std::isfinite(h.noise_sigma) && h.noise_sigma >= 0.0;
  if (!valid) {
    throw InputError("GPR hyperparameters must be finite, length scales and σ_f positive, σ_n ≥ 0");
  }
}

/// Sample std of each column, or 1 where the column is constant.
Eigen::VectorXd columnScales(const Eigen::MatrixXd& A, const Eigen::VectorXd& means) {
  Eigen::VectorXd scales(A.cols());
  const double dof = static_cast<double>(std::max<Eigen::Index>(A.rows() - 1, 1));
  for (Eigen::Index c = 0; c < A.cols(); ++c) {
    const double std_dev = std::sqrt((A.col(c).array() - means(c)).square().sum() / dof);
    const double magnitude = A.col(c).cwiseAbs().maxCoeff();
    scales(c) = std_dev > kConstantColumnTolerance * magnitude ? std_dev : 1.0;
  }
  return scales;
}

Eigen::MatrixXd normaliseInputs(const Eigen::MatrixXd& X, const GprScaling& scaling) {
  return (X.rowwise() - scaling.input_offset.transpose()).array().rowwise() /
         scaling.input_scale.transpose().array();
}

Eigen::MatrixXd standardiseOutputs(const Eigen::MatrixXd& Y, const GprScaling& scaling) {
  return (Y.rowwise() - scaling.output_mean.transpose()).array().rowwise() /
         scaling.output_scale.transpose().array();
}

/// The predictor's parameters from the model's parts; α may be empty (GprPredictor::conditioned
/// solves it).
GprParameters parametersOf(Eigen::MatrixXd normalised_inputs, const GprScaling& scaling,
                           const GprHyperparameters& hyperparameters,
                           Eigen::MatrixXd standardised_targets, Eigen::MatrixXd alpha) {
  GprParameters g;
  g.inputs_normalised = std::move(normalised_inputs);
  g.input_offset = scaling.input_offset;
  g.input_scale = scaling.input_scale;
  g.output_mean = scaling.output_mean;
  g.output_scale = scaling.output_scale;
  g.length_scales = hyperparameters.length_scales;
  g.signal_sigma = hyperparameters.signal_sigma;
  g.noise_sigma = hyperparameters.noise_sigma;
  g.targets_standardised = std::move(standardised_targets);
  g.alpha = std::move(alpha);
  g.payload_force_reference_n = scaling.payload_force_reference_n;
  return g;
}

}  // namespace

GprScaling GprScaling::fromData(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y) {
  requireFiniteData(X, Y);
  GprScaling s;
  s.input_offset = X.colwise().mean().transpose();
  s.input_scale = columnScales(X, s.input_offset);
  s.output_mean = Y.colwise().mean().transpose();
  s.output_scale = columnScales(Y, s.output_mean);
  return s;
}

GprScaling GprScaling::identity(int input_dim, int output_dim) {
  GprScaling s;
  s.input_offset.setZero(input_dim);
  s.input_scale.setOnes(input_dim);
  s.output_mean.setZero(output_dim);
  s.output_scale.setOnes(output_dim);
  return s;
}

Eigen::VectorXd GaussianProcess::startingPoint(int index, int input_dim, const GprBounds& bounds) {
  // k = 0, 1, 2, −1, 3, −2, 4, −3, …
  const int k = index < 3 ? index : (index % 2 == 1 ? -(index - 1) / 2 : (index + 2) / 2);
  Eigen::VectorXd start(input_dim + 2);
  start.head(input_dim).setConstant(std::clamp(k * std::log(3.0), std::log(bounds.min_length_scale),
                                               std::log(bounds.max_length_scale)));
  start(input_dim) =
      std::clamp(0.0, std::log(bounds.min_signal_sigma), std::log(bounds.max_signal_sigma));
  start(input_dim + 1) =
      std::clamp(std::log(index % 2 == 0 ? 0.1 : 0.01), std::log(bounds.min_noise_sigma),
                 std::log(bounds.max_noise_sigma));
  return start;
}

GaussianProcess GaussianProcess::fit(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y,
                                     const GprOptions& options, GprFitReport* report) {
  pinEigenBlocking();
  GprScaling scaling = GprScaling::fromData(X, Y);
  scaling.payload_force_reference_n = options.payload_force_reference_n;
  const Eigen::Index D = X.cols();
  const Eigen::MatrixXd Xn = normaliseInputs(X, scaling);
  const Eigen::MatrixXd Yn = standardiseOutputs(Y, scaling);

  GprBounds b = options.bounds;
  if (options.output_noise_sigma.size() == Y.cols()) {
    if (!(options.output_noise_sigma.array() > 0.0).all() || !options.output_noise_sigma.allFinite()) {
      throw InputError("GPR output noise must be finite and positive");
    }
    const double stated = (options.output_noise_sigma.array() / scaling.output_scale.array()).minCoeff();
    b.min_noise_sigma = std::min(std::max(b.min_noise_sigma, kNoiseBoundShare * stated),
                                 0.5 * b.max_noise_sigma);
  } else if (options.output_noise_sigma.size() != 0) {
    throw InputError("GPR output noise has " + std::to_string(options.output_noise_sigma.size()) +
                     " entries for " + std::to_string(Y.cols()) + " outputs");
  }
  Eigen::VectorXd lower(D + 2), upper(D + 2);
  lower << Eigen::VectorXd::Constant(D, std::log(b.min_length_scale)), std::log(b.min_signal_sigma),
      std::log(b.min_noise_sigma);
  upper << Eigen::VectorXd::Constant(D, std::log(b.max_length_scale)), std::log(b.max_signal_sigma),
      std::log(b.max_noise_sigma);
  if (!((lower.array() < upper.array()).all() && lower.allFinite() && upper.allFinite())) {
    throw InputError("GPR bounds must be positive, finite and increasing");
  }

  const int restarts = std::max(1, options.restarts);
  const int threads = std::clamp(options.threads, 1, restarts);
  // Each start is optimised alone and lands in its own slot, so which thread ran it (and when)
  // changes nothing; so does a failure, rethrown by start index.
  std::vector<GprRestart> results(restarts);
  std::vector<std::exception_ptr> failures(restarts);
  std::atomic<int> next_restart{0};  // starts differ in cost: hand them out on demand
  auto work = [&] {
    for (int r = next_restart++; r < restarts; r = next_restart++) {
      try {
        results[r] = optimiseFrom(Xn, Yn, startingPoint(r, static_cast<int>(D), b), lower, upper,
                                  options.max_iterations,
                                  options.short_length_scale_prior * std::sqrt(static_cast<double>(D)));
      } catch (...) {
        failures[r] = std::current_exception();
      }
    }
  };
  std::vector<std::thread> workers;
  for (int t = 1; t < threads; ++t) workers.emplace_back(work);
  work();
  for (std::thread& worker : workers) worker.join();
  for (const std::exception_ptr& failure : failures) {
    if (failure) std::rethrow_exception(failure);
  }

  int best = 0;
  for (int r = 1; r < restarts; ++r) {
    if (results[r].final_log_posterior > results[best].final_log_posterior) best = r;
  }
  const Eigen::VectorXd theta = results[best].final_log_theta.array().exp();
  GprHyperparameters hyperparameters;
  hyperparameters.length_scales = theta.head(D);
  hyperparameters.signal_sigma = theta(D);
  // The model's K = σ_f² E + σ_n² I equals the K whose likelihood was maximised.
  hyperparameters.noise_sigma =
      std::sqrt(theta(D + 1) * theta(D + 1) + kGprRelativeJitter * theta(D) * theta(D));
  GaussianProcess gp = withHyperparameters(X, Y, scaling, hyperparameters);

  if (report) {
    report->restarts = results;
    report->best_restart = best;
    report->cv_mse = options.cv_folds >= 2 && X.rows() >= 2
                         ? gp.crossValidationMse(options.cv_folds)
                         : Eigen::VectorXd();
  }
  return gp;
}

GaussianProcess GaussianProcess::withHyperparameters(const Eigen::MatrixXd& X,
                                                     const Eigen::MatrixXd& Y,
                                                     const GprScaling& scaling,
                                                     const GprHyperparameters& hyperparameters) {
  pinEigenBlocking();
  requireFiniteData(X, Y);
  requireValidScaling(scaling, X.cols(), Y.cols());
  requireValidHyperparameters(hyperparameters, X.cols());
  return GaussianProcess(GprPredictor::conditioned(parametersOf(
                             normaliseInputs(X, scaling), scaling, hyperparameters,
                             standardiseOutputs(Y, scaling), Eigen::MatrixXd())),
                         scaling, hyperparameters);
}

GaussianProcess GaussianProcess::fromParts(Eigen::MatrixXd normalised_inputs, GprScaling scaling,
                                           GprHyperparameters hyperparameters,
                                           Eigen::MatrixXd alpha,
                                           Eigen::MatrixXd standardised_targets) {
  GaussianProcess gp(GprPredictor::fromParameters(parametersOf(
                         std::move(normalised_inputs), scaling, hyperparameters,
                         std::move(standardised_targets), std::move(alpha))),
                     scaling, hyperparameters);
  const double backward_error = gp.alphaBackwardError();
  if (!(backward_error <= kAlphaBackwardErrorLimit)) {
    throw InputError(
        "GPR α does not solve (K + σ_n² I) α = Y for the stored inputs and "
        "hyperparameters (backward error " +
        std::to_string(backward_error) + ")");
  }
  return gp;
}

GaussianProcess::GaussianProcess(GprPredictor predictor, GprScaling scaling,
                                 GprHyperparameters hyperparameters)
    : predictor_(std::move(predictor)),
      scaling_(std::move(scaling)),
      hyperparameters_(std::move(hyperparameters)),
      log_marginal_likelihood_(logMarginalLikelihoodFromFactor(
          predictor_.choleskyLower(), standardisedTargets(), alpha())) {}

double GaussianProcess::alphaBackwardError() const {
  const Eigen::Index m = trainingSize();
  const Eigen::MatrixXd& L = predictor_.choleskyLower();
  const Eigen::MatrixXd K = L * L.transpose();
  const Eigen::MatrixXd residual = K * alpha() - standardisedTargets();
  const double k_norm = K.cwiseAbs().rowwise().sum().maxCoeff();
  double worst = 0.0;
  for (Eigen::Index o = 0; o < outputDim(); ++o) {
    const double denominator = k_norm * alpha().col(o).cwiseAbs().maxCoeff() +
                               standardisedTargets().col(o).cwiseAbs().maxCoeff();
    const double numerator = residual.col(o).cwiseAbs().maxCoeff();
    worst = std::max(worst, denominator > 0.0 ? numerator / denominator : numerator);
  }
  return m > 0 ? worst : 0.0;
}

Eigen::MatrixXd GaussianProcess::crossValidationResiduals(int folds) const {
  const Eigen::Index m = trainingSize(), P = outputDim();
  if (folds < 2 || m < 2) {
    throw InputError("cross-validation needs at least 2 folds and 2 training points, got " +
                     std::to_string(folds) + " folds and " + std::to_string(m) + " points");
  }
  const Eigen::Index k = std::min<Eigen::Index>(folds, m);
  Eigen::MatrixXd inverse_factor(m, m), inverse(m, m);
  inverseFromCholesky(predictor_.choleskyLower(), inverse_factor, inverse);
  inverse.triangularView<Eigen::StrictlyUpper>() = inverse.transpose();
  // Held-out residual of fold F: y_F − μ_F = ([K⁻¹]_FF)⁻¹ α_F.
  Eigen::MatrixXd residuals(m, P);
  for (Eigen::Index fold = 0; fold < k; ++fold) {
    std::vector<Eigen::Index> rows;
    for (Eigen::Index i = fold; i < m; i += k) rows.push_back(i);
    const Eigen::MatrixXd inverse_block = inverse(rows, rows);
    const Eigen::MatrixXd alpha_block = alpha()(rows, Eigen::all);
    const Eigen::MatrixXd held_out = inverse_block.llt().solve(alpha_block);
    residuals(rows, Eigen::all) = held_out;
  }
  return residuals * scaling_.output_scale.cwiseAbs().asDiagonal();
}

Eigen::VectorXd GaussianProcess::crossValidationMse(int folds) const {
  const Eigen::MatrixXd residuals = crossValidationResiduals(folds);
  return residuals.colwise().squaredNorm().transpose() / static_cast<double>(residuals.rows());
}

GprWorkspace GaussianProcess::makeWorkspace() const { return predictor_.makeWorkspace(); }

void GaussianProcess::predictMeanInto(const double* x, double* mean_out,
                                      GprWorkspace& workspace) const noexcept {
  predictor_.predictInto(x, mean_out, nullptr, workspace);
}

void GaussianProcess::predictInto(const double* x, double* mean_out, double* std_out,
                                  GprWorkspace& workspace) const noexcept {
  predictor_.predictInto(x, mean_out, std_out, workspace);
}

Eigen::VectorXd GaussianProcess::predictMean(const Eigen::VectorXd& x) const {
  if (x.size() != inputDim()) {
    throw InputError("GPR query has " + std::to_string(x.size()) + " inputs, model has " +
                     std::to_string(inputDim()));
  }
  GprWorkspace workspace = makeWorkspace();
  Eigen::VectorXd mean(outputDim());
  predictMeanInto(x.data(), mean.data(), workspace);
  return mean;
}

Eigen::VectorXd GaussianProcess::predictStd(const Eigen::VectorXd& x) const {
  if (x.size() != inputDim()) {
    throw InputError("GPR query has " + std::to_string(x.size()) + " inputs, model has " +
                     std::to_string(inputDim()));
  }
  GprWorkspace workspace = makeWorkspace();
  Eigen::VectorXd mean(outputDim()), std_dev(outputDim());
  predictInto(x.data(), mean.data(), std_dev.data(), workspace);
  return std_dev;
}

double logMarginalLikelihood(const Eigen::MatrixXd& Xn, const Eigen::MatrixXd& Yn,
                             const Eigen::VectorXd& log_theta, Eigen::VectorXd* gradient) {
  requireFiniteData(Xn, Yn);
  if (log_theta.size() != Xn.cols() + 2) {
    throw InputError("GPR log-hyperparameters need " + std::to_string(Xn.cols() + 2) +
                     " entries, got " + std::to_string(log_theta.size()));
  }
  LikelihoodEvaluator evaluator(Xn, Yn);
  return evaluator.evaluate(log_theta, gradient);
}

}  // namespace stepcal::trainer
