// Step 3: multi-output Gaussian process regression of the residual twist (docs/method.md eq. 25–31).
//
// Inputs x ∈ R^D (in stepcal x = (q [rad], wrench [N, N·m]), D = 12, but D is a runtime value)
// are normalised per input, x_n = (x − offset) / scale (offset = mean, scale = std, 1 for a
// constant input). Outputs y ∈ R^P (the residual twist ξ, P = 6) are standardised per output,
// y_s = (y − mean) / scale. All outputs share one squared-exponential ARD kernel on the
// normalised inputs (docs/method.md eq. 27) plus white noise:
//
//   K = σ_f² E + σ_n² I,   E_ij = exp(−½ Σ_d (x_id − x_jd)² / ℓ_d²)
//
// so one Cholesky factor serves every output. The hyperparameters θ = (log ℓ_1..log ℓ_D,
// log σ_f, log σ_n), in normalised input and standardised output units, maximise the summed
// log marginal likelihood (analytic gradient, L-BFGS-B from several deterministic starts) —
// docs/method.md, step 3, "How stepcal does it": gradients instead of Bayesian optimisation.
// While fitting, K carries a jitter ε σ_f² on its diagonal; the fitted σ_n absorbs it
// (σ_n² ← σ_n² + ε σ_f²), so every GaussianProcess uses exactly K = σ_f² E + σ_n² I, the
// form a model file stores.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "stepcal/common/gpr_predictor.hpp"

namespace stepcal::trainer {

/// Diagonal jitter ε of the likelihood maximised by fit, as a fraction of σ_f² (numerical safety).
inline constexpr double kGprRelativeJitter = 1e-10;

/// Search-space limits for the hyperparameters (box bounds of L-BFGS-B, log of these values).
struct GprBounds {
  double min_length_scale = 0.05;   ///< ℓ_d, normalised input units (≈ e^-3)
  double max_length_scale = 150.0;  ///< ℓ_d, normalised input units (≈ e^5: input irrelevant)
  double min_signal_sigma = 1e-3;   ///< σ_f, standardised output units
  double max_signal_sigma = 1e2;    ///< σ_f, standardised output units
  double min_noise_sigma = 1e-4;  ///< σ_n, standardised output units (≈ 1e-4·σ_f for σ_f ≈ 1)
  double max_noise_sigma = 10.0;  ///< σ_n, standardised output units
};

struct GprOptions {
  int restarts = 4;         ///< optimiser starts, see GaussianProcess::startingPoint
  int max_iterations = 80;  ///< L-BFGS-B iterations per start
  int cv_folds = 10;        ///< folds of the cross-validation loss reported by fit (< 2: none)
  int threads = 2;          ///< starts optimised in parallel; the result does not depend on it, bit for bit
  GprBounds bounds;
  /// Length scales below ℓ₀ = this · √D (normalised input units) cost ½ (log(ℓ/ℓ₀))² nats
  /// each: on a white-noise residual the likelihood cannot tell "all noise" from "signal with
  /// length scales so short that the points decorrelate" (both make K diagonal; in D dimensions
  /// that happens below about √D); this one-sided log-normal prior picks the former, so the
  /// predictive variance means something. Real short-scale structure outweighs it easily.
  double short_length_scale_prior = 1.0;
  /// The noise each output carries at least, raw output units (P entries; empty: unknown), e.g.
  /// the tracker's stated σ for the residual twist. σ_n is then bounded below by
  /// kNoiseBoundShare · min_k σ_k / scale_k (standardised units): a GP whose noise sits below
  /// the measurement's interpolates its training rows, noise included (a 60-row campaign's
  /// search otherwise ended at σ_n = 0.01, with every fit row at 0.0000 mm and validation worse).
  Eigen::VectorXd output_noise_sigma;
  /// 0: Y is the residual. > 0, N: Y is the residual per payload force (the residual over
  /// ‖f‖ / this, f the force of the wrench, the last six inputs), and the model's predictions
  /// are scaled back by ‖f‖ / this (GprParameters::payload_force_reference_n).
  double payload_force_reference_n = 0.0;
};

/// Share of the stated output noise σ_n may not go below: rows that a calibration step fitted
/// carry less noise than the instrument, by the degrees of freedom the fit took (a 42-parameter
/// geometry on 60 six-dimensional rows leaves 96 % of its σ; 0.8 leaves room for 36 % taken).
inline constexpr double kNoiseBoundShare = 0.8;

/// Kernel hyperparameters, in normalised input and standardised output units.
struct GprHyperparameters {
  Eigen::VectorXd length_scales;  ///< ℓ_1..ℓ_D (docs/method.md eq. 27: σ_m)
  double signal_sigma = 1.0;      ///< σ_f
  double noise_sigma = 0.1;       ///< σ_n (docs/method.md eq. 26: σ); after fit, includes the jitter
};

/// Affine maps between raw units and the model's units: x_n = (x − input_offset) / input_scale,
/// y = output_mean + output_scale ⊙ y_s.
struct GprScaling {
  Eigen::VectorXd input_offset;  ///< D, raw input units
  Eigen::VectorXd input_scale;   ///< D, raw input units per normalised unit (> 0)
  Eigen::VectorXd output_mean;   ///< P, raw output units
  Eigen::VectorXd output_scale;  ///< P, raw output units per standardised unit (> 0)
  /// 0, or the reference force of a GPR per payload force (GprOptions), N.
  double payload_force_reference_n = 0.0;

  /// Per-column mean and sample std of X (m × D) and Y (m × P); a constant column gets scale 1.
  static GprScaling fromData(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y);
  /// Offset/mean 0 and scale 1: the model works in raw units.
  static GprScaling identity(int input_dim, int output_dim);
};

/// How one optimiser start went (LML values summed over outputs, standardised units).
struct GprRestart {
  Eigen::VectorXd start_log_theta;  ///< D + 2: log ℓ_1..log ℓ_D, log σ_f, log σ_n
  Eigen::VectorXd final_log_theta;  ///< best point seen by this start
  double start_lml = 0.0;
  double final_lml = 0.0;            ///< log marginal likelihood at the final point
  double final_log_posterior = 0.0;  ///< with the length-scale prior: what the starts compete on
  int iterations = 0;                   ///< L-BFGS-B iterations
  int evaluations = 0;                  ///< likelihood + gradient evaluations
  bool stopped_by_line_search = false;  ///< line search gave up (the best point seen is kept)
};

/// Diagnostics of GaussianProcess::fit.
struct GprFitReport {
  std::vector<GprRestart> restarts;  ///< in start order
  int best_restart = 0;
  /// Per-output mean squared k-fold cross-validation error, raw output units² (empty when
  /// GprOptions::cv_folds < 2 or m < 2).
  Eigen::VectorXd cv_mse;
};

/// Scratch for allocation-free single-point prediction (GaussianProcess::makeWorkspace).
using GprWorkspace = GprPredictor::Workspace;

/// Multi-output GP with one shared squared-exponential ARD kernel (docs/method.md eq. 26–31).
/// Immutable once built: const members may run concurrently, each thread with its own workspace.
/// Prediction is common's GprPredictor, built from parameters(): exactly what the model file
/// carries to the runtime.
class GaussianProcess {
 public:
  /// Fits scaling and hyperparameters to X (m × D, raw inputs) and Y (m × P, raw outputs) by
  /// maximising the log marginal likelihood. Throws InputError on empty, mismatched or
  /// non-finite data, or bounds that are not positive and increasing.
  /// Bit-identical for one binary whatever GprOptions::threads and the CPU's cache sizes: it
  /// first pins Eigen's blocking (Eigen::setCpuCacheSizes, for the whole process; so does
  /// withHyperparameters), so no other thread may run Eigen products while it starts.
  static GaussianProcess fit(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y,
                             const GprOptions& options = {}, GprFitReport* report = nullptr);

  /// Conditions on X (m × D raw) and Y (m × P raw) with given scaling and hyperparameters.
  /// Throws InputError on bad sizes or values, or when K is not positive definite.
  static GaussianProcess withHyperparameters(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y,
                                             const GprScaling& scaling,
                                             const GprHyperparameters& hyperparameters);

  /// Rebuilds a predictor from stored arrays without refitting: the Cholesky factor is
  /// recomputed from normalised_inputs (m × D) and the hyperparameters; alpha (m × P) is used
  /// as given. Throws InputError when sizes disagree, values are not finite or positive where
  /// required, K is not positive definite, or alpha does not solve K α = standardised_targets
  /// (m × P) to a normwise backward error of 1e-8.
  static GaussianProcess fromParts(Eigen::MatrixXd normalised_inputs, GprScaling scaling,
                                   GprHyperparameters hyperparameters, Eigen::MatrixXd alpha,
                                   Eigen::MatrixXd standardised_targets);

  /// The deterministic optimiser start number `index` for D inputs (D + 2 log-hyperparameters):
  /// ℓ = 3^k for k = 0, 1, 2, −1, 3, −2, … (all inputs alike), σ_f = 1, σ_n = 0.1 for even
  /// index and 0.01 for odd, clamped into the bounds.
  static Eigen::VectorXd startingPoint(int index, int input_dim, const GprBounds& bounds);

  int inputDim() const { return predictor_.inputDim(); }
  int outputDim() const { return predictor_.outputDim(); }
  int trainingSize() const { return predictor_.trainingSize(); }

  /// Normalised training inputs, m × D.
  const Eigen::MatrixXd& normalisedInputs() const { return parameters().inputs_normalised; }
  /// Standardised training targets, m × P.
  const Eigen::MatrixXd& standardisedTargets() const { return parameters().targets_standardised; }
  /// α = K⁻¹ Y_s = (σ_f² E + σ_n² I)⁻¹ Y_s, m × P, standardised units (docs/method.md eq. 30).
  const Eigen::MatrixXd& alpha() const { return parameters().alpha; }
  const GprScaling& scaling() const { return scaling_; }
  const GprHyperparameters& hyperparameters() const { return hyperparameters_; }
  /// Everything prediction needs (training inputs and targets, scaling, hyperparameters, α),
  /// as the model file stores it.
  const GprParameters& parameters() const { return predictor_.parameters(); }

  /// Log marginal likelihood summed over outputs, standardised units (docs/method.md eq. 26).
  double logMarginalLikelihood() const { return log_marginal_likelihood_; }
  /// Normwise backward error of α: max over outputs of ‖K α − y‖∞ / (‖K‖∞ ‖α‖∞ + ‖y‖∞).
  double alphaBackwardError() const;

  /// Per-output mean squared error of k-fold cross-validation at these hyperparameters,
  /// raw output units². Row i is held out in fold i mod k (k > m: leave-one-out). Closed form
  /// of refitting α on the other folds; the scaling stays that of the whole data.
  Eigen::VectorXd crossValidationMse(int folds = 10) const;
  /// The held-out residuals themselves (target − prediction of the other folds), m × P raw
  /// output units, as crossValidationMse averages them.
  Eigen::MatrixXd crossValidationResiduals(int folds = 10) const;

  /// Predictive mean at x (D, raw input units), P raw output units (docs/method.md eq. 30).
  Eigen::VectorXd predictMean(const Eigen::VectorXd& x) const;
  /// Predictive std of the latent function at x (D raw), P raw output units, without the
  /// noise term (docs/method.md eq. 31).
  Eigen::VectorXd predictStd(const Eigen::VectorXd& x) const;

  /// Scratch sized for this model, for the *Into functions.
  GprWorkspace makeWorkspace() const;
  /// predictMean without heap allocation: x (D raw) → mean_out (P raw).
  void predictMeanInto(const double* x, double* mean_out, GprWorkspace& workspace) const noexcept;
  /// predictMean and predictStd without heap allocation: x (D raw) → mean_out, std_out (P raw).
  void predictInto(const double* x, double* mean_out, double* std_out,
                   GprWorkspace& workspace) const noexcept;

 private:
  /// Takes the predictor and the LML from its Cholesky factor.
  GaussianProcess(GprPredictor predictor, GprScaling scaling, GprHyperparameters hyperparameters);

  GprPredictor predictor_;  // parameters, Cholesky factor L (L Lᵀ = K), prediction
  GprScaling scaling_;
  GprHyperparameters hyperparameters_;
  double log_marginal_likelihood_ = 0.0;
};

/// Log marginal likelihood summed over outputs, as maximised by fit (with the jitter:
/// K = σ_f² (E + ε I) + σ_n² I), of standardised targets Yn (m × P) at normalised inputs Xn
/// (m × D); θ = log_theta (D + 2: log ℓ, log σ_f, log σ_n) (docs/method.md eq. 26–27).
/// Fills gradient (D + 2, ∂L/∂θ) when given. Returns −∞ (gradient zero) when the Cholesky
/// factorisation fails.
double logMarginalLikelihood(const Eigen::MatrixXd& Xn, const Eigen::MatrixXd& Yn,
                             const Eigen::VectorXd& log_theta, Eigen::VectorXd* gradient);

}  // namespace stepcal::trainer
