// The catalogue's families by kind (internal to stepcal::trainer): each kind's screening
// families in its own file, families/<kind>.cpp, listed once in familyBuilders
// (families/families.cpp) in the order the screening tries them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "../candidates.hpp"
#include "../screening_columns.hpp"
#include "../signatures.hpp"

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
void torqueDeflectionFamilies(
    const FamilyContext& c);  // backlash, nonlinear_stiffness, torsion_curve
void jointCouplingFamilies(const FamilyContext& c);
void selfWeightFamilies(const FamilyContext& c);
void sensorBiasFamilies(const FamilyContext& c);
void thermalExpansionFamilies(const FamilyContext& c);
void registrationDriftFamilies(const FamilyContext& c);
void jointZeroDriftFamilies(const FamilyContext& c);
void campaignJointZeroFamilies(const FamilyContext& c);
void transmissionErrorFamilies(const FamilyContext& c);
void offAxisComplianceFamilies(const FamilyContext& c);
void toolMountComplianceFamilies(const FamilyContext& c);

/// How the diagnosis fits a kind's parameters, beyond its physics (MechanismTraits). One per
/// kind that needs one, in families/<kind>.cpp, listed in findKindFit (families.cpp); a kind
/// without one takes the defaults (model.hpp: typicalStep, signConstrained, freeParameters,
/// isShape).
struct KindFit {
  MechanismKind kind;
  /// Typical step of a parameter, SI; null: 1e-4.
  double (*typical_step)(const Mechanism& m, int index) = nullptr;
  /// The parameters that are sizes and stay ≥ 0; null: none.
  std::vector<int> (*sign_constrained)(const Mechanism& m) = nullptr;
  /// The fitted parameters, in the fit's order; null: every one.
  std::vector<int> (*free_parameters)(const Mechanism& m) = nullptr;
  /// Whether a parameter is a shape (a torque scale), not a size; null: none is.
  bool (*is_shape)(int index) = nullptr;
  /// Whether its sign-constrained parameters are sizes of their own (a compliance per
  /// direction): one the global refit holds at zero is that direction's size, zero, and the
  /// cause is dropped only when all are held. Else a part held at zero drops the cause.
  bool parts_independent = false;
  /// The physics' linear bounds beyond the sign-constrained parameters ≥ 0 (model.hpp
  /// PhysicalBound), and how a point breaking them is moved onto them; null: none.
  std::vector<PhysicalBound> (*bounds)(const Mechanism& m, const KinematicChain& chain) = nullptr;
  void (*make_feasible)(Mechanism& m, const KinematicChain& chain) = nullptr;
};
/// A kind's fit; null: the defaults.
const KindFit* findKindFit(MechanismKind kind);

// One per file (families/<kind>.cpp), for the kinds that differ from the defaults.
const KindFit& backlashFit();
const KindFit& nonlinearStiffnessFit();
const KindFit& torsionCurveFit();
const KindFit& selfWeightFit();
const KindFit& sensorBiasFit();
const KindFit& thermalExpansionFit();
const KindFit& registrationDriftFit();
const KindFit& jointZeroDriftFit();
const KindFit& sessionFramesFit();
const KindFit& offAxisComplianceFit();
const KindFit& toolMountComplianceFit();

/// How the diagnosis draws a found effect of a kind against its own variable (diagnose.hpp
/// EffectSignature). One per kind that has one, in families/<kind>.cpp, listed in
/// findKindSignature (families.cpp); a kind without one (a campaign's constants) draws none.
struct KindSignature {
  MechanismKind kind;
  /// Appends the signatures of the model's mechanism at index (context.model.mechanisms).
  void (*append)(const SignatureContext& context, size_t index,
                 std::vector<EffectSignature>& signatures) = nullptr;
};
/// A kind's signature; null: none.
const KindSignature* findKindSignature(MechanismKind kind);

// One per file (families/<kind>.cpp), for the kinds that draw one.
const KindSignature& backlashSignature();
const KindSignature& nonlinearStiffnessSignature();
const KindSignature& torsionCurveSignature();
const KindSignature& transmissionErrorSignature();
const KindSignature& jointCouplingSignature();
const KindSignature& selfWeightSignature();
const KindSignature& thermalExpansionSignature();
const KindSignature& jointZeroDriftSignature();
const KindSignature& offAxisComplianceSignature();
const KindSignature& toolMountComplianceSignature();

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
