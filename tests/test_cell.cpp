// The cell around the calibrated robot (trainer/cell.hpp, docs/cell.md): the TCP fits and the
// work-object fits against closed forms, then on the twin: a true tool 0.3 m beyond the target,
// found from tracker shots and from four-point touches, its axes from a 6-D target at it, and a
// work object touched with that TCP or measured by the tracker, each against the twin's truth and
// within its stated σ.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <cstdio>
#include <filesystem>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>

#include "stepcal/common/lie.hpp"
#include "stepcal/report/text_format.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/trainer/cell.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/command.hpp"
#include "support/files.hpp"

namespace stepcal {
namespace {

using trainer::FrameFit;
using trainer::FramePoint;
using trainer::ToolPointFit;
using report::format;

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
  EXPECT_GT(std::sqrt(flat.covariance_TcpInTip_m2(2, 2)), 1.0);  // metres: not determined
  EXPECT_LT(std::sqrt(flat.covariance_TcpInTip_m2(0, 0)), 1e-4);  // across z it is

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
  std::printf("mean chi2: %.2f (3 parameters)\n", chi2 / draws);
  EXPECT_GT(chi2 / draws, 2.5);
  EXPECT_LT(chi2 / draws, 4.5);
}

// Noisy four-point touches and noisy fiducials: each fit's error against its stated covariance
// over many draws (the mean of e' Σ⁻¹ e is the dimension, 3 and 6, within its spread; the σ
// here is the residuals' own, so a little above: s² on ν degrees of freedom).
TEST(ToolFit, FourPointAndFrameSigmaMatchTheScatter) {
  std::mt19937 random(11);
  std::normal_distribution<double> noise(0.0, 20e-6);
  const Vec3 t(0.04, -0.03, 0.56), p_fixed(1.2, 0.3, 0.4);
  const Pose X_frame = poseOf(Vec3(1.5, -0.2, 0.3), Vec3(0.3, -0.2, 1.0), 0.8);
  const std::vector<Vec3> nominal = {Vec3(0, 0, 0), Vec3(0.4, 0, 0), Vec3(0.1, 0.3, 0),
                                     Vec3(0.4, 0.3, 0.02), Vec3(0.2, 0.1, -0.01), Vec3(0.3, 0.2, 0.0)};
  double chi2_tool = 0.0, chi2_frame = 0.0;
  const int draws = 400;
  for (int d = 0; d < draws; ++d) {
    std::vector<Pose> X;
    for (const Mat3& R : touchOrientations()) {
      Pose x = Pose::Identity();
      x.linear() = R;
      x.translation() = p_fixed - R * t + Vec3(noise(random), noise(random), noise(random));
      X.push_back(x);
    }
    const ToolPointFit fit = trainer::fitToolFromFixedPoint(X, 0.0);
    const Vec3 e = fit.p_TcpInTip_m - t;
    chi2_tool += e.dot(fit.covariance_TcpInTip_m2.inverse() * e);
    std::vector<FramePoint> points;
    for (const Vec3& n : nominal) {
      points.push_back({X_frame * n + Vec3(noise(random), noise(random), noise(random)), Mat3::Zero()});
    }
    const FrameFit frame = trainer::fitFrameToFiducials(points, nominal, 0.0, Mat3::Zero());
    Vec6 ef;
    ef.head<3>() = frame.X_TrackerFrame.linear().transpose() *
                   (X_frame.translation() - frame.X_TrackerFrame.translation());
    ef.tail<3>() = lie::logSO3(frame.X_TrackerFrame.linear().transpose() * X_frame.linear());
    chi2_frame += ef.dot(frame.covariance.inverse() * ef);
  }
  // Tool: ν = 15, E = 3 · 15/13 = 3.5; frame: ν = 12, E = 6 · 12/10 = 7.2. A covariance off by
  // a factor 2 gives half or twice these.
  std::printf("mean chi2: tool %.2f (3 parameters), frame %.2f (6)\n", chi2_tool / draws,
              chi2_frame / draws);
  EXPECT_GT(chi2_tool / draws, 2.6);
  EXPECT_LT(chi2_tool / draws, 4.6);
  EXPECT_GT(chi2_frame / draws, 5.4);
  EXPECT_LT(chi2_frame / draws, 9.2);
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
JointVector jogTo(const runtime::RuntimeModel& model, const twin::TwinRobot& truth, const Vec3& p,
                  const Mat3& R_from, const Mat3& R, const JointVector& seed) {
  runtime::Workspace ws = runtime::makeWorkspace(model);
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
        model, ws, desired, terms, runtime::kUnknownTemperature_c, q,
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
Pose modelTarget(const runtime::RuntimeModel& model, const twin::TwinRobot& truth,
                 const JointVector& q) {
  runtime::Workspace ws = runtime::makeWorkspace(model);
  return runtime::correctForward(model, ws, q, truth.sensorReading(q, 0.0),
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

ToolOnTwin fitToolOnTwin(uint64_t seed) {
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
    X.push_back(modelTarget(*c.model, truth, q));
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
    X.push_back(modelTarget(*c.model, truth, jogTo(*c.model, truth, X_tcp0.translation() + off, out.R0, out.R0 * R, out.q0)));
  }
  out.four_point = trainer::fitToolFromFixedPoint(X, 0.0);
  out.four_point_errors = tcpErrors(c, truth, out.four_point.p_TcpInTip_m);
  return out;
}

const ToolOnTwin& toolOnTwin(uint64_t seed) {
  static std::map<uint64_t, ToolOnTwin> tools;
  auto found = tools.find(seed);
  if (found == tools.end()) found = tools.emplace(seed, fitToolOnTwin(seed)).first;
  return found->second;
}

// The TCP from 8 tracker shots and from 7 four-point touches (0.02 mm touch scatter), over 4
// seeds: its error over the validation poses against the truth, beside the runtime's route
// from the flange with the true tool data; printed for docs/cell.md.
TEST(CellOnTwin, ToolFromTrackerAndFourPoint) {
  for (const uint64_t seed : {1, 2, 3, 4}) {
    const ToolOnTwin& t = toolOnTwin(seed);
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

// The TCP's axes from a 6-D target at it (the twin's tracker: 0.01° per axis) in 8 validation
// poses, over 4 seeds: within 3σ of the true 23° turn (plus a floor: the model's own target
// orientation error, which no row's scatter carries: 0.001°); printed for docs/cell.md.
TEST(CellOnTwin, ToolAxesMeasuredWithinTheirSigma) {
  constexpr double kTrackerSigma_rad = 0.01 * kRadPerDeg;
  for (const uint64_t seed : {1, 2, 3, 4}) {
    const TwinCell& c = twinCell(seed);
    const twin::TwinRobot truth(c.options);
    std::mt19937 random(uint32_t(seed) + 200);
    std::normal_distribution<double> normal(0.0, 1.0);
    const auto rows = c.campaign.rowsIn(RowSet::kValidation);
    std::vector<Pose> X;
    std::vector<Mat3> R_measured;
    for (size_t i = 0; i < rows.size() && X.size() < 8; i += rows.size() / 8) {
      const JointVector& q = rows[i]->q_rad;
      X.push_back(modelTarget(*c.model, truth, q));
      const Vec3 noise = kTrackerSigma_rad * Vec3(normal(random), normal(random), normal(random));
      R_measured.push_back(truth.X_TrackerTip(q, 0.0).linear() * kTargetTcp.linear() *
                           lie::expSO3(noise));
    }
    const trainer::ToolOrientationFit fit =
        trainer::fitToolOrientation(X, R_measured, kTrackerSigma_rad);
    ASSERT_TRUE(fit.note.empty()) << fit.note;
    const Vec3 e = lie::logSO3(fit.R_TipTcp.transpose() * kTargetTcp.linear());
    std::printf("seed %d: TCP axes error %.5f %.5f %.5f deg, 1-sigma %.5f deg per axis, residual "
                "rms %.5f deg\n",
                int(seed), e[0] / kRadPerDeg, e[1] / kRadPerDeg, e[2] / kRadPerDeg,
                std::sqrt(fit.covariance_rad2(0, 0)) / kRadPerDeg,
                fit.rms_residual_rad / kRadPerDeg);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LT(std::abs(e[a]), 3 * std::sqrt(fit.covariance_rad2(a, a)) + 0.001 * kRadPerDeg)
          << "seed " << seed << ", axis " << a;
    }
    // Against the flange's axes (--rotation's default), the turn itself: 23°.
    EXPECT_GT(lie::logSO3(kTargetTcp.linear()).norm(), 100 * std::abs(e.norm()));
  }
}

// Exact rotations: the fit returns them to rounding, with no residual; the σ is the stated one.
TEST(ToolFit, AxesExact) {
  std::vector<Pose> X;
  std::vector<Mat3> R;
  for (const Mat3& turn : touchOrientations()) {
    X.push_back(poseOf(Vec3(1.0, 0.2, 0.5), Vec3(0.3, 1, 0.2), 0.7));
    X.back().linear() = X.back().linear() * turn;
    R.push_back(X.back().linear() * kTargetTcp.linear());
  }
  const trainer::ToolOrientationFit fit = trainer::fitToolOrientation(X, R, 1e-4);
  EXPECT_LT((fit.R_TipTcp - kTargetTcp.linear()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT(fit.rms_residual_rad, 1e-12);
  EXPECT_NEAR(std::sqrt(fit.covariance_rad2(0, 0)), 1e-4 / std::sqrt(double(X.size())), 1e-15);
  EXPECT_FALSE(trainer::fitToolOrientation({}, {}, 1e-4).note.empty());
}

/// A frame's error against the truth in its own axes: (origin shift, rotation), as FrameFit's
/// covariance is.
Vec6 frameError(const Pose& X_fit, const Pose& X_true) {
  Vec6 d;
  d.head<3>() = X_fit.linear().transpose() * (X_true.translation() - X_fit.translation());
  d.tail<3>() = lie::logSO3(X_fit.linear().transpose() * X_true.linear());
  return d;
}

/// Each component of the error within 3σ plus a floor (the model's own target error, which
/// no σ of the points carries: 0.01 mm, 0.001°).
void expectWithinSigma(const FrameFit& fit, const Pose& X_true, const char* what, int seed) {
  ASSERT_TRUE(fit.note.empty()) << fit.note;
  const Vec6 e = frameError(fit.X_TrackerFrame, X_true);
  std::printf("seed %d, %s: origin error %.4f %.4f %.4f mm (1-sigma %.4f %.4f %.4f), rotation "
              "error %.5f %.5f %.5f deg (1-sigma %.5f %.5f %.5f)\n",
              seed, what, e[0] * 1e3, e[1] * 1e3, e[2] * 1e3, std::sqrt(fit.covariance(0, 0)) * 1e3,
              std::sqrt(fit.covariance(1, 1)) * 1e3, std::sqrt(fit.covariance(2, 2)) * 1e3,
              e[3] / kRadPerDeg, e[4] / kRadPerDeg, e[5] / kRadPerDeg,
              std::sqrt(fit.covariance(3, 3)) / kRadPerDeg, std::sqrt(fit.covariance(4, 4)) / kRadPerDeg,
              std::sqrt(fit.covariance(5, 5)) / kRadPerDeg);
  for (int k = 0; k < 6; ++k) {
    const double floor = k < 3 ? 0.01e-3 : 0.001 * kRadPerDeg;
    EXPECT_LT(std::abs(e[k]), 3 * std::sqrt(fit.covariance(k, k)) + floor)
        << what << ", seed " << seed << ", component " << k;
  }
}

// A work object 0.4 × 0.3 m: five fiducials touched with the four-point TCP (0.02 mm touch
// scatter) and fitted by least squares, its first three by the three-point method, and the five
// measured by the tracker; each frame within 3σ of the truth (plus a floor), over 4 seeds.
TEST(CellOnTwin, WorkObjectWithinItsSigma) {
  const std::vector<Vec3> nominal = {Vec3(0, 0, 0), Vec3(0.4, 0, 0), Vec3(0, 0.3, 0),
                                     Vec3(0.4, 0.3, 0.02), Vec3(0.2, 0.15, 0.01)};
  for (const uint64_t seed : {1, 2, 3, 4}) {
    const ToolOnTwin& tool = toolOnTwin(seed);
    const TwinCell& c = twinCell(seed);
    const twin::TwinRobot truth(c.options);
    std::mt19937 random(uint32_t(seed) + 200);
    std::normal_distribution<double> normal(0.0, 1.0);
    const Vec3 p_tcp0 = truth.X_TrackerTip(tool.q0, 0.0) * kTargetTcp.translation();
    const Pose X_true = poseOf(p_tcp0 + Vec3(-0.1, -0.1, -0.05), Vec3(0.1, 0.2, 1.0), 0.5);
    std::vector<FramePoint> touched, measured;
    for (const Vec3& n : nominal) {
      const Vec3 p = X_true * n;
      const Vec3 off = kTouchSigma_m * Vec3(normal(random), normal(random), normal(random));
      const Pose X = modelTarget(*c.model, truth, jogTo(*c.model, truth, p + off, tool.R0, tool.R0, tool.q0));
      touched.push_back({X * tool.four_point.p_TcpInTip_m, X.linear()});
      measured.push_back({p + kTrackerSigma_m * Vec3(normal(random), normal(random), normal(random)),
                          Mat3::Zero()});
    }
    const double sigma = tool.four_point.point_sigma_m;
    const Mat3& covariance_tool = tool.four_point.covariance_TcpInTip_m2;
    expectWithinSigma(trainer::fitFrameToFiducials(touched, nominal, sigma, covariance_tool),
                      X_true, "fiducials touched", int(seed));
    expectWithinSigma(trainer::fitFrameFromThreePoints(touched[0], touched[1], touched[2], sigma,
                                                       covariance_tool),
                      X_true, "three points touched", int(seed));
    expectWithinSigma(trainer::fitFrameToFiducials(measured, nominal, kTrackerSigma_m, Mat3::Zero()),
                      X_true, "fiducials by the tracker", int(seed));
  }
}

// ---- The commands ----

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";

std::string touchLine(const JointVector& q, const twin::TwinRobot& truth) {
  std::string line;
  for (Eigen::Index j = 0; j < q.size(); ++j) line += format("%.12f,", q[j] * kDegPerRad);
  const Vec6 w = truth.sensorReading(q, 0.0);
  for (int k = 0; k < 6; ++k) line += format(k < 5 ? "%.9f," : "%.9f", w[k]);
  return line;
}

const char* const kTouchHeader =
    "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_n,fy_n,fz_n,mx_nm,my_nm,mz_nm";

// `stepcal tool` on four-point touches of the twin written as a touch file, then `stepcal
// frame` on fiducials touched with that TCP: the TCP is the library's fit on the same joints,
// within 0.1 mm of the truth, in the four brands' terms; the frame's origin within 0.1 mm of the
// truth in the base frame; a bad field is refused by file, line and column.
TEST(CellCommands, ToolAndFrameOnTheTwin) {
  const test::TempDir dir;
  const std::string d = dir.path().string();
  const test::CommandResult made = test::run(kStepcal + " simulate --seed 1 --out " + d + "/cell && " +
                                             kStepcal + " calibrate " + d + "/cell --out " + d + "/model.stepcal");
  ASSERT_EQ(made.status, 0) << made.out;
  const auto model = runtime::RuntimeModel::load(d + "/model.stepcal");
  const twin::TwinRobot truth =
      twin::TwinRobot::fromTruthJson(nlohmann::json::parse(test::readText(d + "/cell/truth.json")));
  const JointVector q0 = touchHome();
  const Pose X_tcp0 = truth.X_TrackerTip(q0, 0.0) * kTargetTcp;
  std::string touches = std::string(kTouchHeader) + "\n";
  std::vector<Pose> X;
  for (const Mat3& R : touchOrientations()) {
    const JointVector q = jogTo(*model, truth, X_tcp0.translation(), X_tcp0.linear(), X_tcp0.linear() * R, q0);
    touches += touchLine(q, truth) + "\n";
    X.push_back(modelTarget(*model, truth, q));
  }
  test::writeText(d + "/touches.csv", touches);
  const test::CommandResult tool = test::run(kStepcal + " tool " + d + "/model.stepcal " + d +
                                             "/touches.csv --out " + d + "/tool.json");
  ASSERT_EQ(tool.status, 0) << tool.out;
  std::printf("%s", tool.out.c_str());
  const nlohmann::json j = nlohmann::json::parse(test::readText(d + "/tool.json"));
  const ToolPointFit fit = trainer::fitToolFromFixedPoint(X, 0.0);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(j["tcp_in_target_mm"][size_t(a)].get<double>(), fit.p_TcpInTip_m[a] * 1e3, 1e-6);
    EXPECT_NEAR(fit.p_TcpInTip_m[a], kTargetTcp.translation()[a], 0.1e-3);
  }
  for (const char* brand : {"kuka", "abb", "ur", "fanuc"}) EXPECT_TRUE(j["controller"].contains(brand));
  EXPECT_NE(tool.out.find("KUKA   {X "), std::string::npos);

  // Four fiducials of a frame touched with the TCP.
  const Pose X_true = poseOf(X_tcp0.translation() + Vec3(-0.1, -0.1, -0.05), Vec3(0.1, 0.2, 1.0), 0.5);
  std::string points = std::string(kTouchHeader) + ",nx_mm,ny_mm,nz_mm\n";
  for (const Vec3& n : {Vec3(0, 0, 0), Vec3(0.4, 0, 0), Vec3(0, 0.3, 0), Vec3(0.4, 0.3, 0.02)}) {
    const JointVector q = jogTo(*model, truth, X_true * n, X_tcp0.linear(), X_tcp0.linear(), q0);
    points += touchLine(q, truth) + format(",%.3f,%.3f,%.3f\n", n.x() * 1e3, n.y() * 1e3, n.z() * 1e3);
  }
  test::writeText(d + "/points.csv", points);
  const test::CommandResult frame = test::run(kStepcal + " frame " + d + "/model.stepcal " + d +
                                              "/points.csv --tool " + d + "/tool.json --out " + d + "/frame.json");
  ASSERT_EQ(frame.status, 0) << frame.out;
  std::printf("%s", frame.out.c_str());
  const nlohmann::json f = nlohmann::json::parse(test::readText(d + "/frame.json"));
  std::istringstream user(f["user_frame"].get<std::string>());
  double x_mm, y_mm, z_mm;
  user >> x_mm >> y_mm >> z_mm;
  const Vec3 p_true_mm = (model->file.X_TrackerBase.inverse() * X_true).translation() * 1e3;
  EXPECT_NEAR(x_mm, p_true_mm.x(), 0.1);
  EXPECT_NEAR(y_mm, p_true_mm.y(), 0.1);
  EXPECT_NEAR(z_mm, p_true_mm.z(), 0.1);

  // A bad field: file, line and column named, nothing written.
  std::string bad = touches;
  bad.replace(bad.find('\n', bad.find('\n') + 1) + 1, 0, "1,2,x30,4,5,6,0,0,0,0,0,0\n");
  test::writeText(d + "/bad.csv", bad);
  const test::CommandResult refused = test::run(kStepcal + " tool " + d + "/model.stepcal " + d +
                                                "/bad.csv --out " + d + "/bad.json");
  EXPECT_EQ(refused.status, 2) << refused.out;
  EXPECT_NE(refused.out.find("bad.csv:3"), std::string::npos) << refused.out;
  EXPECT_NE(refused.out.find("q3_deg"), std::string::npos) << refused.out;
  EXPECT_NE(refused.out.find("'x30' is not a number"), std::string::npos) << refused.out;
  EXPECT_FALSE(std::filesystem::exists(d + "/bad.json"));
}

// The other inputs of the commands: tracker shots at the TCP (joints and x_mm …, and a
// campaign folder), touches too
// alike (a result with a warning, exit status 0), and a three-point frame the tracker measured
// (no joint columns at all).
TEST(CellCommands, TrackerShotsSimilarTouchesAndATrackerFrame) {
  const test::TempDir dir;
  const std::string d = dir.path().string();
  const test::CommandResult made = test::run(kStepcal + " simulate --seed 2 --out " + d + "/cell && " +
                                             kStepcal + " calibrate " + d + "/cell --out " + d + "/model.stepcal");
  ASSERT_EQ(made.status, 0) << made.out;
  const std::string model_path = d + "/model.stepcal";
  const auto model = runtime::RuntimeModel::load(model_path);
  const twin::TwinRobot truth =
      twin::TwinRobot::fromTruthJson(nlohmann::json::parse(test::readText(d + "/cell/truth.json")));
  const JointVector q0 = touchHome();
  const Pose X_tcp0 = truth.X_TrackerTip(q0, 0.0) * kTargetTcp;

  std::string shots = std::string(kTouchHeader) + ",x_mm,y_mm,z_mm\n";
  const std::vector<Mat3> orientations = touchOrientations();
  for (size_t k = 0; k < orientations.size(); ++k) {  // the SMR in 3 places, 50 mm apart
    const Vec3 p = X_tcp0.translation() + Vec3(0.0, 0.05 * double(k % 3), 0.0);
    const JointVector q = jogTo(*model, truth, p, X_tcp0.linear(), X_tcp0.linear() * orientations[k], q0);
    const Vec3 p_mm = truth.X_TrackerTip(q, 0.0) * kTargetTcp.translation() * 1e3;
    shots += touchLine(q, truth) + format(",%.4f,%.4f,%.4f\n", p_mm.x(), p_mm.y(), p_mm.z());
  }
  test::writeText(d + "/shots.csv", shots);
  const test::CommandResult tracker = test::run(kStepcal + " tool " + model_path + " " + d +
                                                "/shots.csv --out " + d + "/tool.json");
  ASSERT_EQ(tracker.status, 0) << tracker.out;
  EXPECT_NE(tracker.out.find("TCP by the tracker method from 7 tracker rows"), std::string::npos) << tracker.out;
  const nlohmann::json j = nlohmann::json::parse(test::readText(d + "/tool.json"));
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(j["tcp_in_target_mm"][size_t(a)].get<double>(), kTargetTcp.translation()[a] * 1e3, 0.05);
  }

  // The calibration's own campaign as tracker shots: its measured point is the target itself,
  // so the TCP comes out at the target's origin (within 0.005 mm: the model's error averaged
  // over its 1070 rows).
  const test::CommandResult itself = test::run(kStepcal + " tool " + model_path + " " + d +
                                               "/cell --out " + d + "/itself.json");
  ASSERT_EQ(itself.status, 0) << itself.out;
  const nlohmann::json k = nlohmann::json::parse(test::readText(d + "/itself.json"));
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(k["tcp_in_target_mm"][size_t(a)].get<double>(), 0.0, 0.005);
  // Its rows are 6-D: the TCP's axes are measured, the target's own within 3σ + 0.001°.
  EXPECT_NE(itself.out.find("axes measured from"), std::string::npos) << itself.out;
  ASSERT_EQ(k["tcp_axes_from"], "measured");
  const nlohmann::json& q = k["tool_from_target"];
  const Eigen::Quaterniond q_TipTcp(q["qw"].get<double>(), q["qx"].get<double>(),
                                    q["qy"].get<double>(), q["qz"].get<double>());
  EXPECT_LT(Eigen::AngleAxisd(q_TipTcp).angle() / kRadPerDeg,
            3 * std::sqrt(3.0) * k["tcp_orientation_sigma_deg"][0].get<double>() + 0.001);
  const test::CommandResult given = test::run(kStepcal + " tool " + model_path + " " + d +
                                              "/cell --rotation 1 0 0 0 --out " + d + "/given.json");
  ASSERT_EQ(given.status, 0) << given.out;
  EXPECT_EQ(nlohmann::json::parse(test::readText(d + "/given.json"))["tcp_axes_from"], "rotation");

  std::string alike = std::string(kTouchHeader) + "\n";
  for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(-1, 0, 0)}) {
    const Mat3 R = Eigen::AngleAxisd(5.0 * kRadPerDeg, axis).toRotationMatrix();
    alike += touchLine(jogTo(*model, truth, X_tcp0.translation(), X_tcp0.linear(), X_tcp0.linear() * R, q0), truth) + "\n";
  }
  test::writeText(d + "/alike.csv", alike);
  const test::CommandResult weak = test::run(kStepcal + " tool " + model_path + " " + d + "/alike.csv");
  EXPECT_EQ(weak.status, 0) << weak.out;
  EXPECT_NE(weak.out.find("WARNING: the orientations differ by only"), std::string::npos) << weak.out;

  std::string corners = "point,x_mm,y_mm,z_mm\n";
  const Pose X_true = poseOf(Vec3(1.8, -0.3, 0.4), Vec3(0, 0, 1), 0.3);
  const char* const roles[] = {"origin", "x", "xy"};
  const Vec3 nominal[] = {Vec3(0, 0, 0), Vec3(0.5, 0, 0), Vec3(0.2, 0.4, 0)};
  for (int k = 0; k < 3; ++k) {
    const Vec3 p_mm = X_true * nominal[k] * 1e3;
    corners += format("%s,%.4f,%.4f,%.4f\n", roles[k], p_mm.x(), p_mm.y(), p_mm.z());
  }
  test::writeText(d + "/corners.csv", corners);
  const test::CommandResult frame = test::run(kStepcal + " frame " + model_path + " " + d +
                                              "/corners.csv --out " + d + "/frame.json");
  ASSERT_EQ(frame.status, 0) << frame.out;
  EXPECT_NE(frame.out.find("work object by three-point from 3 points"), std::string::npos) << frame.out;
  const nlohmann::json f = nlohmann::json::parse(test::readText(d + "/frame.json"));
  std::istringstream user(f["user_frame"].get<std::string>());
  double x_mm, y_mm, z_mm;
  user >> x_mm >> y_mm >> z_mm;
  const Vec3 p_true_mm = (model->file.X_TrackerBase.inverse() * X_true).translation() * 1e3;
  EXPECT_NEAR(x_mm, p_true_mm.x(), 1e-3);  // exact points: the registration's frame to the text's 0.1 µm
  EXPECT_NEAR(y_mm, p_true_mm.y(), 1e-3);
  EXPECT_NEAR(z_mm, p_true_mm.z(), 1e-3);
}

}  // namespace
}  // namespace stepcal
