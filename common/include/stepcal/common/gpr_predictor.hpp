// The predictive side of the residual Gaussian process (docs/method.md eq. 30–31), shared by the
// trainer (after fitting) and the runtime (after loading a model file).
//
// Built once from GprParameters (it refactors K + σ_n² I by Cholesky); predictions then run on
// a Workspace sized once, allocate nothing and throw nothing.
#pragma once

#include <vector>

#include "stepcal/common/model_file.hpp"

namespace stepcal {

class GprPredictor {
 public:
  /// Scratch space for one prediction, sized by makeWorkspace().
  struct Workspace {
    Eigen::VectorXd normalised_input;  ///< D: the query normalised, then divided by ℓ
    Eigen::VectorXd varying_input;     ///< its entries the training inputs vary in
    Eigen::VectorXd kernel_column;     ///< m: k(X, x*), then L⁻¹ k(X, x*) or, in its head, L_S⁻¹ k(X_S, x*)
    Eigen::VectorXd subset_column;     ///< boundSubsetSize(): k(X_S, x*)
  };

  /// Most training points of the subset behind the std bound (predictMeanAndBoundInto).
  static constexpr int kMaxBoundSubset = 48;

  GprPredictor() = default;
  /// Refactors the kernel matrix of the stored training inputs and hyperparameters. Throws
  /// InputError when the parameters are inconsistent or the matrix is not positive definite.
  /// Sizes as in GprParameters with m, D, P ≥ 1; every value finite; scales, length scales and
  /// σ_f > 0, σ_n ≥ 0. K_ij = σ_f² exp(−½ Σ_d ((x_id − x_jd) / ℓ_d)²) + σ_n² δ_ij (eq. 27).
  static GprPredictor fromParameters(const GprParameters& parameters);
  /// As fromParameters, but conditions on the training targets itself: parameters.alpha is
  /// replaced by α = (K + σ_n² I)⁻¹ targets_standardised, solved with the Cholesky factor.
  static GprPredictor conditioned(GprParameters parameters);

  /// The factor the GP's output is applied with at x_raw: 1 for the paper's GPR, ‖f‖ /
  /// payload_force_reference_n for a GPR of the residual per payload force (eq. 30a).
  double outputGain(const double* x_raw) const noexcept;
  int inputDim() const noexcept;
  int outputDim() const noexcept;
  int trainingSize() const noexcept;
  /// Inputs that vary over the training set (the others enter every distance alike).
  int varyingInputs() const noexcept { return static_cast<int>(varying_dims_.size()); }
  const GprParameters& parameters() const noexcept { return parameters_; }
  /// Each output's noise 1-σ in standardised units, as its training points left out one at a
  /// time show it (docs/method.md, "The accuracy bound"): √max(0, mean_i r_io² − mean_i (v_i −
  /// σ_n²)), r_io = α_io / [K⁻¹]_ii the residual of point i predicted from the others, v_i =
  /// 1 / [K⁻¹]_ii its predictive variance, K = K_f + σ_n² I: with the latent variance, each
  /// output's left-out residuals on average. One σ_n serves every output in the fit; this is
  /// each output's own (a tracker's position noise is not its orientation's). An output quieter
  /// than the GP's latent variance alone explains gets 0.
  const Eigen::VectorXd& heldOutNoise() const noexcept { return held_out_noise_; }
  /// L with L Lᵀ = K + σ_n² I, m × m, lower triangular (strict upper triangle zero).
  const Eigen::MatrixXd& choleskyLower() const noexcept { return cholesky_lower_; }
  Workspace makeWorkspace() const;
  /// r = min(m, kMaxBoundSubset): training points of the subset behind the std bound.
  int boundSubsetSize() const noexcept { return static_cast<int>(subset_indices_.size()); }
  /// Indices (ascending) of the subset's training points: farthest-point sampling in the
  /// length-scale-scaled input space, from training point 0 (ties: the lowest index).
  const Eigen::VectorXi& boundSubset() const noexcept { return subset_indices_; }

  /// Predictive mean in raw output units (eq. 30) and, when std_out is not null, the predictive
  /// standard deviation of the latent function per output (eq. 31, without the noise term); both
  /// times outputGain (a GPR per payload force: exactly zero at zero force, the GP not evaluated).
  /// x_raw has inputDim() entries in raw input units; mean_out and std_out outputDim().
  /// mean = output_mean + output_scale ⊙ (k*ᵀ α); std = output_scale · √max(0, σ_f² − vᵀv),
  /// v = L⁻¹ k*.
  void predictInto(const double* x_raw, double* mean_out, double* std_out,
                   Workspace& workspace) const noexcept;

  /// Predictive std over prior std (σ_f), ∈ [0, 1]: near 0 beside the training data, 1 where
  /// the data say nothing (extrapolation). Same for every output (the kernel is shared).
  /// outputGain · √max(0, σ_f² − vᵀv) / σ_f, v = L⁻¹ k* (a GPR per payload force: the std of its
  /// correction over its prior std at the reference force, 0 at zero force, above 1 possible).
  double relativeStd(const double* x_raw, Workspace& workspace) const noexcept;

  /// Predictive mean (as predictInto) and a cheap upper bound on the predictive std.
  /// The bound is the latent std of the same GP conditioned on the r = boundSubsetSize()
  /// training points of boundSubset() only (subset of data, noise included): conditioning on
  /// fewer data never lowers the posterior variance, so bound ≥ the exact std of predictInto,
  /// and equals it when r = m. Costs an r × r matrix–vector product with L_S⁻¹ (computed at
  /// construction) instead of an m × m triangular solve; the subset's kernel values are taken
  /// from the full column the mean uses. std_bound_out (outputDim() entries, may be null) = output_scale · √max(0, σ_f² − v_Sᵀv_S), v_S = L_S⁻¹ k(X_S, x*),
  /// L_S L_Sᵀ = K_SS + σ_n² I (docs/method.md eq. 31 on the subset).
  void predictMeanAndBoundInto(const double* x_raw, double* mean_out, double* std_bound_out,
                               Workspace& workspace) const noexcept;
  /// relativeStd with the subset bound of predictMeanAndBoundInto: ≥ relativeStd, ∈ [0, 1].
  double relativeStdBound(const double* x_raw, Workspace& workspace) const noexcept;

 private:
  /// Checks everything but α and factorises K + σ_n² I.
  static GprPredictor factorised(GprParameters parameters);
  /// k* = k(X, x*) into workspace.kernel_column, x* in raw input units: squared distances
  /// ‖z̃_i‖² + ‖z̃‖² − 2 z̃_iᵀz̃ (clamped at 0) over the inputs that vary in training by one
  /// matrix–vector product, plus the others' shared (z̃_d − x̃_d)², then exp.
  void kernelColumn(const double* x_raw, Workspace& workspace) const noexcept;
  /// heldOutNoise from α and the factor (O(m³), once at construction).
  Eigen::VectorXd heldOutNoiseOfAlpha() const;
  /// Zero mean and std (std_out may be null): the correction at zero force.
  void zeroOutputs(double* mean_out, double* std_out) const noexcept;
  /// Mean and std (may be null) times the gain, for a GPR per payload force.
  void applyGain(double gain, double* mean_out, double* std_out) const noexcept;
  /// Predictive mean from the kernel column in workspace (raw output units).
  void meanFromColumn(const Workspace& workspace, double* mean_out) const noexcept;
  /// Latent std of the subset GP from the kernel column in workspace (standardised units).
  double subsetLatentStd(Workspace& workspace) const noexcept;
  /// Latent std of the GP from the kernel column in workspace (standardised units): by the
  /// subset's when the subset is every training point (the same GP), else from L.
  double exactLatentStd(Workspace& workspace) const noexcept;

  GprParameters parameters_;
  std::vector<int> varying_dims_, constant_dims_;  // inputs that vary over the training set, not
  std::vector<double> constant_values_;             // the latter's shared value / ℓ_d
  Eigen::MatrixXd scaled_inputs_;          // m × varying: normalised inputs / ℓ_d
  Eigen::MatrixXd cholesky_lower_;         // m × m
  Eigen::VectorXd cholesky_inverse_diagonal_;  // m: 1 / L_jj
  Eigen::VectorXd inverse_length_scales_;  // D
  Eigen::VectorXd scaled_input_norms_;     // m: ‖row i of scaled_inputs_‖²
  Eigen::VectorXi subset_indices_;         // r, ascending
  Eigen::MatrixXd subset_cholesky_inverse_;  // r × r: L_S⁻¹ (lower triangular)
  Eigen::VectorXd held_out_noise_;           // P, standardised units
};

/// The residual twist in the tip's axes (docs/method.md eq. 32) from a GPR's output at a tip of
/// the physical model turned by R_TrackerTip, in place: the paper's GPR gives it as it is; a GPR
/// per payload force gives the tip's displacement and rotation in the tracker's axes (eq. 30a), in
/// which a load effect of the arm does not turn with the wrist. Allocation-free.
void tipTwistFromGprOutput(const GprParameters& gpr, const Mat3& R_TrackerTip, Vec6& twist) noexcept;

}  // namespace stepcal
