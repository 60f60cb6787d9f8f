#include "candidates.hpp"

#include <algorithm>
#include <numeric>
#include <cmath>
#include <iterator>
#include <utility>

#include "profiles.hpp"
#include "stepcal/common/mechanisms/backlash.hpp"
#include "stepcal/common/mechanisms/joint_zero_drift.hpp"
#include "stepcal/common/mechanisms/nonlinear_stiffness.hpp"
#include "stepcal/common/mechanisms/registration_drift.hpp"
#include "stepcal/common/mechanisms/thermal_expansion.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
// A candidate whose largest column moves the weighted residual by less than this, for a
// parameter step of typical size, has no effect on these rows and is not tried.
constexpr double kNegligibleEffect = 1e-3;
// Degrees of the registration drifts tried: a steady drift, a cubic like the trend test's, and
// one that bends more often over a long campaign.
constexpr int kDriftDegrees[] = {1, 3, 6};
// A joint's zero drift with temperature is tried where temp_c varies by more than a sensor's
// step (0.1 °C): the coefficient is free, so any spread the sensor resolves can show it.
constexpr double kMinZeroDriftSpreadC = 0.1;

Mechanism blank(MechanismKind kind, int dof, int joint = -1, int source = -1, int order = 0) {
  Mechanism m;
  m.kind = kind;
  m.joint = joint;
  m.source_joint = source;
  m.order = order;
  m.parameters.assign(mechanismParameterNames(kind, dof, order).size(), 0.0);
  m.sigma.assign(m.parameters.size(), 0.0);
  return m;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double stdOf(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  double sum = 0.0, sum2 = 0.0;
  for (double x : v) {
    sum += x;
    sum2 += x * x;
  }
  const double mean = sum / static_cast<double>(v.size());
  return std::sqrt(std::max(0.0, sum2 / static_cast<double>(v.size()) - mean * mean));
}

bool present(const PhysicalModel& model, MechanismKind kind, int joint, int source) {
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind != kind) continue;
    const bool one_per_model = kind == MechanismKind::kSelfWeight ||
                               kind == MechanismKind::kSensorBias ||
                               kind == MechanismKind::kThermalExpansion ||
                               kind == MechanismKind::kRegistrationDrift;
    if (one_per_model || (m.joint == joint && m.source_joint == source)) return true;
  }
  return false;
}

// A scaled column of the screening matrix (cross_validation.hpp, ColumnLayout): what multiplies
// its joint's link-angle column in each row.
struct ScaledSource {
  enum class Kind {
    kTorquePart,     // a unit part of a torque–deflection curve at the row's torque of the joint
    kJointAngle,     // another joint's angle (a coupling)
    kGravityTorque,  // the joint's gravity torque under the URDF's masses at the row's link angles
    kProfile,        // a profile's gated harmonics, 2·order columns
    kTemperature,    // the row's temperature less a reference (0 where it is not known)
    kCampaign,       // 1 on the rows of one campaign, 0 on the others
  };
  Kind kind = Kind::kTorquePart;
  Mechanism unit;            // kTorquePart
  int source_joint = -1;     // kJointAngle
  double reference_c = 0.0;  // kTemperature
  int campaign = 0;          // kCampaign; kProfile: ≥ 1, its columns on that campaign's rows only
  AngleCoverage coverage;    // kProfile
  int order = 0;             // kProfile
  Eigen::Index first = 0;    // its first column among the joint's scaled ones
  bool sameColumn(const ScaledSource& other) const {
    return kind == other.kind && kind != Kind::kProfile && source_joint == other.source_joint &&
           reference_c == other.reference_c && campaign == other.campaign &&
           unit.kind == other.unit.kind &&
           unit.parameters == other.unit.parameters;
  }
};

// A dense column of the screening matrix that is a geometry column times a polynomial of the
// row's time order: the tracker registration's columns moved in time (registration_drift). Made
// from the linearisation, no evaluation of its own.
struct TimeScaled {
  Eigen::Index dense = 0;     // its place among a chunk's dense columns
  Eigen::Index geometry = 0;  // the geometry column it scales
  int degree = 1;             // P_degree(s), s the row's time order mapped onto [−1, 1]
  double first_seq = 0.0, last_seq = 1.0;
};

// What a round's screening matrix is made from, chunk by chunk of fit rows: the model it is
// linearised at (its geometry and link-angle columns, its torques and link angles for the
// features), the models whose finite differences are its other dense columns, the geometry
// columns scaled by time, and each joint's scaled sources.
struct ColumnRecipe {
  PhysicalModel whole;
  std::vector<PhysicalModel> moved;  // per finite-difference column, the model moved by its step
  std::vector<double> step;
  std::vector<Eigen::Index> moved_dense;  // per finite-difference column, its dense place
  std::vector<TimeScaled> time_scaled;
  Eigen::Index dense = 0;  // dense columns of a chunk
  std::vector<std::vector<ScaledSource>> scaled;  // per joint
  std::vector<double> masses;                     // the URDF's, for kGravityTorque
};

// Fit rows [begin, end) of a screening matrix in its layout: the geometry's columns and the
// finite differences that `dense` marks (the others zero), the link-angle columns, and each
// scaled source per row. A row's values are those of evaluate, linearise and parameterColumn.
void makeColumns(const ColumnRecipe& recipe, const FitRows& fit, size_t begin, size_t end,
                 const std::vector<bool>& dense, ColumnChunk& chunk) {
  Evaluation e;
  Linearisation lin;
  evaluateAndLinearise(recipe.whole, fit, begin, end, e, lin);
  const Eigen::Index geometry = lin.geometry.cols();
  chunk.dense.resize(e.r.size(), recipe.dense);
  chunk.dense.leftCols(geometry) = lin.geometry;
  std::vector<const PhysicalModel*> moved;
  std::vector<bool> needed;
  for (size_t k = 0; k < recipe.moved.size(); ++k) {
    moved.push_back(&recipe.moved[k]);
    needed.push_back(dense[static_cast<size_t>(recipe.moved_dense[k])]);
  }
  const Eigen::MatrixXd differences =
      differenceColumns(moved, recipe.step, needed, fit, begin, end, e.r);
  for (size_t k = 0; k < moved.size(); ++k) {
    chunk.dense.col(recipe.moved_dense[k]) = differences.col(static_cast<Eigen::Index>(k));
  }
  const Eigen::Index first = equationOf(fit, begin);
  for (const TimeScaled& t : recipe.time_scaled) {
    for (size_t i = begin; i < end; ++i) {
      const double seq = static_cast<double>(fit.rows[i]->seq);
      const double s = 2.0 * (seq - t.first_seq) / (t.last_seq - t.first_seq) - 1.0;
      const Eigen::Index e_i = fit.start[i] - first, k = fit.equations(i);
      chunk.dense.block(e_i, t.dense, k, 1) =
          lin.geometry.block(e_i, t.geometry, k, 1) * legendrePolynomial(t.degree, s);
    }
  }
  chunk.link_angle = std::move(lin.link_angle);
  const KinematicChain& chain = recipe.whole.chain_Tracker;
  const Eigen::Index rows = static_cast<Eigen::Index>(end - begin);
  // The gravity torques once per row, if a source needs them.
  std::vector<JointVector> gravity;
  if (!recipe.masses.empty()) {
    ChainWorkspace ws;
    gravity.resize(end - begin);
    for (size_t i = 0; i < gravity.size(); ++i) {
      forwardKinematics(chain, e.theta_rad[i], ws);
      selfWeightTorques(chain, ws, recipe.whole.gravity_Tracker, recipe.masses, gravity[i]);
    }
  }
  chunk.scaled.resize(recipe.scaled.size());
  for (size_t j = 0; j < recipe.scaled.size(); ++j) {
    Eigen::Index width = 0;
    for (const ScaledSource& source : recipe.scaled[j]) {
      width = std::max(width, source.first + (source.kind == ScaledSource::Kind::kProfile
                                                  ? 2 * source.order
                                                  : 1));
    }
    Eigen::MatrixXd& out = chunk.scaled[j];
    out.resize(rows, width);
    Eigen::VectorXd harmonics;
    for (const ScaledSource& source : recipe.scaled[j]) {
      for (Eigen::Index r = 0; r < rows; ++r) {
        const size_t i = begin + static_cast<size_t>(r);
        const int joint = static_cast<int>(j);
        switch (source.kind) {
          case ScaledSource::Kind::kTorquePart:
            out(r, source.first) = torqueDeflection(source.unit, e.tau_nm[static_cast<size_t>(r)](joint));
            break;
          case ScaledSource::Kind::kJointAngle:
            out(r, source.first) = fit.rows[i]->q_rad(source.source_joint);
            break;
          case ScaledSource::Kind::kGravityTorque:
            out(r, source.first) = gravity[static_cast<size_t>(r)](joint);
            break;
          case ScaledSource::Kind::kTemperature:
            out(r, source.first) =
                fit.rows[i]->temp_c ? *fit.rows[i]->temp_c - source.reference_c : 0.0;
            break;
          case ScaledSource::Kind::kCampaign:
            out(r, source.first) = fit.rows[i]->session == source.campaign ? 1.0 : 0.0;
            break;
          case ScaledSource::Kind::kProfile:
            harmonics.resize(2 * source.order);
            profileFeatures(source.coverage, source.order, fit.rows[i]->q_rad(joint), harmonics.data());
            if (source.campaign > 0 && fit.rows[i]->session != source.campaign) harmonics.setZero();
            out.row(r).segment(source.first, 2 * source.order) = harmonics.transpose();
            break;
        }
      }
    }
  }
}

// Appends columns to a growing screening matrix: the geometry's, finite differences of a
// model, a repeat of a column, a joint's scaled features (one column per distinct feature) and
// profile blocks. Each column gets a ridge (0: none).
struct ColumnSink {
  ColumnSink(ColumnLayout& layout, ColumnRecipe& recipe, Eigen::Index geometry, int joints)
      : layout_(layout), recipe_(recipe) {
    layout_.dense = geometry;
    recipe_.dense = geometry;
    layout_.scaled.assign(static_cast<size_t>(joints), 0);
    recipe_.scaled.resize(static_cast<size_t>(joints));
  }
  std::vector<double> ridge;  // per column

  Eigen::Index geometry(Eigen::Index c) { return added({-1, c}, 0.0); }
  Eigen::Index difference(const PhysicalModel& model, const Parameter& p, double column_ridge) {
    PhysicalModel moved = model;
    shift(moved, p, p.step);
    recipe_.moved.push_back(std::move(moved));
    recipe_.step.push_back(p.step);
    recipe_.moved_dense.push_back(layout_.dense);
    recipe_.dense = layout_.dense + 1;
    return added({-1, layout_.dense++}, column_ridge);
  }
  // Geometry column c times P_degree of the time order (one column per distinct pair).
  Eigen::Index timeScaled(Eigen::Index c, int degree, double first_seq, double last_seq) {
    for (const TimeScaled& t : recipe_.time_scaled) {
      if (t.geometry == c && t.degree == degree) return added({-1, t.dense}, 0.0);
    }
    recipe_.time_scaled.push_back({layout_.dense, c, degree, first_seq, last_seq});
    recipe_.dense = layout_.dense + 1;
    return added({-1, layout_.dense++}, 0.0);
  }
  Eigen::Index repeat(Eigen::Index column, double column_ridge) {
    return added(layout_.place[static_cast<size_t>(column)], column_ridge);
  }
  Eigen::Index feature(int joint, ScaledSource source) {
    std::vector<ScaledSource>& sources = recipe_.scaled[static_cast<size_t>(joint)];
    for (const ScaledSource& other : sources) {
      if (other.sameColumn(source)) return added({joint, other.first}, 0.0);
    }
    source.first = layout_.scaled[static_cast<size_t>(joint)]++;
    sources.push_back(std::move(source));
    return added({joint, sources.back().first}, 0.0);
  }
  std::vector<Eigen::Index> profile(int joint, const AngleCoverage& coverage, int order,
                                    int campaign = 0) {
    ScaledSource source;
    source.kind = ScaledSource::Kind::kProfile;
    source.coverage = coverage;
    source.order = order;
    source.campaign = campaign;
    source.first = layout_.scaled[static_cast<size_t>(joint)];
    layout_.scaled[static_cast<size_t>(joint)] += 2 * order;
    recipe_.scaled[static_cast<size_t>(joint)].push_back(source);
    std::vector<Eigen::Index> columns;
    for (int k = 0; k < 2 * order; ++k) columns.push_back(added({joint, source.first + k}, 0.0));
    return columns;
  }

 private:
  Eigen::Index added(ColumnLayout::Place place, double column_ridge) {
    layout_.place.push_back(place);
    ridge.push_back(column_ridge);
    return layout_.size() - 1;
  }
  ColumnLayout& layout_;
  ColumnRecipe& recipe_;
};

}  // namespace

std::vector<int> gravityLoadedJoints(const PhysicalModel& global, const FitRows& fit,
                                     const std::vector<JointVector>& theta_rad,
                                     const std::vector<double>& masses,
                                     std::vector<double>* torque_std_nm) {
  const int n = global.chain_Tracker.dof();
  std::vector<std::vector<double>> tau(static_cast<size_t>(n));
  ChainWorkspace ws;
  JointVector t;
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    forwardKinematics(global.chain_Tracker, theta_rad[i], ws);
    selfWeightTorques(global.chain_Tracker, ws, global.gravity_Tracker, masses, t);
    for (int j = 0; j < n; ++j) tau[static_cast<size_t>(j)].push_back(t(j));
  }
  std::vector<double> spread;
  for (const auto& v : tau) spread.push_back(stdOf(v));
  const double largest = *std::max_element(spread.begin(), spread.end());
  std::vector<int> joints;
  for (int j = 0; j < n; ++j) {
    const double s = spread[static_cast<size_t>(j)];
    if (s >= 1.0 && s >= 0.1 * largest) joints.push_back(j);
  }
  if (torque_std_nm) *torque_std_nm = spread;
  return joints;
}

Screening screening(const DiagnosisModel& model, const FitRows& fit, const Evaluation& start,
                    const DiagnoseOptions& options,
                    const std::optional<std::vector<double>>& body_masses,
                    const ScreeningScope& scope) {
  const Mechanism* only = scope.only;
  const PhysicalModel& global = model.global;
  // Columns are changes of the whole model (its global mechanisms come first in it, so a
  // parameter indexes both alike); what is present is asked of the global part.
  const PhysicalModel whole = model.combined();
  const int n = global.chain_Tracker.dof();
  Screening s;
  const Eigen::Index geometry = 6 * (n + 1);
  auto recipe = std::make_shared<ColumnRecipe>();
  recipe->whole = whole;
  ColumnSink sink(s.columns.layout, *recipe, geometry, n);

  // Stage 1: geometry, then the global model's fitted parameters (their values kept for the
  // lumped masses' prior).
  for (Eigen::Index c = 0; c < geometry; ++c) {
    s.stage1.push_back(sink.geometry(c));
  }
  std::vector<double> stage1_values;
  for (const Parameter& p : globalParameters(model)) {
    const bool lumped_mass =
        p.mechanism >= 0 &&
        global.mechanisms[static_cast<size_t>(p.mechanism)].kind == MechanismKind::kSelfWeight;
    s.stage1.push_back(sink.difference(
        whole, p, lumped_mass ? 1.0 / (kSelfWeightPriorSigma * kSelfWeightPriorSigma) : 0.0));
    stage1_values.push_back(
        p.mechanism < 0
            ? global.compliance_rad_per_nm(p.index)
            : global.mechanisms[static_cast<size_t>(p.mechanism)].parameter(p.index));
  }
  // Stage 2: the geometry's change that goes with the profiles (every fit row lies inside every
  // profile's gate, so its columns are the geometry's; their ridges come with the Grams,
  // completeScreening), then the current profiles.
  for (Eigen::Index c = 0; c < geometry; ++c) s.stage2.push_back(sink.repeat(c, 0.0));
  const int max_order = *std::max_element(options.profile_orders.begin(), options.profile_orders.end());
  for (const Profile& p : model.profiles) {
    Family f;
    f.stage = Stage::kProfile;
    f.mechanism = blank(MechanismKind::kTransmissionError, n, p.mechanism.joint, -1,
                        std::max(max_order, p.mechanism.order));
    f.mechanism.coverage = p.mechanism.coverage;
    f.columns = sink.profile(f.mechanism.joint, f.mechanism.coverage, f.mechanism.order);
    s.profiled.push_back(std::move(f));
  }

  auto wanted = [&](MechanismKind kind, int joint = -1, int source = -1) {
    return scope.families &&
           (only == nullptr ||
            (only->kind == kind && only->joint == joint && only->source_joint == source));
  };
  // A global family with its columns and their typical parameter steps: whether it moves the tip
  // at these rows is judged once its columns' norms are known (completeScreening).
  auto addGlobal = [&](Family family, std::vector<Eigen::Index> columns,
                       std::vector<double> steps, double column_ridge = 0.0) {
    for (Eigen::Index c : columns) sink.ridge[static_cast<size_t>(c)] = column_ridge;
    family.columns = std::move(columns);
    family.steps = std::move(steps);
    family.untestable_before = s.untestable.size();
    s.families.push_back(std::move(family));
  };

  // Torque-driven mechanisms need load torque on the joint; their torque scales come from the
  // loads the joint sees. Lost motion is taken up at a tenth of the typical load (far above the
  // sensor's noise, far below the loads); a nonlinear stiffness fades at, and a torsion curve's
  // knee sits at, a torque of a grid (the deflection is linear in the compliance for a given
  // torque; far below the loads either is lost motion, far above them linear compliance). A
  // joint has one torque–deflection curve: without one yet, backlash alone, nonlinear stiffness
  // alone and torsion curves (lost motion or not, one or two knees) compete; a backlash or a
  // torsion curve found is extended by the part it lacks (lost motion, a knee at another torque),
  // and a nonlinear stiffness by a backlash beside it.
  constexpr double kTorqueFactors[] = {0.1, 0.25, 0.5, 1.0, 2.0};
  const auto wantedTorque = [&](int joint) {
    return scope.families &&
           (only == nullptr || (isTorqueDeflection(only->kind) && only->joint == joint));
  };
  for (int j = 0; j < n; ++j) {
    std::vector<double> loaded;
    double largest = 0.0;  // a curve's τ_lin: above it no row shows the curve
    for (const JointVector& tau : start.tau_nm) {
      if (std::abs(tau(j)) > 1.0) loaded.push_back(std::abs(tau(j)));
      largest = std::max(largest, std::abs(tau(j)));
    }
    const double typical = median(loaded);
    if (loaded.size() < 10 || typical < 10.0) {
      for (const char* name : {"backlash", "nonlinear_stiffness", "torsion_curve"}) {
        s.untestable.push_back({std::string(name) + " (joint " + std::to_string(j + 1) + ")",
                                "the joint carries too little load torque on these rows"});
      }
      continue;
    }
    if (!wantedTorque(j)) continue;
    const double smoothing = 0.1 * typical;
    // The link-angle column of one part of a curve at unit size (torqueDeflection's shapes).
    const auto partColumn = [&](MechanismKind kind, double scale_nm) {
      Mechanism unit = blank(kind, n, j, -1, kind == MechanismKind::kTorsionCurve ? 1 : 0);
      if (kind == MechanismKind::kBacklash) {
        view<mechanism::Backlash>(unit).lostMotion_rad() = 1.0;
        view<mechanism::Backlash>(unit).smoothingTorque_nm() = scale_nm;
      } else if (kind == MechanismKind::kNonlinearStiffness) {
        view<mechanism::NonlinearStiffness>(unit).extraCompliance_rad_per_nm() = 1.0;
        view<mechanism::NonlinearStiffness>(unit).saturationTorque_nm() = scale_nm;
      } else {  // a knee alone: c = 1 at T = scale
        view<mechanism::TorsionCurve>(unit).extraCompliance_rad_per_nm(1) = 1.0;
        view<mechanism::TorsionCurve>(unit).kneeTorque_nm(1) = scale_nm;
      }
      ScaledSource source;
      source.unit = std::move(unit);
      return sink.feature(j, std::move(source));
    };
    const auto lostColumn = [&] { return partColumn(MechanismKind::kBacklash, smoothing); };
    const auto kneeColumn = [&](double knee) { return partColumn(MechanismKind::kTorsionCurve, knee); };
    // A curve of lost motion (b, smoothing; 0: none) and knees (compliance, torque).
    const auto curve = [&](double b, double lost_smoothing,
                           const std::vector<std::pair<double, double>>& knees) {
      Mechanism m = blank(MechanismKind::kTorsionCurve, n, j, -1, static_cast<int>(knees.size()));
      const mechanism::TorsionCurve<double> c = view<mechanism::TorsionCurve>(m);
      c.lostMotion_rad() = b;
      c.smoothingTorque_nm() = lost_smoothing;
      for (int term = 1; term <= m.order; ++term) {
        c.extraCompliance_rad_per_nm(term) = knees[static_cast<size_t>(term - 1)].first;
        c.kneeTorque_nm(term) = knees[static_cast<size_t>(term - 1)].second;
      }
      c.linearAbove_nm() = largest;
      return m;
    };
    int existing = -1, count = 0;
    for (size_t k = 0; k < global.mechanisms.size(); ++k) {
      const Mechanism& m = global.mechanisms[k];
      if (!isTorqueDeflection(m.kind) || m.joint != j) continue;
      if (existing < 0 || m.kind == MechanismKind::kNonlinearStiffness) existing = static_cast<int>(k);
      ++count;
    }
    if (count > 1) continue;  // a nonlinear stiffness and a backlash beside it: the whole curve
    const auto addBacklash = [&] {
      Family f;
      f.mechanism = blank(MechanismKind::kBacklash, n, j);
      view<mechanism::Backlash>(f.mechanism).smoothingTorque_nm() = smoothing;
      f.free = {mechanism::Backlash<double>::kLostMotion};
      addGlobal(std::move(f), {lostColumn()}, {typicalStep(blank(MechanismKind::kBacklash, n, j), 0)});
    };
    if (existing < 0) {
      addBacklash();
      for (double factor : kTorqueFactors) {
        Family f;
        f.mechanism = blank(MechanismKind::kNonlinearStiffness, n, j);
        const double t0 = factor * typical;
        view<mechanism::NonlinearStiffness>(f.mechanism).saturationTorque_nm() = t0;
        view<mechanism::NonlinearStiffness>(f.mechanism).linearAbove_nm() = largest;
        f.free = {mechanism::NonlinearStiffness<double>::kExtraCompliance};
        f.chosen = 1;
        addGlobal(std::move(f), {partColumn(MechanismKind::kNonlinearStiffness, t0)}, {1e-4 / t0});
      }
      for (const bool with_lost : {true, false}) {
        for (size_t a = 0; a < std::size(kTorqueFactors); ++a) {
          for (size_t b = a; b < std::size(kTorqueFactors); ++b) {
            std::vector<std::pair<double, double>> knees = {{0.0, kTorqueFactors[a] * typical}};
            if (b > a) knees.push_back({0.0, kTorqueFactors[b] * typical});
            if (!with_lost && knees.size() == 1) continue;  // a single knee: nonlinear stiffness's part
            Family f;
            f.mechanism = curve(0.0, with_lost ? smoothing : 0.0, knees);
            f.free = signConstrained(f.mechanism);
            f.chosen = static_cast<int>(knees.size());
            std::vector<Eigen::Index> columns;
            std::vector<double> steps;
            if (with_lost) {
              columns.push_back(lostColumn());
              steps.push_back(1e-4);
            }
            for (const auto& knee : knees) {
              columns.push_back(kneeColumn(knee.second));
              steps.push_back(1e-4 / knee.second);
            }
            addGlobal(std::move(f), std::move(columns), std::move(steps));
          }
        }
      }
      continue;
    }
    const Mechanism& m = global.mechanisms[static_cast<size_t>(existing)];
    if (m.kind == MechanismKind::kNonlinearStiffness) {
      addBacklash();  // its fade is no knee: lost motion joins it as a backlash of its own
      continue;
    }
    // A backlash or a torsion curve, extended by one part at a time.
    const mechanism::TorsionCurve<const double> c = view<mechanism::TorsionCurve>(m);
    const bool lost = c.smoothingTorque_nm() > 0.0;
    std::vector<std::pair<double, double>> knees;
    for (int term = 1; term <= m.order; ++term) {
      knees.push_back({c.extraCompliance_rad_per_nm(term), c.kneeTorque_nm(term)});
    }
    if (!lost) {
      Family f;
      f.mechanism = curve(0.0, smoothing, knees);
      f.free = {mechanism::TorsionCurve<double>::kLostMotion};
      f.extends = existing;
      addGlobal(std::move(f), {lostColumn()}, {1e-4});
    }
    if (static_cast<int>(knees.size()) >= kMaxTorsionTerms) continue;
    for (double factor : kTorqueFactors) {
      const double knee = factor * typical;
      // A knee within a factor 1.5 of one the curve has is that knee again.
      bool near = false;
      for (const auto& k : knees) near = near || (knee < 1.5 * k.second && k.second < 1.5 * knee);
      if (near) continue;
      std::vector<std::pair<double, double>> more = knees;
      more.push_back({0.0, knee});
      std::sort(more.begin(), more.end(),
                [](const auto& x, const auto& y) { return x.second < y.second; });
      const auto at = std::find_if(more.begin(), more.end(), [&](const auto& x) { return x.second == knee; });
      Family f;
      f.mechanism = curve(c.lostMotion_rad(), c.smoothingTorque_nm(), more);
      f.free = {mechanism::TorsionCurve<double>::complianceIndex(1 + static_cast<int>(at - more.begin()))};
      f.chosen = 1;
      f.extends = existing;
      addGlobal(std::move(f), {kneeColumn(knee)}, {1e-4 / knee});
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (i == j || present(global, MechanismKind::kJointCoupling, j, i) ||
          !wanted(MechanismKind::kJointCoupling, j, i)) {
        continue;
      }
      Family f;
      f.mechanism = blank(MechanismKind::kJointCoupling, n, j, i);
      f.free = {0};
      ScaledSource source;
      source.kind = ScaledSource::Kind::kJointAngle;
      source.source_joint = i;
      addGlobal(std::move(f), {sink.feature(j, std::move(source))}, {1e-4});
    }
  }

  // Self weight: with the URDF's masses, the compliance of every joint their gravity loads
  // enough is identified from the arm's own weight alone (no payload needed); without them, the
  // lumped masses act through a compliance the loads identified.
  const bool compliant = global.compliance_rad_per_nm.size() == n &&
                         global.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (present(global, MechanismKind::kSelfWeight, -1, -1) || !wanted(MechanismKind::kSelfWeight)) {
  } else if (global.gravity_Tracker.norm() == 0.0) {
    s.untestable.push_back({"self_weight", "gravity is unknown (campaign.yaml gravity_in_base)"});
  } else if (body_masses) {
    Family f;
    f.mechanism = blank(MechanismKind::kSelfWeight, n);
    f.mechanism.parameters = *body_masses;
    f.compliance = gravityLoadedJoints(global, fit, start.theta_rad, *body_masses);
    recipe->masses = *body_masses;
    std::vector<Eigen::Index> columns;
    std::vector<double> steps;
    for (const int joint : f.compliance) {
      ScaledSource source;
      source.kind = ScaledSource::Kind::kGravityTorque;
      columns.push_back(sink.feature(joint, std::move(source)));
      steps.push_back(1e-6);  // rad/(N·m): a soft joint
    }
    if (columns.empty()) {
      s.untestable.push_back({"self_weight", "no joint's gravity torque varies over these rows"});
    } else {
      addGlobal(std::move(f), std::move(columns), std::move(steps));
    }
  } else if (!compliant) {
    s.untestable.push_back({"self_weight",
                            "no link masses in the URDF, and no joint compliance from loads to "
                            "act on lumped ones"});
  } else {
    Family f;
    f.mechanism = blank(MechanismKind::kSelfWeight, n);
    PhysicalModel with = whole;
    with.mechanisms.push_back(f.mechanism);
    const int index = static_cast<int>(with.mechanisms.size()) - 1;
    std::vector<Eigen::Index> columns;
    std::vector<double> steps;
    for (int i : freeParameters(f.mechanism, false)) {
      f.free.push_back(i);
      const Parameter p{index, i, typicalStep(f.mechanism, i)};
      columns.push_back(sink.difference(with, p, 0.0));
      steps.push_back(p.step);
    }
    addGlobal(std::move(f), std::move(columns), std::move(steps),
              1.0 / (kSelfWeightPriorSigma * kSelfWeightPriorSigma));
  }
  if (present(global, MechanismKind::kSensorBias, -1, -1) || !wanted(MechanismKind::kSensorBias)) {
  } else if (global.sensor_frame < 0 || !compliant) {
    s.untestable.push_back({"sensor_bias", "the model has no F/T sensor or no compliance"});
  } else {
    Family f;
    f.mechanism = blank(MechanismKind::kSensorBias, n);
    PhysicalModel with = whole;
    with.mechanisms.push_back(f.mechanism);
    const int index = static_cast<int>(with.mechanisms.size()) - 1;
    std::vector<Eigen::Index> columns;
    std::vector<double> steps;
    for (int i = 0; i < 6; ++i) {
      f.free.push_back(i);
      const Parameter p{index, i, typicalStep(f.mechanism, i)};
      columns.push_back(sink.difference(with, p, 0.0));
      steps.push_back(p.step);
    }
    addGlobal(std::move(f), std::move(columns), std::move(steps));
  }
  // The rows' temperatures: the thermal families' reference (their mean) and whether they vary.
  std::vector<double> temps;
  for (const Measurement* row : fit.rows) {
    if (row->temp_c) temps.push_back(*row->temp_c);
  }
  double mean_temp = 0.0;
  for (double t : temps) mean_temp += t;
  mean_temp = temps.empty() ? 0.0 : mean_temp / static_cast<double>(temps.size());
  const double temp_spread = stdOf(temps);
  const bool few_temps = temps.size() * 2 < fit.rows.size();
  if (!present(global, MechanismKind::kThermalExpansion, -1, -1) &&
      wanted(MechanismKind::kThermalExpansion)) {
    if (few_temps) {
      s.untestable.push_back({"thermal_expansion", "fewer than half the fit rows have temp_c"});
    } else if (temp_spread < 0.5) {
      char reason[120];
      std::snprintf(reason, sizeof reason,
                    "temp_c varies by less than 0.5 °C (standard deviation %.2f °C)", temp_spread);
      s.untestable.push_back({"thermal_expansion", reason});
    } else {
      Family f;
      f.mechanism = blank(MechanismKind::kThermalExpansion, n);
      view<mechanism::ThermalExpansion>(f.mechanism).referenceTemp_c() = mean_temp;
      f.free = {mechanism::ThermalExpansion<double>::kExpansion};
      PhysicalModel with = whole;
      with.mechanisms.push_back(f.mechanism);
      const Parameter p{static_cast<int>(with.mechanisms.size()) - 1, 0, 1e-5};
      addGlobal(std::move(f), {sink.difference(with, p, 0.0)}, {p.step});
    }
  }

  // What drifts while a campaign is measured. The tracker's registration in time order (a
  // tripod settling, the floor warming: 6 DOF, a polynomial of the time order per degree tried),
  // and each joint's zero with temperature (a motor's or gearbox's heat). The first is the
  // measurement's, the second the robot's: told apart by how they move the tip (the whole frame,
  // one joint), not by when.
  if (!present(global, MechanismKind::kRegistrationDrift, -1, -1) &&
      wanted(MechanismKind::kRegistrationDrift)) {
    double first_seq = 0.0, last_seq = 0.0;
    for (size_t i = 0; i < fit.rows.size(); ++i) {
      const double seq = static_cast<double>(fit.rows[i]->seq);
      first_seq = i == 0 ? seq : std::min(first_seq, seq);
      last_seq = i == 0 ? seq : std::max(last_seq, seq);
    }
    const bool several_campaigns = std::any_of(fit.rows.begin(), fit.rows.end(),
                                               [](const Measurement* row) { return row->session > 0; });
    // A campaign's seq is unique (the reader refuses repeats); one built in memory may not be.
    if (several_campaigns) {
      s.untestable.push_back({"registration_drift",
                              "the fit rows are several campaigns, each with its own tracker "
                              "station; a drift within one of them is not modelled"});
    } else if (!(last_seq > first_seq)) {
      s.untestable.push_back({"registration_drift", "every fit row has the same seq"});
    } else {
      for (const int degree : kDriftDegrees) {
        Family f;
        f.mechanism = blank(MechanismKind::kRegistrationDrift, n, -1, -1, degree);
        view<mechanism::RegistrationDrift>(f.mechanism).firstSeq() = first_seq;
        view<mechanism::RegistrationDrift>(f.mechanism).lastSeq() = last_seq;
        std::vector<Eigen::Index> columns;
        for (int d = 1; d <= degree; ++d) {
          for (Eigen::Index c = 0; c < 6; ++c) {
            f.free.push_back(2 + 6 * (d - 1) + static_cast<int>(c));
            columns.push_back(sink.timeScaled(c, d, first_seq, last_seq));
          }
        }
        std::vector<double> steps(columns.size(), typicalStep(f.mechanism, 2));
        addGlobal(std::move(f), std::move(columns), std::move(steps));
      }
    }
  }
  for (int j = 0; j < n; ++j) {
    if (present(global, MechanismKind::kJointZeroDrift, j, -1) ||
        !wanted(MechanismKind::kJointZeroDrift, j)) {
      continue;
    }
    const std::string name = "joint_zero_drift (joint " + std::to_string(j + 1) + ")";
    if (few_temps) {
      s.untestable.push_back({name, "fewer than half the fit rows have temp_c"});
      continue;
    }
    if (temp_spread < kMinZeroDriftSpreadC) {
      char reason[120];
      std::snprintf(reason, sizeof reason,
                    "temp_c varies by less than %.2f °C (standard deviation %.3f °C)",
                    kMinZeroDriftSpreadC, temp_spread);
      s.untestable.push_back({name, reason});
      continue;
    }
    Family f;
    f.mechanism = blank(MechanismKind::kJointZeroDrift, n, j);
    view<mechanism::JointZeroDrift>(f.mechanism).referenceTemp_c() = mean_temp;
    f.free = {mechanism::JointZeroDrift<double>::kDriftRate};
    ScaledSource source;
    source.kind = ScaledSource::Kind::kTemperature;
    source.reference_c = mean_temp;
    // A step that moves the joint by ~1e-4 rad over the rows' spread of temperature.
    addGlobal(std::move(f), {sink.feature(j, std::move(source))}, {1e-4 / temp_spread});
  }

  // Several campaigns: each joint's zero in each later campaign against the first's (a joint
  // re-mastered between them), one column per later campaign.
  const int campaigns = 1 + std::accumulate(fit.rows.begin(), fit.rows.end(), 0,
                                            [](int most, const Measurement* row) {
                                              return std::max(most, row->session);
                                            });
  for (int j = 0; j < n && campaigns > 1; ++j) {
    if (present(global, MechanismKind::kCampaignJointZero, j, -1) ||
        !wanted(MechanismKind::kCampaignJointZero, j)) {
      continue;
    }
    Family f;
    f.mechanism = blank(MechanismKind::kCampaignJointZero, n, j, -1, campaigns - 1);
    std::vector<Eigen::Index> columns;
    for (int k = 1; k < campaigns; ++k) {
      f.free.push_back(k - 1);
      ScaledSource source;
      source.kind = ScaledSource::Kind::kCampaign;
      source.campaign = k;
      columns.push_back(sink.feature(j, std::move(source)));
    }
    std::vector<double> steps(columns.size(), typicalStep(f.mechanism, 0));
    addGlobal(std::move(f), std::move(columns), std::move(steps));
  }

  // Each current profile's difference in one later campaign: whether one profile serves them.
  for (const Profile& p : model.profiles) {
    if (scope.campaign_profiles < 1) break;
    Family f;
    f.stage = Stage::kProfile;
    f.campaign = scope.campaign_profiles;
    f.mechanism = blank(MechanismKind::kTransmissionError, n, p.mechanism.joint, -1, p.mechanism.order);
    f.mechanism.coverage = p.mechanism.coverage;
    f.columns = sink.profile(f.mechanism.joint, f.mechanism.coverage, f.mechanism.order, f.campaign);
    s.families.push_back(std::move(f));
  }

  // One profile per joint not yet profiled, at the highest order (lower orders are its leading
  // columns), over the angles the fit rows cover.
  for (int j = 0; j < n && scope.families && only == nullptr; ++j) {
    bool profiled = false;
    for (const Profile& p : model.profiles) profiled = profiled || p.mechanism.joint == j;
    if (profiled) continue;
    std::vector<double> angles;
    for (const Measurement* row : fit.rows) angles.push_back(row->q_rad(j));
    Family f;
    f.stage = Stage::kProfile;
    f.mechanism = blank(MechanismKind::kTransmissionError, n, j, -1, max_order);
    f.mechanism.coverage = coverageOfAngles(angles, options.coverage_gap_deg * kDegToRad,
                                            options.coverage_fade_deg * kDegToRad);
    f.columns = sink.profile(j, f.mechanism.coverage, max_order);
    s.families.push_back(std::move(f));
  }

  const Eigen::Index total = s.columns.layout.size();
  s.columns.make = [recipe = std::shared_ptr<const ColumnRecipe>(std::move(recipe)), &fit](
                       size_t begin, size_t end, const std::vector<bool>& dense,
                       ColumnChunk& chunk) {
    makeColumns(*recipe, fit, begin, end, dense, chunk);
  };
  s.ridge = Eigen::Map<const Eigen::VectorXd>(sink.ridge.data(), total);
  s.current = Eigen::VectorXd::Zero(total);
  for (size_t k = 0; k < stage1_values.size(); ++k) {
    s.current(s.stage1[static_cast<size_t>(geometry) + k]) = stage1_values[k];
  }
  setStage2(s, model, geometry);
  return s;
}

void completeScreening(Screening& s, const FoldGrams& grams, Eigen::Index geometry) {
  const Eigen::MatrixXd& G = grams.G.back();
  for (Eigen::Index c = 0; c < geometry; ++c) {
    const Eigen::Index column = s.stage2[static_cast<size_t>(c)];
    s.ridge(column) = kProfileGeometryRidge * std::max(G(column, column), 1e-300);
  }
  // The global families that move the tip at these rows, and in their places among the reasons
  // for what was not tried, those that do not.
  std::vector<Family> kept;
  std::vector<UntestableCandidate> untestable;
  size_t next = 0;
  for (Family& family : s.families) {
    if (family.stage == Stage::kGlobal) {
      while (next < family.untestable_before) untestable.push_back(std::move(s.untestable[next++]));
      double effect = 0.0;
      for (size_t c = 0; c < family.columns.size(); ++c) {
        effect = std::max(effect, std::sqrt(G(family.columns[c], family.columns[c])) * family.steps[c]);
      }
      if (effect < kNegligibleEffect) {
        untestable.push_back({describe(family.mechanism), "no effect on the tip at these rows"});
        continue;
      }
    }
    kept.push_back(std::move(family));
  }
  while (next < s.untestable.size()) untestable.push_back(std::move(s.untestable[next++]));
  s.families = std::move(kept);
  s.untestable = std::move(untestable);
}

void setStage2(Screening& s, const DiagnosisModel& model, Eigen::Index geometry) {
  s.stage2.resize(static_cast<size_t>(geometry));
  Eigen::VectorXd share = Eigen::VectorXd::Zero(geometry);
  for (const Profile& p : model.profiles) {
    if (p.geometry.size() == geometry) share += p.geometry;
  }
  for (Eigen::Index c = 0; c < geometry; ++c) s.current(s.stage2[static_cast<size_t>(c)]) = share(c);
  for (size_t i = 0; i < model.profiles.size(); ++i) {
    const Profile& p = model.profiles[i];
    const Family& family = s.profiled[i];
    for (size_t c = 0; c < family.columns.size(); ++c) {
      const Eigen::Index column = family.columns[c];
      const bool fitted = c < static_cast<size_t>(2 * p.mechanism.order);
      s.current(column) = fitted ? p.mechanism.parameter(static_cast<int>(c)) : 0.0;
      if (!fitted) continue;
      s.stage2.push_back(column);
      s.ridge(column) = p.ridge;
    }
  }
}

}  // namespace stepcal::trainer::diagnosis
