// The catalogue's families by kind (internal to stepcal::trainer): each kind's screening
// families in its own file, families/<kind>.cpp, listed once in familyBuilders
// (families/families.cpp) in the order the screening tries them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "../candidates.hpp"
#include "../screening_columns.hpp"

namespace stepcal::trainer::diagnosis {

/// One round's screening under way: what a kind's families are made from and where they go.
struct FamilyContext {
  const DiagnosisModel& model;
  const PhysicalModel& global;  ///< model.global: what is present is asked of it
  const PhysicalModel& whole;   ///< model.combined(): the columns are changes of it
  const FitRows& fit;
  const Evaluation& start;  ///< the whole model's evaluation: the rows' torques and link angles
  const DiagnoseOptions& options;
  const std::optional<std::vector<double>>& body_masses;  ///< the URDF's, if any
  const ScreeningScope& scope;
  int n;          ///< joints
  int max_order;  ///< the highest profile order tried
  Screening& s;
  ColumnSink& sink;
  ColumnRecipe& recipe;

  /// Whether the scope tries a family of this kind, joint and source joint.
  bool wanted(MechanismKind kind, int joint = -1, int source = -1) const;
  /// A global family with its columns and their typical parameter steps: whether it moves the
  /// tip at these rows is judged once its columns' norms are known (completeScreening).
  void addGlobal(Family family, std::vector<Eigen::Index> columns, std::vector<double> steps,
                 double column_ridge = 0.0) const;
};

/// Appends one kind's (or a few competing kinds') families and untestable entries.
using FamilyBuilder = void (*)(const FamilyContext& context);

/// Every builder, in the order the screening tries them (the order of its families and
/// untestable entries).
const std::vector<FamilyBuilder>& familyBuilders();

// One per file (families/<kind>.cpp).
void torqueDeflectionFamilies(const FamilyContext& c);  // backlash, nonlinear_stiffness, torsion_curve
void jointCouplingFamilies(const FamilyContext& c);
void selfWeightFamilies(const FamilyContext& c);
void sensorBiasFamilies(const FamilyContext& c);
void thermalExpansionFamilies(const FamilyContext& c);
void registrationDriftFamilies(const FamilyContext& c);
void jointZeroDriftFamilies(const FamilyContext& c);
void campaignJointZeroFamilies(const FamilyContext& c);
void transmissionErrorFamilies(const FamilyContext& c);

/// A mechanism of a kind at zero, sized for an n-joint chain.
Mechanism blank(MechanismKind kind, int dof, int joint = -1, int source = -1, int order = 0);
double median(std::vector<double> v);
double stdOf(const std::vector<double>& v);
/// Whether the model has this kind (one per model), or this kind on this joint and source joint.
bool present(const PhysicalModel& model, MechanismKind kind, int joint, int source);

/// The rows' temperatures: the thermal families' reference (their mean) and whether they vary.
struct RowTemperatures {
  double mean_c = 0.0;
  double spread_c = 0.0;  ///< standard deviation
  bool few = true;        ///< fewer than half the rows have one
};
RowTemperatures rowTemperatures(const FitRows& fit);

}  // namespace stepcal::trainer::diagnosis
