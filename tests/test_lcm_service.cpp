// The runtime's LCM service (runtime/service): requests through an in-process memq:// LCM get the
// runtime's own answers (at the temperature they carry, for a model with mechanisms too), bad
// bytes get BAD_REQUEST or are counted and never crash it, a stale
// live wrench gives STALE_WRENCH, a reload keeps answering and changes the model id, handling a
// request allocates nothing, and the daemon refuses what it cannot serve with exit status 2.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <functional>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm.h>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_reply_v1_t.hpp>
#include <stepcal_lcm/correction_reply_v2_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>
#include <stepcal_lcm/correction_request_v1_t.hpp>
#include <stepcal_lcm/runtime_status_t.hpp>
#include <stepcal_lcm/sensor_command_t.hpp>
#include <stepcal_lcm/sensor_status_t.hpp>
#include <stepcal_lcm/wrench_t.hpp>
#include <sys/socket.h>

#include "stepcal/common/error.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/ftsim/simulator.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/can_feed.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/reply.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/command.hpp"
#include "stepcal/allocation_counter.hpp"
#include "support/files.hpp"
#include "support/mechanisms.hpp"

namespace stepcal::service {
namespace {

using runtime::Clock;
using runtime::Status;
using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;

constexpr uint64_t kFirstModelId = 0x5EED2;
constexpr uint64_t kSecondModelId = 0x5EED3;

struct Paper {
  Campaign campaign;
  CalibratedModel model;
};

// The paper protocol simulated and calibrated once for the whole binary (about a second).
const Paper& paper() {
  static const Paper p = [] {
    twin::TwinOptions options;
    options.protocol = "paper";
    options.seed = 2;
    Paper result;
    result.campaign = twin::simulateCampaign(options, nullptr);
    const trainer::CalibrationOutcome outcome = trainer::calibrateCampaign(result.campaign);
    result.model = trainer::modelFromOutcome(result.campaign, outcome);
    return result;
  }();
  return p;
}

std::unique_ptr<const runtime::RuntimeModel> paperModel(uint64_t model_id = kFirstModelId) {
  return runtime::RuntimeModel::fromModel(paper().model, model_id);
}

/// The paper model with a mechanism of every kind (thermal expansion about 20 °C among them).
std::unique_ptr<const runtime::RuntimeModel> mechanismModel(uint64_t model_id = kFirstModelId) {
  CalibratedModel model = paper().model;
  model.mechanisms = test::mechanismOfEveryKind();
  return runtime::RuntimeModel::fromModel(model, model_id);
}

const Measurement& validationRow(size_t i = 0) {
  const auto rows = paper().campaign.rowsIn(RowSet::kValidation);
  return *rows[i % rows.size()];
}

ServiceOptions generousOptions() {
  ServiceOptions options;
  options.budget_ns = 1'000'000'000;  // 1 s: answers independent of the machine's load
  return options;
}

correction_request_t forwardRequest(const Measurement& row, int64_t id) {
  correction_request_t msg = blankRequest();
  msg.request_id = id;
  msg.mode = correction_request_t::MODE_FORWARD;
  msg.wrench_source = correction_request_t::WRENCH_GIVEN;
  for (int j = 0; j < 6; ++j) msg.q_rad[j] = row.q_rad[j];
  for (int j = 0; j < 6; ++j) msg.wrench[j] = row.wrenchOrZero()[j];
  return msg;
}

// Asks for X (default: the row's measured pose) from 2° off the row's joints.
correction_request_t inverseRequest(const Measurement& row, int64_t id,
                                    std::optional<Pose> X_TrackerTip_desired = std::nullopt) {
  correction_request_t msg = forwardRequest(row, id);
  msg.mode = correction_request_t::MODE_INVERSE;
  toPositionQuaternion(X_TrackerTip_desired.value_or(row.X_TrackerTip()), msg.desired_position_m,
            msg.desired_quaternion_wxyz);
  for (int j = 0; j < 6; ++j) msg.seed_q_rad[j] = row.q_rad[j] + (j % 2 ? -2 : 2) * kRadPerDeg;
  return msg;
}

/// Handles bytes directly (no LCM); the decoded reply, or nullopt when none was due. Bytes whose
/// message_version reads 2 get the version-2 refusal: its id and status.
std::optional<correction_reply_t> handle(Service& service, const std::vector<uint8_t>& bytes) {
  std::vector<uint8_t> reply(static_cast<size_t>(Service::replyBytes()));
  const int size = service.handleRequest(bytes.data(), int(bytes.size()), Clock::now(),
                                         reply.data(), int(reply.size()));
  if (size == 0) return std::nullopt;
  correction_reply_t decoded;
  if (decodeReply(reply.data(), size, decoded) == ReplyKind::kOldVersion) {
    stepcal_lcm::correction_reply_v2_t refusal{};
    EXPECT_EQ(refusal.decode(reply.data(), 0, size), size);
    decoded.request_id = refusal.request_id;
    decoded.status = refusal.status;
    return decoded;
  }
  EXPECT_EQ(decodeReply(reply.data(), size, decoded), ReplyKind::kReply);
  return decoded;
}

Pose poseOf(const double* p, const double* q_wxyz) {
  Pose X = Pose::Identity();
  X.translation() = Vec3(p[0], p[1], p[2]);
  X.linear() = Eigen::Quaterniond(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]).toRotationMatrix();
  return X;
}

double poseDifference(const Pose& a, const Pose& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

/// A service on an in-process LCM, and a client side on the same instance.
class MemqService {
 public:
  explicit MemqService(ServiceOptions options = generousOptions(),
                       std::unique_ptr<const runtime::RuntimeModel> model = paperModel())
      : lcm_(lcm_create("memq://"), &lcm_destroy),
        service_(std::move(model), "paper.stepcal", options),
        server_(lcm_.get(), service_),
        feed_(lcm_.get(), kWrenchChannel, service_) {
    lcm_subscribe(lcm_.get(), kReplyChannel, &MemqService::onReply, this);
    lcm_subscribe(lcm_.get(), kStatusChannel, &MemqService::onStatus, this);
  }

  Service& service() { return service_; }
  LcmServer& server() { return server_; }
  const LcmWrenchFeed& feed() const { return feed_; }

  void publish(const char* channel, const std::vector<uint8_t>& bytes) {
    ASSERT_EQ(lcm_publish(lcm_.get(), channel, bytes.data(), unsigned(bytes.size())), 0);
  }
  /// Dispatches every queued message (requests, then the replies they publish).
  void pump() {
    while (lcm_handle_timeout(lcm_.get(), 10) > 0) {
    }
  }
  /// Publishes a request and returns the replies that came back.
  std::vector<correction_reply_t> exchange(const std::vector<uint8_t>& bytes) {
    replies_.clear();
    publish(kRequestChannel, bytes);
    pump();
    return replies_;
  }
  const std::vector<stepcal_lcm::runtime_status_t>& statuses() const { return statuses_; }

 private:
  static void onReply(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    correction_reply_t reply;
    ASSERT_EQ(decodeReply(rbuf->data, int(rbuf->data_size), reply), ReplyKind::kReply);
    static_cast<MemqService*>(user)->replies_.push_back(reply);
  }
  static void onStatus(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    stepcal_lcm::runtime_status_t status;
    ASSERT_EQ(status.decode(rbuf->data, 0, int(rbuf->data_size)), int(rbuf->data_size));
    static_cast<MemqService*>(user)->statuses_.push_back(status);
  }

  std::unique_ptr<lcm_t, void (*)(lcm_t*)> lcm_;  // first: destroyed after the subscribers
  Service service_;
  LcmServer server_;
  LcmWrenchFeed feed_;
  std::vector<correction_reply_t> replies_;
  std::vector<stepcal_lcm::runtime_status_t> statuses_;
};

TEST(LcmService, DecodeRequestKeepsEveryField) {
  const Measurement& row = validationRow(3);
  correction_request_t msg = inverseRequest(row, -42);
  msg.utime = 1234567;
  msg.deadline_us = 150;
  msg.temp_c = 23.5;
  Request request;
  ASSERT_EQ(decodeRequest(encodeRequest(msg).data(), msg.getEncodedSize(), request), Status::kOk);
  EXPECT_EQ(request.temp_c, 23.5);
  EXPECT_TRUE(request.request_id_known);
  EXPECT_EQ(request.request_id, -42);
  EXPECT_EQ(request.utime, 1234567);
  EXPECT_EQ(request.deadline_us, 150);
  EXPECT_EQ(request.mode, Mode::kInverse);
  EXPECT_EQ(request.wrench_source, WrenchSource::kGiven);
  EXPECT_EQ(request.q_rad, row.q_rad);
  EXPECT_EQ(request.terms.wrench_Sensor, row.wrenchOrZero());
  EXPECT_EQ(request.terms.load_from, runtime::LoadFrom::kWrench);
  EXPECT_EQ(request.terms.frame, runtime::PoseFrame::kTracker);
  EXPECT_EQ(request.terms.tool_from, runtime::ToolFrom::kTarget);
  EXPECT_TRUE(request.terms.X_Tool.isApprox(Pose::Identity(), 0.0));
  EXPECT_LT(poseDifference(request.X_FrameTcp_desired, row.X_TrackerTip()), 1e-15);
  EXPECT_EQ(request.seed_q_rad.size(), 6);
  EXPECT_DOUBLE_EQ(request.seed_q_rad[0], row.q_rad[0] + 2 * kRadPerDeg);

  // Not measured (NaN) is a valid temperature; so are both ends of the range.
  for (const double temp_c : {std::nan(""), -50.0, 150.0}) {
    msg.temp_c = temp_c;
    ASSERT_EQ(decodeRequest(encodeRequest(msg).data(), msg.getEncodedSize(), request), Status::kOk)
        << temp_c;
    EXPECT_TRUE(std::isnan(temp_c) ? std::isnan(request.temp_c) : request.temp_c == temp_c);
  }
}

TEST(LcmService, RequestsCarryTheTemperatureToTheModel) {
  // A model with thermal expansion (and every other mechanism): forward and inverse replies are
  // the runtime's own answers at the request's temperature, and 15 K move the tip.
  MemqService memq(generousOptions(), mechanismModel());
  const auto model = mechanismModel();
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  for (size_t i = 0; i < 10; ++i) {
    const Measurement& row = validationRow(i * 13);
    for (const double temp_c : {runtime::kUnknownTemperature_c, 35.0}) {
      correction_request_t msg = forwardRequest(row, int64_t(i));
      msg.temp_c = temp_c;
      std::vector<correction_reply_t> replies = memq.exchange(encodeRequest(msg));
      ASSERT_EQ(replies.size(), 1u);
      const runtime::ForwardResult expected =
          runtime::correctForward(*model, ws, row.q_rad, row.wrenchOrZero(), temp_c);
      ASSERT_EQ(replies[0].status, int8_t(Status::kOk));
      EXPECT_LT(poseDifference(
                    poseOf(replies[0].predicted_position_m, replies[0].predicted_quaternion_wxyz),
                    expected.X_TrackerTip),
                1e-12);
      const runtime::ForwardResult at_reference =
          runtime::correctForward(*model, ws, row.q_rad, row.wrenchOrZero(), 20.0);
      const double shift_m =
          (expected.X_TrackerTip.translation() - at_reference.X_TrackerTip.translation()).norm();
      if (std::isnan(temp_c)) {
        EXPECT_EQ(shift_m, 0.0) << "not measured is the reference temperature";
      } else {
        EXPECT_GT(shift_m, 1e-5);
      }

      correction_request_t inverse = inverseRequest(row, int64_t(100 + i), expected.X_TrackerTip);
      inverse.temp_c = temp_c;
      replies = memq.exchange(encodeRequest(inverse));
      ASSERT_EQ(replies.size(), 1u);
      EXPECT_EQ(replies[0].status, int8_t(Status::kOk));
      EXPECT_LT(replies[0].residual_position_m, 1e-6);
      for (int k = 0; k < 6; ++k) EXPECT_NEAR(replies[0].q_target_rad[k], row.q_rad[k], 1e-5);
    }
  }
}

TEST(LcmService, ForwardReplyEqualsCorrectForward) {
  MemqService memq;
  const auto model = paperModel();
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  for (size_t i = 0; i < 20; ++i) {
    const Measurement& row = validationRow(i * 7);
    const std::vector<correction_reply_t> replies =
        memq.exchange(encodeRequest(forwardRequest(row, int64_t(i))));
    ASSERT_EQ(replies.size(), 1u);
    const correction_reply_t& r = replies[0];
    const runtime::ForwardResult expected = runtime::correctForward(
        *model, ws, row.q_rad, row.wrenchOrZero(), runtime::kUnknownTemperature_c);
    ASSERT_EQ(expected.status, Status::kOk);
    EXPECT_EQ(r.request_id, int64_t(i));
    EXPECT_EQ(r.message_version, correction_reply_t::VERSION);
    EXPECT_EQ(r.status, int8_t(Status::kOk));
    EXPECT_EQ(r.model_id, int64_t(kFirstModelId));
    for (int k = 0; k < 6; ++k) EXPECT_EQ(r.wrench[k], row.wrenchOrZero()[k]) << "the wrench used";
    EXPECT_LT(poseDifference(poseOf(r.predicted_position_m, r.predicted_quaternion_wxyz),
                             expected.X_TrackerTip),
              1e-12);
    for (int k = 0; k < 6; ++k) EXPECT_EQ(r.gpr_std[k], expected.gpr_std[k]);
    EXPECT_GT(r.compute_ns, 0);
    // The model's prediction is at the measurement's noise level from what was measured.
    EXPECT_LT((expected.X_TrackerTip.translation() - row.p_TipInTracker_m).norm(), 0.2e-3);
  }
}

TEST(LcmService, InverseReplyEqualsSolveInverse) {
  MemqService memq;
  const auto model = paperModel();
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  for (size_t i = 0; i < 20; ++i) {
    const Measurement& row = validationRow(i * 11);
    // The model's own pose at the row's joints: the targets must come back to them.
    const Pose X_TrackerTip = runtime::correctForward(*model, ws, row.q_rad, row.wrenchOrZero(),
                                                      runtime::kUnknownTemperature_c)
                                  .X_TrackerTip;
    const correction_request_t msg = inverseRequest(row, int64_t(100 + i), X_TrackerTip);
    const std::vector<correction_reply_t> replies = memq.exchange(encodeRequest(msg));
    ASSERT_EQ(replies.size(), 1u);
    const correction_reply_t& r = replies[0];
    Request request;
    ASSERT_EQ(decodeRequest(encodeRequest(msg).data(), msg.getEncodedSize(), request), Status::kOk);
    const runtime::InverseResult expected = runtime::solveInverse(
        *model, ws, request.X_FrameTcp_desired, request.terms.wrench_Sensor,
        runtime::kUnknownTemperature_c, request.seed_q_rad, Clock::now() + std::chrono::seconds(1));
    EXPECT_EQ(r.status, int8_t(expected.status));
    EXPECT_EQ(r.status, int8_t(Status::kOk));
    EXPECT_EQ(r.iterations, expected.iterations);
    for (int k = 0; k < 6; ++k) EXPECT_EQ(r.q_target_rad[k], expected.q_target_rad[k]);
    EXPECT_LT(poseDifference(poseOf(r.commanded_position_m, r.commanded_quaternion_wxyz),
                             expected.X_BaseTip_commanded),
              1e-12);
    EXPECT_LT(poseDifference(poseOf(r.predicted_position_m, r.predicted_quaternion_wxyz),
                             expected.X_TrackerTip_predicted),
              1e-12);
    EXPECT_EQ(r.residual_position_m, expected.residual_position_m);
    EXPECT_LT(r.residual_position_m, 1e-6);
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(r.q_target_rad[k], row.q_rad[k], 1e-5);
  }
}

TEST(LcmService, BadRequestsGetBadRequestOrAreCounted) {
  MemqService memq;
  const Measurement& row = validationRow();
  const auto badReply = [&](const correction_request_t& msg) {
    const std::vector<correction_reply_t> replies = memq.exchange(encodeRequest(msg));
    EXPECT_EQ(replies.size(), 1u);
    return !replies.empty() && replies[0].status == int8_t(Status::kBadRequest) &&
           replies[0].request_id == msg.request_id;
  };
  correction_request_t msg = forwardRequest(row, 1);
  msg.q_rad[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(badReply(msg));
  msg = forwardRequest(row, 2);
  msg.wrench[4] = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(badReply(msg));
  msg = forwardRequest(row, 3);
  msg.mode = 7;
  EXPECT_TRUE(badReply(msg));
  msg = forwardRequest(row, 4);
  msg.wrench_source = -1;
  EXPECT_TRUE(badReply(msg));
  msg = inverseRequest(row, 5);
  msg.desired_quaternion_wxyz[1] += 1e-3;  // norm off by more than 1e-6
  EXPECT_TRUE(badReply(msg));
  msg = inverseRequest(row, 6);
  msg.desired_position_m[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(badReply(msg));
  // A temperature is NaN (not measured) or within −50 … 150 °C.
  for (const double temp_c : {std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity(), 150.5, -50.5, 1e9}) {
    msg = forwardRequest(row, 7);
    msg.temp_c = temp_c;
    EXPECT_TRUE(badReply(msg)) << temp_c;
    msg = inverseRequest(row, 8);
    msg.temp_c = temp_c;
    EXPECT_TRUE(badReply(msg)) << temp_c;
  }

  // Truncated: a reply when the id can be read, none (counted) below 16 bytes.
  const std::vector<uint8_t> good = encodeRequest(forwardRequest(row, 77));
  for (size_t size = 0; size < good.size(); ++size) {
    const std::vector<uint8_t> truncated(good.begin(), good.begin() + long(size));
    const int64_t unaddressable = memq.service().counters().unaddressable;
    const std::optional<correction_reply_t> reply = handle(memq.service(), truncated);
    if (size >= 16) {
      ASSERT_TRUE(reply) << size;
      EXPECT_EQ(reply->request_id, 77);
      EXPECT_EQ(reply->status, int8_t(Status::kBadRequest));
    } else {
      EXPECT_FALSE(reply) << size;
      EXPECT_EQ(memq.service().counters().unaddressable, unaddressable + 1);
    }
  }
  std::vector<uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_EQ(handle(memq.service(), longer)->status, int8_t(Status::kBadRequest));

  // Garbage of every length never crashes and gets no reply (wrong fingerprint).
  std::mt19937_64 rng(7);
  const int64_t unaddressable = memq.service().counters().unaddressable;
  for (int i = 0; i < 5000; ++i) {
    std::vector<uint8_t> garbage(size_t(rng() % 400));
    for (uint8_t& b : garbage) b = uint8_t(rng());
    EXPECT_FALSE(handle(memq.service(), garbage));
  }
  EXPECT_EQ(memq.service().counters().unaddressable, unaddressable + 5000);
  // The right fingerprint with random contents: always a reply, never a crash.
  for (int i = 0; i < 5000; ++i) {
    std::vector<uint8_t> random = good;
    for (size_t b = 8; b < random.size(); ++b) {
      if (rng() % 8 == 0) random[b] = uint8_t(rng());
    }
    EXPECT_TRUE(handle(memq.service(), random));
  }
  memq.publish(kRequestChannel, {1, 2, 3});
  memq.pump();
  // Still answering.
  const std::vector<correction_reply_t> replies = memq.exchange(good);
  ASSERT_EQ(replies.size(), 1u);
  EXPECT_EQ(replies[0].status, int8_t(Status::kOk));
}

// A client of message version 1 (the layout before tools, frames and payloads) is refused by
// name: a version-1 BAD_REQUEST reply it can read, counted as old_version_requests, never a
// misread; with a key such requests are dropped (they carry no code), counted alike.
TEST(LcmService, AVersion1RequestIsRefusedByName) {
  const Measurement& row = validationRow();
  stepcal_lcm::correction_request_v1_t old{};
  old.request_id = 4242;
  old.mode = stepcal_lcm::correction_request_v1_t::MODE_FORWARD;
  old.wrench_source = stepcal_lcm::correction_request_v1_t::WRENCH_GIVEN;
  old.desired_quaternion_wxyz[0] = 1.0;
  old.temp_c = std::nan("");
  for (int j = 0; j < 6; ++j) old.q_rad[j] = row.q_rad[j];
  std::vector<uint8_t> bytes(size_t(old.getEncodedSize()));
  ASSERT_EQ(old.encode(bytes.data(), 0, int(bytes.size())), int(bytes.size()));

  Request request;
  EXPECT_EQ(decodeRequest(bytes.data(), int(bytes.size()), request), Status::kBadRequest);
  EXPECT_TRUE(request.old_version);
  EXPECT_TRUE(request.request_id_known);
  EXPECT_EQ(request.request_id, 4242);
  ASSERT_NE(stepcal_lcm::correction_request_v1_t::getHash(), correction_request_t::getHash());

  Service service(paperModel(), "paper.stepcal", generousOptions());
  std::vector<uint8_t> reply(static_cast<size_t>(Service::replyBytes()));
  const int size = service.handleRequest(bytes.data(), int(bytes.size()), Clock::now(),
                                         reply.data(), int(reply.size()));
  stepcal_lcm::correction_reply_v1_t refusal{};
  ASSERT_GT(size, 0);
  ASSERT_EQ(refusal.decode(reply.data(), 0, size), size) << "a reply the old client can read";
  EXPECT_EQ(refusal.request_id, 4242);
  EXPECT_EQ(refusal.status, stepcal_lcm::correction_reply_v1_t::STATUS_BAD_REQUEST);
  EXPECT_EQ(refusal.model_id, int64_t(kFirstModelId));
  EXPECT_EQ(service.counters().old_version, 1);
  EXPECT_EQ(service.counters().status_counts[size_t(Status::kBadRequest)], 1);
  EXPECT_EQ(service.status(false).old_version_requests, 1);
  correction_reply_t as_new{};
  EXPECT_EQ(decodeReply(reply.data(), size, as_new), ReplyKind::kOldVersion)
      << "and no new client misreads it";

  ServiceOptions keyed = generousOptions();
  keyed.key = CellKey::fromBytes({});
  Service with_key(paperModel(), "paper.stepcal", keyed);
  EXPECT_EQ(with_key.handleRequest(bytes.data(), int(bytes.size()), Clock::now(), reply.data(),
                                   int(reply.size())),
            0);
  EXPECT_EQ(with_key.counters().old_version, 1);
  EXPECT_EQ(with_key.counters().forged, 0);
}

// A client of message version 2 (this request layout, message_version 2; it reads only
// correction_reply_v2_t) is refused by name: a version-2 BAD_REQUEST reply it can read, counted
// as old_version_requests; with a key its code is checked as any request's and the refusal is
// sealed for it.
TEST(LcmService, AVersion2RequestIsRefusedByName) {
  correction_request_t old = forwardRequest(validationRow(), 4343);
  old.message_version = 2;
  const std::vector<uint8_t> bytes = encodeRequest(old);
  Service service(paperModel(), "paper.stepcal", generousOptions());
  std::vector<uint8_t> reply(static_cast<size_t>(Service::replyBytes()));
  const int size = service.handleRequest(bytes.data(), int(bytes.size()), Clock::now(),
                                         reply.data(), int(reply.size()));
  stepcal_lcm::correction_reply_v2_t refusal{};
  ASSERT_GT(size, 0);
  ASSERT_EQ(refusal.decode(reply.data(), 0, size), size) << "a reply the old client can read";
  EXPECT_EQ(refusal.request_id, 4343);
  EXPECT_EQ(refusal.message_version, 2);
  EXPECT_EQ(refusal.status, stepcal_lcm::correction_reply_v2_t::STATUS_BAD_REQUEST);
  EXPECT_EQ(refusal.model_id, int64_t(kFirstModelId));
  EXPECT_EQ(service.counters().old_version, 1);
  EXPECT_EQ(service.counters().status_counts[size_t(Status::kBadRequest)], 1);
  EXPECT_EQ(service.status(false).old_version_requests, 1);
  correction_reply_t as_new{};
  EXPECT_EQ(decodeReply(reply.data(), size, as_new), ReplyKind::kOldVersion)
      << "and no new client misreads it";

  ServiceOptions keyed = generousOptions();
  keyed.key = CellKey::fromBytes({});
  Service with_key(paperModel(), "paper.stepcal", keyed);
  MessageSigner client(*keyed.key);
  std::vector<uint8_t> sealed = bytes;
  client.seal(sealed.data(), int(sealed.size()));
  const int sealed_size = with_key.handleRequest(sealed.data(), int(sealed.size()), Clock::now(),
                                                 reply.data(), int(reply.size()));
  ASSERT_GT(sealed_size, 0);
  MessageVerifier verifier(*keyed.key, kDefaultAuthWindowUs);
  EXPECT_EQ(verifier.verify(reply.data(), sealed_size, unixMicroseconds()), Verdict::kAuthentic);
  EXPECT_EQ(oldReplyVersion(reply.data(), sealed_size), 2);
  EXPECT_EQ(with_key.counters().old_version, 1);
  // Unsealed: dropped as forged, as any request without the cell's code.
  EXPECT_EQ(with_key.handleRequest(bytes.data(), int(bytes.size()), Clock::now(), reply.data(),
                                   int(reply.size())),
            0);
  EXPECT_EQ(with_key.counters().forged, 1);
}

TEST(LcmService, StaleLiveWrenchIsStaleWrench) {
  ServiceOptions options = generousOptions();
  // Ages far apart, so a descheduled test thread can neither freshen nor stale a sample.
  options.max_wrench_age_ns = 500'000'000;
  MemqService memq(options);
  const Measurement& row = validationRow();
  correction_request_t msg = forwardRequest(row, 9);
  msg.wrench_source = correction_request_t::WRENCH_LIVE_SENSOR;
  const auto status = [&] {
    const std::vector<correction_reply_t> replies = memq.exchange(encodeRequest(msg));
    EXPECT_EQ(replies.size(), 1u);
    return replies.empty() ? Status::kOk : static_cast<Status>(replies[0].status);
  };
  EXPECT_EQ(status(), Status::kStaleWrench);  // nothing published yet

  const auto nowNs = [] {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
        .count();
  };
  runtime::WrenchSample sample;
  sample.wrench_Sensor = row.wrenchOrZero();
  sample.stamp_ns = nowNs() - 5'000'000'000;  // 5 s old
  memq.service().publishWrench(sample);
  EXPECT_EQ(status(), Status::kStaleWrench);
  sample.stamp_ns = nowNs();
  sample.sensor_status = 3;  // a sensor fault
  memq.service().publishWrench(sample);
  EXPECT_EQ(status(), Status::kStaleWrench);

  // A fresh wrench_t through the LCM feed: the same answer as the wrench given in the request.
  stepcal_lcm::wrench_t wrench{};
  for (int k = 0; k < 6; ++k) wrench.wrench[k] = row.wrenchOrZero()[k];
  wrench.sequence = 1;
  std::vector<uint8_t> bytes(size_t(wrench.getEncodedSize()));
  wrench.encode(bytes.data(), 0, int(bytes.size()));
  memq.publish(kWrenchChannel, bytes);
  std::vector<correction_reply_t> live = memq.exchange(encodeRequest(msg));
  const std::vector<correction_reply_t> given = memq.exchange(encodeRequest(forwardRequest(row, 9)));
  ASSERT_EQ(live.size(), 1u);
  ASSERT_EQ(given.size(), 1u);
  EXPECT_EQ(live[0].status, int8_t(Status::kOk));
  for (int k = 0; k < 3; ++k) EXPECT_EQ(live[0].predicted_position_m[k], given[0].predicted_position_m[k]);

  memq.publish(kWrenchChannel, {9, 9, 9});
  memq.pump();
  EXPECT_EQ(memq.feed().undecodable(), 1);
}

/// Every message on one channel of an LCM instance, as bytes.
struct ChannelLog {
  std::vector<std::vector<uint8_t>> messages;
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    const auto* data = static_cast<const uint8_t*>(rbuf->data);
    static_cast<ChannelLog*>(user)->messages.emplace_back(data, data + rbuf->data_size);
  }
};

// The CAN feed with the simulated sensor on a socketpair (the same driver runs on vcan in
// test_ft_sensor): live requests use its wrench, stamped; commands arrive over LCM; its health and
// the republished samples leave over LCM.
TEST(LcmService, CanFeedServesTheLiveWrenchAndTakesCommands) {
  const std::unique_ptr<lcm_t, void (*)(lcm_t*)> lcm(lcm_create("memq://"), &lcm_destroy);
  ServiceOptions service_options = generousOptions();
  service_options.max_wrench_age_ns = 1'000'000'000;  // what is tested is the wrench, not its age
  Service service(paperModel(), "paper.stepcal", service_options);
  LcmServer server(lcm.get(), service);
  int ends[2];
  ASSERT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, ends), 0);
  runtime::CanSocket sensor_end = runtime::CanSocket::adopt(ends[1], "socketpair");
  const Measurement& row = validationRow(3);
  ftsim::SensorSimulator simulator({});
  simulator.setWrench(row.wrenchOrZero());
  std::atomic<bool> stop{false};
  std::thread sensor([&] { simulator.serve(sensor_end, stop); });

  ChannelLog replies, statuses, republished;
  lcm_subscribe(lcm.get(), kReplyChannel, &ChannelLog::on, &replies);
  lcm_subscribe(lcm.get(), kSensorStatusChannel, &ChannelLog::on, &statuses);
  lcm_subscribe(lcm.get(), "CAN_WRENCH", &ChannelLog::on, &republished);
  {
    runtime::FtSensorOptions options;
    options.bias_samples = 2;
    options.poll_hz = 100.0;  // republished samples 10 ms apart: pump() (5 ms idle) returns
    CanWrenchFeed feed(lcm.get(), runtime::CanSocket::adopt(ends[0], "socketpair"), options,
                       "CAN_WRENCH", service);
    EXPECT_NE(feed.describe().find("serial FT24093"), std::string::npos) << feed.describe();
    const auto pump = [&] {
      while (lcm_handle_timeout(lcm.get(), 5) > 0) {
      }
    };
    correction_request_t live = forwardRequest(row, 21);
    live.wrench_source = correction_request_t::WRENCH_LIVE_SENSOR;
    const auto ask = [&](const correction_request_t& msg) {
      replies.messages.clear();
      const std::vector<uint8_t> bytes = encodeRequest(msg);
      lcm_publish(lcm.get(), kRequestChannel, bytes.data(), unsigned(bytes.size()));
      pump();
      correction_reply_t reply{};
      EXPECT_EQ(replies.messages.size(), 1u);
      if (!replies.messages.empty()) {
        decodeReply(replies.messages[0].data(), int(replies.messages[0].size()), reply);
      }
      return reply;
    };
    while (feed.driver().counters().samples < 3) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const int64_t before_ns = runtime::steadyNowNs();
    const correction_reply_t from_sensor = ask(live);
    const correction_reply_t from_row = ask(forwardRequest(row, 22));
    ASSERT_EQ(from_sensor.status, int8_t(Status::kOk));
    EXPECT_GT(from_sensor.wrench_stamp_ns, before_ns - service_options.max_wrench_age_ns);
    EXPECT_LE(from_sensor.wrench_stamp_ns, runtime::steadyNowNs());
    EXPECT_EQ(from_row.wrench_stamp_ns, 0) << "a given wrench has no stamp";
    // The sensor rounds the wrench to whole gauge counts (≈ 0.05 N): far below a micrometre.
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(from_sensor.predicted_position_m[k], from_row.predicted_position_m[k], 1e-7);
    }

    stepcal_lcm::sensor_command_t bias{};
    bias.command = stepcal_lcm::sensor_command_t::COMMAND_BIAS;
    std::vector<uint8_t> bytes(size_t(bias.getEncodedSize()));
    bias.encode(bytes.data(), 0, int(bytes.size()));
    lcm_publish(lcm.get(), kSensorCommandChannel, bytes.data(), unsigned(bytes.size()));
    pump();
    while (!feed.driver().biased()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    // Garbage and unknown commands change nothing and are counted.
    lcm_publish(lcm.get(), kSensorCommandChannel, bytes.data(), unsigned(bytes.size() - 1));
    bias.command = 42;
    bias.encode(bytes.data(), 0, int(bytes.size()));
    lcm_publish(lcm.get(), kSensorCommandChannel, bytes.data(), unsigned(bytes.size()));
    pump();
    EXPECT_EQ(feed.refusedCommands(), 2);
    EXPECT_TRUE(feed.driver().biased());
    // Two samples more: the second is published after the first, which the bias already tares.
    const int64_t samples = feed.driver().counters().samples;
    while (feed.driver().counters().samples < samples + 2) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    correction_request_t unloaded = forwardRequest(row, 23);
    for (double& w : unloaded.wrench) w = 0.0;
    const correction_reply_t tared = ask(live);
    const correction_reply_t zero = ask(unloaded);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(tared.predicted_position_m[k], zero.predicted_position_m[k], 1e-12)
          << "after the tare the sensor reads zero";
    }

    feed.publishStatus();
    pump();
    ASSERT_EQ(statuses.messages.size(), 1u);
    stepcal_lcm::sensor_status_t status{};
    status.decode(statuses.messages[0].data(), 0, int(statuses.messages[0].size()));
    EXPECT_EQ(status.serial, "FT24093");
    EXPECT_EQ(status.firmware, "3.2.41");
    EXPECT_EQ(status.state, stepcal_lcm::sensor_status_t::STATE_RUNNING);
    EXPECT_EQ(status.biased, 1);
    EXPECT_GT(status.samples, 3);
    EXPECT_LE(status.polls - status.timeouts - status.samples, 1) << "one poll may be in flight";
    pump();
    EXPECT_GE(int64_t(republished.messages.size()), 1);
    stepcal_lcm::wrench_t sample{};
    ASSERT_GT(sample.decode(republished.messages.back().data(), 0, int(republished.messages.back().size())), 0);
    EXPECT_GT(sample.sequence, 0);
  }
  stop = true;
  sensor.join();
}

TEST(LcmService, ReloadKeepsAnsweringAndChangesTheModelId) {
  MemqService memq;
  Service& service = memq.service();
  EXPECT_EQ(service.modelId(), kFirstModelId);
  std::atomic<bool> reloaded{false};
  std::thread reloader([&] {
    service.reload(paperModel(kSecondModelId), "second.stepcal");
    reloaded = true;
  });
  int answers = 0;
  int64_t last_model = 0;
  for (int64_t id = 0; !reloaded || answers < 10; ++id) {
    const std::vector<correction_reply_t> replies =
        memq.exchange(encodeRequest(forwardRequest(validationRow(size_t(id)), id)));
    ASSERT_EQ(replies.size(), 1u);
    EXPECT_EQ(replies[0].status, int8_t(Status::kOk));
    last_model = replies[0].model_id;
    EXPECT_TRUE(last_model == int64_t(kFirstModelId) || last_model == int64_t(kSecondModelId));
    ++answers;
  }
  reloader.join();
  EXPECT_EQ(service.modelId(), kSecondModelId);
  EXPECT_EQ(last_model, int64_t(kSecondModelId));

  // A bad file is refused and the model in service kept.
  const test::TempDir dir;
  const std::string bad = (dir.path() / "bad.stepcal").string();
  test::writeText(bad, "not a model");
  EXPECT_THROW(service.reloadFile(bad), InputError);
  EXPECT_THROW(service.reloadFile((dir.path() / "missing.stepcal").string()), InputError);
  EXPECT_EQ(service.modelId(), kSecondModelId);
  const std::string good = (dir.path() / "paper.stepcal").string();
  writeModelFile(paper().model, good);
  service.reloadFile(good);
  EXPECT_NE(service.modelId(), kSecondModelId);
  const std::vector<correction_reply_t> replies =
      memq.exchange(encodeRequest(forwardRequest(validationRow(), 1)));
  ASSERT_EQ(replies.size(), 1u);
  EXPECT_EQ(replies[0].model_id, int64_t(service.modelId()));

  // The status message names the file in service.
  memq.server().publishStatus(false);
  memq.pump();
  ASSERT_FALSE(memq.statuses().empty());
  EXPECT_EQ(memq.statuses().back().model_path, good);
  EXPECT_EQ(memq.statuses().back().model_id, int64_t(service.modelId()));
}

/// The paper model cut down to its first five joints (no compliance, no GPR).
CalibratedModel fiveJointModel() {
  const CalibratedModel& six = paper().model;
  const auto cut = [](const KinematicChain& chain) {
    std::vector<ChainJoint> joints(chain.joints().begin(), chain.joints().begin() + 5);
    std::vector<Pose> poses(chain.initialPoses().begin(), chain.initialPoses().begin() + 6);
    return KinematicChain(joints, poses);
  };
  CalibratedModel five;
  five.chain_Tracker = cut(six.chain_Tracker);
  five.nominal_Base = cut(six.nominal_Base);
  five.X_TrackerBase = six.X_TrackerBase;
  return five;
}

TEST(LcmService, ModelsWithOtherThanSixJointsAreRefused) {
  MemqService memq;
  ASSERT_EQ(runtime::RuntimeModel::fromModel(fiveJointModel(), 5)->file.chain_Tracker.dof(), 5);
  EXPECT_THROW(Service(runtime::RuntimeModel::fromModel(fiveJointModel(), 5), "five", {}),
               InputError);
  EXPECT_THROW(
      memq.service().reload(runtime::RuntimeModel::fromModel(fiveJointModel(), 5), "five"),
      InputError);
  EXPECT_EQ(memq.service().modelId(), kFirstModelId);
}

TEST(LcmService, StatusCountsRepliesAndComputeTimes) {
  MemqService memq;
  for (int64_t id = 0; id < 30; ++id) memq.exchange(encodeRequest(forwardRequest(validationRow(size_t(id)), id)));
  correction_request_t bad = forwardRequest(validationRow(), 99);
  bad.mode = 3;
  memq.exchange(encodeRequest(bad));
  memq.server().publishStatus(true);
  memq.pump();
  ASSERT_EQ(memq.statuses().size(), 1u);
  const stepcal_lcm::runtime_status_t& s = memq.statuses()[0];
  EXPECT_EQ(s.requests, 31);
  EXPECT_EQ(s.replies, 31);
  EXPECT_EQ(s.status_counts[int(Status::kOk)], 30);
  EXPECT_EQ(s.status_counts[int(Status::kBadRequest)], 1);
  EXPECT_GT(s.p50_us, 0.0);
  EXPECT_LE(s.p50_us, s.p99_us);
  EXPECT_LE(s.p99_us, s.max_us);
  EXPECT_EQ(s.realtime, 1);
  EXPECT_EQ(s.model_path, "paper.stepcal");
  EXPECT_EQ(s.model_id, int64_t(kFirstModelId));
  // A new window starts after each status.
  EXPECT_EQ(memq.service().status(false).max_us, 0.0);
}

TEST(LcmService, HandlingARequestAllocatesNothing) {
  Service service(paperModel(), "paper.stepcal", generousOptions());
  Service with_mechanisms(mechanismModel(), "mechanisms.stepcal", generousOptions());
  const auto model = mechanismModel();
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  std::vector<std::vector<uint8_t>> requests, mechanism_requests;
  for (size_t i = 0; i < 20; ++i) {
    requests.push_back(encodeRequest(forwardRequest(validationRow(i), int64_t(i))));
    requests.push_back(encodeRequest(inverseRequest(validationRow(i), int64_t(i))));
    // With mechanisms: at 18 … 37 °C, the inverse asking for the model's own pose.
    const Measurement& row = validationRow(i);
    const double temp_c = 18.0 + double(i);
    correction_request_t forward = forwardRequest(row, int64_t(i));
    forward.temp_c = temp_c;
    correction_request_t inverse = inverseRequest(
        row, int64_t(i),
        runtime::correctForward(*model, ws, row.q_rad, row.wrenchOrZero(), temp_c).X_TrackerTip);
    inverse.temp_c = temp_c;
    mechanism_requests.push_back(encodeRequest(forward));
    mechanism_requests.push_back(encodeRequest(inverse));
  }
  // In the controller's terms: a user frame, a tool from the flange, a payload.
  const auto paper_model = paperModel();
  runtime::Workspace paper_ws = runtime::makeWorkspace(*paper_model);
  runtime::CallTerms terms;
  terms.frame = runtime::PoseFrame::kUser;
  terms.X_BaseUser.translation() = Vec3(1.2, 0.3, 0.1);
  terms.tool_from = runtime::ToolFrom::kFlange;
  terms.X_Tool.translation() = Vec3(0.0, 0.05, 0.3);
  terms.load_from = runtime::LoadFrom::kPayload;
  terms.payload.mass_kg = 30.0;
  terms.payload.p_CoG_m = Vec3(0.0, 0.0, 0.1);
  for (size_t i = 0; i < 10; ++i) {
    const Measurement& row = validationRow(i * 3);
    correction_request_t msg = forwardRequest(row, int64_t(100 + i));
    msg.frame = correction_request_t::FRAME_USER;
    msg.user_frame_position_m[0] = 1.2;
    msg.user_frame_position_m[1] = 0.3;
    msg.user_frame_position_m[2] = 0.1;
    msg.tool_from = correction_request_t::TOOL_FROM_FLANGE;
    msg.tool_position_m[1] = 0.05;
    msg.tool_position_m[2] = 0.3;
    msg.wrench_source = correction_request_t::WRENCH_PAYLOAD;
    msg.payload_kg = 30.0;
    msg.payload_cog_m[2] = 0.1;
    requests.push_back(encodeRequest(msg));
    const Pose X = runtime::correctForward(*paper_model, paper_ws, row.q_rad, terms,
                                           runtime::kUnknownTemperature_c).X_FrameTcp;
    correction_request_t inverse = inverseRequest(row, int64_t(200 + i), X);
    std::copy(msg.user_frame_position_m, msg.user_frame_position_m + 3, inverse.user_frame_position_m);
    inverse.frame = msg.frame;
    inverse.tool_from = msg.tool_from;
    std::copy(msg.tool_position_m, msg.tool_position_m + 3, inverse.tool_position_m);
    inverse.wrench_source = msg.wrench_source;
    inverse.payload_kg = msg.payload_kg;
    inverse.payload_cog_m[2] = 0.1;
    requests.push_back(encodeRequest(inverse));
  }
  correction_request_t live = forwardRequest(validationRow(), 5);
  live.wrench_source = correction_request_t::WRENCH_LIVE_SENSOR;
  requests.push_back(encodeRequest(live));
  requests.push_back({1, 2, 3});
  requests.push_back(std::vector<uint8_t>(requests[0].begin(), requests[0].end() - 3));
  std::vector<uint8_t> reply(static_cast<size_t>(Service::replyBytes()));
  const auto handleAll = [&](Service& server, const std::vector<std::vector<uint8_t>>& all) {
    int ok = 0;
    for (const auto& bytes : all) {
      const int size = server.handleRequest(bytes.data(), int(bytes.size()), Clock::now(),
                                            reply.data(), int(reply.size()));
      ok += size > 0 && reply[8 + 8 + 2 + 8] == uint8_t(Status::kOk);  // after id, version, utime
    }
    return ok;
  };
  handleAll(service, requests);  // warm-up: first-call statics (fingerprints)
  long allocations = 0;
  int ok = 0, ok_mechanisms = 0;
  {
    const test::AllocationCounter counter;
    ok = handleAll(service, requests);
    ok_mechanisms = handleAll(with_mechanisms, mechanism_requests);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(ok, 60);
  EXPECT_EQ(ok_mechanisms, 40);
}

// ---- the daemon and the client as processes (memq:// or no LCM at all: no network needed) ---

using test::CommandResult;
using test::run;

const std::string kDaemon = std::string(STEPCAL_BIN_DIR) + "/stepcal-runtime";

TEST(LcmService, DaemonRefusesWhatItCannotServeWithExitStatus2) {
  const test::TempDir dir;
  const std::string missing = (dir.path() / "missing.stepcal").string();
  CommandResult r = run(kDaemon + " --model " + missing);
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find(missing), std::string::npos) << r.out;

  const std::string five = (dir.path() / "five.stepcal").string();
  writeModelFile(fiveJointModel(), five);
  r = run(kDaemon + " --model " + five);
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("5 joints"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(five), std::string::npos) << r.out;

  r = run(kDaemon + " --model " + five + " --budget-us 0");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("--budget-us"), std::string::npos) << r.out;

  const std::string six = (dir.path() / "six.stepcal").string();
  writeModelFile(paper().model, six);
  // No such interface (and on this kernel perhaps no SocketCAN at all): named, with a hint.
  r = run(kDaemon + " --model " + six + " --sensor can:nocan9 --lcm-url memq://");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("CAN interface 'nocan9'"), std::string::npos) << r.out;
  r = run(kDaemon + " --model " + six + " --sensor serial:/dev/ttyS0 --lcm-url memq://");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("expected lcm"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("can:IFACE"), std::string::npos) << r.out;
}

TEST(LcmService, DaemonReloadsOnSighupAndStopsOnSigterm) {
  const test::TempDir dir;
  const std::string model = (dir.path() / "model.stepcal").string();
  const std::string log = (dir.path() / "daemon.log").string();
  writeModelFile(paper().model, model);
  // Waits (up to 20 s) until the log holds a line with the text.
  const std::string await = "await() { for i in $(seq 200); do grep -q \"$1\" " + log +
                            " && return; sleep 0.1; done; echo timeout: $1; }; ";
  const CommandResult r = run(
      await + kDaemon + " --model " + model + " --lcm-url memq:// 2>" + log + " & pid=$!; " +
      "await serving; kill -HUP $pid; await reloaded; " +
      "echo garbage > " + model + "; kill -HUP $pid; await 'reload refused'; " +
      "kill -TERM $pid; wait $pid; echo exit=$?; cat " + log);
  EXPECT_EQ(r.out.find("timeout"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("exit=0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("reloaded " + model), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("reload refused, keeping model"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not a stepcal model file"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("stopping"), std::string::npos) << r.out;
}

const std::string kClient = std::string(STEPCAL_BIN_DIR) + "/stepcal-client";

TEST(LcmService, ClientRefusesBadArgumentsWithExitStatus2) {
  const test::TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "choose exactly one"},
      {"--forward 1 2 3 4 5 6 --ping 3", "choose exactly one"},
      {"--campaign " + (dir.path() / "none").string(), (dir.path() / "none").string()},
      {"--forward 1 2 3 4 5 6 --seed 1 2 3 4 5 6", "--seed"},
      {"--forward 1 2 3 4 5 6 --timeout-ms 0", "--timeout-ms"},
      {"--forward 1 2 3 4 5 6 --lcm-url nowhere://", "--lcm-url"},
      {"--forward 1 2 3 4 5 6 --temp-c 150.5", "--temp-c"},
      {"--forward 1 2 3 4 5 6 --temp-c inf", "--temp-c"},
      {"--campaign " + (dir.path() / "none").string() + " --temp-c 20", "--temp-c"},
  };
  for (const auto& [args, expected] : cases) {
    const CommandResult r = run(kClient + " " + args);
    EXPECT_EQ(r.status, 2) << args << ": " << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << args << ": " << r.out;
  }
}

// ---- real UDP multicast (udpm://) --------------------------------------------------------------

/// Datagrams the kernel dropped for full socket receive buffers in this network namespace
/// (RcvbufErrors of the Udp line in /proc/net/snmp), or −1 when it cannot be read.
int64_t udpReceiveBufferErrors() {
  std::FILE* snmp = std::fopen("/proc/net/snmp", "r");
  if (snmp == nullptr) return -1;
  char line[1024];
  int column = -1;
  int64_t errors = -1;
  while (std::fgets(line, sizeof line, snmp) != nullptr) {
    if (std::strncmp(line, "Udp: ", 5) != 0) continue;
    std::vector<std::string> fields;
    for (char* f = std::strtok(line + 5, " \n"); f != nullptr; f = std::strtok(nullptr, " \n")) {
      fields.emplace_back(f);
    }
    if (column < 0) {  // the header line names the columns
      for (size_t k = 0; k < fields.size(); ++k) {
        if (fields[k] == "RcvbufErrors") column = int(k);
      }
    } else if (column < int(fields.size())) {
      errors = std::stoll(fields[size_t(column)]);
    }
  }
  std::fclose(snmp);
  return errors;
}

/// Messages received on a channel.
struct MessageCount {
  int messages = 0;
  static void on(const lcm_recv_buf_t*, const char*, void* user) {
    ++static_cast<MessageCount*>(user)->messages;
  }
};

/// Dispatches what an LCM instance has queued, until it has nothing for 200 ms.
void drain(lcm_t* lcm) {
  while (lcm_handle_timeout(lcm, 200) > 0) {
  }
}

// Over real UDP multicast (udpm://; ctest net_lcm_queue runs this in a private network namespace
// through tests/system/in_netns.sh): requests that arrive while the serving thread handles nothing (a
// stall: the machine preempting it, slow answers under ASan) are all answered once it handles
// again, and a client that handles nothing meanwhile still gets every reply. A subscription with
// LCM's default queue capacity, stalled alike, keeps only 30 of them and drops the rest without
// a word: what lost the long run's replies (docs/runtime.md).
TEST(LcmUdpm, MessagesQueuedDuringAStallAreAllHandled) {
  if (std::getenv("STEPCAL_NETNS") == nullptr) {
    GTEST_SKIP() << "needs a private network namespace with multicast on its loopback "
                    "(tests/system/in_netns.sh; ctest -R net_lcm_queue)";
  }
  // 4 MB socket buffers hold the whole burst in the kernel, whatever the receive threads' pace:
  // what is tested is LCM's queue.
  const std::string url = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304";
  constexpr int kStalledRequests = 600;  // 0.3 s of the long run's 2 kHz; 20 × LCM's default
  static_assert(kStalledRequests <= kSubscriptionQueueCapacity);
  using LcmPtr = std::unique_ptr<lcm_t, void (*)(lcm_t*)>;
  const LcmPtr daemon_lcm(lcm_create(url.c_str()), &lcm_destroy);
  const LcmPtr client_lcm(lcm_create(url.c_str()), &lcm_destroy);
  const LcmPtr bystander_lcm(lcm_create(url.c_str()), &lcm_destroy);
  ASSERT_TRUE(daemon_lcm && client_lcm && bystander_lcm) << url;
  Service service(paperModel(), "paper.stepcal", generousOptions());
  LcmServer server(daemon_lcm.get(), service);
  ChannelLog replies;
  subscribeQueued(client_lcm.get(), kReplyChannel, &ChannelLog::on, &replies);
  MessageCount with_default_queue;
  lcm_subscribe(bystander_lcm.get(), kRequestChannel, &MessageCount::on, &with_default_queue);
  const int64_t kernel_drops_before = udpReceiveBufferErrors();

  for (int i = 0; i < kStalledRequests; ++i) {
    const std::vector<uint8_t> bytes = encodeRequest(forwardRequest(validationRow(size_t(i)), i));
    ASSERT_EQ(lcm_publish(client_lcm.get(), kRequestChannel, bytes.data(), unsigned(bytes.size())), 0);
    std::this_thread::sleep_for(std::chrono::microseconds(100));  // 10 kHz: receivers keep pace
  }
  // LCM's receive threads take every datagram in while no thread handles them.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  drain(daemon_lcm.get());  // the serving thread runs again: a reply leaves per request
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  drain(client_lcm.get());  // and so does the client
  drain(bystander_lcm.get());

  EXPECT_EQ(udpReceiveBufferErrors(), kernel_drops_before)
      << "the kernel dropped datagrams (socket buffers full): this test is about LCM's queue";
  EXPECT_EQ(service.counters().requests, kStalledRequests) << "requests lost before the daemon";
  ASSERT_EQ(int(replies.messages.size()), kStalledRequests) << "replies lost before the client";
  std::vector<bool> answered(size_t(kStalledRequests), false);
  for (const std::vector<uint8_t>& bytes : replies.messages) {
    correction_reply_t reply;
    ASSERT_EQ(decodeReply(bytes.data(), int(bytes.size()), reply), ReplyKind::kReply);
    ASSERT_GE(reply.request_id, 0);
    ASSERT_LT(reply.request_id, kStalledRequests);
    EXPECT_FALSE(answered[size_t(reply.request_id)]) << "two replies to " << reply.request_id;
    answered[size_t(reply.request_id)] = true;
    EXPECT_EQ(reply.status, int8_t(Status::kOk));
  }
  // LCM 1.3.1 keeps one more than its stated capacity: 31 here.
  EXPECT_NEAR(with_default_queue.messages, 30, 1)
      << "LCM's default queue capacity (lcm.h: 30) dropped all but about 30 of the stalled "
         "requests";
}

/// An LCM instance handled on a thread of its own until destroyed, with `each_tick` run every
/// 100 ms (a daemon's status timer): the other end for a stepcal-client process.
class HandledLcm {
 public:
  HandledLcm(const std::string& url, std::function<void()> each_tick = nullptr)
      : lcm_(lcm_create(url.c_str()), &lcm_destroy), each_tick_(std::move(each_tick)) {}
  ~HandledLcm() { stop(); }
  lcm_t* get() const { return lcm_.get(); }
  void start() {
    thread_ = std::thread([this] {
      Clock::time_point next_tick = Clock::now();
      while (!stop_) {
        lcm_handle_timeout(lcm_.get(), 10);
        if (each_tick_ && Clock::now() >= next_tick) {
          each_tick_();
          next_tick += std::chrono::milliseconds(100);
        }
      }
    });
  }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::unique_ptr<lcm_t, void (*)(lcm_t*)> lcm_;
  std::function<void()> each_tick_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// A stand-in for the daemon that answers every request with the status it is told.
struct StatusAnswerer {
  lcm_t* lcm = nullptr;
  std::atomic<int> status{int(Status::kOk)};
  correction_request_t last_request{};  ///< read after the client's process has ended
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    auto* self = static_cast<StatusAnswerer*>(user);
    correction_request_t request{};
    if (request.decode(rbuf->data, 0, int(rbuf->data_size)) <= 0) return;
    self->last_request = request;
    correction_reply_t reply{};
    reply.request_id = request.request_id;
    reply.status = int8_t(self->status.load());
    reply.predicted_quaternion_wxyz[0] = 1.0;
    uint8_t bytes[4096];
    const int size = encodeReply(reply, bytes, int(sizeof bytes));
    lcm_publish(self->lcm, kReplyChannel, bytes, unsigned(size));
  }
};

// The client's exit status says whether its request was corrected (exit_codes.hpp): 0 for OK,
// 3 (done in part) for any other status, also when only some of repeated requests failed, and 4
// when nothing answers; its lengths are taken in mm and its angles in degrees. Over real UDP
// multicast: the client is a process of its own.
TEST(LcmUdpm, ClientExitStatusSaysWhetherTheRequestWasCorrected) {
  if (std::getenv("STEPCAL_NETNS") == nullptr) {
    GTEST_SKIP() << "needs a private network namespace with multicast on its loopback "
                    "(tests/system/in_netns.sh; ctest -R net_lcm_queue)";
  }
  const std::string url = "udpm://239.255.76.69:7669?ttl=0";
  const std::string forward = kClient + " --lcm-url '" + url +
                              "' --forward 0 0 0 0 28.6 0 --wrench 0 0 -100 0 0 0";
  StatusAnswerer answerer;
  {
    HandledLcm daemon(url);
    answerer.lcm = daemon.get();
    lcm_subscribe(daemon.get(), kRequestChannel, &StatusAnswerer::on, &answerer);
    daemon.start();
    for (const auto& [status, expected_exit] :
         std::vector<std::pair<Status, int>>{{Status::kOk, 0},
                                             {Status::kStaleWrench, 3},
                                             {Status::kNotConverged, 3},
                                             {Status::kBadRequest, 3}}) {
      answerer.status = int(status);
      const CommandResult r = run(forward + " --timeout-ms 1000");
      EXPECT_EQ(r.status, expected_exit) << runtime::toString(status) << ": " << r.out;
      EXPECT_NE(r.out.find(runtime::toString(status)), std::string::npos) << r.out;
      if (expected_exit != 0) {
        EXPECT_NE(r.out.find("1 of 1 requests not corrected (0 without a reply in time, 1 with a "
                             "status other than OK)"),
                  std::string::npos)
            << r.out;
      }
    }
    // Lengths on the command line in mm, angles in degrees; the message carries SI.
    EXPECT_NEAR(answerer.last_request.q_rad[4], 28.6 * kRadPerDeg, 1e-15);
    answerer.status = int(Status::kOk);
    const std::string inverse = kClient + " --lcm-url '" + url +
                                "' --timeout-ms 1000 --inverse 1500 -200 300 1 0 0 0 --seed 0 10 20 "
                                "0 45 0 --frame user --user-frame 100 0 50 1 0 0 0 --tool 0 0 350 1 "
                                "0 0 0 --payload 30 --cog 0 0 300";
    const CommandResult in_mm = run(inverse);
    EXPECT_EQ(in_mm.status, 0) << in_mm.out;
    EXPECT_EQ(in_mm.out.find("warning"), std::string::npos) << in_mm.out;
    const correction_request_t& sent = answerer.last_request;
    EXPECT_NEAR(sent.desired_position_m[0], 1.5, 1e-15);
    EXPECT_NEAR(sent.desired_position_m[1], -0.2, 1e-15);
    EXPECT_NEAR(sent.user_frame_position_m[0], 0.1, 1e-15);
    EXPECT_NEAR(sent.tool_position_m[2], 0.35, 1e-15);
    EXPECT_NEAR(sent.payload_cog_m[2], 0.3, 1e-15);
    EXPECT_NEAR(sent.seed_q_rad[4], 45.0 * kRadPerDeg, 1e-15);
    // Metres where mm are expected: said, not refused.
    const CommandResult in_m = run(kClient + " --lcm-url '" + url +
                                   "' --timeout-ms 1000 --inverse 1.5 -0.2 0.3 1 0 0 0");
    EXPECT_EQ(in_m.status, 0) << in_m.out;
    EXPECT_NE(in_m.out.find("warning: --inverse x y z lie within 5 mm of the origin: metres given "
                            "where mm are expected?"),
              std::string::npos)
        << in_m.out;
    answerer.status = int(Status::kStaleWrench);
    const CommandResult repeated = run(forward + " --timeout-ms 1000 --count 3 --rate 20");
    EXPECT_EQ(repeated.status, 3) << repeated.out;
    EXPECT_NE(repeated.out.find("3 of 3 requests not corrected"), std::string::npos) << repeated.out;
  }
  const CommandResult silence = run(forward + " --timeout-ms 200");
  EXPECT_EQ(silence.status, 4) << silence.out;
  EXPECT_NE(silence.out.find("no reply within 200 ms"), std::string::npos) << silence.out;
}

// A sensor command is confirmed by the daemon's sensor status, never assumed: with the daemon's
// key it is accepted (exit 0); with another key the daemon's forged-command counter grows and the
// client says it was refused (exit 4); with no daemon it is not confirmed (exit 4).
TEST(LcmUdpm, SensorCommandSaysWhetherTheDaemonTookIt) {
  if (std::getenv("STEPCAL_NETNS") == nullptr) {
    GTEST_SKIP() << "needs a private network namespace with multicast on its loopback "
                    "(tests/system/in_netns.sh; ctest -R net_lcm_queue)";
  }
  const test::TempDir dir;
  const std::string key_file = (dir.path() / "cell.key").string(),
                    other_key = (dir.path() / "other.key").string();
  ASSERT_EQ(run("printf '%032d' 7 > " + key_file + " && chmod 600 " + key_file +
                " && printf '%032d' 8 > " + other_key + " && chmod 600 " + other_key)
                .status,
            0);
  std::array<uint8_t, kKeyBytes> key_bytes{};
  const std::string key_text = test::readText(key_file);
  std::copy(key_text.begin(), key_text.end(), key_bytes.begin());
  const std::string url = "udpm://239.255.76.70:7670?ttl=0";
  const std::string command = kClient + " --lcm-url '" + url + "' --sensor-command bias";

  ServiceOptions options = generousOptions();
  options.key = CellKey::fromBytes(key_bytes);
  Service service(paperModel(), "paper.stepcal", options);
  int ends[2];
  ASSERT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, ends), 0);
  runtime::CanSocket sensor_end = runtime::CanSocket::adopt(ends[1], "socketpair");
  ftsim::SensorSimulator simulator({});
  std::atomic<bool> stop_sensor{false};
  std::thread sensor([&] { simulator.serve(sensor_end, stop_sensor); });
  {
    std::unique_ptr<CanWrenchFeed> feed;
    HandledLcm daemon(url, [&] { feed->publishStatus(); });
    runtime::FtSensorOptions sensor_options;
    sensor_options.bias_samples = 2;
    feed = std::make_unique<CanWrenchFeed>(daemon.get(),
                                           runtime::CanSocket::adopt(ends[0], "socketpair"),
                                           sensor_options, "", service);
    daemon.start();
    const CommandResult genuine = run(command + " --key-file " + key_file);
    EXPECT_EQ(genuine.status, 0) << genuine.out;
    EXPECT_NE(genuine.out.find("accepted by the daemon (authenticated)"), std::string::npos)
        << genuine.out;
    const CommandResult wrong = run(command + " --key-file " + other_key);
    EXPECT_EQ(wrong.status, 4) << wrong.out;
    EXPECT_NE(wrong.out.find("REFUSED by the daemon: its code did not verify"), std::string::npos)
        << wrong.out;
    EXPECT_EQ(wrong.out.find("accepted"), std::string::npos) << wrong.out;
    const CommandResult keyless = run(command);
    EXPECT_EQ(keyless.status, 4) << keyless.out;
    daemon.stop();
    EXPECT_EQ(feed->forgedCommands(), 2);
    feed.reset();
  }
  stop_sensor = true;
  sensor.join();
  const CommandResult nobody = run(command);
  EXPECT_EQ(nobody.status, 4) << nobody.out;
  EXPECT_NE(nobody.out.find("not confirmed: no sensor status"), std::string::npos) << nobody.out;
}

}  // namespace
}  // namespace stepcal::service
