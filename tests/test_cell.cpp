// The cell around the calibrated robot (trainer/cell.hpp, docs/cell.md): the TCP fits and the
// work-object fits against closed forms, then on the twin: a true tool 0.3 m beyond the target,
// found from tracker shots and from four-point touches, and a work object touched with that TCP
// or measured by the tracker, each against the twin's truth and within its stated σ.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <cstdio>
#include <random>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/trainer/cell.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal {
namespace {

using trainer::FrameFit;
using trainer::FramePoint;
using trainer::ToolPointFit;

Pose poseOf(const Vec3& p_m, const Vec3& axis, double angle_rad) {
  Pose X = Pose::Identity();
  X.linear() = Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
  X.translation() = p_m;
  return X;
}

/// Orientations 35° apart about x, y and z and between: what a four-point routine asks for.
std::vector<Mat3> touchOrientations() {
  const double a = 35.0 * kRadPerDeg;
  std::vector<Mat3> R = {Mat3::Identity()};
  for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(-1, 0, 0), Vec3(0, -1, 0),
                           Vec3(1, 1, 0), Vec3(0, 0, 1)}) {
    R.push_back(Eigen::AngleAxisd(a, axis.normalized()).toRotationMatrix());
  }
  return R;
}

// Exact data: the four-point fit returns the TCP and the touched point to rounding, with no
// residual, and says nothing.
TEST(ToolFit, FourPointExact) {
  const Vec3 t(0.04, -0.03, 0.56), p_fixed(1.2, 0.3, 0.4);
  std::vector<Pose> X;
  for (const Mat3& R : touchOrientations()) {
    Pose x = Pose::Identity();
    x.linear() = R * Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    x.translation() = p_fixed - x.linear() * t;
    X.push_back(x);
  }
  const ToolPointFit fit = trainer::fitToolFromFixedPoint(X, 0.0);
  EXPECT_LT((fit.p_TcpInTip_m - t).norm(), 1e-12);
  EXPECT_LT((fit.p_FixedInTracker_m - p_fixed).norm(), 1e-12);
  EXPECT_LT(fit.rms_residual_m, 1e-12);
  EXPECT_EQ(fit.redundancy, 3 * int(X.size()) - 6);
  EXPECT_TRUE(fit.well_conditioned) << fit.note;
  EXPECT_GT(fit.least_spread_rad, 30.0 * kRadPerDeg);
}

// Two orientations θ apart about one axis: the closed form of the spread across it is θ
// (sin²(θ/2) = λ/N); about one axis alone the TCP along that axis is not determined, a result
// that says so, and 8° apart is flagged as too similar with the σ along the weak direction.
TEST(ToolFit, FourPointSaysWhenOrientationsAreTooSimilar) {
  const Vec3 t(0.0, 0.0, 0.3);
  const auto touches = [&](const std::vector<Mat3>& R) {
    std::vector<Pose> X;
    for (const Mat3& r : R) {
      Pose x = Pose::Identity();
      x.linear() = r;
      x.translation() = Vec3(1, 0, 0.5) - r * t;
      X.push_back(x);
    }
    return X;
  };
  std::vector<Mat3> about_z;
  for (int k = 0; k < 5; ++k) about_z.push_back(Eigen::AngleAxisd(0.4 * k, Vec3::UnitZ()).toRotationMatrix());
  const ToolPointFit flat = trainer::fitToolFromFixedPoint(touches(about_z), 1e-5);
  EXPECT_FALSE(flat.well_conditioned);
  EXPECT_NE(flat.note.find("not determined"), std::string::npos) << flat.note;
  EXPECT_NEAR(std::abs(flat.least_spread_direction.z()), 1.0, 1e-9);

  std::vector<Mat3> close;
  for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)}) {
    close.push_back(Mat3::Identity());
    close.push_back(Eigen::AngleAxisd(8.0 * kRadPerDeg, axis).toRotationMatrix());
  }
  const ToolPointFit near = trainer::fitToolFromFixedPoint(touches(close), 1e-5);
  EXPECT_FALSE(near.well_conditioned);
  EXPECT_NE(near.note.find("differ by only"), std::string::npos) << near.note;
  EXPECT_LT((near.p_TcpInTip_m - t).norm(), 1e-9);  // exact data: still the right answer

  // Closed form: two orientations 50° apart about x give a spread of 50° (across x).
  std::vector<Mat3> two = {Mat3::Identity(), Eigen::AngleAxisd(50 * kRadPerDeg, Vec3::UnitX()).toRotationMatrix()};
  std::vector<Pose> X = touches(two);
  const ToolPointFit tracker = trainer::fitToolFromTracker(X, {Vec3(1, 0, 0.5), Vec3(1, 0, 0.5)}, 1e-5);
  EXPECT_NEAR(tracker.least_spread_rad, 0.0, 1e-6);  // along x nothing varies
  EXPECT_LT((tracker.p_TcpInTip_m - t).norm(), 1e-12);  // a tracker shot needs no spread
}

// Noisy tracker shots: the TCP's error against its σ over many draws (a χ² check of the stated
// covariance: the mean squared standardised error of 3 components is 3 within its spread).
TEST(ToolFit, TrackerSigmaMatchesTheScatter) {
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, 20e-6);
  const Vec3 t(0.01, 0.02, 0.3);
  double chi2 = 0.0;
  const int draws = 400;
  for (int d = 0; d < draws; ++d) {
    std::vector<Pose> X;
    std::vector<Vec3> p;
    for (const Mat3& R : touchOrientations()) {
      Pose x = Pose::Identity();
      x.linear() = R;
      x.translation() = Vec3(1, 0.1 * d / draws, 0.5);
      X.push_back(x);
      p.push_back(x * t + Vec3(noise(random), noise(random), noise(random)));
    }
    const ToolPointFit fit = trainer::fitToolFromTracker(X, p, 0.0);
    const Vec3 e = fit.p_TcpInTip_m - t;
    chi2 += e.dot(fit.covariance_TcpInTip_m2.inverse() * e);
  }
  // 400 draws of a χ²₃ scaled by s²/σ² (s on 18 degrees of freedom): mean near 3·18/16 = 3.4;
  // a covariance off by a factor 2 gives 1.7 or 6.8.
  EXPECT_GT(chi2 / draws, 2.5);
  EXPECT_LT(chi2 / draws, 4.5);
}

// Exact points: the three-point frame and the fiducial fit return the frame; points on a line
// give a frame-less result that says so.
TEST(FrameFit, ThreePointsAndFiducialsExact) {
  const Pose X_true = poseOf(Vec3(1.5, -0.2, 0.3), Vec3(0.3, -0.2, 1.0), 0.8);
  const std::vector<Vec3> nominal = {Vec3(0, 0, 0), Vec3(0.4, 0, 0), Vec3(0.1, 0.3, 0),
                                     Vec3(0.4, 0.3, 0.02)};
  std::vector<FramePoint> points;
  for (const Vec3& n : nominal) points.push_back({X_true * n, Mat3::Zero()});
  const FrameFit three = trainer::fitFrameFromThreePoints(points[0], points[1], points[2], 1e-5, Mat3::Zero());
  EXPECT_TRUE(three.note.empty()) << three.note;
  EXPECT_LT((three.X_TrackerFrame.matrix() - X_true.matrix()).norm(), 1e-12);
  // σ of the origin is the point's σ (the origin is a touched point).
  EXPECT_NEAR(std::sqrt(three.covariance(0, 0)), 1e-5, 1e-8);
  const FrameFit fitted = trainer::fitFrameToFiducials(points, nominal, 1e-5, Mat3::Zero());
  EXPECT_LT((fitted.X_TrackerFrame.matrix() - X_true.matrix()).norm(), 1e-12);
  EXPECT_LT(fitted.rms_residual_m, 1e-12);
  const std::vector<Vec3> on_line = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0.3, 0, 0)};
  std::vector<FramePoint> line_points;
  for (const Vec3& n : on_line) line_points.push_back({X_true * n, Mat3::Zero()});
  EXPECT_FALSE(trainer::fitFrameFromThreePoints(line_points[0], line_points[1], line_points[2],
                                                1e-5, Mat3::Zero()).note.empty());
  EXPECT_FALSE(trainer::fitFrameToFiducials(line_points, on_line, 1e-5, Mat3::Zero()).note.empty());
}

// ---- On the twin ----

struct TwinCell {
  twin::TwinOptions options;
  Campaign campaign;
  std::unique_ptr<const runtime::RuntimeModel> model;
};

const TwinCell& twinCell(uint64_t seed) {
  static std::map<uint64_t, TwinCell> cells;
  auto found = cells.find(seed);
  if (found != cells.end()) return found->second;
  TwinCell c;
  c.options.seed = seed;
  c.campaign = twin::simulateCampaign(c.options, nullptr);
  c.model = runtime::RuntimeModel::fromModel(
      trainer::modelFromOutcome(c.campaign, trainer::calibrateCampaign(c.campaign)), seed);
  return cells.emplace(seed, std::move(c)).first->second;
}

/// The true TCP: 0.3 m beyond the twin's true target and turned 23° (docs/runtime.md's tool).
const Pose kTargetTcp = poseOf(Vec3(0.0, 0.0, 0.3), Vec3(1, 1, 0), 0.4);

/// What an operator's jog does: joints at which the TRUE TCP sits at p (tracker frame, within
/// 1 µm) with the orientation R, found with the model's inverse (turning from R_from in steps,
/// each from the last one's joints) and corrected on the truth.
JointVector jogTo(const TwinCell& c, const twin::TwinRobot& truth, const Vec3& p, const Mat3& R_from,
                  const Mat3& R, const JointVector& seed) {
  runtime::Workspace ws = runtime::makeWorkspace(*c.model);
  runtime::CallTerms terms;
  terms.X_Tool = kTargetTcp;
  Pose desired = Pose::Identity();
  desired.translation() = p;
  const Vec3 turn = lie::logSO3(R_from.transpose() * R);
  JointVector q = seed;
  constexpr int kSteps = 4, kCorrections = 3;
  for (int pass = 1; pass <= kSteps + kCorrections; ++pass) {
    desired.linear() = R_from * lie::expSO3(turn * std::min(1.0, double(pass) / kSteps));
    terms.wrench_Sensor = truth.sensorReading(q, 0.0);
    const runtime::InverseResult inverse = runtime::solveInverse(
        *c.model, ws, desired, terms, runtime::kUnknownTemperature_c, q,
        runtime::Clock::time_point::max());
    EXPECT_TRUE(inverse.status == runtime::Status::kOk ||
                inverse.status == runtime::Status::kOutOfDomain)
        << runtime::toString(inverse.status) << " at pass " << pass;
    q = inverse.q_target_rad;
    if (pass >= kSteps) desired.translation() += p - truth.X_TrackerTip(q, 0.0) * kTargetTcp.translation();
  }
  EXPECT_LT((truth.X_TrackerTip(q, 0.0) * kTargetTcp.translation() - p).norm(), 1e-6);
  return q;
}

/// Joints with the arm mid-range and the wrist away from its singularity: where the touches are.
JointVector touchHome() {
  JointVector q(6);
  q << 0.1, 0.3, 0.2, 0.2, -0.9, 0.3;
  return q;
}

/// The calibrated model's target at joints q under the unloaded robot's sensor reading.
Pose modelTarget(const TwinCell& c, const twin::TwinRobot& truth, const JointVector& q) {
  runtime::Workspace ws = runtime::makeWorkspace(*c.model);
  return runtime::correctForward(*c.model, ws, q, truth.sensorReading(q, 0.0),
                                 runtime::kUnknownTemperature_c)
      .X_TrackerTip;
}

/// Mean error of the fitted TCP against the true one over the campaign's validation poses
/// (unloaded), and that of the runtime's route from the flange with the TRUE flange-to-TCP
/// transform (docs/runtime.md: 0.012–0.28 mm over 8 seeds).
struct TcpErrors {
  double fitted_m = 0, from_flange_m = 0;
};
TcpErrors tcpErrors(const TwinCell& c, const twin::TwinRobot& truth, const Vec3& p_TcpInTip) {
  runtime::Workspace ws = runtime::makeWorkspace(*c.model);
  const auto rows = c.campaign.rowsIn(RowSet::kValidation);
  // The twin's flange hangs at the nominal place on its deflected joint-6 frame, rigid with
  // the target: the true X_FlangeTcp is one transform.
  const JointVector& q0 = rows.front()->q_rad;
  ChainWorkspace chain;
  truth.deflectedFrames(q0, 0.0, twin::kNoThermalExpansion, chain);
  const Pose X_true_flange = truth.X_TrackerBase() * chain.X_RootFrame[size_t(q0.size())] *
                             c.model->X_LastFlange_nominal;
  const Pose X_FlangeTcp = X_true_flange.inverse() * truth.X_TrackerTip(q0, 0.0) * kTargetTcp;
  TcpErrors e;
  for (const Measurement* row : rows) {
    const Vec3 p_true = truth.X_TrackerTip(row->q_rad, 0.0) * kTargetTcp.translation();
    runtime::CallTerms terms;
    terms.wrench_Sensor = truth.sensorReading(row->q_rad, 0.0);
    e.fitted_m += (runtime::correctForward(*c.model, ws, row->q_rad, terms, runtime::kUnknownTemperature_c)
                       .X_TrackerTip * p_TcpInTip - p_true).norm();
    terms.tool_from = runtime::ToolFrom::kFlange;
    terms.X_Tool = X_FlangeTcp;
    e.from_flange_m += (runtime::correctForward(*c.model, ws, row->q_rad, terms, runtime::kUnknownTemperature_c)
                            .X_FrameTcp.translation() - p_true).norm();
  }
  e.fitted_m /= double(rows.size());
  e.from_flange_m /= double(rows.size());
  return e;
}

constexpr double kTouchSigma_m = 0.02e-3;    // an operator's touch: 0.02 mm per axis
constexpr double kTrackerSigma_m = 0.015e-3;  // the twin's tracker

struct ToolOnTwin {
  ToolPointFit tracker, four_point;
  TcpErrors tracker_errors, four_point_errors;
  JointVector q0;
  Mat3 R0;
};

ToolOnTwin toolOnTwin(uint64_t seed) {
  const TwinCell& c = twinCell(seed);
  const twin::TwinRobot truth(c.options);
  std::mt19937 random(uint32_t(seed) + 100);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto rows = c.campaign.rowsIn(RowSet::kValidation);
  ToolOnTwin out;
  // Tracker shots at the TCP in 8 validation poses, unloaded.
  std::vector<Pose> X;
  std::vector<Vec3> p;
  for (size_t i = 0; i < rows.size() && X.size() < 8; i += rows.size() / 8) {
    const JointVector& q = rows[i]->q_rad;
    X.push_back(modelTarget(c, truth, q));
    p.push_back(truth.X_TrackerTip(q, 0.0) * kTargetTcp.translation() +
                kTrackerSigma_m * Vec3(normal(random), normal(random), normal(random)));
  }
  out.tracker = trainer::fitToolFromTracker(X, p, 0.0);
  out.tracker_errors = tcpErrors(c, truth, out.tracker.p_TcpInTip_m);
  // Four-point: one fixed point touched in 7 orientations 35° apart.
  out.q0 = touchHome();
  const Pose X_tcp0 = truth.X_TrackerTip(out.q0, 0.0) * kTargetTcp;
  out.R0 = X_tcp0.linear();
  X.clear();
  for (const Mat3& R : touchOrientations()) {
    const Vec3 off = kTouchSigma_m * Vec3(normal(random), normal(random), normal(random));
    X.push_back(modelTarget(c, truth, jogTo(c, truth, X_tcp0.translation() + off, out.R0, out.R0 * R, out.q0)));
  }
  out.four_point = trainer::fitToolFromFixedPoint(X, 0.0);
  out.four_point_errors = tcpErrors(c, truth, out.four_point.p_TcpInTip_m);
  return out;
}

// The TCP from 8 tracker shots and from 7 four-point touches (0.02 mm touch scatter), over 4
// seeds: its error over the validation poses against the truth, beside the runtime's route
// from the flange with the true tool data; printed for docs/cell.md.
TEST(CellOnTwin, ToolFromTrackerAndFourPoint) {
  for (const uint64_t seed : {1, 2, 3, 4}) {
    const ToolOnTwin t = toolOnTwin(seed);
    const Vec3 e_tracker = t.tracker.p_TcpInTip_m - kTargetTcp.translation();
    const Vec3 e_four = t.four_point.p_TcpInTip_m - kTargetTcp.translation();
    std::printf("seed %d: TCP mean error over the validation poses: tracker %.4f mm (sigma %.4f), "
                "four-point %.4f mm (sigma %.4f, residual rms %.4f, spread %.1f deg); from the "
                "flange with the true tool data %.4f mm\n",
                int(seed), t.tracker_errors.fitted_m * 1e3,
                std::sqrt(t.tracker.covariance_TcpInTip_m2.trace()) * 1e3,
                t.four_point_errors.fitted_m * 1e3,
                std::sqrt(t.four_point.covariance_TcpInTip_m2.trace()) * 1e3,
                t.four_point.rms_residual_m * 1e3, t.four_point.least_spread_rad / kRadPerDeg,
                t.tracker_errors.from_flange_m * 1e3);
    EXPECT_TRUE(t.four_point.well_conditioned) << t.four_point.note;
    EXPECT_LT(t.tracker_errors.fitted_m, 0.03e-3);
    EXPECT_LT(t.four_point_errors.fitted_m, 0.1e-3);
    // Against its σ: the model's target frame itself is off the twin's by its accuracy
    // (0.005–0.013 mm at 0.3 m, docs/runtime.md), hence the floor.
    for (int a = 0; a < 3; ++a) {
      EXPECT_LT(std::abs(e_tracker[a]), 3 * std::sqrt(t.tracker.covariance_TcpInTip_m2(a, a)) + 0.02e-3);
      EXPECT_LT(std::abs(e_four[a]), 3 * std::sqrt(t.four_point.covariance_TcpInTip_m2(a, a)) + 0.02e-3);
    }
  }
}

}  // namespace
}  // namespace stepcal
