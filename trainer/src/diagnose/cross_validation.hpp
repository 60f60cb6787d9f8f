// Cross-validation of linear corrections of the diagnosis's model over folds of poses, from
// per-fold Gram blocks (internal to stepcal::trainer).
//
// The whole model (global part and profiles) is linearised at its joint fit (jointChange, applied
// by the diagnosis before each round): r0 is its residual, every column a change of one
// parameter, and the ridges hold a parameter's value (current + change), not its change, near
// zero. A change is fitted in the two stages of model.hpp: stage 1, the global columns (geometry
// and global parameters), first; stage 2, the geometry's share of the profiles and the profiles'
// columns, with their ridges, on what stage 1 leaves. From the joint fit neither stage takes what
// the other holds (linearised at the global part alone, with the profiles out of r0, a lumped
// self weight fitted first took the part of a shoulder profile in its direction, and what was left
// looked like a profile of another joint). A candidate (value 0) joins stage 1 (a global
// mechanism) or stage 2 (a profile). For each fold the change is fitted on the other folds and
// judged on this one.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "fit_rows.hpp"
#include "stepcal/common/mechanisms.hpp"

namespace stepcal::trainer::diagnosis {

/// Where each column of a screening matrix A lives in a chunk of it (ColumnChunk). A column is
/// dense (a value per equation: the geometry's, a finite difference's) or a joint's link-angle
/// column times a per-row scalar (a torque-driven part, a coupling's angle, a gravity torque, a
/// profile's gated harmonic): then a chunk holds one value per row for it, and its Grams are
/// summed over the link angles' n × n products (cross_validation.cpp).
struct ColumnLayout {
  struct Place {
    int joint = -1;          ///< −1: dense
    Eigen::Index index = 0;  ///< in the chunk's dense columns, or in its joint's scaled ones
  };
  Eigen::Index dense = 0;            ///< dense columns of a chunk
  std::vector<Eigen::Index> scaled;  ///< per joint, its scaled columns in a chunk
  std::vector<Place> place;          ///< per column of A (two may share one place)
  Eigen::Index size() const { return static_cast<Eigen::Index>(place.size()); }
  /// Columns of a chunk: the dense ones, then each joint's scaled ones in joint order.
  Eigen::Index compactSize() const;
  /// Index of column c of A among a chunk's columns in compactSize's order.
  Eigen::Index compactIndex(Eigen::Index c) const;
};

/// Fit rows [begin, end) of a screening matrix in its layout: row i's equations of dense column
/// d are dense.middleRows(e_i, k_i).col(d), of scaled column (j, m) link_angle.middleRows(e_i,
/// k_i).col(j) · scaled[j](i − begin, m) (e_i its first equation in the chunk, k_i its count).
struct ColumnChunk {
  Eigen::MatrixXd dense;                ///< equations × layout.dense
  Eigen::MatrixXd link_angle;           ///< equations × n (Linearisation::link_angle)
  std::vector<Eigen::MatrixXd> scaled;  ///< per joint: rows × layout.scaled[j]
};

/// A screening matrix as made chunk by chunk, never whole: its layout, and the function that
/// makes fit rows [begin, end) of it (called on the cores, each call for its own chunk). It
/// makes the dense columns that `dense` marks (the others it may leave zero: a finite difference
/// costs an evaluation of the model per row), every scaled one.
struct ScreeningColumns {
  ColumnLayout layout;
  std::function<void(size_t begin, size_t end, const std::vector<bool>& dense, ColumnChunk& chunk)>
      make;
};

/// The columns of one screening matrix A (count × p, the residual's weighting) against the
/// model's residual, summed per fold: what every cross-validated fit on them needs. A is made
/// chunk by chunk of fit rows whenever its rows are needed (the Grams, held-out errors), so that
/// it holds its parameters' square and the residual it was built at, not a row per equation.
/// Built whenever the model changes.
struct FoldGrams {
  /// r0: the model's residual on every fit equation, where A was made.
  FoldGrams(ScreeningColumns columns, Eigen::VectorXd r0, const FitRows& fit);
  /// Moves the residual to r0 + A·v: the linearised model with a part of it (values v in its
  /// columns, 0 elsewhere) taken out (−v: a change put in). From the Grams alone: the rows see
  /// it as the values taken_out, in every held-out error.
  void takeOut(const Eigen::VectorXd& v);
  /// A copy with takeOut(v); it makes A as this one does.
  FoldGrams without(const Eigen::VectorXd& v) const;
  std::vector<Eigen::MatrixXd> G;  ///< per fold AᵀA of its rows, then the total (index folds)
  std::vector<Eigen::VectorXd> b;  ///< per fold Aᵀ r, then the total (r = r0 + A·taken_out)
  std::vector<double> e0;          ///< per fold Σ r²
  Eigen::VectorXd scale;           ///< √ of the total Gram's diagonal (1 where it is 0)
  Eigen::VectorXd taken_out;       ///< Σ of the values taken out (per column)
  /// The residual A was made at, per fit equation.
  const Eigen::VectorXd& r0() const { return *r0_; }

  const ColumnLayout& layout() const { return columns_->layout; }
  const FitRows& fit() const { return *fit_; }
  /// Fit rows [begin, end) of A: the dense columns `dense` marks, every scaled one.
  void make(size_t begin, size_t end, const std::vector<bool>& dense, ColumnChunk& chunk) const {
    columns_->make(begin, end, dense, chunk);
  }
  /// Calls body(slice, begin, end, chunk) for every chunk of fit rows [begin, end) of A, the
  /// chunks in kGramSlices contiguous slices on the cores (chunked_gram.hpp).
  void forEachChunk(
      const std::function<void(size_t slice, size_t begin, size_t end, const ColumnChunk& chunk)>&
          body) const;

 private:
  std::shared_ptr<const ScreeningColumns> columns_;
  std::shared_ptr<const Eigen::VectorXd> r0_;
  const FitRows* fit_;
};

/// The fewest corrections CrossValidation::heldOut is given at once.
inline constexpr size_t kMinHeldOutBatch = 8;
/// How many corrections' outcomes to ask of CrossValidation::heldOut at once: their per-pose
/// errors in a fixed budget (512 MB), so that a batch's memory does not grow with the poses
/// beyond kMinHeldOutBatch of them.
size_t heldOutBatch(const FitRows& fit);

class CrossValidation {
 public:
  /// grams must outlive it; stage1, stage2: the current model's columns; ridge: per column
  /// (0 = none); current: per column, the parameter's value at which r0 was computed (0 for a
  /// candidate; only where a ridge is and in stage 2 does it matter).
  CrossValidation(const FoldGrams& grams, const FitRows& fit, std::vector<Eigen::Index> stage1,
                  std::vector<Eigen::Index> stage2, Eigen::VectorXd ridge,
                  Eigen::VectorXd current);

  /// A linear correction: its columns, and the changes of their parameters fitted without each
  /// fold (index f) and on every row (index folds).
  struct Correction {
    std::vector<Eigen::Index> columns;
    std::vector<Eigen::VectorXd> x;
    double sse = 0.0;  ///< held-out weighted squared error over all folds
  };

  /// The current model.
  const Correction& base() const { return base_; }
  /// The current model with global columns added to stage 1 (stage 2 refitted after it).
  Correction withGlobal(const std::vector<Eigen::Index>& columns) const;
  /// The same, each fit (per fold and on every row) under linear bounds on the added columns'
  /// changes, C x ≥ d (C: bounds × columns.size(), every d ≤ 0): the constrained least squares
  /// of least_squares.hpp on the fold's ridged Gram (its square root, truncated as solveRidged).
  Correction withGlobal(const std::vector<Eigen::Index>& columns, const Eigen::MatrixXd& C,
                        const Eigen::VectorXd& d) const;

  /// A profile candidate's columns at its highest order, with what every order shares (per
  /// fold, T the training Gram, H the current profiles' ridged block).
  struct ProfileCandidate {
    std::vector<Eigen::Index> columns;
    std::vector<Eigen::MatrixXd> X;       ///< H⁻¹ T[stage2, columns]
    std::vector<Eigen::MatrixXd> schur;   ///< T[columns, columns] − T[columns, stage2] X
    std::vector<Eigen::VectorXd> rhs;     ///< its right-hand side after stages 1 and 2
  };
  ProfileCandidate prepareProfile(const std::vector<Eigen::Index>& columns) const;
  /// The current model with the candidate's first `width` columns added to stage 2, ridge λ.
  Correction withProfile(const ProfileCandidate& candidate, int width, double lambda) const;

  /// The given columns of the current model (stage 1 and the profiles, without the geometry's
  /// share: it duplicates the geometry) fitted together on every row, as one least-squares
  /// problem with the ridges on their values: each column's change, in the order given, the
  /// diagonal of (AᵀA + R)⁺ and the residual variance after it (σ² = variance · unit_variance).
  struct JointFit {
    Eigen::VectorXd change, unit_variance;
    double variance = 0.0;
  };
  JointFit jointFit(const std::vector<Eigen::Index>& columns) const;

  /// Row by row on the held-out folds: weighted squared error per pose, and the position errors
  /// of the rows summed.
  struct Outcome {
    std::vector<double> pose_sse;
    double position_sum_m = 0.0;
    size_t rows = 0;
    /// Σ pose_sse.
    double total() const;
  };
  /// Every correction's outcome from one pass over A's rows.
  std::vector<Outcome> heldOut(const std::vector<const Correction*>& corrections) const;
  Outcome heldOut(const Correction& correction) const { return heldOut({&correction}).front(); }
  /// The outcomes of groups of corrections, each group's together, the groups batched in order
  /// into passes of at most `batch` corrections (a larger group alone); done(first, outcomes)
  /// takes a pass's as it comes back: outcomes[i], those of group first + i.
  void heldOutInGroups(
      const std::vector<std::vector<const Correction*>>& groups, size_t batch,
      const std::function<void(size_t first, std::vector<std::vector<Outcome>> outcomes)>& done) const;

 private:
  Eigen::MatrixXd trainingGram(int f, const std::vector<Eigen::Index>& a,
                               const std::vector<Eigen::Index>& b) const;
  Eigen::VectorXd trainingRhs(int f, const std::vector<Eigen::Index>& a) const;
  Eigen::VectorXd solveRidged(int f, const std::vector<Eigen::Index>& columns,
                              Eigen::VectorXd* unit_variance = nullptr) const;
  Eigen::VectorXd solveRidgedBounded(int f, const std::vector<Eigen::Index>& columns,
                                     const Eigen::MatrixXd& C, const Eigen::VectorXd& d) const;
  Correction globalCorrection(const std::vector<Eigen::Index>& columns,
                              const Eigen::MatrixXd* C, const Eigen::VectorXd* d) const;
  double heldOutSse(int f, const std::vector<Eigen::Index>& columns, const Eigen::VectorXd& x) const;

  const FoldGrams& grams_;
  const FitRows& fit_;
  std::vector<Eigen::Index> stage1_, stage2_;
  Eigen::VectorXd ridge_, current_;
  // The current model per fold (and on every row at index folds).
  std::vector<Eigen::VectorXd> u_, p_, rhs2_;
  std::vector<Eigen::LLT<Eigen::MatrixXd>> H_;
  Correction base_;
};

/// Per-pose comparison of two held-out outcomes.
struct Comparison {
  double relative_reduction = 0.0;  ///< of the total held-out squared error
  double z = 0.0, p = 1.0;          ///< one-sided signed-rank test of the per-pose reduction
  double gain_mm = 0.0;             ///< mean held-out position error removed, mm
};
Comparison compare(const CrossValidation::Outcome& base, const CrossValidation::Outcome& with);

/// Wilcoxon signed-rank statistic of the pairs a_i − b_i, as a standard normal z (ties and zeros
/// handled; positive: a has the larger errors). Robust where a t statistic is not: one pose that
/// a candidate extrapolates to badly cannot hide a reduction that holds at most poses.
double signedRankZ(const std::vector<double>& a, const std::vector<double>& b);

/// One-sided p-value of a standard normal z (upper tail).
double upperTailP(double z);

}  // namespace stepcal::trainer::diagnosis
