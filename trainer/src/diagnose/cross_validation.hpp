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

#include <memory>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "fit_rows.hpp"
#include "stepcal/common/mechanisms.hpp"

namespace stepcal::trainer::diagnosis {

/// A block of a transmission profile's columns in a screening matrix, never stored: made from
/// the fit rows when needed (profileColumns: joint j's link-angle column times each gated basis
/// function), columns first … first + 2·order − 1.
struct ProfileBlock {
  Eigen::Index first = 0;
  int joint = 0;
  AngleCoverage coverage;
  int order = 0;
};

/// A column of a screening matrix that is a joint's link-angle column times a per-row feature
/// (a torque-driven part, a coupling's angle, a gravity torque), held as that feature.
struct FeatureColumn {
  int joint = 0;
  Eigen::VectorXd feature;  ///< per fit row
};

/// Where a column of a screening matrix comes from.
struct ColumnSource {
  enum class Kind { kStored, kFeature, kProfile };
  Kind kind = Kind::kStored;
  Eigen::Index index = 0;  ///< in stored (two columns may share one), features or blocks
};

/// The columns of a screening matrix A (count × p, the residual's weighting) as they are handed
/// to FoldGrams: stored ones, and the features' and the profiles' columns (most of them), which
/// are made again from the link-angle columns where needed, so that A takes a few stored columns
/// per equation, not several hundred.
struct ScreeningColumns {
  std::vector<Eigen::VectorXd> stored;  ///< count each
  std::vector<FeatureColumn> features;
  std::vector<ProfileBlock> blocks;
  std::vector<ColumnSource> source;  ///< per column of A
  Eigen::MatrixXd link_angle;        ///< count × n (Linearisation::link_angle)
  Eigen::Index size() const { return static_cast<Eigen::Index>(source.size()); }
};

/// The columns of one screening matrix A (count × p, the residual's weighting) against the
/// model's residual r0, summed per fold: what every cross-validated fit on them needs. Built
/// whenever the model changes.
struct FoldGrams {
  /// The stored columns are released one by one as they are sorted into the folds.
  FoldGrams(ScreeningColumns columns, const Eigen::VectorXd& r0, const FitRows& fit);
  /// Every column stored.
  FoldGrams(const Eigen::MatrixXd& A, const Eigen::VectorXd& r0, const FitRows& fit);
  /// Moves r0 to r0 + A·v: the linearised model with a part of it (values v in its columns, 0
  /// elsewhere) taken out (−v: a change put in).
  void takeOut(const Eigen::VectorXd& v);
  /// A copy with takeOut(v); it shares A's rows with this one.
  FoldGrams without(const Eigen::VectorXd& v) const;
  std::vector<Eigen::MatrixXd> G;  ///< per fold AᵀA of its rows, then the total (index folds)
  std::vector<Eigen::VectorXd> b;  ///< per fold Aᵀ r0, then the total
  std::vector<double> e0;          ///< per fold Σ r0²
  Eigen::VectorXd scale;           ///< √ of the total Gram's diagonal (1 where it is 0)
  /// Per fold, its equations' r0 and the fit rows they belong to (in order, each row's equations
  /// together), for row-by-row held-out errors over just the columns used.
  std::vector<Eigen::VectorXd> r0_fold;
  std::vector<std::vector<int>> rows_of_fold;

  /// Rows [begin, end) of fold f (indices into rows_of_fold[f]) of A, every column: the stored
  /// ones and the profiles' blocks made (their equations × p).
  Eigen::MatrixXd foldRows(size_t f, size_t begin, size_t end) const;
  /// Fold f's equations of profile block b's leading `width` columns (count_f × width), or of its
  /// rows [begin, end) only.
  Eigen::MatrixXd blockColumns(size_t f, Eigen::Index b, int width) const;
  Eigen::MatrixXd blockColumns(size_t f, Eigen::Index b, int width, size_t begin, size_t end) const;
  const ColumnSource& source(Eigen::Index c) const { return columns_->source[static_cast<size_t>(c)]; }
  const ProfileBlock& block(Eigen::Index b) const { return columns_->blocks[static_cast<size_t>(b)]; }
  /// Fold f's equations of stored column s.
  auto storedColumn(size_t f, Eigen::Index s) const { return columns_->stored_by_fold[f].col(s); }
  /// e −= x · (fold f's equations of feature column k), count_f.
  void subtractFeatureColumn(size_t f, Eigen::Index k, double x, Eigen::VectorXd& e) const;

 private:
  /// A's columns by fold, shared by the copies (without()) and never changed.
  struct Columns {
    std::vector<Eigen::MatrixXd> stored_by_fold;      ///< count_f × stored
    std::vector<Eigen::MatrixXd> link_angle_by_fold;  ///< count_f × n
    std::vector<Eigen::MatrixXd> q_by_fold;           ///< per fold row, its joint angles, rad
    std::vector<Eigen::MatrixXd> feature_by_fold;     ///< per fold row, each feature
    /// Per fold row, its first equation in the fold; then count_f.
    std::vector<std::vector<Eigen::Index>> start_by_fold;
    std::vector<int> feature_joint;
    std::vector<ProfileBlock> blocks;
    std::vector<ColumnSource> source;
  };
  std::shared_ptr<const Columns> columns_;
};

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

  /// Row by row on the held-out folds: weighted squared error per pose, position error per row.
  struct Outcome {
    std::vector<double> pose_sse;
    std::vector<double> position_m;
  };
  Outcome heldOut(const Correction& correction) const;

 private:
  Eigen::MatrixXd trainingGram(int f, const std::vector<Eigen::Index>& a,
                               const std::vector<Eigen::Index>& b) const;
  Eigen::VectorXd trainingRhs(int f, const std::vector<Eigen::Index>& a) const;
  Eigen::VectorXd solveRidged(int f, const std::vector<Eigen::Index>& columns,
                              Eigen::VectorXd* unit_variance = nullptr) const;
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
