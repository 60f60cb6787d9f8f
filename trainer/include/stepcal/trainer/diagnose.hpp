// Diagnosis: what the physical model (geometry + compliance) gets wrong, which catalogued
// mechanism (mechanisms.hpp) explains it, and how much the extended model gains.
//
// The model is built in two stages (trainer/src/diagnose/model.hpp): a global physical model
// (geometry δ, compliances, every mechanism that holds at any pose: self weight, backlash,
// nonlinear stiffness, coupling, thermal expansion, sensor bias), and on what it leaves, one
// transmission profile per joint (a Fourier series in the joint angle, ridge-regularised, gated
// to the joint angles it was fitted on). First the residual of the starting model is compared
// with the tracker noise and tested for trends in q_j, τ_j, load, temperature and seq. Then, each
// round (trainer/src/diagnose/search.hpp has the phases):
// 1. Every family not in the model yet (a global mechanism with its parameters; a joint's
//    profile at every order and ridge of a grid) is added to the linearised two-stage model and
//    judged by cross-validation over poses (folds by pose_id). A one-sided Wilcoxon signed-rank
//    test of the per-pose reduction of the held-out squared error, Bonferroni-corrected over
//    every configuration tried in the round, keeps chance from naming a cause; a cause must also
//    remove ≥ 1 % and have the signs its physics needs.
// 2. One significant family is added (physical constants of the arm first; else the best unless
//    a simpler one is not significantly worse) and the model refitted. Repeat until nothing
//    significant is left.
// Then backward elimination, each profile's order and ridge chosen again, the final joint fits,
// and every cause the final fit leaves without a size (what the data identify of it within one σ
// of zero) dropped; the verdict (found, none, unexplained), with the residual after the effects
// tested for trends again; the extended model (with a GPR refitted on its residual) and its gain
// on validation rows.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer {

struct DiagnoseOptions {
  int folds = 5;                ///< cross-validation folds over poses
  /// Orders a transmission profile is tried at (harmonics 1 … order); the largest bounds it.
  std::vector<int> profile_orders = {1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48};
  /// Ridges a profile is tried with, relative to the mean diagonal of its Gram block (λ = ρ ·
  /// mean ‖column‖²): the prior that keeps harmonics the data cannot tell apart near zero.
  std::vector<double> profile_ridges = {1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1};
  /// A profile covers the arcs of its joint's fitted angles without gaps wider than this, deg
  /// (at least twice the fade).
  double coverage_gap_deg = 10.0;
  /// Beyond the outermost fitted angles of each arc, the profile fades out over this width, deg.
  double coverage_fade_deg = 5.0;
  int max_rounds = 12;          ///< rounds of "add the best family, refit"
  double family_alpha = 0.01;   ///< false-positive rate per round, all configurations together
  /// A cause must also remove at least this fraction of the held-out noise-weighted squared
  /// error: significant in practice, not only statistically (tiny, consistent misfits of the
  /// model otherwise accumulate as spurious causes).
  double min_relative_reduction = 0.01;
  int refit_iterations = 12;    ///< Gauss–Newton iterations of a global refit
  /// A residual this many times the stated tracker noise (RMS of noise-weighted entries) counts
  /// as unexplained even when it follows no tested variable.
  double noise_ratio_limit = 1.3;
  CalibrationOptions calibration;  ///< GPR options of the extended model's step 3
};

enum class Verdict { kFound, kNone, kUnexplained };
/// "found", "none" or "unexplained".
const char* toString(Verdict verdict) noexcept;

/// One family of one round, at its best configuration, scored on held-out poses.
struct CandidateScore {
  /// Parameters fitted on all fit rows (linearised), SI; a profile at its best order.
  Mechanism mechanism;
  int round = 1;
  double ridge = 0.0;        ///< a profile's relative ridge ρ (DiagnoseOptions::profile_ridges)
  int configurations = 1;    ///< configurations tried for it (orders × ridges for a profile)
  double cv_gain_mm = 0.0;   ///< held-out mean position error without minus with it, mm
  double relative_reduction = 0.0;  ///< fraction of the held-out squared error it removes
  /// Signed-rank z of the per-pose reduction of the noise-weighted squared error (a profile: at
  /// its best configuration, which the test is about; gain and reduction are those of the
  /// configuration added, the simplest one not significantly worse)
  double z_statistic = 0.0;
  double p_value = 1.0;      ///< one-sided, normal approximation
  /// Its fitted parameters are physically possible (lost motion, extra compliance ≥ 0, a lumped
  /// link mass ≥ 0 with its centre of mass within the link's reach: they are fitted within those
  /// bounds), and freeing its joints' compliance does not make them all negative.
  bool physical = true;
  /// When its fit without the physics' bounds was physically impossible: what made it so (e.g.
  /// "link 3 mass -115 kg"), and that fit's held-out outcome; the score above is then the fit's
  /// within the bounds: a candidate that explains the residual only beyond them stands for
  /// something else. Empty: the fit needed no bound.
  std::string impossible_unbounded;
  double unbounded_cv_gain_mm = 0.0, unbounded_relative_reduction = 0.0;
  double unbounded_z_statistic = 0.0, unbounded_p_value = 1.0;
  /// The unbounded fit passes the round's test (as `significant`, but for being possible).
  bool unbounded_significant = false;
  /// A global cause whose gain a joint's torque modulated by harmonics of its angle (a stiffness
  /// varying with the angle, which the catalogue does not hold) explains: those columns add
  /// significantly beside it and it adds nothing significant beside them, so it is not named
  /// (docs/diagnosis.md "A cause standing in for a stiffness that varies with the angle").
  struct ModulatedStandIn {
    int joint = -1;           ///< 0-based joint of the modulated columns; −1: not set aside
    int modulated_order = 0;  ///< their order, the best of the orders tried held out
    /// The modulated columns beside the cause: held-out gain, reduction of the round's error, z.
    double modulated_gain_mm = 0.0, modulated_reduction = 0.0, modulated_z = 0.0;
    /// The cause beside the modulated columns.
    double gain_mm = 0.0, reduction = 0.0, z = 0.0;
  };
  ModulatedStandIn modulated_stand_in;
  /// Significant only beside a joint's modulated columns, in a round where they set every cause
  /// significant alone aside (its reduction alone stays in the score's other fields).
  struct BesideModulated {
    int joint = -1;           ///< 0-based joint of the modulated columns; −1: not scored so
    int modulated_order = 0;  ///< their order
    double gain_mm = 0.0, reduction = 0.0, z = 0.0;  ///< the cause beside them
  };
  BesideModulated beside_modulated;
  bool significant = false;  ///< physical, p < family_alpha / (configurations in the round), enough removed
  bool chosen = false;
};

/// A candidate that could not be tried on this campaign, and why.
struct UntestableCandidate {
  std::string name;
  std::string reason;
};

/// A named cause, in the order found.
struct FoundEffect {
  Mechanism mechanism;  ///< parameters and 1-σ from the final refit
  int round = 1;
  double cv_gain_mm = 0.0, z_statistic = 0.0, p_value = 1.0;
  /// transmission_error: RMS over the fit rows of the link-angle offset (gate included), rad;
  /// its largest harmonic amplitude, rad; its relative ridge; per harmonic the share of its
  /// effect a geometric error could produce.
  double rms_rad = 0.0;
  double largest_amplitude_rad = 0.0;
  double ridge = 0.0;
  std::vector<double> geometry_share;
  /// transmission_error: whether its single harmonics mean something on the arc it covers. Not
  /// when the largest harmonic's amplitude exceeds 3× the profile's RMS: the harmonics then
  /// cancel each other over the arc (too narrow to tell them apart) and only the profile's
  /// values there are determined.
  bool harmonics_separable = true;
  /// self_weight: joints whose compliance it frees (0-based).
  std::vector<int> compliance_joints;
  /// self_weight with the URDF's masses, at the final model: the joints whose gravity torque
  /// varies enough over the fit rows to identify their compliance, the std of each joint's
  /// gravity torque (N·m, n entries), and the joints whose compliance neither it nor a load
  /// identifies (0-based).
  std::vector<int> gravity_loaded_joints;
  std::vector<double> gravity_torque_std_nm;
  std::vector<int> weak_gravity_joints;
  /// backlash, nonlinear_stiffness, torsion_curve: the largest |τ_j| of the joint on the fit
  /// rows, N·m (the curve is identified up to it; beyond it the model goes on with its last
  /// stiffness, which the rows do not show), and the joint's stiffness in segments as a gear
  /// catalogue gives it, lost motion apart: the secant stiffness of C τ plus the stiffening terms
  /// over [0, T_1], [T_1, T_2], …, [T_last, max], the T_k being the curve's fade torques below
  /// the largest (nonlinear_stiffness: τ₀), N·m/rad.
  double max_torque_nm = 0.0;
  struct StiffnessSegment {
    double from_nm = 0.0, to_nm = 0.0, stiffness_nm_per_rad = 0.0;
  };
  std::vector<StiffnessSegment> stiffness_segments;
  /// registration_drift, joint_zero_drift: how far it moves the tip over the fit rows (a
  /// registration drift: as the tracker sees it), RMS and largest, m.
  double tip_motion_rms_m = 0.0, tip_motion_max_m = 0.0;
  /// Other significant families of its round that removed nearly as much held-out error (at
  /// least 80 %) and nothing more once it was in the model: the data cannot tell them from it.
  std::vector<Mechanism> alternatives;
  /// Its size in the final fit: χ² of what the data identify of it over the size_dof directions
  /// they determine (a profile: cᵀ Σ_c⁻¹ c over 2·order; a global cause whose fit ended on a
  /// bound of its physics, where that χ² falls short: what the fit loses without it, in units of
  /// the residual variance); every cause kept has χ² > dof.
  double size_chi2 = 0.0;
  int size_dof = 0;
};

/// What the search did to the model that the verdict says: a compliance held at zero, or a cause
/// dropped, and why (in the order done).
struct ModelChange {
  enum class Kind {
    /// A joint's compliance the rows push below zero refitted with the rest: held at zero.
    kComplianceHeldAtZero,
    /// A cause whose lost motion or extra compliance the rows push below zero refitted with the
    /// others.
    kDroppedWrongSign,
    /// A torsion curve some of whose parts (its lost motion, a stiffening term) the rows push
    /// below zero refitted with the others: those parts removed, the rest kept.
    kPartDroppedWrongSign,
    /// A cause that the causes named after it explain: tried again with them in the model, it
    /// is no longer significant (relative_reduction, z_statistic of that trial).
    kDroppedExplained,
    /// A cause left without a size in the final fit: what the data identify of it lies within
    /// one σ of zero (size_chi2 ≤ size_dof over its size_dof determined directions; a profile:
    /// its coefficients' cᵀ Σ⁻¹ c against 2·order).
    kDroppedWithoutSize,
  };
  Kind kind = Kind::kComplianceHeldAtZero;
  int joint = -1;                      ///< kComplianceHeldAtZero (0-based)
  /// kComplianceHeldAtZero: where the refit's last step would take it without its bound
  double compliance_rad_per_nm = 0.0;
  Mechanism mechanism;                 ///< the cause dropped (kPartDroppedWrongSign: before)
  Mechanism kept;                      ///< kPartDroppedWrongSign: what is left of it
  double relative_reduction = 0.0, z_statistic = 0.0;  ///< kDroppedExplained
  double size_chi2 = 0.0;                               ///< kDroppedWithoutSize
  int size_dof = 0;                                     ///< kDroppedWithoutSize
};

/// A cross-validated trend of the residual in one variable (cubic in the variable).
struct TrendScore {
  std::string variable;      ///< e.g. "q2_deg", "tau3_nm", "load_kg", "temp_c", "seq"
  double cv_gain_mm = 0.0;   ///< held-out mean position error removed by the trend, mm
  double z_statistic = 0.0, p_value = 1.0;
  bool significant = false;  ///< Bonferroni over the variables tested
};

/// What a physical model gets wrong on the fit rows.
struct ResidualStatistics {
  int rows = 0;
  double mean_position_m = 0.0, rms_position_m = 0.0, max_position_m = 0.0;
  double rms_orientation_rad = 0.0;   ///< over rows with orientation
  double noise_ratio = 0.0;           ///< RMS of the noise-weighted entries: 1 = tracker noise
  std::vector<TrendScore> trends;     ///< most significant first
  std::vector<double> position_error_m;  ///< per fit row, for plots
};

/// Accuracy on one validation load: physical model before and after, and the GPR references.
struct GainRow {
  double load_kg = 0.0;
  int rows = 0;
  AccuracySummary before, after, gpr, after_gpr;
};

/// How far a variable moves with the time order (or another family's driver): the multiple
/// correlation R of the driver with the variable's functions (each of its levels when it has at
/// most 8 distinct values, else P_1..P_3 of it over its range) over the fit rows, 0 … 1.
struct DriverCorrelation {
  /// "load_kg", "temp_c", "q2_deg", "tau3_nm" (the model's torque), "fx_n" … "mz_nm" (the
  /// wrench, sensor axes) or "seq"
  std::string variable;
  double r = 0.0;
};

/// A time-order family (registration_drift: the time order; joint_zero_drift: temp_c) that was
/// significant in a round, scored again beside each variable that moves with its driver (R ≥
/// 0.3): its own columns times the variable's functions added to the model as nuisance. It may
/// be named only when it stays significant beside every one of them (the round's family-wise
/// test and practical minimum); otherwise the rows cannot tell it from that variable, and what
/// it explained stays with the robot's causes or the residual.
struct ConfoundTest {
  Mechanism mechanism;  ///< the family at its best configuration in that round
  int round = 1;
  std::string driver;   ///< "seq" or "temp_c"
  double z_statistic = 0.0;  ///< its signed-rank z in that round, alone
  struct Beside {
    std::string variable;
    double r = 0.0;  ///< DriverCorrelation of the driver with it
    double cv_gain_mm = 0.0, relative_reduction = 0.0, z_statistic = 0.0, p_value = 1.0;
    bool told_apart = false;  ///< still significant beside it
  };
  std::vector<Beside> beside;  ///< empty: nothing moves with the driver
  bool told_apart = true;      ///< from every variable beside: it may be named
};

/// What drifted while the campaign was measured: the tracker's registration in time order (the
/// measurement's), a joint's zero with temperature (the robot's), both, or neither, and what
/// the rows can tell apart.
struct DriftVerdict {
  bool registration = false;            ///< a registration_drift is among the effects
  std::vector<int> zero_drift_joints;   ///< joints with a joint_zero_drift effect (0-based)
  /// Pearson correlation of temp_c and seq over the fit rows with a temperature (NaN: fewer than
  /// 3 such rows, or either constant).
  double seq_temp_correlation = 0.0;
  /// How far each variable moves with the time order over the fit rows (the confounders a
  /// drift in time must be told apart from), largest first.
  std::vector<DriverCorrelation> time_order_correlations;
  /// Per time-order family significant in some round, its last round's test beside the
  /// variables that move with its driver (in the order first tested).
  std::vector<ConfoundTest> confound_tests;
  std::string text;  ///< the verdict's sentences
};

/// Whether one profile of a joint serves a later campaign as it serves the first: the profile's
/// difference on that campaign's rows alone, screened held out like a candidate (over the orders
/// up to the profile's and the ridges), reported and never added to the model.
struct CampaignProfileDifference {
  /// The difference (a transmission_error of the profile's joint and coverage) at its simplest
  /// configuration, with its held-out gain, reduction, z; significant as a candidate would be.
  CandidateScore score;
  double rms_rad = 0.0;  ///< its RMS over the campaign's fit rows (gate included), rad
};

/// One of several campaigns of one robot diagnosed together (`stepcal diagnose DIR1 DIR2 …`):
/// one robot, each campaign measured from its own tracker station with its own tool.
struct DiagnosedCampaign {
  std::string directory;
  int fit_rows = 0;
  /// Its tracker station and tool against the first campaign's, with 1-σ (session_frames); the
  /// first campaign's are the model's own, and this is empty (no parameters).
  Mechanism frames;
  /// Its fit rows' mean position error, m: the starting model refitted, the extended model.
  double before_mean_m = 0.0, after_mean_m = 0.0;
  /// After the first: per profile of the extended model, its difference here (empty for the first).
  std::vector<CampaignProfileDifference> profile_differences;
};

/// A variable the extended model's residual may follow (Diagnosis::unexplained), judged held out
/// as a family is: the residual fitted on a cubic in it (Legendre P1–P3 of the variable over its
/// range on the fit rows) in the tracker's axes, and, where it belongs to a joint, through the
/// arm: joint j's link angle (its angle, its torque, its torque from the arm's own weight), or the tilt and shift of joint j's frame
/// (the payload's wrench in that frame); a torque modulated by harmonic h of its joint's angle
/// through the link angle alone (τ_j cos h q_j, τ_j sin h q_j; one variable per h = 1–12).
struct UnexplainedVariable {
  /// e.g. "load_kg", "temp_c", "seq", "q3_deg", "tau3_nm", "weight2_nm" (the links' gravity
  /// torque: the model's self weight, else the URDF's masses), "joint3_mx_nm", "joint3_fz_n",
  /// "tau3_nm*h7(q3)"
  std::string name;
  std::string description;  ///< in words, e.g. "the payload's moment about joint 3's x axis"
  int joint = -1;           ///< the joint it belongs to (0-based), −1 for none
  /// A moment component of the payload's wrench in joint's frame, perpendicular to its axis
  /// (what a bearing's tilt follows).
  bool perpendicular_moment = false;
  double cv_gain_mm = 0.0;  ///< held-out mean position error it removes, mm
  double relative_reduction = 0.0;
  double z_statistic = 0.0, p_value = 1.0;
  /// p below family_alpha / (variables tested), and at least min_relative_reduction removed
  bool significant = false;
};

/// The verdict's "unexplained" part: what the extended model leaves beyond the tracker noise
/// held out, which variables it follows, and how much a free learner over physical features
/// removes of it that the catalogue does not.
struct UnexplainedPart {
  /// The extended model's mean position error held out, m: on the validation rows (every load),
  /// or, with none, on the fit rows (residual_rows says which).
  double residual_m = 0.0;
  std::string residual_rows;  ///< "validation" or "fit"
  double floor_m = 0.0;       ///< the mean error the stated tracker noise alone gives, m
  double ratio = 0.0;         ///< residual_m / floor_m
  bool noise_stated = false;  ///< false: the campaign states no tracker noise (the default σ)
  int variables_tested = 0;
  /// Every variable tested: the significant ones first, by their held-out reduction (as the
  /// rounds choose among families), then the others by z.
  std::vector<UnexplainedVariable> variables;
  /// The free learner: a ridge fit over a dictionary of physical features (per joint: its torque
  /// times harmonics 0–12 of its angle through its link angle, its frame's tilt under each moment
  /// component and shift under each force component of the payload's wrench), its ridge chosen
  /// held out among a few; its held-out gain and signed-rank test (Bonferroni over the ridges).
  int learner_features = 0;
  double learner_gain_mm = 0.0, learner_relative_reduction = 0.0, learner_z = 0.0,
         learner_p = 1.0;
  bool learner_significant = false;
  /// Something is unexplained: the residual above DiagnoseOptions::noise_ratio_limit × the
  /// floor, a significant variable, or a significant learner.
  bool any = false;
  std::string text;  ///< the verdict's sentences
};

/// Whether the extended model's geometry was pinned by the unloaded fit rows (docs/diagnosis.md,
/// "The extended model"): the geometry refitted on them alone, the rest held, against the geometry
/// of the global fit on every fit row; pinned when the unloaded rows reject the latter (F test).
struct GeometryPin {
  bool tested = false;  ///< false: the fit rows are all unloaded or all loaded
  bool pinned = false;
  int unloaded_rows = 0;
  int rank = 0;         ///< identifiable geometry directions on the unloaded rows
  double f_statistic = 0.0;  ///< (Δcost / rank) / (cost_pinned / (equations − rank))
  double f_limit = 0.0;      ///< pinned above it
  /// How far the unloaded rows' geometry moves the modelled tip from the global fit's, over every
  /// fit row (loaded ones included), RMS and largest, m: what the pin changed (pinned), or would
  /// have (not pinned).
  double tip_shift_rms_m = 0.0, tip_shift_max_m = 0.0;
};

/// A joint's transmission profile tried against the same profile modulated by the joint's
/// torque (each harmonic times the row's τ_j: a stiffness that varies with the angle, which the
/// catalogue does not hold), held out with the profile's ridge: the profile at its order, the
/// modulated columns at the order that fits best alone. The profile is not
/// named when the modulated columns explain significantly more beside it and it adds nothing
/// significant beside them; named, with the modulated part left, when both add. Rows that cannot
/// tell them apart (neither adds beside the other) leave no entry.
struct LoadModulatedProfile {
  int joint = 0;  ///< 0-based
  int order = 0;            ///< the profile's
  int modulated_order = 0;  ///< the modulated columns', the best of the orders tried held out
  int round = 1;
  bool profile_named = false;
  double torque_std_nm = 0.0;  ///< the joint's torque over the fit rows
  /// The modulated columns added beside the profile: held-out gain, reduction, signed-rank z, p.
  double modulated_gain_mm = 0.0, modulated_reduction = 0.0, modulated_z = 0.0, modulated_p = 1.0;
  /// The profile added beside the modulated columns.
  double profile_gain_mm = 0.0, profile_reduction = 0.0, profile_z = 0.0, profile_p = 1.0;
};

/// The family a round chose against another global family significant in that round (the
/// largest reductions first): whether the rows tell the two apart. Their collinearity on the fit
/// rows is ρ, the largest canonical correlation of their columns once the round's model columns
/// are taken out (1: a direction of one is a direction of the other; variance inflation 1/(1−ρ²));
/// the test is held out, each added beside the other with the round's family-wise level and
/// practical minimum. Neither adds beside the other: the rows cannot tell them apart, and the
/// one named stands for either.
struct FamilyPairTest {
  Mechanism chosen, other;  ///< at their round's configurations
  int round = 1;
  double canonical_correlation = 0.0;
  double variance_inflation = 1.0;  ///< 1/(1−ρ²); infinite at ρ = 1
  struct Beside {
    double cv_gain_mm = 0.0, relative_reduction = 0.0, z_statistic = 0.0, p_value = 1.0;
    bool significant = false;
  };
  Beside chosen_beside_other, other_beside_chosen;
  /// One of them adds significantly beside the other.
  bool told_apart = true;
};

struct Diagnosis {
  Verdict verdict = Verdict::kNone;
  DriftVerdict drift;
  std::vector<FoundEffect> effects;
  std::vector<CandidateScore> candidates;  ///< every round's, in order
  std::vector<UntestableCandidate> untestable;
  /// Compliances held at zero and causes dropped, in the order done (what the data can and
  /// cannot tell apart is in each effect: alternatives, geometry_share, harmonics_separable, …).
  std::vector<ModelChange> changes;
  /// Profiles tried against the same profile times the joint's torque, where the rows tell them apart.
  std::vector<LoadModulatedProfile> load_modulated_profiles;
  /// Per round that chose a global family, its tests against the other significant ones.
  std::vector<FamilyPairTest> family_pairs;
  ResidualStatistics before, after;        ///< of the model without / with the effects
  std::string unexplained_trend;           ///< what the residual still follows, if anything
  /// What the catalogue does not explain, held out, and what it follows.
  UnexplainedPart unexplained;
  std::vector<GainRow> gain;               ///< per validation load
  std::string gpr_method;                  ///< the GPR reference, e.g. "poe+stiffness+gpr"
  /// The extended model's GPR: its training rows, the signed-rank z of its held-out reduction
  /// and whether it was taken (ResidualModel::taken; not taken, the extended+gpr column is the
  /// extended model's and the model file holds no GPR).
  int extended_gpr_rows = 0;
  double extended_gpr_z = 0.0;
  bool extended_gpr_taken = true;
  GeometryPin geometry_pin;                ///< of the extended model
  double floor_position_m = 0.0;           ///< mean error the tracker noise alone gives
  CalibratedModel extended_model;          ///< the model with the effects and its GPR
  /// With several campaigns, each in the order given; empty for one. The extended model's tracker
  /// and tool are the first campaign's.
  std::vector<DiagnosedCampaign> campaigns;
  /// Fit-row variables for plots: names (trend variables) and values (row-major, per fit row).
  std::vector<std::string> variable_names;
  std::vector<std::vector<double>> variable_values;
  int fit_rows = 0, fit_poses = 0, validation_rows = 0, folds = 0;
  double seconds_refit = 0.0, seconds_screening = 0.0, seconds_trends = 0.0,
         seconds_gpr = 0.0, seconds_evaluation = 0.0;  ///< wall time of each part
};

/// What a found effect's signature is plotted against.
enum class SignatureVariable {
  kJointAngle,   ///< a joint's commanded angle, rad
  kJointTorque,  ///< a joint's torque in the model, N·m (self_weight: the links' gravity torque)
  kTemperature,  ///< the row's temp_c, °C
  /// off_axis_compliance: the load's moment about the joint's origin along one direction across
  /// its axis (EffectSignature::direction), N·m
  kMomentAcrossAxis,
  /// tool_mount_compliance: the load's force along one of the mount's axes
  /// (EffectSignature::direction: 0 x, 1 y, 2 z), N
  kForceAlongMountAxis,
};

/// What a signature's values are: the joint's link-angle offset, rad, the links' length scale
/// change (thermal expansion), dimensionless, the joint frame's tilt about one direction
/// across its axis (off_axis_compliance), rad, or the tool's shift along one of its mount's
/// axes (tool_mount_compliance), m.
enum class SignatureResponse { kLinkAngle, kLengthScale, kFrameTilt, kToolShift };

/// A found effect against its own variable on the fit rows: a partial-residual plot. At each row
/// the fitted effect, and the effect plus what the extended model leaves there along the
/// effect's direction (the weighted least-squares projection of the row's residual on the tip's
/// motion per unit of the effect). Points spread evenly about the curve say the effect's form
/// describes the data; structure left about it says it does not.
struct EffectSignature {
  Mechanism mechanism;
  int joint = -1;  ///< kLinkAngle: the joint whose link angle it moves (0-based)
  SignatureVariable variable = SignatureVariable::kJointAngle;
  int variable_joint = -1;  ///< kJointAngle, kJointTorque: the variable's joint (0-based)
  SignatureResponse response = SignatureResponse::kLinkAngle;
  /// kFrameTilt: the direction across the joint's axis, 0 u, 1 v (mechanism::tiltDirections);
  /// kToolShift: the mount's axis, 0 x, 1 y, 2 z
  int direction = -1;
  /// Per fit row kept: the variable, the fitted effect and the partial residual (SI).
  std::vector<double> x, effect, partial_residual;
  /// Fit rows left out: there the effect barely moves the tip (its direction's weighted norm
  /// below a quarter of the median), so the projection would be mostly noise.
  int rows_left_out = 0;
  /// The fitted effect along the variable over the rows' range (a profile sampled densely, so
  /// that it shows its fade outside the coverage; other effects at the rows, by x).
  std::vector<double> curve_x, curve_y;
};

/// Signatures of the extended model's mechanisms on the campaign's fit rows: a profile, backlash
/// or nonlinear stiffness, a coupling, and per joint the self weight identifies a compliance
/// for, thermal expansion. Sensor bias (six constants, no single variable) and profile geometry
/// (shown with its profile) have none.
std::vector<EffectSignature> effectSignatures(const Campaign& campaign, const Diagnosis& diagnosis,
                                              const DiagnoseOptions& options = {});

/// Diagnoses a campaign against a calibrated model (its chain, compliance and mechanisms are
/// the starting point; its GPR, if any, is the reference of the gain table). Link masses come
/// from the campaign's URDF <inertial> elements when it has them. A campaign merged from
/// several (mergeCampaigns) is one robot seen from several tracker stations: the model's tracker
/// and tool are the first campaign's, each later one has its own (session_frames, fitted with the
/// rest), and every row is weighed by the merged campaign's tracker noise (the largest stated).
/// Throws InputError when the campaign does not fit the model or has too few fit poses for the
/// folds.
Diagnosis diagnose(const Campaign& campaign, const CalibratedModel& model,
                   const DiagnoseOptions& options = {});

}  // namespace stepcal::trainer
