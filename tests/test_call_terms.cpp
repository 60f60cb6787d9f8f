// The runtime in the controller's terms (runtime/corrector.hpp CallTerms): a tool 0.3 m from the
// measured target, given from the target or from the flange, against the twin's truth (forward
// and inverse); the base and user frames round trip; a payload's wrench against the twin's
// gravity wrench; a model that needs no wrench.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/reply.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/files.hpp"

namespace stepcal {
namespace {

using runtime::CallTerms;
using runtime::Status;


struct Cell {
  twin::TwinOptions options;
  Campaign campaign;
  CalibratedModel model;
};

// The paper protocol on seed 3, calibrated once for the binary (about a second).
const Cell& cell() {
  static const Cell c = [] {
    Cell out;
    out.options.seed = 3;
    out.campaign = twin::simulateCampaign(out.options, nullptr);
    out.model = trainer::modelFromOutcome(out.campaign, trainer::calibrateCampaign(out.campaign));
    return out;
  }();
  return c;
}

Pose translation(double x, double y, double z) {
  Pose X = Pose::Identity();
  X.translation() = Vec3(x, y, z);
  return X;
}

/// The twin's true flange, tracker frame: the deflected robot's joint-n frame, then the
/// nominal flange offset (the twin keeps the flange, like its sensor, at its nominal place).
Pose trueFlange(const twin::TwinRobot& truth, const runtime::RuntimeModel& model,
                const JointVector& q_rad, double load_kg) {
  ChainWorkspace ws;
  truth.deflectedFrames(q_rad, load_kg, twin::kNoThermalExpansion, ws);
  return truth.X_TrackerBase() * ws.X_RootFrame[size_t(q_rad.size())] * model.X_LastFlange_nominal;
}

double distance(const Pose& a, const Pose& b) { return (a.translation() - b.translation()).norm(); }
double angle(const Pose& a, const Pose& b) { return lie::angleBetween(a.linear(), b.linear()); }

Pose rotated(const Pose& X, const Vec3& axis, double angle_rad) {
  Pose out = X;
  out.linear() = X.linear() * Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
  return out;
}

JointVector seedOff(const JointVector& q_rad) {
  JointVector seed = q_rad;
  for (Eigen::Index j = 0; j < seed.size(); ++j) seed(j) += (j % 2 ? -2.0 : 2.0) * kRadPerDeg;
  return seed;
}

// The TCP 0.3 m beyond the target (the target sits 40, −30, 260 mm from the IRB 4400's flange,
// along its z), given from the target and from the flange: the errors docs/runtime.md states
// (8 seeds, "Tool"): from the target 0.006–0.013 mm mean, at the target's own accuracy; from the
// flange 0.012–0.28 mm mean, the joint-6 frame's unidentifiable translation along its axis; and,
// printed beside them, what the two other ways to place the flange would cost.
TEST(CallTerms, ToolFromTheTargetAndTheFlangeAgainstTheTwin) {
  const auto model = runtime::RuntimeModel::fromModel(cell().model, 1);
  ASSERT_TRUE(model->has_flange);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  const twin::TwinRobot truth(cell().options);
  const Pose X_TargetTcp = rotated(translation(0.0, 0.0, 0.3), Vec3(1, 1, 0), 0.4);
  const Pose X_FlangeTcp = rotated(translation(0.040, -0.030, 0.260 + 0.3), Vec3(1, 1, 0), 0.4);
  ASSERT_NEAR(X_TargetTcp.translation().norm(), 0.3, 1e-12);
  const Pose X_TipFlange_nominal =
      model->file.nominal_Base.initialPose(6).inverse() * model->X_LastFlange_nominal;
  const Pose X_TipFlange_unsplit = model->X_LastTip.inverse() * model->X_LastFlange_nominal;
  double sum[5] = {}, max_flange_m = 0.0, max_inverse_m[2] = {}, max_inverse_rad = 0.0;
  int rows = 0;
  for (const Measurement* row : cell().campaign.rowsIn(RowSet::kValidation)) {
    CallTerms terms;
    terms.wrench_Sensor = row->wrenchOrZero();
    const Pose X_target = runtime::correctForward(*model, ws, row->q_rad, terms,
                                                  runtime::kUnknownTemperature_c).X_TrackerTip;
    const Pose X_true = truth.X_TrackerTip(row->q_rad, row->load_kg);
    const Pose X_true_flange = trueFlange(truth, *model, row->q_rad, row->load_kg);
    for (const runtime::ToolFrom from : {runtime::ToolFrom::kTarget, runtime::ToolFrom::kFlange}) {
      const bool flange = from == runtime::ToolFrom::kFlange;
      terms.tool_from = from;
      terms.X_Tool = flange ? X_FlangeTcp : X_TargetTcp;
      const Pose X_true_tcp = flange ? Pose(X_true_flange * X_FlangeTcp) : Pose(X_true * X_TargetTcp);
      const runtime::ForwardResult forward = runtime::correctForward(
          *model, ws, row->q_rad, terms, runtime::kUnknownTemperature_c);
      ASSERT_TRUE(forward.status == Status::kOk || forward.status == Status::kOutOfDomain);
      EXPECT_LT(distance(forward.X_TrackerTip, X_target), 1e-15) << "the tool leaves the target";
      const double e_m = distance(forward.X_FrameTcp, X_true_tcp);
      sum[flange ? 2 : 1] += e_m;
      if (flange) max_flange_m = std::max(max_flange_m, e_m);
      // Inverse: the true TCP of the row, asked for from 2° off; where the twin's TCP lands.
      const runtime::InverseResult inverse =
          runtime::solveInverse(*model, ws, X_true_tcp, terms, runtime::kUnknownTemperature_c,
                                seedOff(row->q_rad), runtime::Clock::time_point::max());
      ASSERT_TRUE(inverse.status == Status::kOk || inverse.status == Status::kOutOfDomain)
          << runtime::toString(inverse.status) << " at seq " << row->seq;
      EXPECT_LE(inverse.residual_position_m, 1e-6);
      EXPECT_LE(inverse.residual_orientation_rad, 1e-6);
      EXPECT_LT(distance(inverse.X_FrameTcp_predicted, X_true_tcp), 1.5e-6);
      const Pose X_landed = flange ? Pose(trueFlange(truth, *model, inverse.q_target_rad, row->load_kg) * X_FlangeTcp)
                                   : Pose(truth.X_TrackerTip(inverse.q_target_rad, row->load_kg) * X_TargetTcp);
      max_inverse_m[flange] = std::max(max_inverse_m[flange], distance(X_landed, X_true_tcp));
      if (!flange) max_inverse_rad = std::max(max_inverse_rad, angle(X_landed, X_true_tcp));
    }
    sum[0] += distance(X_target, X_true);
    sum[3] += distance(X_target * X_TipFlange_nominal * X_FlangeTcp, X_true_flange * X_FlangeTcp);
    sum[4] += distance(X_target * X_TipFlange_unsplit * X_FlangeTcp, X_true_flange * X_FlangeTcp);
    ++rows;
  }
  for (double& s : sum) s /= rows;
  std::printf("%d validation poses, mean error against the twin's truth: target %.4f mm; TCP 0.3 m "
              "out, from the target %.4f mm, from the flange %.4f mm (max %.4f); the flange by the "
              "nominal target-to-flange transform instead %.4f mm, on the calibrated joint-6 frame "
              "as fitted %.4f mm; inverse, landed at most %.4f mm (from the target), %.4f mm "
              "(from the flange)\n",
              rows, sum[0] * 1e3, sum[1] * 1e3, sum[2] * 1e3, max_flange_m * 1e3, sum[3] * 1e3,
              sum[4] * 1e3, max_inverse_m[0] * 1e3, max_inverse_m[1] * 1e3);
  EXPECT_LT(sum[1], 0.03e-3);
  EXPECT_LT(sum[2], 0.35e-3);
  EXPECT_LT(max_inverse_m[0], 0.1e-3);
  EXPECT_LT(max_inverse_m[1], 0.5e-3);
  EXPECT_LT(max_inverse_rad, 0.01 * kRadPerDeg);
}

// Poses in the base frame and in a user frame: the same answer as in the tracker frame, moved
// by X_TrackerBase and X_BaseUser; the inverse takes the forward's pose back to its joints; the
// pre-distorted pose is the controller's (nominal FK · tool) in the user frame.
TEST(CallTerms, BaseAndUserFramesRoundTrip) {
  const auto model = runtime::RuntimeModel::fromModel(cell().model, 1);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  // What the base frame is: the nominal robot's registration, not the twin's true base_link (the
  // registration takes up the nominal model's errors); printed for docs/runtime.md.
  const twin::TwinRobot truth(cell().options);
  const Pose X_TrueBaseModelBase = truth.X_TrackerBase().inverse() * model->file.X_TrackerBase;
  std::printf("base frame (registration) against the twin's true base_link: %.3f mm, %.4f deg\n",
              X_TrueBaseModelBase.translation().norm() * 1e3,
              lie::angleBetween(Mat3::Identity(), X_TrueBaseModelBase.linear()) / kRadPerDeg);
  Pose X_BaseUser = rotated(translation(1.4, -0.3, 0.2), Vec3(0.2, 0.1, 1.0), 0.7);
  const auto rows = cell().campaign.rowsIn(RowSet::kValidation);
  for (size_t i = 0; i < rows.size(); i += 37) {
    const Measurement& row = *rows[i];
    CallTerms terms;
    terms.wrench_Sensor = row.wrenchOrZero();
    terms.tool_from = runtime::ToolFrom::kFlange;
    terms.X_Tool = rotated(translation(0.0, 0.1, 0.4), Vec3(0, 1, 0), 0.3);
    const Pose X_tracker = runtime::correctForward(*model, ws, row.q_rad, terms,
                                                   runtime::kUnknownTemperature_c).X_FrameTcp;
    terms.frame = runtime::PoseFrame::kBase;
    const Pose X_base = runtime::correctForward(*model, ws, row.q_rad, terms,
                                                runtime::kUnknownTemperature_c).X_FrameTcp;
    EXPECT_LT((X_base.matrix() - (model->file.X_TrackerBase.inverse() * X_tracker).matrix())
                  .cwiseAbs().maxCoeff(), 1e-12);
    terms.frame = runtime::PoseFrame::kUser;
    terms.X_BaseUser = X_BaseUser;
    const runtime::ForwardResult user = runtime::correctForward(
        *model, ws, row.q_rad, terms, runtime::kUnknownTemperature_c);
    EXPECT_LT((user.X_FrameTcp.matrix() - (X_BaseUser.inverse() * X_base).matrix())
                  .cwiseAbs().maxCoeff(), 1e-12);

    const runtime::InverseResult inverse =
        runtime::solveInverse(*model, ws, user.X_FrameTcp, terms, runtime::kUnknownTemperature_c,
                              seedOff(row.q_rad), runtime::Clock::time_point::max());
    ASSERT_TRUE(inverse.status == Status::kOk || inverse.status == Status::kOutOfDomain);
    for (Eigen::Index j = 0; j < row.q_rad.size(); ++j) {
      EXPECT_NEAR(inverse.q_target_rad(j), row.q_rad(j), 1e-5);
    }
    EXPECT_LT(distance(inverse.X_FrameTcp_predicted, user.X_FrameTcp), 1.5e-6);
    EXPECT_LT(angle(inverse.X_FrameTcp_predicted, user.X_FrameTcp), 1e-6);
    const Pose X_UserTcp_nominal = runtime::nominalTcp(*model, ws, inverse.q_target_rad, terms);
    EXPECT_LT((inverse.X_ControllerTcp_commanded.matrix() - X_UserTcp_nominal.matrix())
                  .cwiseAbs().maxCoeff(), 1e-12);
    // The controller's view: nominal flange at q_target times the tool, in the user frame.
    ChainWorkspace chain;
    forwardKinematics(model->file.nominal_Base, inverse.q_target_rad, chain);
    const Pose X_expected = X_BaseUser.inverse() * chain.X_RootFrame[6] *
                            model->X_LastFlange_nominal * terms.X_Tool;
    EXPECT_LT((inverse.X_ControllerTcp_commanded.matrix() - X_expected.matrix())
                  .cwiseAbs().maxCoeff(), 1e-12);
  }
}

/// A model of the twin's own truth: its true chain, compliance, sensor and gravity (no GPR), so
/// that the model's deflection is the twin's.
CalibratedModel truthModel(const twin::TwinRobot& truth) {
  CalibratedModel m = cell().model;
  m.chain_Tracker = truth.trueChain().rerooted(truth.X_TrackerBase());
  m.X_TrackerBase = truth.X_TrackerBase();
  m.sensor_frame = truth.sensorFrame();
  m.gravity_Base = truth.gravityInBase();
  m.compliance_rad_per_nm.resize(6);
  for (int j = 0; j < 6; ++j) m.compliance_rad_per_nm(j) = 1.0 / twin::kPaperStiffnessNmPerRad[size_t(j)];
  m.compliance_sigma_rad_per_nm = JointVector::Zero(6);
  m.mechanisms.clear();
  m.gpr.reset();
  return m;
}

// A payload (the controller's load data) on a model of the twin's truth: the wrench a sensor
// reads equals the twin's gravity wrench at the deflected pose to 1e-9 relative, the pose is the
// twin's, and the inverse lands on the twin's pose exactly (the payload's weight is inside the
// fixed point the steps invert).
TEST(CallTerms, PayloadWrenchIsTheTwinsGravityWrench) {
  const twin::TwinRobot truth(cell().options);
  const auto model = runtime::RuntimeModel::fromModel(truthModel(truth), 2);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  // The tool frame is the sensor frame, so the twin's centre of gravity (given in it) is the
  // payload's as the controller's load data gives it.
  const Pose X_LastSensor =
      truth.trueChain().frames()[size_t(truth.sensorFrame())].X_ParentFrame;
  CallTerms terms;
  terms.X_Tool = model->X_LastTip.inverse() * X_LastSensor;
  terms.load_from = runtime::LoadFrom::kPayload;
  terms.payload.frame = runtime::CogFrame::kTool;
  terms.payload.p_CoG_m = truth.p_CoGInSensor_m();
  double worst_relative = 0.0;
  const auto rows = cell().campaign.rowsIn(RowSet::kValidation);
  for (size_t i = 0; i < rows.size(); i += 7) {
    const Measurement& row = *rows[i];
    for (const double load_kg : {20.0, 40.0, 55.0}) {  // the campaign's loads
      terms.payload.mass_kg = load_kg;
      const runtime::ForwardResult forward = runtime::correctForward(
          *model, ws, row.q_rad, terms, runtime::kUnknownTemperature_c);
      ASSERT_EQ(forward.status, Status::kOk);
      const Vec6 expected = truth.sensorWrench(row.q_rad, load_kg);
      worst_relative = std::max(worst_relative,
                                (forward.wrench_Sensor - expected).norm() / expected.norm());
      const Pose X_true = truth.X_TrackerTip(row.q_rad, load_kg);
      EXPECT_LT(distance(forward.X_TrackerTip, X_true), 1e-9);
      EXPECT_LT(angle(forward.X_TrackerTip, X_true), 1e-9);
      // The same pose as that wrench given: the payload's fixed point is the given wrench's.
      CallTerms given;
      given.wrench_Sensor = expected;
      EXPECT_LT(distance(runtime::correctForward(*model, ws, row.q_rad, given,
                                                 runtime::kUnknownTemperature_c).X_TrackerTip,
                         forward.X_TrackerTip), 1e-9);

      const runtime::InverseResult inverse =
          runtime::solveInverse(*model, ws, X_true * terms.X_Tool, terms,
                                runtime::kUnknownTemperature_c, seedOff(row.q_rad),
                                runtime::Clock::time_point::max());
      ASSERT_EQ(inverse.status, Status::kOk) << "seq " << row.seq << ", " << load_kg << " kg";
      EXPECT_LT(distance(truth.X_TrackerTip(inverse.q_target_rad, load_kg), X_true), 2e-6);
      for (Eigen::Index j = 0; j < row.q_rad.size(); ++j) {
        EXPECT_NEAR(inverse.q_target_rad(j), row.q_rad(j), 2e-6);
      }
      EXPECT_LT((inverse.wrench_Sensor - expected).norm() / expected.norm(), 1e-5);
    }
  }
  std::printf("payload wrench against the twin's gravity wrench: worst relative difference %.3g\n",
              worst_relative);
  EXPECT_LT(worst_relative, 1e-9);
}

// The flange comes from campaign.yaml's flange_link: written and read back, kept by the trainer
// as the frame "flange" on the last joint's frame, refused when the URDF has no such link.
TEST(CallTerms, TheCampaignNamesTheFlange) {
  EXPECT_EQ(cell().campaign.flange_link, "flange");
  const test::TempDir dir;
  writeCampaign(cell().campaign, dir.path().string());
  const Campaign read = readCampaign(dir.path().string());
  EXPECT_EQ(read.flange_link, "flange");
  const int flange = cell().model.nominal_Base.findFrame(kFlangeFrameName);
  ASSERT_GE(flange, 0);
  EXPECT_EQ(cell().model.nominal_Base.frames()[size_t(flange)].parent, 6);
  EXPECT_EQ(cell().model.chain_Tracker.findFrame(kFlangeFrameName), flange);
  EXPECT_EQ(cell().model.sensor_frame, 0) << "the sensor stays frame 0";
  Campaign wrong = cell().campaign;
  wrong.flange_link = "nosuch";
  try {
    trainer::campaignChain(wrong);
    ADD_FAILURE() << "a flange_link the URDF lacks was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'nosuch' is not a link"), std::string::npos) << e.what();
  }
}

// Terms a model cannot serve are BAD_REQUEST, never a wrong answer.
TEST(CallTerms, TermsThatDoNotHoldAreBadRequest) {
  const auto model = runtime::RuntimeModel::fromModel(cell().model, 1);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  const Measurement& row = *cell().campaign.rowsIn(RowSet::kValidation)[0];
  const auto status = [&](const runtime::RuntimeModel& m, runtime::Workspace& w, const CallTerms& t) {
    const Status forward = runtime::correctForward(m, w, row.q_rad, t, 20.0).status;
    const Status inverse = runtime::solveInverse(m, w, row.X_TrackerTip(), t, 20.0, row.q_rad,
                                                 runtime::Clock::time_point::max()).status;
    EXPECT_EQ(forward == Status::kBadRequest, inverse == Status::kBadRequest);
    return forward;
  };
  CallTerms terms;
  EXPECT_NE(status(*model, ws, terms), Status::kBadRequest);
  terms.X_Tool.linear() *= 1.01;  // not a rotation
  EXPECT_EQ(status(*model, ws, terms), Status::kBadRequest);
  terms = CallTerms{};
  terms.frame = runtime::PoseFrame::kUser;
  terms.X_BaseUser.translation().x() = std::nan("");
  EXPECT_EQ(status(*model, ws, terms), Status::kBadRequest);
  terms = CallTerms{};
  terms.load_from = runtime::LoadFrom::kPayload;
  terms.payload.mass_kg = -1.0;
  EXPECT_EQ(status(*model, ws, terms), Status::kBadRequest);
  terms.payload.mass_kg = 30.0;
  EXPECT_NE(status(*model, ws, terms), Status::kBadRequest);
  terms.frame = static_cast<runtime::PoseFrame>(7);
  EXPECT_EQ(status(*model, ws, terms), Status::kBadRequest);

  // A model without a flange: tools and centres of gravity from it are refused.
  CalibratedModel no_flange = cell().model;
  std::vector<AttachedFrame> frames = {no_flange.nominal_Base.frames()[0]};
  no_flange.nominal_Base = KinematicChain(no_flange.nominal_Base.joints(),
                                          no_flange.nominal_Base.initialPoses(), frames);
  const auto bare = runtime::RuntimeModel::fromModel(no_flange, 3);
  EXPECT_FALSE(bare->has_flange);
  runtime::Workspace bare_ws = runtime::makeWorkspace(*bare);
  terms = CallTerms{};
  terms.tool_from = runtime::ToolFrom::kFlange;
  EXPECT_EQ(status(*bare, bare_ws, terms), Status::kBadRequest);
  terms = CallTerms{};
  terms.load_from = runtime::LoadFrom::kPayload;
  terms.payload.mass_kg = 30.0;
  EXPECT_EQ(status(*bare, bare_ws, terms), Status::kBadRequest);
  terms.payload.frame = runtime::CogFrame::kTool;
  EXPECT_NE(status(*bare, bare_ws, terms), Status::kBadRequest);
  terms.payload.mass_kg = 0.0;  // no load needs no flange
  terms.payload.frame = runtime::CogFrame::kFlange;
  EXPECT_NE(status(*bare, bare_ws, terms), Status::kBadRequest);

  // Without gravity a payload weighs nothing the model could know.
  CalibratedModel weightless = cell().model;
  weightless.gravity_Base = Vec3::Zero();
  const auto floating = runtime::RuntimeModel::fromModel(weightless, 4);
  runtime::Workspace floating_ws = runtime::makeWorkspace(*floating);
  terms.payload.mass_kg = 30.0;
  EXPECT_EQ(status(*floating, floating_ws, terms), Status::kBadRequest);
}

// A model without compliance whose GPR saw no wrench (a campaign without an F/T sensor, as the
// UR10's): a request for the live sensor is answered without one, never STALE_WRENCH; a model
// that turns the wrench into deflection still refuses a missing sample. The arm's own weight,
// which the geometric layer cannot take, gives the GPR something to learn, so it is taken.
TEST(CallTerms, AModelThatNeedsNoWrenchAnswersWithoutOne) {
  twin::TwinOptions options;
  options.protocol = "geometry";
  options.seed = 5;
  options.hidden_effects.push_back(nlohmann::json::parse(
      R"({"name":"self_weight","links":[{"link":2,"mass_kg":40,"com_m":[0.3,0,0.1]},)"
      R"({"link":3,"mass_kg":30,"com_m":[0.2,0,0.05]}]})"));
  Campaign campaign = twin::simulateCampaign(options, nullptr);
  campaign.sensor_link.clear();
  for (Measurement& row : campaign.rows) {
    row.has_wrench = false;
    row.wrench_Sensor.setZero();
  }
  const CalibratedModel file = trainer::modelFromOutcome(campaign, trainer::calibrateCampaign(campaign));
  ASSERT_TRUE(file.gpr.has_value());
  ASSERT_EQ(file.compliance_rad_per_nm.size(), 0);
  const auto model = runtime::RuntimeModel::fromModel(file, 5);
  EXPECT_FALSE(model->needs_wrench);
  EXPECT_TRUE(model->unloaded_wrench_Sensor.isZero(0.0));
  EXPECT_TRUE(runtime::RuntimeModel::fromModel(cell().model, 6)->needs_wrench);

  const auto answer = [](std::unique_ptr<const runtime::RuntimeModel> m, const Measurement& row) {
    service::Service server(std::move(m), "model.stepcal", {});
    stepcal_lcm::correction_request_t msg = service::blankRequest();
    msg.request_id = 7;
    msg.wrench_source = stepcal_lcm::correction_request_t::WRENCH_LIVE_SENSOR;
    for (int j = 0; j < 6; ++j) msg.q_rad[j] = row.q_rad[j];
    const std::vector<uint8_t> bytes = service::encodeRequest(msg);
    std::vector<uint8_t> reply(size_t(service::replyBytes()));
    const int size = server.handleRequest(bytes.data(), int(bytes.size()), runtime::Clock::now(),
                                          reply.data(), int(reply.size()));
    stepcal_lcm::correction_reply_t decoded{};
    EXPECT_EQ(service::decodeReply(reply.data(), size, decoded), service::ReplyKind::kReply);
    return decoded;
  };
  const Measurement& row = *campaign.rowsIn(RowSet::kValidation)[0];
  const stepcal_lcm::correction_reply_t reply = answer(runtime::RuntimeModel::fromModel(file, 5), row);
  EXPECT_EQ(reply.status, int8_t(Status::kOk));
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  const Pose expected = runtime::correctForward(*model, ws, row.q_rad, Vec6::Zero(),
                                                runtime::kUnknownTemperature_c).X_TrackerTip;
  for (int a = 0; a < 3; ++a) EXPECT_EQ(reply.predicted_position_m[a], expected.translation()[a]);
  EXPECT_EQ(answer(runtime::RuntimeModel::fromModel(cell().model, 6), row).status,
            int8_t(Status::kStaleWrench));
}

}  // namespace
}  // namespace stepcal
