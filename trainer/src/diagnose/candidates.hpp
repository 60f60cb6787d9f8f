// The catalogue a diagnosis screens each round, as families with columns in one screening matrix
// (internal to stepcal::trainer).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

enum class Stage { kGlobal, kProfile };

/// A family screened as one: a global mechanism (its free parameters, and the compliances it
/// makes identifiable), or a joint's transmission profile (every order up to the highest).
struct Family {
  Stage stage = Stage::kGlobal;
  /// Parameters at their start (zero, τ₀ and T_ref chosen; self weight's masses from the URDF);
  /// a profile: its joint, the highest order, its coverage.
  Mechanism mechanism;
  std::vector<int> free;        ///< global: the mechanism's fitted parameters
  std::vector<int> compliance;  ///< global: joints whose compliance it frees (self weight)
  std::vector<Eigen::Index> columns;  ///< in the screening matrix, free then compliance
  /// global: per column, a typical step of its parameter (SI): with the column's norm, whether
  /// the family moves the tip at all (completeScreening)
  std::vector<double> steps;
  /// global: how many of the screening's untestable entries come before it
  size_t untestable_before = 0;
  /// Constants it picks from a grid (a fade torque each): spent like fitted parameters.
  int chosen = 0;
  /// A joint's torque-deflection mechanism already in the model that this family extends
  /// (index in the global mechanisms; mechanism is then the whole curve, the new parts free),
  /// −1: a family of its own.
  int extends = -1;
  /// Fitted on every row it makes every compliance it frees negative: not a deflection.
  bool negative_compliance = false;
  /// A time-order family (confounds.hpp): its driver ("seq", "temp_c"; empty: none) and, per
  /// variable that moves with it, the nuisance columns that re-make it as a function of that
  /// variable (its own columns times the variable's functions).
  std::string driver;
  struct Confound {
    std::string variable;
    double r = 0.0;  ///< DriverCorrelation of the driver with it
    std::vector<Eigen::Index> columns;
  };
  std::vector<Confound> confounds;
  /// global: the linear bounds its physics puts on its mechanism's parameters (physicalBounds).
  std::vector<PhysicalBound> bounds;
  /// A profile's difference in this later campaign (its columns zero on the other campaigns'
  /// rows), tested for the report and never added; 0: a family of the robot.
  int campaign = 0;
  /// A profile of the robot: the same profile's columns times the joint's torque (the
  /// screening's kProfileTorque), what profile_load_check.cpp tells it apart from; empty where
  /// the joint carries no torque. Where the model holds a self weight, times the torque without
  /// its weight, and weight_modulated times that weight (a self weight found in an early round
  /// may stand in for part of a load effect: the two parts let the fit weigh it again).
  std::vector<Eigen::Index> torque_modulated, weight_modulated;
  double torque_std_nm = 0.0;
};

/// One round's screening matrix: the current model's columns and every family's.
struct Screening {
  /// Its columns (the residual's weighting), geometry first, as made chunk by chunk; handed to
  /// FoldGrams.
  ScreeningColumns columns;
  Eigen::VectorXd ridge;                ///< per column (lumped masses' prior, profiles' ridges)
  /// Per column, the parameter's value in the model the round starts from (0: a candidate).
  Eigen::VectorXd current;
  std::vector<Eigen::Index> stage1, stage2;
  std::vector<Family> families;  ///< not in the model yet
  /// The model's profiles as families at the highest order (model order): stage 2 holds the
  /// leading 2·order columns of each, so each can be tried again at every order.
  std::vector<Family> profiled;
  std::vector<UntestableCandidate> untestable;
};

/// Stage 2 of a screening for the model's profiles: the geometry's share (its first `geometry`
/// entries, kept), then the leading 2·order columns of each profiled family, with their ridges
/// set in the screening's ridge and their values (the model's) in its current.
void setStage2(Screening& s, const DiagnosisModel& model, Eigen::Index geometry);

/// What a screening tries beside the model's own columns: every catalogued family not in the
/// model yet, none (the model's joint fit, its profiles tried again), or only the global
/// families of one mechanism's kind, joint and source joint (a cause tried again).
struct ScreeningScope {
  bool families = true;
  const Mechanism* only = nullptr;
  /// ≥ 1: the families are each current profile's difference in that later campaign alone.
  int campaign_profiles = 0;
};

/// Builds the round's screening: the current model's stage-1 and stage-2 columns, and the
/// families its scope tries. start: the whole model's evaluation (profiles in), the round's r0;
/// body_masses: the URDF's (bodyMassesFromUrdf), if any. The columns are made from the model
/// when needed; fit must outlive them.
Screening screening(const DiagnosisModel& model, const FitRows& fit, const Evaluation& start,
                    const DiagnoseOptions& options,
                    const std::optional<std::vector<double>>& body_masses,
                    const ScreeningScope& scope = {});

/// What the screening needs of its Grams (the columns' norms): the ridges of the geometry's share
/// in stage 2, and the global families that do not move the tip at these rows taken out into
/// the untestable ones (in their places).
void completeScreening(Screening& s, const FoldGrams& grams, Eigen::Index geometry);

/// Joint `joint`'s gravity torque under self_weight parameters `masses` ((m, m·com) per link) at
/// link angles theta_rad on the model's chain, N·m; 0 for no masses.
double modelWeightTorque(const PhysicalModel& whole, const std::vector<double>& masses,
                         const JointVector& theta_rad, int joint);

/// Joints whose gravity torque under the given self_weight parameters varies enough over the
/// fit rows to identify their compliance from it (std ≥ 1 N·m and ≥ 10 % of the largest), and the
/// std of each joint's gravity torque, N·m.
std::vector<int> gravityLoadedJoints(const PhysicalModel& global, const FitRows& fit,
                                     const std::vector<JointVector>& theta_rad,
                                     const std::vector<double>& masses,
                                     std::vector<double>* torque_std_nm = nullptr);

}  // namespace stepcal::trainer::diagnosis
