#include "stepcal/trainer/diagnose.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>

#include <Eigen/Eigenvalues>

#include "least_squares.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal::trainer {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Singular values below this fraction of the largest are unobservable (as in step 1).
constexpr double kRankTolerance = 1e-9;
// The same on the eigenvalues of a Gram matrix (their squares).
constexpr double kGramRankTolerance = 1e-15;
// A candidate whose largest column moves the weighted residual by less than this, for a
// parameter step of typical size, has no effect on these rows and is not tried.
constexpr double kNegligibleEffect = 1e-3;
// Lumped link masses are identifiable only in combinations (the gravity torques on the compliant
// joints); a weak prior keeps the rest near zero instead of drifting along near-null directions:
// 1-σ of 50 kg and 50 kg·m per parameter, far wider than any link's imbalance.
constexpr double kSelfWeightPriorSigma = 50.0;
// Fold assignment is a fixed shuffle of the poses: the same campaign, the same folds.
constexpr uint64_t kFoldSeed = 20240521;

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// One-sided p-value of a t statistic, normal approximation (hundreds of poses).
double upperTailP(double t) { return 0.5 * std::erfc(t / std::sqrt(2.0)); }

// The fit rows as noise-weighted equations: 3 position rows, then 3 rotation rows when measured.
struct Equations {
  std::vector<const Measurement*> rows;
  std::vector<int> start;  // first equation of each row
  std::vector<int> fold;   // cross-validation fold of each row
  std::vector<int> pose;   // pose group of each row
  int count = 0, poses = 0, folds = 0;
  double w_p = 1.0, w_r = 1.0;  // 1/σ
};

Equations makeEquations(const std::vector<const Measurement*>& rows, const TrackerNoise& noise,
                        int folds) {
  Equations eq;
  eq.rows = rows;
  eq.folds = folds;
  eq.w_p = 1.0 / noise.position_sigma_m;
  eq.w_r = 1.0 / noise.orientation_sigma_rad;
  std::map<std::string, int> pose_index;
  for (const Measurement* row : rows) pose_index.emplace(row->pose_id, 0);
  std::vector<int> order(pose_index.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::mt19937_64 rng(kFoldSeed);
  std::shuffle(order.begin(), order.end(), rng);
  int i = 0;
  for (auto& [id, index] : pose_index) index = i++;
  eq.poses = static_cast<int>(pose_index.size());
  for (const Measurement* row : rows) {
    const int p = pose_index.at(row->pose_id);
    eq.start.push_back(eq.count);
    eq.pose.push_back(p);
    eq.fold.push_back(order[static_cast<size_t>(p)] % folds);
    eq.count += row->has_orientation ? 6 : 3;
  }
  return eq;
}

int equationsOf(const Equations& eq, size_t row) {
  return eq.rows[row]->has_orientation ? 6 : 3;
}

// Noise-weighted residuals (measured − modelled) of every fit row; τ per row if asked.
Eigen::VectorXd residuals(const PhysicalModel& model, const Equations& eq,
                          std::vector<JointVector>* tau_out = nullptr) {
  Eigen::VectorXd r(eq.count);
  ChainWorkspace ws;
  JointVector theta, tau;
  if (tau_out) tau_out->resize(eq.rows.size());
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const Measurement& row = *eq.rows[i];
    physicalLinkAngles(model, row.q_rad, row.wrenchOrZero(), rowTemperature(row), ws, theta, tau);
    const Pose& X = tipPose(ws);
    const int e = eq.start[i];
    r.segment<3>(e) = eq.w_p * (row.p_TipInTracker_m - X.translation());
    if (row.has_orientation) {
      r.segment<3>(e + 3) =
          eq.w_r * lie::logSO3(row.q_TrackerTip.toRotationMatrix() * X.linear().transpose());
    }
    if (tau_out) (*tau_out)[i] = tau;
  }
  return r;
}

// d(modelled)/d(δ) of the 6(n+1) initial-pose corrections (METHOD.md eq. 7), noise-weighted.
Eigen::MatrixXd geometryColumns(const PhysicalModel& model, const Equations& eq,
                                const Eigen::VectorXd& r) {
  const KinematicChain& chain = model.chain_Tracker;
  const int n = chain.dof();
  Eigen::MatrixXd A(eq.count, 6 * (n + 1));
  Eigen::Matrix<double, 6, Eigen::Dynamic> P(6, 6 * (n + 1));
  ChainWorkspace ws;
  JointVector theta, tau;
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const Measurement& row = *eq.rows[i];
    physicalLinkAngles(model, row.q_rad, row.wrenchOrZero(), rowTemperature(row), ws, theta, tau);
    parameterJacobian(chain, ws, P);
    const int e = eq.start[i];
    A.middleRows<3>(e) =
        eq.w_p * (P.topRows<3>() - lie::hat(tipPose(ws).translation()) * P.bottomRows<3>());
    if (row.has_orientation) {
      const Mat3 Jr_inv = lie::rightJacobianInverseSO3(r.segment<3>(e + 3) / eq.w_r);
      A.middleRows<3>(e + 3) = eq.w_r * Jr_inv * P.bottomRows<3>();
    }
  }
  return A;
}

// A scalar parameter of the physical model beyond the geometry: a joint's compliance
// (mechanism −1) or a mechanism's parameter.
struct Parameter {
  int mechanism = -1;
  int index = 0;
  double step = 0.0;  // finite-difference step of typical size, SI
};

void shift(PhysicalModel& model, const Parameter& p, double delta) {
  if (p.mechanism < 0) {
    model.compliance_rad_per_nm(p.index) += delta;
  } else {
    model.mechanisms[static_cast<size_t>(p.mechanism)].parameters[static_cast<size_t>(p.index)] +=
        delta;
  }
}

// A step that moves the link angles by ~1e-4 rad or the tip by ~0.1 mm.
double typicalStep(const Mechanism& m, int index) {
  switch (m.kind) {
    case MechanismKind::kNonlinearStiffness:
      return index == 0 ? 1e-4 / m.parameters[1] : 0.01 * m.parameters[1];
    case MechanismKind::kThermalExpansion: return 1e-5;
    case MechanismKind::kSensorBias: return index < 3 ? 1.0 : 0.1;
    case MechanismKind::kSelfWeight: return index % 4 == 0 ? 1.0 : 0.5;
    default: return 1e-4;
  }
}

// The fitted parameters of a mechanism (thermal's reference temperature is chosen, not fitted;
// nonlinear stiffness's τ₀ only once its compliance is nonzero).
std::vector<int> freeParameters(const Mechanism& m) {
  std::vector<int> free;
  for (size_t i = 0; i < m.parameters.size(); ++i) {
    if ((m.kind == MechanismKind::kThermalExpansion || m.kind == MechanismKind::kBacklash) &&
        i == 1) {
      continue;
    }
    if (m.kind == MechanismKind::kNonlinearStiffness && i == 1 && m.parameters[0] == 0.0) continue;
    free.push_back(static_cast<int>(i));
  }
  return free;
}

// Compliances of the joints the model holds as compliant, then every mechanism's free parameters.
std::vector<Parameter> modelParameters(const PhysicalModel& model) {
  std::vector<Parameter> params;
  for (int j = 0; j < model.compliance_rad_per_nm.size(); ++j) {
    const double c = model.compliance_rad_per_nm(j);
    if (c > 0.0) params.push_back({-1, j, 0.01 * c});
  }
  for (size_t k = 0; k < model.mechanisms.size(); ++k) {
    const Mechanism& m = model.mechanisms[k];
    for (int i : freeParameters(m)) params.push_back({static_cast<int>(k), i, typicalStep(m, i)});
  }
  return params;
}

// Forward-difference column of the modelled pose by one parameter, noise-weighted.
Eigen::VectorXd parameterColumn(const PhysicalModel& model, const Equations& eq,
                                const Eigen::VectorXd& r0, const Parameter& p) {
  PhysicalModel moved = model;
  shift(moved, p, p.step);
  return (r0 - residuals(moved, eq)) / p.step;
}

Eigen::MatrixXd jacobian(const PhysicalModel& model, const Equations& eq,
                         const Eigen::VectorXd& r, const std::vector<Parameter>& params) {
  const Eigen::MatrixXd G = geometryColumns(model, eq, r);
  Eigen::MatrixXd A(eq.count, G.cols() + static_cast<Eigen::Index>(params.size()));
  A.leftCols(G.cols()) = G;
  for (size_t c = 0; c < params.size(); ++c) {
    A.col(G.cols() + static_cast<Eigen::Index>(c)) = parameterColumn(model, eq, r, params[c]);
  }
  return A;
}

bool apply(const PhysicalModel& model, const std::vector<Parameter>& params,
           const Eigen::VectorXd& x, double fraction, PhysicalModel& out) {
  const int geometry = 6 * (model.chain_Tracker.dof() + 1);
  out = model;
  out.chain_Tracker = model.chain_Tracker.corrected(fraction * x.head(geometry));
  for (size_t c = 0; c < params.size(); ++c) {
    shift(out, params[c], fraction * x(geometry + static_cast<Eigen::Index>(c)));
  }
  for (const Mechanism& m : out.mechanisms) {
    if (!mechanismProblem(m, out.chain_Tracker.dof()).empty()) return false;
  }
  return true;
}

double priorCost(const PhysicalModel& model) {
  double cost = 0.0;
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind != MechanismKind::kSelfWeight) continue;
    for (double v : m.parameters) cost += (v / kSelfWeightPriorSigma) * (v / kSelfWeightPriorSigma);
  }
  return cost;
}

// Prior rows (value − 0)/σ for the self_weight parameters, appended to a linearised system.
void addPriors(const PhysicalModel& model, const std::vector<Parameter>& params, Eigen::MatrixXd& A,
               Eigen::VectorXd& r) {
  const Eigen::Index geometry = A.cols() - static_cast<Eigen::Index>(params.size());
  for (size_t c = 0; c < params.size(); ++c) {
    const Parameter& p = params[c];
    if (p.mechanism < 0 ||
        model.mechanisms[static_cast<size_t>(p.mechanism)].kind != MechanismKind::kSelfWeight) {
      continue;
    }
    const double value =
        model.mechanisms[static_cast<size_t>(p.mechanism)].parameters[static_cast<size_t>(p.index)];
    A.conservativeResize(A.rows() + 1, Eigen::NoChange);
    A.row(A.rows() - 1).setZero();
    A(A.rows() - 1, geometry + static_cast<Eigen::Index>(c)) = 1.0 / kSelfWeightPriorSigma;
    r.conservativeResize(r.size() + 1);
    r(r.size() - 1) = -value / kSelfWeightPriorSigma;
  }
}

struct RefitResult {
  PhysicalModel model;
  Eigen::VectorXd r;
  double cost = 0.0;
};

// Joint Gauss–Newton refit of geometry, compliances and mechanisms on every fit row; fills the
// mechanisms' and compliances' 1-σ from the final linearisation (residual variance estimated).
RefitResult refit(PhysicalModel model, const Equations& eq, int iterations,
                  JointVector* compliance_sigma) {
  RefitResult out;
  out.r = residuals(model, eq);
  out.cost = out.r.squaredNorm() + priorCost(model);
  for (int it = 0; it < iterations; ++it) {
    const std::vector<Parameter> params = modelParameters(model);
    Eigen::MatrixXd A = jacobian(model, eq, out.r, params);
    Eigen::VectorXd rhs = out.r;
    addPriors(model, params, A, rhs);
    const SvdSolution s = solveTruncated(A, rhs, kRankTolerance);
    bool improved = false;
    for (double fraction = 1.0; fraction > 1e-3; fraction *= 0.5) {
      PhysicalModel candidate;
      if (!apply(model, params, s.x, fraction, candidate)) continue;
      const Eigen::VectorXd r = residuals(candidate, eq);
      const double cost = r.squaredNorm() + priorCost(candidate);
      if (cost < out.cost) {
        improved = out.cost - cost > 1e-10 * out.cost;
        model = std::move(candidate);
        out.r = r;
        out.cost = cost;
        break;
      }
    }
    if (!improved) break;
  }
  // Covariance of the final linearisation: s² (AᵀA)⁺ in column-normalised coordinates.
  const std::vector<Parameter> params = modelParameters(model);
  Eigen::MatrixXd A = jacobian(model, eq, out.r, params);
  Eigen::VectorXd rhs = out.r;
  addPriors(model, params, A, rhs);
  const SvdSolution s = solveTruncated(A, rhs, kRankTolerance);
  const double variance = out.cost / std::max(1, eq.count - s.rank);
  const int geometry = 6 * (model.chain_Tracker.dof() + 1);
  for (auto& m : model.mechanisms) m.sigma.assign(m.parameters.size(), 0.0);
  for (size_t c = 0; c < params.size(); ++c) {
    const Eigen::Index col = geometry + static_cast<Eigen::Index>(c);
    double var_z = 0.0;
    for (int k = 0; k < s.rank; ++k) {
      var_z += std::pow(s.V(col, k) / s.singular_values(k), 2);
    }
    const double sigma = std::sqrt(variance * var_z) / s.column_scale(col);
    const Parameter& p = params[c];
    if (p.mechanism < 0) {
      if (compliance_sigma) (*compliance_sigma)(p.index) = sigma;
    } else {
      model.mechanisms[static_cast<size_t>(p.mechanism)].sigma[static_cast<size_t>(p.index)] =
          sigma;
    }
  }
  out.model = std::move(model);
  return out;
}

// ---- Candidates -------------------------------------------------------------------------

struct Candidate {
  Mechanism mechanism;      // parameters at zero (τ₀ / T_ref chosen)
  std::vector<int> free;
  Eigen::Index first_column = 0;
  int columns = 0;
};

bool sameMechanism(const Mechanism& a, const Mechanism& b) {
  return a.kind == b.kind && a.joint == b.joint && a.source_joint == b.source_joint &&
         a.harmonic == b.harmonic;
}

Mechanism blank(MechanismKind kind, int dof, int joint = -1, int source = -1, int harmonic = 0) {
  Mechanism m;
  m.kind = kind;
  m.joint = joint;
  m.source_joint = source;
  m.harmonic = harmonic;
  m.parameters.assign(mechanismParameterNames(kind, dof).size(), 0.0);
  m.sigma.assign(m.parameters.size(), 0.0);
  return m;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Every catalogued mechanism that can act on these rows and is not in the model yet.
std::vector<Candidate> catalogue(const PhysicalModel& model, const Equations& eq,
                                 const std::vector<JointVector>& tau, const DiagnoseOptions& o,
                                 std::vector<UntestableCandidate>& untestable) {
  const int n = model.chain_Tracker.dof();
  std::vector<Mechanism> all;
  for (int j = 0; j < n; ++j) {
    for (int k = 1; k <= o.max_harmonic; ++k) {
      all.push_back(blank(MechanismKind::kTransmissionError, n, j, -1, k));
    }
  }
  // Backlash and nonlinear stiffness need load torque on the joint; their torque scales (τ_b,
  // τ₀) come from the loads the joint sees. Backlash is taken up at a tenth of the typical
  // load (far above the sensor's noise, far below the loads). Nonlinear stiffness: τ₀ on a
  // grid (the compliance is linear in c for a given τ₀); far below the loads it is backlash,
  // far above them linear compliance.
  for (int j = 0; j < n; ++j) {
    std::vector<double> loaded;
    for (size_t i = 0; i < eq.rows.size(); ++i) {
      if (std::abs(tau[i](j)) > 1.0) loaded.push_back(std::abs(tau[i](j)));
    }
    const double typical = median(loaded);
    if (loaded.size() < 10 || typical < 10.0) {
      for (const char* name : {"backlash", "nonlinear_stiffness"}) {
        untestable.push_back({std::string(name) + " (joint " + std::to_string(j + 1) + ")",
                              "the joint carries too little load torque on these rows"});
      }
      continue;
    }
    Mechanism backlash = blank(MechanismKind::kBacklash, n, j);
    backlash.parameters[1] = 0.1 * typical;
    all.push_back(backlash);
    for (double f : {0.1, 0.25, 0.5, 1.0, 2.0}) {
      Mechanism m = blank(MechanismKind::kNonlinearStiffness, n, j);
      m.parameters[1] = f * typical;
      all.push_back(m);
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (i != j) all.push_back(blank(MechanismKind::kJointCoupling, n, j, i));
    }
  }
  const bool compliant = model.compliance_rad_per_nm.size() == n &&
                         model.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (!compliant) {
    untestable.push_back({"self_weight", "the model has no joint compliance to act on gravity"});
  } else if (model.gravity_Tracker.norm() == 0.0) {
    untestable.push_back({"self_weight", "gravity is unknown (gravity_in_base)"});
  } else {
    all.push_back(blank(MechanismKind::kSelfWeight, n));
  }
  if (model.sensor_frame < 0 || !compliant) {
    untestable.push_back({"sensor_bias", "the model has no F/T sensor or no compliance"});
  } else {
    all.push_back(blank(MechanismKind::kSensorBias, n));
  }
  double sum = 0.0, sum2 = 0.0;
  int with_temp = 0;
  for (const Measurement* row : eq.rows) {
    if (!row->temp_c) continue;
    sum += *row->temp_c;
    sum2 += *row->temp_c * *row->temp_c;
    ++with_temp;
  }
  const double mean_temp = with_temp > 0 ? sum / with_temp : 0.0;
  const double spread = with_temp > 1 ? std::sqrt(std::max(0.0, sum2 / with_temp - mean_temp * mean_temp)) : 0.0;
  if (with_temp * 2 < static_cast<int>(eq.rows.size())) {
    untestable.push_back({"thermal_expansion", "fewer than half the fit rows have temp_c"});
  } else if (spread < 0.5) {
    untestable.push_back({"thermal_expansion",
                          "temp_c varies by less than 0.5 °C (standard deviation " +
                              std::to_string(spread) + " °C)"});
  } else {
    Mechanism m = blank(MechanismKind::kThermalExpansion, n);
    m.parameters[1] = mean_temp;
    all.push_back(m);
  }

  std::vector<Candidate> out;
  for (Mechanism& m : all) {
    bool present = false;
    for (const Mechanism& have : model.mechanisms) {
      present = present || sameMechanism(have, m) ||
                (have.kind == m.kind && (m.kind == MechanismKind::kSelfWeight ||
                                         m.kind == MechanismKind::kSensorBias ||
                                         m.kind == MechanismKind::kThermalExpansion));
    }
    if (present) continue;
    Candidate c;
    c.free = freeParameters(m);
    if (m.kind == MechanismKind::kNonlinearStiffness) c.free = {0};
    c.mechanism = std::move(m);
    out.push_back(std::move(c));
  }
  return out;
}

// Candidate columns at the model, appended after the base columns; candidates without effect
// on these rows are dropped (and reported).
Eigen::MatrixXd candidateColumns(const PhysicalModel& model, const Equations& eq,
                                 const Eigen::VectorXd& r0, const Eigen::MatrixXd& base,
                                 std::vector<Candidate>& candidates,
                                 std::vector<UntestableCandidate>& untestable) {
  std::vector<Eigen::VectorXd> columns;
  std::vector<Candidate> kept;
  Eigen::Index next = base.cols();
  for (Candidate& c : candidates) {
    PhysicalModel with = model;
    with.mechanisms.push_back(c.mechanism);
    const int index = static_cast<int>(with.mechanisms.size()) - 1;
    std::vector<Eigen::VectorXd> mine;
    double effect = 0.0;
    for (int i : c.free) {
      const Parameter p{index, i, typicalStep(c.mechanism, i)};
      mine.push_back(parameterColumn(with, eq, r0, p));
      effect = std::max(effect, mine.back().norm() * p.step);
    }
    if (effect < kNegligibleEffect) {
      untestable.push_back({describe(c.mechanism), "no effect on the tip at these rows"});
      continue;
    }
    c.first_column = next;
    c.columns = static_cast<int>(mine.size());
    next += c.columns;
    for (auto& col : mine) columns.push_back(std::move(col));
    kept.push_back(std::move(c));
  }
  candidates = std::move(kept);
  Eigen::MatrixXd A(eq.count, next);
  A.leftCols(base.cols()) = base;
  for (size_t c = 0; c < columns.size(); ++c) {
    A.col(base.cols() + static_cast<Eigen::Index>(c)) = columns[c];
  }
  return A;
}

// Least squares on a column subset from Gram blocks, truncated eigen-decomposition on the
// column-normalised normal equations.
Eigen::VectorXd solveGram(const Eigen::MatrixXd& G, const Eigen::VectorXd& b,
                          const Eigen::VectorXd& scale) {
  const Eigen::MatrixXd Gs = scale.cwiseInverse().asDiagonal() * G * scale.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Gs);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double cutoff = kGramRankTolerance * lambda.maxCoeff();
  const Eigen::VectorXd bs = b.cwiseQuotient(scale);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(G.rows());
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    if (lambda(i) > cutoff) {
      z += eig.eigenvectors().col(i) * (eig.eigenvectors().col(i).dot(bs) / lambda(i));
    }
  }
  return z.cwiseQuotient(scale);
}

// Cross-validation of linear fits over column subsets of A, folds by pose.
class CrossValidation {
 public:
  CrossValidation(const Eigen::MatrixXd& A, const Eigen::VectorXd& r, const Equations& eq)
      : A_(A), r_(r), eq_(eq) {
    const Eigen::Index p = A.cols();
    G_.assign(static_cast<size_t>(eq.folds), Eigen::MatrixXd::Zero(p, p));
    b_.assign(static_cast<size_t>(eq.folds), Eigen::VectorXd::Zero(p));
    rows_of_fold_.resize(static_cast<size_t>(eq.folds));
    for (size_t i = 0; i < eq.rows.size(); ++i) {
      rows_of_fold_[static_cast<size_t>(eq.fold[i])].push_back(static_cast<int>(i));
    }
    for (int f = 0; f < eq.folds; ++f) {
      Eigen::Index count = 0;
      for (int i : rows_of_fold_[static_cast<size_t>(f)]) count += equationsOf(eq, static_cast<size_t>(i));
      Eigen::MatrixXd Af(count, p);
      Eigen::VectorXd rf(count);
      Eigen::Index e = 0;
      for (int i : rows_of_fold_[static_cast<size_t>(f)]) {
        const int k = equationsOf(eq, static_cast<size_t>(i));
        Af.middleRows(e, k) = A.middleRows(eq.start[static_cast<size_t>(i)], k);
        rf.segment(e, k) = r.segment(eq.start[static_cast<size_t>(i)], k);
        e += k;
      }
      G_[static_cast<size_t>(f)].selfadjointView<Eigen::Lower>().rankUpdate(Af.transpose());
      G_[static_cast<size_t>(f)] = G_[static_cast<size_t>(f)].selfadjointView<Eigen::Lower>();
      b_[static_cast<size_t>(f)] = Af.transpose() * rf;
    }
    G_total_ = Eigen::MatrixXd::Zero(p, p);
    b_total_ = Eigen::VectorXd::Zero(p);
    for (int f = 0; f < eq.folds; ++f) {
      G_total_ += G_[static_cast<size_t>(f)];
      b_total_ += b_[static_cast<size_t>(f)];
    }
    scale_ = G_total_.diagonal().cwiseSqrt();
    for (Eigen::Index c = 0; c < p; ++c) {
      if (!(scale_(c) > 0.0)) scale_(c) = 1.0;
    }
  }

  struct Outcome {
    std::vector<double> pose_sse;       // held-out weighted squared error per pose
    std::vector<double> position_m;     // held-out position error per row, m
  };

  Outcome heldOut(const std::vector<Eigen::Index>& columns) const {
    Outcome out;
    out.pose_sse.assign(static_cast<size_t>(eq_.poses), 0.0);
    out.position_m.assign(eq_.rows.size(), 0.0);
    const Eigen::Index p = static_cast<Eigen::Index>(columns.size());
    for (int f = 0; f < eq_.folds; ++f) {
      Eigen::MatrixXd G(p, p);
      Eigen::VectorXd b(p), s(p);
      for (Eigen::Index a = 0; a < p; ++a) {
        b(a) = b_total_(columns[a]) - b_[static_cast<size_t>(f)](columns[a]);
        s(a) = scale_(columns[a]);
        for (Eigen::Index c = 0; c < p; ++c) {
          G(a, c) = G_total_(columns[a], columns[c]) - G_[static_cast<size_t>(f)](columns[a], columns[c]);
        }
      }
      const Eigen::VectorXd x = solveGram(G, b, s);
      for (int i : rows_of_fold_[static_cast<size_t>(f)]) {
        const int k = equationsOf(eq_, static_cast<size_t>(i));
        const int e0 = eq_.start[static_cast<size_t>(i)];
        Eigen::VectorXd e = r_.segment(e0, k);
        for (Eigen::Index a = 0; a < p; ++a) e -= A_.block(e0, columns[a], k, 1) * x(a);
        out.pose_sse[static_cast<size_t>(eq_.pose[static_cast<size_t>(i)])] += e.squaredNorm();
        out.position_m[static_cast<size_t>(i)] = e.head<3>().norm() / eq_.w_p;
      }
    }
    return out;
  }

  /// Fit on every row.
  Eigen::VectorXd fitAll(const std::vector<Eigen::Index>& columns) const {
    const Eigen::Index p = static_cast<Eigen::Index>(columns.size());
    Eigen::MatrixXd G(p, p);
    Eigen::VectorXd b(p), s(p);
    for (Eigen::Index a = 0; a < p; ++a) {
      b(a) = b_total_(columns[a]);
      s(a) = scale_(columns[a]);
      for (Eigen::Index c = 0; c < p; ++c) G(a, c) = G_total_(columns[a], columns[c]);
    }
    return solveGram(G, b, s);
  }

 private:
  const Eigen::MatrixXd& A_;
  const Eigen::VectorXd& r_;
  const Equations& eq_;
  std::vector<Eigen::MatrixXd> G_;
  std::vector<Eigen::VectorXd> b_;
  Eigen::MatrixXd G_total_;
  Eigen::VectorXd b_total_, scale_;
  std::vector<std::vector<int>> rows_of_fold_;
};

struct Comparison {
  double mean_reduction = 0.0;  // per pose, noise-weighted squared error
  double relative_reduction = 0.0;  // of the total held-out squared error
  double t = 0.0, p = 1.0, gain_mm = 0.0;
};

Comparison compare(const CrossValidation::Outcome& base, const CrossValidation::Outcome& with) {
  Comparison c;
  const size_t n = base.pose_sse.size();
  double sum = 0.0, sum2 = 0.0, total = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double d = base.pose_sse[i] - with.pose_sse[i];
    sum += d;
    sum2 += d * d;
    total += base.pose_sse[i];
  }
  c.mean_reduction = sum / static_cast<double>(n);
  c.relative_reduction = total > 0.0 ? sum / total : 0.0;
  const double var = (sum2 - sum * c.mean_reduction) / static_cast<double>(n - 1);
  c.t = var > 0.0 ? c.mean_reduction / std::sqrt(var / static_cast<double>(n)) : 0.0;
  c.p = upperTailP(c.t);
  double gain = 0.0;
  for (size_t i = 0; i < base.position_m.size(); ++i) gain += base.position_m[i] - with.position_m[i];
  c.gain_mm = 1e3 * gain / static_cast<double>(base.position_m.size());
  return c;
}

// ---- Residual statistics and trends -------------------------------------------------------

struct Variables {
  std::vector<std::string> names;
  std::vector<std::vector<double>> values;  // per variable, per fit row (NaN = absent)
};

Variables trendVariables(const Equations& eq, const std::vector<JointVector>& tau, int n) {
  Variables v;
  auto add = [&](const std::string& name, auto value) {
    std::vector<double> column;
    for (size_t i = 0; i < eq.rows.size(); ++i) column.push_back(value(i));
    v.names.push_back(name);
    v.values.push_back(std::move(column));
  };
  constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
  for (int j = 0; j < n; ++j) {
    add("q" + std::to_string(j + 1) + "_deg", [&](size_t i) { return kRadToDeg * eq.rows[i]->q_rad(j); });
  }
  for (int j = 0; j < n; ++j) {
    add("tau" + std::to_string(j + 1) + "_nm", [&](size_t i) { return tau[i](j); });
  }
  add("load_kg", [&](size_t i) { return eq.rows[i]->load_kg; });
  add("temp_c", [&](size_t i) { return rowTemperature(*eq.rows[i]); });
  add("seq", [&](size_t i) { return static_cast<double>(eq.rows[i]->seq); });
  return v;
}

// Cubic trend of each residual component in one variable, cross-validated against no trend.
std::optional<Comparison> trendOf(const std::vector<double>& values, const Eigen::VectorXd& r,
                                  const Equations& eq) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  size_t present = 0;
  for (double x : values) {
    if (!std::isfinite(x)) continue;
    lo = std::min(lo, x);
    hi = std::max(hi, x);
    ++present;
  }
  if (present * 10 < values.size() * 9 || !(hi - lo > 1e-9 * std::max(1.0, std::abs(hi)))) {
    return std::nullopt;
  }
  auto basis = [&](size_t row) {
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    if (!std::isfinite(values[row])) return b;
    const double x = 2.0 * (values[row] - lo) / (hi - lo) - 1.0;
    b << x, 0.5 * (3 * x * x - 1), 0.5 * (5 * x * x * x - 3 * x);  // Legendre P1..P3
    return b;
  };
  // Per fold and component: normal equations of the training rows.
  const int folds = eq.folds;
  std::vector<std::array<Eigen::Matrix3d, 6>> G(static_cast<size_t>(folds));
  std::vector<std::array<Eigen::Vector3d, 6>> b(static_cast<size_t>(folds));
  for (auto& g : G) g.fill(Eigen::Matrix3d::Zero());
  for (auto& v : b) v.fill(Eigen::Vector3d::Zero());
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const Eigen::Vector3d B = basis(i);
    const int k = equationsOf(eq, i);
    for (int c = 0; c < k; ++c) {
      G[static_cast<size_t>(eq.fold[i])][static_cast<size_t>(c)] += B * B.transpose();
      b[static_cast<size_t>(eq.fold[i])][static_cast<size_t>(c)] += B * r(eq.start[i] + c);
    }
  }
  CrossValidation::Outcome none, with;
  none.pose_sse.assign(static_cast<size_t>(eq.poses), 0.0);
  with.pose_sse = none.pose_sse;
  none.position_m.assign(eq.rows.size(), 0.0);
  with.position_m = none.position_m;
  std::vector<std::array<Eigen::Vector3d, 6>> beta(static_cast<size_t>(folds));
  for (int f = 0; f < folds; ++f) {
    for (int c = 0; c < 6; ++c) {
      Eigen::Matrix3d Gt = Eigen::Matrix3d::Zero();
      Eigen::Vector3d bt = Eigen::Vector3d::Zero();
      for (int g = 0; g < folds; ++g) {
        if (g == f) continue;
        Gt += G[static_cast<size_t>(g)][static_cast<size_t>(c)];
        bt += b[static_cast<size_t>(g)][static_cast<size_t>(c)];
      }
      beta[static_cast<size_t>(f)][static_cast<size_t>(c)] =
          Gt.trace() > 0.0 ? Eigen::Vector3d(Gt.ldlt().solve(bt)) : Eigen::Vector3d::Zero();
    }
  }
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const Eigen::Vector3d B = basis(i);
    const int k = equationsOf(eq, i);
    Eigen::Matrix<double, 6, 1> e0 = Eigen::Matrix<double, 6, 1>::Zero(), e1 = e0;
    for (int c = 0; c < k; ++c) {
      e0(c) = r(eq.start[i] + c);
      e1(c) = e0(c) - B.dot(beta[static_cast<size_t>(eq.fold[i])][static_cast<size_t>(c)]);
    }
    const size_t pose = static_cast<size_t>(eq.pose[i]);
    none.pose_sse[pose] += e0.squaredNorm();
    with.pose_sse[pose] += e1.squaredNorm();
    none.position_m[i] = e0.head<3>().norm() / eq.w_p;
    with.position_m[i] = e1.head<3>().norm() / eq.w_p;
  }
  return compare(none, with);
}

ResidualStatistics statistics(const Eigen::VectorXd& r, const Equations& eq,
                              const Variables& variables, double alpha) {
  ResidualStatistics s;
  s.rows = static_cast<int>(eq.rows.size());
  double sum_p = 0.0, sum_p2 = 0.0, sum_r2 = 0.0;
  int oriented = 0;
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const double p = r.segment<3>(eq.start[i]).norm() / eq.w_p;
    s.position_error_m.push_back(p);
    sum_p += p;
    sum_p2 += p * p;
    s.max_position_m = std::max(s.max_position_m, p);
    if (eq.rows[i]->has_orientation) {
      sum_r2 += (r.segment<3>(eq.start[i] + 3) / eq.w_r).squaredNorm();
      ++oriented;
    }
  }
  s.mean_position_m = sum_p / s.rows;
  s.rms_position_m = std::sqrt(sum_p2 / s.rows);
  s.rms_orientation_rad = oriented > 0 ? std::sqrt(sum_r2 / oriented) : 0.0;
  s.noise_ratio = std::sqrt(r.squaredNorm() / static_cast<double>(eq.count));
  int tested = 0;
  for (size_t v = 0; v < variables.names.size(); ++v) {
    const std::optional<Comparison> c = trendOf(variables.values[v], r, eq);
    if (!c) continue;
    ++tested;
    s.trends.push_back({variables.names[v], c->gain_mm, c->t, c->p, false});
  }
  for (TrendScore& t : s.trends) {
    t.significant = t.p_value < alpha / std::max(1, tested) && t.cv_gain_mm > 0.0;
  }
  std::sort(s.trends.begin(), s.trends.end(), [](const TrendScore& a, const TrendScore& b) {
    return a.t_statistic > b.t_statistic;
  });
  return s;
}

std::string trendSummary(const ResidualStatistics& s, double limit) {
  std::string out;
  for (const TrendScore& t : s.trends) {
    if (!t.significant) continue;
    char line[160];
    std::snprintf(line, sizeof line, "%s%s (a cubic trend in it removes %.4f mm held-out, t = %.1f)",
                  out.empty() ? "" : "; ", t.variable.c_str(), t.cv_gain_mm, t.t_statistic);
    out += line;
  }
  if (out.empty() && s.noise_ratio > limit) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "no tested variable; the residual is %.1f times the stated tracker noise "
                  "(scatter from pose to pose, or the noise is understated)",
                  s.noise_ratio);
    out = line;
  }
  return out;
}

// Parameters a candidate spends: its fitted ones, plus τ₀ picked from a grid.
int spentParameters(const Mechanism& m) {
  return static_cast<int>(freeParameters(m).size()) +
         (m.kind == MechanismKind::kNonlinearStiffness ? 1 : 0);
}

// The significant candidate with the largest held-out reduction, unless one with fewer
// parameters is not significantly worse (paired t < 2 on the per-pose errors): then the
// simplest such (nonlinear stiffness with a small τ₀ imitates backlash, for instance).
size_t choose(const std::vector<CandidateScore>& scores,
              const std::vector<CrossValidation::Outcome>& outcomes,
              const std::vector<size_t>& significant, size_t first) {
  auto mean_sse = [&](size_t k) {
    const auto& sse = outcomes[k - first].pose_sse;
    double sum = 0.0;
    for (double v : sse) sum += v;
    return sum;
  };
  size_t best = significant.front();
  for (size_t k : significant) {
    if (mean_sse(k) < mean_sse(best)) best = k;
  }
  size_t chosen = best;
  for (size_t k : significant) {
    const int spent = spentParameters(scores[k].mechanism);
    if (spent >= spentParameters(scores[chosen].mechanism)) continue;
    const auto& a = outcomes[k - first].pose_sse;
    const auto& b = outcomes[best - first].pose_sse;
    double sum = 0.0, sum2 = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
      sum += a[i] - b[i];
      sum2 += (a[i] - b[i]) * (a[i] - b[i]);
    }
    const double n = static_cast<double>(a.size()), mean = sum / n;
    const double var = (sum2 - sum * mean) / (n - 1.0);
    const double t = var > 0.0 ? mean / std::sqrt(var / n) : 0.0;
    if (t < 2.0) chosen = k;
  }
  return chosen;
}

std::vector<Measurement> validationRows(const Campaign& campaign) {
  std::vector<Measurement> rows;
  for (const Measurement& m : campaign.rows) {
    if (m.set == RowSet::kValidation) rows.push_back(m);
  }
  return rows;
}

}  // namespace

const char* toString(Verdict verdict) noexcept {
  switch (verdict) {
    case Verdict::kFound: return "found";
    case Verdict::kNone: return "none";
    case Verdict::kUnexplained: return "unexplained";
  }
  return "unknown";
}

Diagnosis diagnose(const Campaign& campaign, const CalibratedModel& model,
                   const DiagnoseOptions& options) {
  Diagnosis d;
  const int n = model.chain_Tracker.dof();
  std::vector<const Measurement*> fit;
  for (const Measurement& row : campaign.rows) {
    if (row.q_rad.size() != n) {
      throw InputError("row has " + std::to_string(row.q_rad.size()) +
                           " joint angles but the model's chain has " + std::to_string(n),
                       campaign.measurements_file, row.source_line);
    }
    if (row.set != RowSet::kValidation) fit.push_back(&row);
  }
  const Equations eq = makeEquations(fit, campaign.tracker, options.folds);
  if (eq.poses < 4 * options.folds) {
    throw InputError("diagnosis needs at least " + std::to_string(4 * options.folds) +
                         " fit poses (distinct pose_id outside set=validation) for " +
                         std::to_string(options.folds) + "-fold cross-validation, got " +
                         std::to_string(eq.poses),
                     campaign.directory + "/" + campaign.measurements_file);
  }
  d.fit_rows = static_cast<int>(fit.size());
  d.fit_poses = eq.poses;
  d.folds = options.folds;

  // 1. The physical model refitted jointly; what it gets wrong.
  auto clock = std::chrono::steady_clock::now();
  JointVector compliance_sigma = model.compliance_sigma_rad_per_nm.size() == n
                                     ? model.compliance_sigma_rad_per_nm
                                     : JointVector(JointVector::Zero(n));
  RefitResult current = refit(physicalModelOf(model), eq, options.refit_iterations,
                              &compliance_sigma);
  d.seconds_refit += secondsSince(clock);
  std::vector<JointVector> tau;
  residuals(current.model, eq, &tau);
  const Variables variables = trendVariables(eq, tau, n);
  d.variable_names = variables.names;
  d.variable_values = variables.values;
  clock = std::chrono::steady_clock::now();
  d.before = statistics(current.r, eq, variables, options.family_alpha);
  d.seconds_trends += secondsSince(clock);

  // 2. Candidates, round by round.
  for (int round = 1; round <= options.max_mechanisms; ++round) {
    clock = std::chrono::steady_clock::now();
    residuals(current.model, eq, &tau);
    std::vector<UntestableCandidate> untestable;
    std::vector<Candidate> candidates = catalogue(current.model, eq, tau, options, untestable);
    const std::vector<Parameter> base_params = modelParameters(current.model);
    const Eigen::MatrixXd base = jacobian(current.model, eq, current.r, base_params);
    const Eigen::MatrixXd A =
        candidateColumns(current.model, eq, current.r, base, candidates, untestable);
    if (round == 1) d.untestable = untestable;
    const CrossValidation cv(A, current.r, eq);
    std::vector<Eigen::Index> base_columns(static_cast<size_t>(base.cols()));
    for (Eigen::Index c = 0; c < base.cols(); ++c) base_columns[static_cast<size_t>(c)] = c;
    const CrossValidation::Outcome without = cv.heldOut(base_columns);

    std::vector<CrossValidation::Outcome> outcomes;
    std::vector<size_t> significant;  // indices into d.candidates
    const size_t first = d.candidates.size();
    for (const Candidate& c : candidates) {
      std::vector<Eigen::Index> columns = base_columns;
      for (int k = 0; k < c.columns; ++k) columns.push_back(c.first_column + k);
      outcomes.push_back(cv.heldOut(columns));
      const Comparison cmp = compare(without, outcomes.back());
      const Eigen::VectorXd x = cv.fitAll(columns);
      CandidateScore score;
      score.mechanism = c.mechanism;
      for (size_t k = 0; k < c.free.size(); ++k) {
        score.mechanism.parameters[static_cast<size_t>(c.free[k])] =
            x(base.cols() + static_cast<Eigen::Index>(k));
      }
      score.round = round;
      score.cv_gain_mm = cmp.gain_mm;
      score.relative_reduction = cmp.relative_reduction;
      score.t_statistic = cmp.t;
      score.p_value = cmp.p;
      score.significant = cmp.p < options.family_alpha / static_cast<double>(candidates.size()) &&
                          cmp.relative_reduction >= options.min_relative_reduction;
      if (score.significant) significant.push_back(d.candidates.size());
      d.candidates.push_back(std::move(score));
    }
    d.seconds_screening += secondsSince(clock);
    if (significant.empty()) break;
    const size_t best = choose(d.candidates, outcomes, significant, first);
    CandidateScore& chosen = d.candidates[best];
    chosen.chosen = true;

    clock = std::chrono::steady_clock::now();
    // From zero: the first Gauss–Newton step is the linear fit, base parameters included.
    PhysicalModel extended = current.model;
    Mechanism added = chosen.mechanism;
    for (int i : freeParameters(added)) {
      if (!(added.kind == MechanismKind::kNonlinearStiffness && i == 1)) {
        added.parameters[static_cast<size_t>(i)] = 0.0;
      }
    }
    extended.mechanisms.push_back(added);
    current = refit(std::move(extended), eq, options.refit_iterations, &compliance_sigma);
    d.seconds_refit += secondsSince(clock);
    d.effects.push_back({current.model.mechanisms.back(), round, chosen.cv_gain_mm,
                         chosen.t_statistic, chosen.p_value});
  }
  // Parameters and σ of every effect from the last refit.
  const size_t base_mechanisms = model.mechanisms.size();
  for (size_t k = 0; k < d.effects.size(); ++k) {
    d.effects[k].mechanism = current.model.mechanisms[base_mechanisms + k];
  }

  // 3. Verdict.
  clock = std::chrono::steady_clock::now();
  residuals(current.model, eq, &tau);
  const Variables after_variables = trendVariables(eq, tau, n);
  d.after = statistics(current.r, eq, after_variables, options.family_alpha);
  d.seconds_trends += secondsSince(clock);
  const std::string remaining = trendSummary(d.after, options.noise_ratio_limit);
  if (!d.effects.empty()) {
    d.verdict = Verdict::kFound;
    d.unexplained_trend = remaining;
  } else if (!remaining.empty()) {
    d.verdict = Verdict::kUnexplained;
    d.unexplained_trend = remaining;
  }

  // 4. The extended model with its GPR, and the gain on validation rows.
  clock = std::chrono::steady_clock::now();
  CalibratedModel& ext = d.extended_model;
  ext = model;
  ext.chain_Tracker = current.model.chain_Tracker;
  ext.mechanisms = current.model.mechanisms;
  if (model.compliance_rad_per_nm.size() == n) {
    ext.compliance_rad_per_nm = current.model.compliance_rad_per_nm;
    ext.compliance_sigma_rad_per_nm = compliance_sigma;
  }
  std::vector<const Measurement*> gpr_rows = campaign.rowsIn(RowSet::kResidual);
  std::string gpr_set = "residual";
  if (gpr_rows.empty()) {
    gpr_rows = campaign.rowsIn(RowSet::kGeometry);
    gpr_set = "geometry";
  }
  const PoseModel after = physicalPoseModel(current.model);
  const ResidualModel residual = fitResidual(after, gpr_rows, gpr_set, options.calibration);
  ext.gpr = residual.gp.parameters();
  d.seconds_gpr = secondsSince(clock);

  clock = std::chrono::steady_clock::now();
  const std::vector<Measurement> validation = validationRows(campaign);
  d.validation_rows = static_cast<int>(validation.size());
  d.floor_position_m = noiseFloorMean(campaign.tracker.position_sigma_m);
  if (!validation.empty()) {
    const auto base_layers = modelLayers(model);
    const PoseModel before = physicalPoseModel(physicalModelOf(model));
    const bool has_gpr = model.gpr.has_value();
    d.gpr_method = has_gpr ? base_layers.back().first : "";
    const auto s_before = summarize("before", before, validation);
    const auto s_after = summarize(kMethodExtended, after, validation);
    const auto s_after_gpr = summarize(kMethodExtendedGpr, withResidual(after, residual.gp), validation);
    std::vector<AccuracySummary> s_gpr;
    if (has_gpr) s_gpr = summarize(d.gpr_method, base_layers.back().second, validation);
    for (size_t g = 0; g < s_before.size(); ++g) {
      GainRow row;
      row.load_kg = s_before[g].load_kg;
      row.rows = s_before[g].rows;
      row.before = s_before[g];
      row.after = s_after[g];
      row.after_gpr = s_after_gpr[g];
      if (has_gpr) row.gpr = s_gpr[g];
      d.gain.push_back(row);
    }
    ext.provenance.validation.clear();
    for (const auto& [method, layer] : modelLayers(ext)) {
      for (const AccuracySummary& s : summarize(method, layer, validation)) {
        ext.provenance.validation.push_back({s.method, s.load_kg, s.rows, s.mean_position_m,
                                             s.max_position_m, s.mean_orientation_rad});
      }
    }
  }
  d.seconds_evaluation = secondsSince(clock);
  return d;
}

}  // namespace stepcal::trainer
