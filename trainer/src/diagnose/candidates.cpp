#include "candidates.hpp"

#include <algorithm>
#include <numeric>
#include <cmath>
#include <iterator>
#include <utility>

#include "families/families.hpp"
#include "profiles.hpp"
#include "screening_columns.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// A candidate whose largest column moves the weighted residual by less than this, for a
// parameter step of typical size, has no effect on these rows and is not tried.
constexpr double kNegligibleEffect = 1e-3;

}  // namespace

double modelWeightTorque(const PhysicalModel& whole, const std::vector<double>& masses,
                         const JointVector& theta_rad, int joint) {
  if (masses.empty()) return 0.0;
  ChainWorkspace ws;
  JointVector tau;
  forwardKinematics(whole.chain_Tracker, theta_rad, ws);
  selfWeightTorques(whole.chain_Tracker, ws, whole.gravity_Tracker, masses, tau);
  return tau(joint);
}

namespace {

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
  for (const VariableScaled& v : recipe.variable_scaled) {
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Index e_i = fit.start[i] - first, k = fit.equations(i);
      chunk.dense.block(e_i, v.dense, k, 1) =
          lin.geometry.block(e_i, v.geometry, k, 1) * v.variable->function(v.function, i);
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
      width = std::max(width, source.first + (source.isProfile() ? 2 * source.order : 1));
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
          case ScaledSource::Kind::kConfounder:
            out(r, source.first) = source.variable->function(source.function, i);
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
          case ScaledSource::Kind::kProfileTorque: {
            harmonics.resize(2 * source.order);
            profileFeatures(source.coverage, source.order, fit.rows[i]->q_rad(joint), harmonics.data());
            const double weight = modelWeightTorque(recipe.whole, source.self_weight_masses,
                                                    e.theta_rad[static_cast<size_t>(r)], joint);
            const double tau = source.weight_part
                                   ? weight
                                   : e.tau_nm[static_cast<size_t>(r)](joint) - weight;
            out.row(r).segment(source.first, 2 * source.order) =
                harmonics.transpose() * (tau / source.torque_scale_nm);
            break;
          }
        }
      }
    }
  }
}

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

namespace {

// Stage 1: geometry, then the global model's fitted parameters; their values (kept for the
// lumped masses' prior) returned.
std::vector<double> stage1Columns(const DiagnosisModel& model, const PhysicalModel& whole,
                                  Eigen::Index geometry, ColumnSink& sink, Screening& s) {
  const PhysicalModel& global = model.global;
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
        p.mechanism < 0 ? global.compliance_rad_per_nm(p.index)
                        : global.mechanisms[static_cast<size_t>(p.mechanism)].parameter(p.index));
  }
  return stage1_values;
}

// Stage 2: the geometry's change that goes with the profiles (every fit row lies inside every
// profile's gate, so its columns are the geometry's; their ridges come with the Grams,
// completeScreening), then the current profiles at the highest order.
void stage2Columns(const DiagnosisModel& model, Eigen::Index geometry, int max_order,
                   ColumnSink& sink, Screening& s) {
  const int n = model.global.chain_Tracker.dof();
  for (Eigen::Index c = 0; c < geometry; ++c) s.stage2.push_back(sink.repeat(c, 0.0));
  for (const Profile& p : model.profiles) {
    Family f;
    f.stage = Stage::kProfile;
    f.mechanism = blank(MechanismKind::kTransmissionError, n, p.mechanism.joint, -1,
                        std::max(max_order, p.mechanism.order));
    f.mechanism.coverage = p.mechanism.coverage;
    f.columns = sink.profile(f.mechanism.joint, f.mechanism.coverage, f.mechanism.order);
    s.profiled.push_back(std::move(f));
  }
}

}  // namespace

Screening screening(const DiagnosisModel& model, const FitRows& fit, const Evaluation& start,
                    const DiagnoseOptions& options,
                    const std::optional<std::vector<double>>& body_masses,
                    const ScreeningScope& scope) {
  // Columns are changes of the whole model (its global mechanisms come first in it, so a
  // parameter indexes both alike); what is present is asked of the global part.
  const PhysicalModel whole = model.combined();
  const int n = model.global.chain_Tracker.dof();
  Screening s;
  const Eigen::Index geometry = 6 * (n + 1);
  auto recipe = std::make_shared<ColumnRecipe>();
  recipe->whole = whole;
  ColumnSink sink(s.columns.layout, *recipe, geometry, n);

  const std::vector<double> stage1_values = stage1Columns(model, whole, geometry, sink, s);
  const int max_order =
      *std::max_element(options.profile_orders.begin(), options.profile_orders.end());
  stage2Columns(model, geometry, max_order, sink, s);
  // Every kind's families, in the registry's order (families/).
  const FamilyContext context{model, model.global, whole, fit,  start,  options, body_masses, scope,
                              n,     max_order,    s,     sink, *recipe};
  for (const FamilyBuilder build : familyBuilders()) build(context);

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
