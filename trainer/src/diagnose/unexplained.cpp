// The verdict's "unexplained" part (unexplained.hpp).
//
// Columns of a variable v at a fit row, in the residual's weighting (P_d: Legendre polynomials of
// v over its range on the fit rows, d = 1..3):
// - in the tracker's axes: P_d(v) on each of the row's equations alone (a cubic per component,
//   the residual trend of residual_statistics.hpp): what a drift of the measurement follows;
// - through the arm, where v belongs to a joint: joint j's link-angle column times P_d(v) (its
//   angle, its torque), or the tip's motion per tilt of joint j's frame about each of its axes
//   (a moment of the payload's wrench in that frame) or per shift along each (a force) times
//   P_d(v): what a property of the arm follows, the tip moving as the arm carries it;
// - a torque modulated by harmonic h of its joint's angle: the link-angle column times
//   τ_j cos h q_j and τ_j sin h q_j alone (a compliance that varies with the angle), h = 1..12.
// A joint's frame is joint j's before its motion, T_{0,j−1}(θ) · T_{j−1,j}(0): its tilt is the
// geometry's rotation columns of initial pose j−1 (Linearisation::geometry), so that several
// campaigns' stations and the registration drift are the linearisation's.
#include "unexplained.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include <Eigen/Cholesky>

#include "chunked_gram.hpp"
#include "stepcal/common/compliance.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/accuracy.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr int kDegree = 3;     // Legendre P1..P3 of a variable
// Harmonics of a joint's angle that may modulate its torque (a gear's mesh stiffness varies
// at the teeth's and the bearings' frequencies over a revolution): each one a variable, and the
// learner's features up to this one.
constexpr int kHarmonics = 12;
constexpr int kMaxEquations = 6;
// The learner's ridges, relative to the mean diagonal of its training Gram.
constexpr std::array<double, 3> kLearnerRidges = {1e-6, 1e-4, 1e-2};
constexpr std::array<char, 3> kAxes = {'x', 'y', 'z'};

// Per fit row, the scalar variables, in this order.
struct Layout {
  int n = 0;
  int q(int j) const { return j; }
  int tau(int j) const { return n + j; }
  int load() const { return 2 * n; }
  int temp() const { return 2 * n + 1; }
  int seq() const { return 2 * n + 2; }
  /// Component c of the payload's wrench in joint j's frame: fx, fy, fz (N), mx, my, mz (N·m).
  int wrench(int j, int c) const { return 2 * n + 3 + 6 * j + c; }
  /// Joint j's gravity torque of the arm's own links (N·m; NaN: no masses known).
  int weight(int j) const { return 8 * n + 3 + j; }
  int size() const { return 9 * n + 3; }
  /// The links' masses and first moments (a self_weight's parameters): the model's self weight
  /// where it has one, else the URDF's; null: neither.
  const std::vector<double>* link_masses = nullptr;
};

using RowValues = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 9 * kMaxJoints + 3, 1>;

// The row's variables: its recorded angles (deg), the model's torques, its load, temperature and
// time order, the payload's measured wrench in each joint's frame before its motion, and each
// joint's torque from the links' own weight, at the model's link angles.
RowValues rowValues(const PhysicalModel& model, const Measurement& row, const JointVector& theta,
                    const JointVector& tau, const Layout& at, ChainWorkspace& ws) {
  RowValues v = RowValues::Zero(at.size());
  const KinematicChain& chain = model.chain_Tracker;
  for (int j = 0; j < at.n; ++j) {
    v(at.q(j)) = kDegPerRad * row.q_rad(j);
    v(at.tau(j)) = tau(j);
    v(at.weight(j)) = std::numeric_limits<double>::quiet_NaN();
  }
  v(at.load()) = row.load_kg;
  v(at.temp()) = rowTemperature(row);
  v(at.seq()) = static_cast<double>(row.seq);
  const bool weight = at.link_masses != nullptr && model.gravity_Tracker.squaredNorm() > 0.0;
  const bool wrench = model.sensor_frame >= 0 && row.has_wrench;
  if (!weight && !wrench) return v;
  forwardKinematics(chain, theta, ws);
  if (weight) {
    JointVector weight_nm;
    selfWeightTorques(chain, ws, model.gravity_Tracker, *at.link_masses, weight_nm);
    for (int j = 0; j < at.n; ++j) v(at.weight(j)) = weight_nm(j);
  }
  if (!wrench) return v;
  const Vec6 W = wrenchInRoot(framePose(chain, ws, model.sensor_frame), row.wrench_Sensor);
  for (int j = 0; j < at.n; ++j) {
    const Pose X_RootJoint = ws.X_RootFrame[static_cast<size_t>(j)] * chain.initialPose(j);
    const Mat3 R = X_RootJoint.linear();
    const Vec3 f = W.head<3>(), m = W.tail<3>() - X_RootJoint.translation().cross(f);
    v.segment<3>(at.wrench(j, 0)) = R.transpose() * f;
    v.segment<3>(at.wrench(j, 3)) = R.transpose() * m;
  }
  return v;
}

// How a variable reaches the residual besides (or, kModulatedTorque, instead of) a cubic in the
// tracker's axes.
enum class Reach {
  kTrackerOnly,
  kLinkAngle,
  kFrameTilt,
  kFrameShift,
  kModulatedTorque,
  /// the frame tilted about each axis perpendicular to the joint's by a cubic in the payload's
  /// moment about that axis, alone (a bearing's tilt); value: the first such axis' moment
  kPerpendicularTilt,
};

struct Spec {
  UnexplainedVariable variable;
  int value = 0;  ///< its index in Layout (kModulatedTorque: the torque's)
  Reach reach = Reach::kTrackerOnly;
  int harmonic = 0;  ///< kModulatedTorque: of the joint's angle
  std::array<int, 2> perpendicular_axes = {0, 0};  ///< kPerpendicularTilt: of the joint's frame
  int width() const {
    switch (reach) {
      case Reach::kTrackerOnly: return kMaxEquations * kDegree;
      case Reach::kLinkAngle: return (kMaxEquations + 1) * kDegree;
      case Reach::kFrameTilt:
      case Reach::kFrameShift: return (kMaxEquations + 3) * kDegree;
      case Reach::kModulatedTorque: return 2;
      case Reach::kPerpendicularTilt: return 2 * kDegree;
    }
    return 0;
  }
};

std::string jointText(int j) { return "joint " + std::to_string(j + 1); }

// Every variable the residual is judged against.
std::vector<Spec> variableSpecs(const KinematicChain& chain, const Layout& at) {
  std::vector<Spec> specs;
  auto add = [&](std::string name, std::string description, int value, Reach reach, int joint) {
    Spec s;
    s.variable.name = std::move(name);
    s.variable.description = std::move(description);
    s.variable.joint = joint;
    s.value = value;
    s.reach = reach;
    specs.push_back(std::move(s));
  };
  const int n = at.n;
  for (int j = 0; j < n; ++j) {
    const std::string J = std::to_string(j + 1);
    add("q" + J + "_deg", jointText(j) + "'s angle", at.q(j), Reach::kLinkAngle, j);
    add("tau" + J + "_nm", jointText(j) + "'s torque", at.tau(j), Reach::kLinkAngle, j);
    add("weight" + J + "_nm", jointText(j) + "'s torque from the arm's own weight", at.weight(j),
        Reach::kLinkAngle, j);
  }
  for (int j = 0; j < n; ++j) {
    const std::string J = std::to_string(j + 1);
    for (int h = 1; h <= kHarmonics; ++h) {
      add("tau" + J + "_nm*h" + std::to_string(h) + "(q" + J + ")",
          jointText(j) + "'s torque modulated by harmonic " + std::to_string(h) + " of its angle",
          at.tau(j), Reach::kModulatedTorque, j);
      specs.back().harmonic = h;
    }
  }
  add("load_kg", "the payload's mass", at.load(), Reach::kTrackerOnly, -1);
  add("temp_c", "the temperature", at.temp(), Reach::kTrackerOnly, -1);
  add("seq", "the time order", at.seq(), Reach::kTrackerOnly, -1);
  for (int j = 0; j < n; ++j) {
    const Vec3 axis = chain.joints()[static_cast<size_t>(j)].twist_Local.tail<3>();
    for (int c = 0; c < 3; ++c) {
      const std::string a(1, kAxes[static_cast<size_t>(c)]);
      const bool perpendicular = std::abs(axis(c)) < 0.5;
      add("joint" + std::to_string(j + 1) + "_f" + a + "_n",
          "the payload's force along " + jointText(j) + "'s " + a + " axis", at.wrench(j, c),
          Reach::kFrameShift, j);
      add("joint" + std::to_string(j + 1) + "_m" + a + "_nm",
          "the payload's moment about " + jointText(j) + "'s " + a + " axis" +
              (perpendicular ? " (perpendicular to the joint's axis)" : " (the joint's axis)"),
          at.wrench(j, 3 + c), Reach::kFrameTilt, j);
      specs.back().variable.perpendicular_moment = perpendicular;
    }
    // Both moments perpendicular to a coordinate axis, each tilting the frame about its own axis.
    const int along = chain.coordinateAxis(j);
    if (along < 0) continue;
    add("joint" + std::to_string(j + 1) + "_mperp_nm",
        "the payload's moment perpendicular to " + jointText(j) + "'s axis, tilting its frame",
        at.wrench(j, 3 + (along + 1) % 3), Reach::kPerpendicularTilt, j);
    specs.back().variable.perpendicular_moment = true;
    specs.back().perpendicular_axes = {(along + 1) % 3, (along + 2) % 3};
  }
  return specs;
}

// A variable's range over the fit rows and whether it can be tested there (present on ≥ 90 % of
// the rows, not constant).
struct Range {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, scale = 0.0;
  size_t present = 0;
  bool testable(size_t rows) const {
    return present * 10 >= rows * 9 && hi - lo > 1e-9 * std::max(1.0, std::abs(hi));
  }
  Eigen::Vector3d legendre(double value) const {
    if (!std::isfinite(value) || !(hi > lo)) return Eigen::Vector3d::Zero();
    const double x = 2.0 * (value - lo) / (hi - lo) - 1.0;
    return {x, 0.5 * (3 * x * x - 1), 0.5 * (5 * x * x * x - 3 * x)};
  }
  /// value / its largest magnitude (0 where absent)
  double scaled(double value) const {
    return std::isfinite(value) && scale > 0.0 ? value / scale : 0.0;
  }
};

std::vector<Range> rangesOf(const PhysicalModel& model, const FitRows& fit, const Layout& at) {
  const Evaluation e = evaluate(model, fit);
  std::vector<Range> ranges(static_cast<size_t>(at.size()));
  ChainWorkspace ws;
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    const RowValues v = rowValues(model, *fit.rows[i], e.theta_rad[i], e.tau_nm[i], at, ws);
    for (int k = 0; k < at.size(); ++k) {
      Range& r = ranges[static_cast<size_t>(k)];
      if (!std::isfinite(v(k))) continue;
      r.lo = std::min(r.lo, v(k));
      r.hi = std::max(r.hi, v(k));
      r.scale = std::max(r.scale, std::abs(v(k)));
      ++r.present;
    }
  }
  return ranges;
}

// One fit row of a chunk: its equations' residual and linearisation, and its variables.
struct RowColumns {
  int equations = 0;
  Eigen::Ref<const Eigen::MatrixXd> link_angle, geometry;  // equations × n, × 6(n+1)
  const RowValues& values;
  const Measurement& row;
};

// The tracker-axes cubic: column c·3 + d is P_d(v) on equation c alone.
void trackerColumns(const Eigen::Vector3d& P, int equations, Eigen::Ref<Eigen::MatrixXd> A) {
  for (int c = 0; c < equations; ++c) A.block(c, c * kDegree, 1, kDegree) = P.transpose();
}

// Spec s's columns at a row (row.equations × s.width(), zero where it has no equation).
void specColumns(const Spec& s, const std::vector<Range>& ranges, const RowColumns& row,
                 Eigen::Ref<Eigen::MatrixXd> A) {
  A.setZero();
  const Range& range = ranges[static_cast<size_t>(s.value)];
  const int j = s.variable.joint;
  if (s.reach == Reach::kPerpendicularTilt) {
    for (int k = 0; k < 2; ++k) {
      const int axis = s.perpendicular_axes[static_cast<size_t>(k)];
      const int value = s.value + axis - s.perpendicular_axes[0];
      const Eigen::Vector3d P = ranges[static_cast<size_t>(value)].legendre(row.values(value));
      for (int d = 0; d < kDegree; ++d) {
        A.col(k * kDegree + d) = row.geometry.col(6 * j + 3 + axis) * P(d);
      }
    }
    return;
  }
  if (s.reach == Reach::kModulatedTorque) {
    const double t = range.scaled(row.values(s.value)), hq = s.harmonic * row.row.q_rad(j);
    A.col(0) = row.link_angle.col(j) * (t * std::cos(hq));
    A.col(1) = row.link_angle.col(j) * (t * std::sin(hq));
    return;
  }
  const Eigen::Vector3d P = range.legendre(row.values(s.value));
  trackerColumns(P, row.equations, A.leftCols(kMaxEquations * kDegree));
  const int first = kMaxEquations * kDegree;
  for (int d = 0; d < kDegree; ++d) {
    if (s.reach == Reach::kLinkAngle) A.col(first + d) = row.link_angle.col(j) * P(d);
    if (s.reach == Reach::kFrameTilt || s.reach == Reach::kFrameShift) {
      const int offset = 6 * j + (s.reach == Reach::kFrameTilt ? 3 : 0);
      for (int a = 0; a < 3; ++a) {
        A.col(first + 3 * d + a) = row.geometry.col(offset + a) * P(d);
      }
    }
  }
}

// The learner's dictionary at a row: per joint its torque times harmonics 0..12 of its angle
// through its link angle, its frame's tilt about each axis times each moment component and its
// shift along each axis times each force component (each variable over its largest magnitude).
constexpr int kTorqueFeatures = 1 + 2 * kHarmonics;
constexpr int kLearnerPerJoint = kTorqueFeatures + 9 + 9;
void learnerColumns(const std::vector<Range>& ranges, const Layout& at, const RowColumns& row,
                    Eigen::Ref<Eigen::MatrixXd> A) {
  A.setZero();
  auto scaled = [&](int value) {
    return ranges[static_cast<size_t>(value)].scaled(row.values(value));
  };
  for (int j = 0; j < at.n; ++j) {
    const int c0 = j * kLearnerPerJoint;
    const double t = scaled(at.tau(j)), q = row.row.q_rad(j);
    A.col(c0) = row.link_angle.col(j) * t;
    for (int h = 1; h <= kHarmonics; ++h) {
      A.col(c0 + 2 * h - 1) = row.link_angle.col(j) * t * std::cos(h * q);
      A.col(c0 + 2 * h) = row.link_angle.col(j) * t * std::sin(h * q);
    }
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        A.col(c0 + kTorqueFeatures + 3 * a + b) =
            row.geometry.col(6 * j + 3 + a) * scaled(at.wrench(j, 3 + b));
        A.col(c0 + kTorqueFeatures + 9 + 3 * a + b) =
            row.geometry.col(6 * j + a) * scaled(at.wrench(j, b));
      }
    }
  }
}

// Per fold, the Gram and right-hand side of a set of columns.
struct FoldSystem {
  std::vector<Eigen::MatrixXd> G;
  std::vector<Eigen::VectorXd> b;
  FoldSystem(int folds, Eigen::Index width)
      : G(static_cast<size_t>(folds), Eigen::MatrixXd::Zero(width, width)),
        b(static_cast<size_t>(folds), Eigen::VectorXd::Zero(width)) {}
  void add(int fold, const Eigen::MatrixXd& A, const Eigen::VectorXd& r) {
    G[static_cast<size_t>(fold)].selfadjointView<Eigen::Lower>().rankUpdate(A.transpose());
    b[static_cast<size_t>(fold)].noalias() += A.transpose() * r;
  }
  void add(const FoldSystem& other) {
    for (size_t f = 0; f < G.size(); ++f) {
      G[f] += other.G[f];
      b[f] += other.b[f];
    }
  }
  /// Fold f's fit on the other folds, ridge relative to the mean diagonal (a tiny one keeps a
  /// column the rows never see at zero).
  Eigen::VectorXd solveWithout(int f, double relative_ridge) const {
    Eigen::MatrixXd Gt = Eigen::MatrixXd::Zero(G.front().rows(), G.front().cols());
    Eigen::VectorXd bt = Eigen::VectorXd::Zero(Gt.rows());
    for (size_t g = 0; g < G.size(); ++g) {
      if (static_cast<int>(g) == f) continue;
      Gt += G[g];
      bt += b[g];
    }
    Gt.triangularView<Eigen::StrictlyUpper>() = Gt.transpose();
    const double mean_diagonal = Gt.trace() / static_cast<double>(std::max<Eigen::Index>(1, Gt.rows()));
    if (!(mean_diagonal > 0.0)) return Eigen::VectorXd::Zero(Gt.rows());
    Gt.diagonal().array() += relative_ridge * mean_diagonal;
    return Gt.ldlt().solve(bt);
  }
};

// Runs visit(slice, i, columns, r_i) for every fit row i, chunk by chunk on the cores
// (chunked_gram.hpp's slices), the model evaluated and linearised on each chunk.
template <typename Visit>
void forEachRow(const PhysicalModel& model, const FitRows& fit, const Layout& at,
                const Visit& visit) {
  forEachChunk(fit, [&](size_t slice, size_t begin, size_t end) {
    Evaluation e;
    Linearisation lin;
    evaluateAndLinearise(model, fit, begin, end, e, lin);
    ChainWorkspace ws;
    const Eigen::Index first = equationOf(fit, begin);
    for (size_t i = begin; i < end; ++i) {
      const int k = fit.equations(i);
      const Eigen::Index at_row = fit.start[i] - first;
      const RowValues values =
          rowValues(model, *fit.rows[i], e.theta_rad[i - begin], e.tau_nm[i - begin], at, ws);
      const RowColumns columns{k, lin.link_angle.middleRows(at_row, k),
                               lin.geometry.middleRows(at_row, k), values, *fit.rows[i]};
      visit(slice, i, columns, Eigen::VectorXd(e.r.segment(at_row, k)));
    }
  });
}

// The columns of test t at a row: a variable's (t < specs), else the learner's.
struct Tests {
  std::vector<Spec> specs;  ///< the testable variables
  Eigen::Index learner_width = 0;
  const std::vector<Range>* ranges = nullptr;
  const Layout* at = nullptr;
  size_t count() const { return specs.size() + 1; }
  Eigen::Index width(size_t t) const {
    return t < specs.size() ? specs[t].width() : learner_width;
  }
  void columns(size_t t, const RowColumns& row, Eigen::MatrixXd& A) const {
    A.resize(row.equations, width(t));
    if (t < specs.size()) {
      specColumns(specs[t], *ranges, row, A);
    } else {
      learnerColumns(*ranges, *at, row, A);
    }
  }
};

// Pass 1: per test and fold, the Grams of its columns against the residual.
std::vector<FoldSystem> foldSystems(const PhysicalModel& model, const FitRows& fit,
                                    const Tests& tests) {
  std::vector<std::vector<FoldSystem>> per_slice(kGramSlices);
  for (auto& systems : per_slice) {
    for (size_t t = 0; t < tests.count(); ++t) systems.emplace_back(fit.folds, tests.width(t));
  }
  forEachRow(model, fit, *tests.at,
             [&](size_t slice, size_t i, const RowColumns& row, const Eigen::VectorXd& r) {
               Eigen::MatrixXd A;
               for (size_t t = 0; t < tests.count(); ++t) {
                 tests.columns(t, row, A);
                 per_slice[slice][t].add(fit.fold[i], A, r);
               }
             });
  std::vector<FoldSystem> systems = std::move(per_slice.front());
  for (size_t s = 1; s < kGramSlices; ++s) {
    for (size_t t = 0; t < tests.count(); ++t) systems[t].add(per_slice[s][t]);
  }
  return systems;
}

// Pass 2: the held-out outcome of no correction (first) and of each fit (per fold: its
// coefficients per test, the learner once per ridge).
std::vector<CrossValidation::Outcome> heldOutOutcomes(
    const PhysicalModel& model, const FitRows& fit, const Tests& tests,
    const std::vector<std::vector<Eigen::VectorXd>>& fits) {
  const size_t fits_count = fits.size(), rows = fit.rows.size();
  // Per fit (and no correction at 0): each row's held-out squared error; per slice the position
  // sums. Rows are disjoint between slices.
  std::vector<std::vector<double>> row_sse(fits_count + 1, std::vector<double>(rows, 0.0));
  std::vector<std::vector<double>> position(kGramSlices, std::vector<double>(fits_count + 1, 0.0));
  forEachRow(model, fit, *tests.at,
             [&](size_t slice, size_t i, const RowColumns& row, const Eigen::VectorXd& r) {
               row_sse[0][i] = r.squaredNorm();
               position[slice][0] += r.head<3>().norm() / fit.w_p;
               Eigen::MatrixXd A;
               for (size_t k = 0; k < fits_count; ++k) {
                 tests.columns(std::min(k, tests.count() - 1), row, A);
                 const Eigen::VectorXd e =
                     r - A * fits[k][static_cast<size_t>(fit.fold[i])];
                 row_sse[k + 1][i] = e.squaredNorm();
                 position[slice][k + 1] += e.head<3>().norm() / fit.w_p;
               }
             });
  std::vector<CrossValidation::Outcome> outcomes(fits_count + 1);
  for (size_t k = 0; k <= fits_count; ++k) {
    CrossValidation::Outcome& o = outcomes[k];
    o.pose_sse.assign(static_cast<size_t>(fit.poses), 0.0);
    o.rows = rows;
    for (size_t i = 0; i < rows; ++i) o.pose_sse[static_cast<size_t>(fit.pose[i])] += row_sse[k][i];
    for (size_t s = 0; s < kGramSlices; ++s) o.position_sum_m += position[s][k];
  }
  return outcomes;
}

// Part (a): the extended model's mean error held out (the validation rows, every load; with none,
// the fit rows) against the floor the tracker noise gives.
void heldOutResidual(const Diagnosis& d, const TrackerNoise& noise, UnexplainedPart& u) {
  double sum_m = 0.0;
  int rows = 0;
  for (const GainRow& g : d.gain) {
    sum_m += g.after.mean_position_m * g.after.rows;
    rows += g.after.rows;
  }
  u.residual_rows = rows > 0 ? "validation" : "fit";
  u.residual_m = rows > 0 ? sum_m / rows : d.after.mean_position_m;
  u.floor_m = noiseFloorMean(noise.position_sigma_m);
  u.ratio = u.floor_m > 0.0 ? u.residual_m / u.floor_m : 0.0;
  u.noise_stated = noise.stated;
}

std::string printed(const char* fmt, double a, double b = 0.0, double c = 0.0, double e = 0.0) {
  char text[400];
  std::snprintf(text, sizeof text, fmt, a, b, c, e);
  return text;
}

std::string variableText(const UnexplainedVariable& v) {
  return v.description + " (" + v.name +
         printed(": %.4f mm, z %.1f)", v.cv_gain_mm, v.z_statistic);
}

// What the residual follows, in words: the significant variables (at most three, the strongest
// first), and the time order's part.
std::string followsText(const UnexplainedPart& u) {
  constexpr size_t kNamed = 3;
  std::string out;
  size_t named = 0;
  bool time_named = false;
  for (const UnexplainedVariable& v : u.variables) {
    if (!v.significant || named == kNamed) continue;
    out += (named++ == 0 ? "it follows " : "; ") + variableText(v);
    time_named = time_named || v.name == "seq";
  }
  if (named == 0) {
    return "it follows none of the " + std::to_string(u.variables_tested) +
           " variables tested (scatter from pose to pose, or the noise is understated)";
  }
  for (const UnexplainedVariable& v : u.variables) {
    if (v.name != "seq" || time_named) continue;
    out += v.significant ? "; the time order less (" + v.name +
                               printed(": %.4f mm, z %.1f)", v.cv_gain_mm, v.z_statistic)
                         : printed("; not the time order (seq: z %.1f)", v.z_statistic);
  }
  return out;
}

std::string learnerText(const UnexplainedPart& u) {
  // Without a payload's wrench (no sensor, or unloaded), its features are zero: the torques are
  // the arm's own weight's.
  const bool wrench = std::any_of(u.variables.begin(), u.variables.end(),
                                  [](const UnexplainedVariable& v) { return v.name.rfind("joint", 0) == 0; });
  const std::string learner =
      std::string(wrench ? "a learner over the payload's wrench and the torques in the joints' frames"
                         : "a learner over the joints' torques and angles") +
      " (" + std::to_string(u.learner_features) + " features)";
  if (!u.learner_significant) {
    return learner + printed(" removes nothing significant held out (z %.1f)", u.learner_z);
  }
  return learner + printed(" removes %.4f mm of it held out (z %.1f) that the catalogue does not",
                           u.learner_gain_mm, u.learner_z);
}

std::string unexplainedText(const UnexplainedPart& u) {
  // Without validation rows the fit rows are all there is: the figure is not held out.
  const std::string where = u.residual_rows == "validation"
                                ? "held out (the validation rows)"
                                : "on the fit rows (the campaign holds no validation rows out)";
  const std::string noise =
      u.noise_stated ? "" : " (the campaign states no tracker noise: the floor is the default sigma's)";
  if (!u.any) {
    return "nothing unexplained: the extended model leaves " +
           printed("%.4f mm ", kMmPerM * u.residual_m) + where +
           printed(", %.2f times the noise floor of %.4f mm", u.ratio, kMmPerM * u.floor_m) + noise +
           ", and follows none of the " + std::to_string(u.variables_tested) +
           " variables tested; " + learnerText(u);
  }
  return "nothing in the catalogue explains " +
         printed("%.4f mm above the noise: the extended model leaves %.4f mm ",
                 kMmPerM * std::max(0.0, u.residual_m - u.floor_m), kMmPerM * u.residual_m) +
         where + printed(", %.1f times the noise floor of %.4f mm", u.ratio, kMmPerM * u.floor_m) +
         noise + "; " + followsText(u) + "; " + learnerText(u);
}

// The variables' held-out scores: the significant ones first, by the held-out reduction, as the
// rounds choose among families; then the others by z.
void judgeVariables(const Tests& tests, const std::vector<CrossValidation::Outcome>& outcomes,
                    const DiagnoseOptions& options, UnexplainedPart& u) {
  u.variables_tested = static_cast<int>(tests.specs.size());
  for (size_t t = 0; t < tests.specs.size(); ++t) {
    const Comparison c = compare(outcomes.front(), outcomes[t + 1]);
    UnexplainedVariable v = tests.specs[t].variable;
    v.cv_gain_mm = c.gain_mm;
    v.relative_reduction = c.relative_reduction;
    v.z_statistic = c.z;
    v.p_value = c.p;
    v.significant = c.p < options.family_alpha / std::max(1, u.variables_tested) &&
                    c.relative_reduction >= options.min_relative_reduction && c.gain_mm > 0.0;
    u.variables.push_back(std::move(v));
  }
  std::stable_sort(u.variables.begin(), u.variables.end(),
                   [](const UnexplainedVariable& a, const UnexplainedVariable& b) {
                     if (a.significant != b.significant) return a.significant;
                     if (a.significant) return a.relative_reduction > b.relative_reduction;
                     return a.z_statistic > b.z_statistic;
                   });
}

// The learner at the ridge whose held-out error is least (outcomes after the variables').
void judgeLearner(const Tests& tests, const std::vector<CrossValidation::Outcome>& outcomes,
                  const DiagnoseOptions& options, UnexplainedPart& u) {
  const size_t first = tests.specs.size() + 1;
  size_t best = first;
  for (size_t k = first; k < outcomes.size(); ++k) {
    if (outcomes[k].total() < outcomes[best].total()) best = k;
  }
  const Comparison c = compare(outcomes.front(), outcomes[best]);
  u.learner_features = static_cast<int>(tests.learner_width);
  u.learner_gain_mm = c.gain_mm;
  u.learner_relative_reduction = c.relative_reduction;
  u.learner_z = c.z;
  u.learner_p = c.p;
  u.learner_significant = c.p < options.family_alpha / static_cast<double>(kLearnerRidges.size()) &&
                          c.relative_reduction >= options.min_relative_reduction && c.gain_mm > 0.0;
}

}  // namespace

void judgeUnexplained(Search& search, const PhysicalModel& extended, const TrackerNoise& noise) {
  const auto clock = std::chrono::steady_clock::now();
  Diagnosis& d = search.d;
  const FitRows& fit = search.fit;
  const DiagnoseOptions& options = search.options;
  UnexplainedPart& u = d.unexplained;
  heldOutResidual(d, noise, u);

  Layout at{extended.chain_Tracker.dof()};
  at.link_masses = search.body_masses ? &*search.body_masses : nullptr;
  for (const Mechanism& m : extended.mechanisms) {
    if (m.kind == MechanismKind::kSelfWeight) at.link_masses = &m.parameters;
  }
  const std::vector<Range> ranges = rangesOf(extended, fit, at);
  Tests tests;
  tests.ranges = &ranges;
  tests.at = &at;
  tests.learner_width = kLearnerPerJoint * at.n;
  for (Spec& s : variableSpecs(extended.chain_Tracker, at)) {
    if (ranges[static_cast<size_t>(s.value)].testable(fit.rows.size())) tests.specs.push_back(std::move(s));
  }
  const std::vector<FoldSystem> systems = foldSystems(extended, fit, tests);
  // Per fit, per fold: each variable's coefficients, then the learner's at each ridge.
  constexpr double kTinyRidge = 1e-10;
  std::vector<std::vector<Eigen::VectorXd>> fits;
  for (size_t t = 0; t < tests.specs.size(); ++t) {
    fits.emplace_back();
    for (int f = 0; f < fit.folds; ++f) fits.back().push_back(systems[t].solveWithout(f, kTinyRidge));
  }
  for (const double ridge : kLearnerRidges) {
    fits.emplace_back();
    for (int f = 0; f < fit.folds; ++f) fits.back().push_back(systems.back().solveWithout(f, ridge));
  }
  const std::vector<CrossValidation::Outcome> outcomes = heldOutOutcomes(extended, fit, tests, fits);
  judgeVariables(tests, outcomes, options, u);
  judgeLearner(tests, outcomes, options, u);
  u.any = u.ratio > options.noise_ratio_limit || u.learner_significant ||
          (!u.variables.empty() && u.variables.front().significant);
  u.text = unexplainedText(u);
  d.seconds_trends += std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
}

}  // namespace stepcal::trainer::diagnosis
