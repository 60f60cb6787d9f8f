// The wire contract in one place (runtime/service: request.hpp, reply.hpp): requests of every
// kind and replies of every status go through the shared encoders and come back from the decoders
// unchanged, in the bytes LCM's generated code writes; and LcmRequester, the controller's side
// every client uses, over an in-process memq:// LCM: its reply matched by id, a daemon of message
// version 1 refused by name, a reply the cell key does not vouch for refused and counted.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>
#include <vector>

#include <lcm/lcm.h>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_reply_v1_t.hpp>
#include <stepcal_lcm/correction_reply_v2_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>

#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_requester.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/reply.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal::service {
namespace {

using runtime::Status;
using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;

/// The pose decodeRequest makes of a message's fields: the quaternion normalised.
Pose poseOfFields(const double* position_m, const double* quaternion_wxyz) {
  Pose X = Pose::Identity();
  X.linear() = Eigen::Quaterniond(quaternion_wxyz[0], quaternion_wxyz[1], quaternion_wxyz[2],
                                  quaternion_wxyz[3])
                   .normalized()
                   .toRotationMatrix();
  X.translation() = Vec3(position_m[0], position_m[1], position_m[2]);
  return X;
}

void setPoseFields(double* position_m, double* quaternion_wxyz, const Vec3& p,
                   const Eigen::Vector4d& q_wxyz) {
  for (int i = 0; i < 3; ++i) position_m[i] = p[i];
  for (int i = 0; i < 4; ++i) quaternion_wxyz[i] = q_wxyz[i];
}

/// Requests of every kind: both modes, the three frames, tools from the target and the flange,
/// the three wrench sources, both centre-of-gravity frames, temperatures measured and not.
std::vector<correction_request_t> requestsOfEveryKind() {
  std::vector<correction_request_t> requests;
  int64_t id = -3;
  for (int8_t mode : {correction_request_t::MODE_FORWARD, correction_request_t::MODE_INVERSE}) {
    for (int8_t frame = 0; frame <= correction_request_t::FRAME_USER; ++frame) {
      for (int8_t tool_from = 0; tool_from <= correction_request_t::TOOL_FROM_FLANGE; ++tool_from) {
        for (int8_t source = 0; source <= correction_request_t::WRENCH_PAYLOAD; ++source) {
          correction_request_t msg = blankRequest();
          msg.request_id = id;
          msg.utime = 1'700'000'000'000'000 + id;
          msg.mode = mode;
          msg.frame = frame;
          msg.tool_from = tool_from;
          msg.wrench_source = source;
          msg.deadline_us = int32_t(100 + id);
          msg.temp_c = id % 2 ? runtime::kUnknownTemperature_c : 20.0 + 0.25 * double(id);
          for (int j = 0; j < 6; ++j) {
            msg.q_rad[j] = 0.1 * j - 0.03 * double(id);
            msg.seed_q_rad[j] = -0.2 * j + 0.01 * double(id);
            msg.wrench[j] = 3.0 * j - double(id);
          }
          // A quaternion off unit norm by less than the tolerance: sent as given.
          setPoseFields(msg.desired_position_m, msg.desired_quaternion_wxyz, Vec3(2.1, -0.3, 1.4),
                        Eigen::Vector4d(0.5, 0.5, -0.5, 0.5 + 4e-7));
          if (frame == correction_request_t::FRAME_USER) {
            setPoseFields(msg.user_frame_position_m, msg.user_frame_quaternion_wxyz,
                          Vec3(1.2, 0.4, 0.1),
                          Eigen::Vector4d(0.9238795325112867, 0.0, 0.0, 0.3826834323650898));
          }
          setPoseFields(msg.tool_position_m, msg.tool_quaternion_wxyz, Vec3(0.0, 0.05, 0.3),
                        Eigen::Vector4d(0.0, 1.0, 0.0, 0.0));
          msg.payload_kg = 40.0 + double(id);
          msg.payload_cog_frame = int8_t(id & 1);
          msg.payload_cog_m[2] = -0.1;
          requests.push_back(msg);
          ++id;
        }
      }
    }
  }
  return requests;
}

void expectDecodedAsSent(const correction_request_t& msg, const Request& r) {
  EXPECT_TRUE(r.request_id_known);
  EXPECT_FALSE(r.old_version);
  EXPECT_EQ(r.request_id, msg.request_id);
  EXPECT_EQ(r.utime, msg.utime);
  EXPECT_EQ(int(r.mode), int(msg.mode));
  EXPECT_EQ(int(r.wrench_source), int(msg.wrench_source));
  EXPECT_EQ(r.deadline_us, msg.deadline_us);
  EXPECT_TRUE(std::isnan(msg.temp_c) ? std::isnan(r.temp_c) : r.temp_c == msg.temp_c);
  for (int j = 0; j < kMessageJoints; ++j) {
    EXPECT_EQ(r.q_rad[j], msg.q_rad[j]);
    EXPECT_EQ(r.seed_q_rad[j], msg.seed_q_rad[j]);
  }
  const runtime::CallTerms& terms = r.terms;
  EXPECT_EQ(int(terms.frame), int(msg.frame));
  EXPECT_EQ(int(terms.tool_from), int(msg.tool_from));
  for (int k = 0; k < 6; ++k) EXPECT_EQ(terms.wrench_Sensor[k], msg.wrench[k]);
  EXPECT_TRUE(terms.X_Tool.isApprox(poseOfFields(msg.tool_position_m, msg.tool_quaternion_wxyz), 0.0));
  const Pose X_BaseUser = msg.frame == correction_request_t::FRAME_USER
                              ? poseOfFields(msg.user_frame_position_m, msg.user_frame_quaternion_wxyz)
                              : Pose::Identity();
  EXPECT_TRUE(terms.X_BaseUser.isApprox(X_BaseUser, 0.0));
  const bool payload = msg.wrench_source == correction_request_t::WRENCH_PAYLOAD;
  EXPECT_EQ(terms.load_from, payload ? runtime::LoadFrom::kPayload : runtime::LoadFrom::kWrench);
  if (payload) {
    EXPECT_EQ(terms.payload.mass_kg, msg.payload_kg);
    EXPECT_EQ(int(terms.payload.frame), int(msg.payload_cog_frame));
    for (int k = 0; k < 3; ++k) EXPECT_EQ(terms.payload.p_CoG_m[k], msg.payload_cog_m[k]);
  }
  const Pose X_desired = msg.mode == correction_request_t::MODE_INVERSE
                             ? poseOfFields(msg.desired_position_m, msg.desired_quaternion_wxyz)
                             : Pose::Identity();
  EXPECT_TRUE(r.X_FrameTcp_desired.isApprox(X_desired, 0.0));
}

/// Replies of every status, every field set to a value of its own.
std::vector<correction_reply_t> repliesOfEveryStatus() {
  std::vector<correction_reply_t> replies;
  for (int8_t status = 0; status <= correction_reply_t::STATUS_BAD_REQUEST; ++status) {
    correction_reply_t r{};
    double next = 0.5 + status;
    const auto fill = [&](double* values, int n) {
      for (int i = 0; i < n; ++i) values[i] = (next += 0.125);
    };
    r.request_id = (int64_t(1) << 40) + status;
    r.message_version = correction_reply_t::VERSION;
    r.utime = 1'700'000'000'000'000 + status;
    r.status = status;
    fill(r.q_target_rad, 6);
    fill(r.commanded_position_m, 3);
    fill(r.commanded_quaternion_wxyz, 4);
    fill(r.predicted_position_m, 3);
    fill(r.predicted_quaternion_wxyz, 4);
    fill(r.gpr_std, 6);
    r.uncovered_joints = 0b100101 >> (status % 3);
    r.iterations = 3 + status;
    r.compute_ns = 41'000 + status;
    r.wrench_stamp_ns = status == correction_reply_t::STATUS_STALE_WRENCH ? 0 : 123'456'789 + status;
    fill(r.wrench, 6);
    r.model_id = int64_t(0xC0FFEE00u) + status;
    r.residual_position_m = 1e-7 * status;
    r.residual_orientation_rad = 2e-7 * status;
    // Odd statuses: a model that states no accuracy (NaN).
    const double stated = status % 2 ? PoseAccuracy::kUnknown : 1.0;
    r.position_rms_m = 1e-4 * status * stated;
    r.position_bound_m = 2.5e-4 * status * stated;
    r.orientation_rms_rad = 3e-5 * status * stated;
    r.orientation_bound_rad = 7e-5 * status * stated;
    r.auth_sender = 77;
    r.auth_counter = 1'700'000'000'000'000;
    for (int i = 0; i < 32; ++i) r.auth_mac[i] = uint8_t(i * 7 + status);
    replies.push_back(r);
  }
  return replies;
}

std::vector<uint8_t> lcmBytes(const correction_reply_t& r) {
  std::vector<uint8_t> bytes(size_t(r.getEncodedSize()));
  r.encode(bytes.data(), 0, int(bytes.size()));
  return bytes;
}

TEST(Wire, RequestsOfEveryKindRoundTrip) {
  for (const correction_request_t& msg : requestsOfEveryKind()) {
    SCOPED_TRACE(msg.request_id);
    const std::vector<uint8_t> bytes = encodeRequest(msg);
    ASSERT_EQ(int(bytes.size()), requestBytes());
    std::vector<uint8_t> generated(size_t(msg.getEncodedSize()));
    msg.encode(generated.data(), 0, int(generated.size()));
    EXPECT_EQ(bytes, generated) << "the bytes LCM's generated code writes";
    Request decoded;
    ASSERT_EQ(decodeRequest(bytes.data(), int(bytes.size()), decoded), Status::kOk);
    expectDecodedAsSent(msg, decoded);
  }
  // The blank request asks for the runtime's defaults.
  const std::vector<uint8_t> blank = encodeRequest(blankRequest());
  Request decoded;
  ASSERT_EQ(decodeRequest(blank.data(), int(blank.size()), decoded), Status::kOk);
  EXPECT_EQ(decoded.mode, Mode::kForward);
  EXPECT_EQ(decoded.wrench_source, WrenchSource::kLiveSensor);
  EXPECT_TRUE(std::isnan(decoded.temp_c));
  EXPECT_TRUE(decoded.terms.X_Tool.isApprox(Pose::Identity(), 0.0));
  // A version-2 request (the same layout, its version number): refused as version 2, addressable.
  correction_request_t version2 = blankRequest();
  version2.request_id = 99;
  version2.message_version = 2;
  const std::vector<uint8_t> old = encodeRequest(version2);
  ASSERT_EQ(decodeRequest(old.data(), int(old.size()), decoded), Status::kBadRequest);
  EXPECT_EQ(decoded.old_version, 2);
  EXPECT_TRUE(decoded.request_id_known);
  EXPECT_EQ(decoded.request_id, 99);
  // Too small a buffer: nothing written.
  std::vector<uint8_t> small(size_t(requestBytes() - 1));
  EXPECT_EQ(encodeRequest(blankRequest(), small.data(), int(small.size())), 0);
}

TEST(Wire, RepliesOfEveryStatusRoundTrip) {
  for (const correction_reply_t& reply : repliesOfEveryStatus()) {
    SCOPED_TRACE(int(reply.status));
    std::vector<uint8_t> bytes(static_cast<size_t>(replyBytes()));
    const int size = encodeReply(reply, bytes.data(), int(bytes.size()));
    ASSERT_EQ(size, reply.getEncodedSize());
    bytes.resize(size_t(size));
    EXPECT_EQ(bytes, lcmBytes(reply)) << "the bytes LCM's generated code writes";
    correction_reply_t decoded;
    ASSERT_EQ(decodeReply(bytes.data(), size, decoded), ReplyKind::kReply);
    EXPECT_EQ(lcmBytes(decoded), bytes) << "every field as sent";
    EXPECT_EQ(decoded.request_id, reply.request_id);
    EXPECT_EQ(decoded.status, reply.status);
    EXPECT_EQ(decoded.predicted_position_m[2], reply.predicted_position_m[2]);
    EXPECT_EQ(std::isnan(decoded.position_bound_m), std::isnan(reply.position_bound_m));
    if (!std::isnan(reply.position_bound_m)) {
      EXPECT_EQ(decoded.position_rms_m, reply.position_rms_m);
      EXPECT_EQ(decoded.position_bound_m, reply.position_bound_m);
      EXPECT_EQ(decoded.orientation_rms_rad, reply.orientation_rms_rad);
      EXPECT_EQ(decoded.orientation_bound_rad, reply.orientation_bound_rad);
    }
    EXPECT_EQ(std::memcmp(decoded.auth_mac, reply.auth_mac, 32), 0);
    // Truncated or longer: malformed, never a reply.
    EXPECT_EQ(decodeReply(bytes.data(), size - 1, decoded), ReplyKind::kMalformed);
    bytes.push_back(0);
    EXPECT_EQ(decodeReply(bytes.data(), size + 1, decoded), ReplyKind::kMalformed);
  }
  // A version-1 or version-2 refusal is told apart by name, and a client of that version reads
  // it.
  std::vector<uint8_t> old(static_cast<size_t>(replyBytes()));
  int size = encodeOldVersionRefusal(1, 4242, 17, 99, old.data(), int(old.size()));
  ASSERT_GT(size, 0);
  correction_reply_t as_new;
  EXPECT_EQ(decodeReply(old.data(), size, as_new), ReplyKind::kOldVersion);
  EXPECT_EQ(oldReplyVersion(old.data(), size), 1);
  stepcal_lcm::correction_reply_v1_t v1{};
  ASSERT_EQ(v1.decode(old.data(), 0, size), size);
  EXPECT_EQ(v1.request_id, 4242);
  EXPECT_EQ(v1.utime, 17);
  EXPECT_EQ(v1.model_id, 99);
  EXPECT_EQ(v1.status, stepcal_lcm::correction_reply_v1_t::STATUS_BAD_REQUEST);
  size = encodeOldVersionRefusal(2, 4243, 18, 98, old.data(), int(old.size()));
  ASSERT_GT(size, 0);
  EXPECT_EQ(decodeReply(old.data(), size, as_new), ReplyKind::kOldVersion);
  EXPECT_EQ(oldReplyVersion(old.data(), size), 2);
  stepcal_lcm::correction_reply_v2_t v2{};
  ASSERT_EQ(v2.decode(old.data(), 0, size), size);
  EXPECT_EQ(v2.request_id, 4243);
  EXPECT_EQ(v2.message_version, 2);
  EXPECT_EQ(v2.utime, 18);
  EXPECT_EQ(v2.model_id, 98);
  EXPECT_EQ(v2.status, stepcal_lcm::correction_reply_v2_t::STATUS_BAD_REQUEST);
  EXPECT_EQ(encodeOldVersionRefusal(3, 4244, 0, 0, old.data(), int(old.size())), 0)
      << "version 3 is no old version";
  ASSERT_NE(stepcal_lcm::correction_reply_v2_t::getHash(), correction_reply_t::getHash());
  const std::vector<uint8_t> current = lcmBytes(repliesOfEveryStatus()[0]);
  EXPECT_EQ(oldReplyVersion(current.data(), int(current.size())), 0);
  // A request on the reply channel, or a few bytes: malformed.
  const std::vector<uint8_t> request = encodeRequest(blankRequest());
  EXPECT_EQ(decodeReply(request.data(), int(request.size()), as_new), ReplyKind::kMalformed);
  EXPECT_EQ(decodeReply(request.data(), 7, as_new), ReplyKind::kMalformed);
  EXPECT_EQ(decodeReply(nullptr, 0, as_new), ReplyKind::kMalformed);
}

// ---- LcmRequester over memq:// ---------------------------------------------------------------

const CalibratedModel& model() {
  static const CalibratedModel m = [] {
    twin::TwinOptions options;
    options.seed = 2;
    const Campaign campaign = twin::simulateCampaign(options, nullptr);
    return trainer::modelFromOutcome(campaign, trainer::calibrateCampaign(campaign));
  }();
  return m;
}

CellKey key(uint8_t fill) {
  std::array<uint8_t, kKeyBytes> bytes{};
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = uint8_t(fill + 13 * i);
  return CellKey::fromBytes(bytes);
}

correction_request_t forwardRequest() {
  correction_request_t msg = blankRequest();
  msg.wrench_source = correction_request_t::WRENCH_GIVEN;
  for (int j = 0; j < 6; ++j) msg.q_rad[j] = 0.2 * j - 0.5;
  return msg;
}

using LcmPtr = std::unique_ptr<lcm_t, void (*)(lcm_t*)>;
constexpr std::chrono::milliseconds kTimeout{500};

TEST(LcmRequester, GetsTheServicesReplyToItsRequest) {
  const LcmPtr lcm(lcm_create("memq://"), &lcm_destroy);
  Service service(runtime::RuntimeModel::fromModel(model(), 21), "model.stepcal", {});
  LcmServer server(lcm.get(), service);
  LcmRequester requester(lcm.get(), std::nullopt);
  EXPECT_FALSE(requester.authenticated());
  correction_request_t msg = forwardRequest();
  const std::optional<correction_reply_t> reply = requester.exchange(msg, 1234, kTimeout);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->request_id, 1234);
  EXPECT_EQ(msg.request_id, 1234);
  EXPECT_EQ(reply->status, int8_t(Status::kOk));
  EXPECT_EQ(reply->model_id, 21);
  EXPECT_TRUE(requester.explainSilence("--key-file").empty());
}

/// A daemon of an older message version (1 or 2): every request gets its BAD_REQUEST refusal.
struct OldDaemon {
  lcm_t* lcm;
  int version;
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    const auto* self = static_cast<OldDaemon*>(user);
    Request request;
    decodeRequest(rbuf->data, int(rbuf->data_size), request);
    std::vector<uint8_t> bytes(static_cast<size_t>(replyBytes()));
    const int size = encodeOldVersionRefusal(self->version, request.request_id, 0, 5,
                                             bytes.data(), int(bytes.size()));
    lcm_publish(self->lcm, kReplyChannel, bytes.data(), unsigned(size));
  }
};

TEST(LcmRequester, RefusesADaemonOfMessageVersion1Or2ByName) {
  for (int version : {1, 2}) {
    SCOPED_TRACE(version);
    const LcmPtr lcm(lcm_create("memq://"), &lcm_destroy);
    OldDaemon old{lcm.get(), version};
    lcm_subscribe(lcm.get(), kRequestChannel, &OldDaemon::on, &old);
    LcmRequester requester(lcm.get(), std::nullopt);
    correction_request_t msg = forwardRequest();
    EXPECT_FALSE(requester.exchange(msg, 7, std::chrono::milliseconds(50)));
    EXPECT_EQ(requester.counters().old_version, 1);
    EXPECT_EQ(requester.counters().old_version_seen, version);
    const std::vector<std::string> reasons = requester.explainSilence("key_file");
    ASSERT_EQ(reasons.size(), 1u);
    const std::string name = std::to_string(version);
    EXPECT_NE(reasons[0].find("message version " + name + " (correction_reply_v" + name +
                              "_t): it predates this client's version 3"),
              std::string::npos)
        << reasons[0];
    EXPECT_NE(reasons[0].find("update stepcal-runtime"), std::string::npos) << reasons[0];
    // Counted since a snapshot: nothing new, nothing to say.
    EXPECT_TRUE(requester.explainSilence("key_file", requester.counters()).empty());
  }
}

/// The reply the service encodes for msg (bytes through handleRequest, as the daemon sends).
correction_reply_t serviceReply(Service& service, correction_request_t msg, int64_t request_id) {
  msg.request_id = request_id;
  const std::vector<uint8_t> bytes = encodeRequest(msg);
  std::vector<uint8_t> reply(static_cast<size_t>(Service::replyBytes()));
  const int size = service.handleRequest(bytes.data(), int(bytes.size()),
                                         runtime::Clock::now(), reply.data(), int(reply.size()));
  correction_reply_t decoded{};
  EXPECT_EQ(decodeReply(reply.data(), size, decoded), ReplyKind::kReply);
  return decoded;
}

/// The reply's accuracy is `accuracy` within a relative tolerance.
void expectAccuracyOf(const correction_reply_t& reply, const PoseAccuracy& accuracy,
                      double relative) {
  EXPECT_NEAR(reply.position_rms_m, accuracy.position_rms_m, relative * accuracy.position_rms_m);
  EXPECT_NEAR(reply.position_bound_m, accuracy.position_bound_m,
              relative * accuracy.position_bound_m);
  EXPECT_NEAR(reply.orientation_rms_rad, accuracy.orientation_rms_rad,
              relative * accuracy.orientation_rms_rad);
  EXPECT_NEAR(reply.orientation_bound_rad, accuracy.orientation_bound_rad,
              relative * accuracy.orientation_bound_rad);
}

// The reply carries the runtime's stated accuracy: finite for a model with the accuracy factors
// (ACCU), the forward's at q and the inverse's at its targets; NaN for a model without them.
TEST(Wire, TheReplyCarriesTheRuntimesAccuracy) {
  const auto runtime_model = runtime::RuntimeModel::fromModel(model(), 21);
  ASSERT_TRUE(runtime_model->file.accuracy.has_value());
  runtime::Workspace ws = runtime::makeWorkspace(*runtime_model);
  ServiceOptions options;
  options.budget_ns = 1'000'000'000;  // a busy machine never cuts the inverse short
  Service service(runtime::RuntimeModel::fromModel(model(), 21), "model.stepcal", options);
  const correction_request_t forward = forwardRequest();
  const correction_reply_t forward_reply = serviceReply(service, forward, 1);
  ASSERT_EQ(forward_reply.status, int8_t(Status::kOk));
  const std::vector<uint8_t> forward_bytes = encodeRequest(forward);
  Request decoded;
  ASSERT_EQ(decodeRequest(forward_bytes.data(), int(forward_bytes.size()), decoded), Status::kOk);
  const runtime::ForwardResult expected = runtime::correctForward(
      *runtime_model, ws, decoded.q_rad, decoded.terms, decoded.temp_c);
  ASSERT_TRUE(std::isfinite(expected.accuracy.position_bound_m));
  ASSERT_GT(expected.accuracy.position_bound_m, 0.0);
  ASSERT_GT(expected.accuracy.orientation_bound_rad, 0.0);
  expectAccuracyOf(forward_reply, expected.accuracy, 1e-12);

  // The inverse of the forward's pose: the accuracy at its targets, as the forward states it
  // there (to the inverse's approximation of the deflection, test_accuracy_bound.cpp).
  correction_request_t inverse = forward;
  inverse.mode = correction_request_t::MODE_INVERSE;
  std::copy(forward_reply.predicted_position_m, forward_reply.predicted_position_m + 3,
            inverse.desired_position_m);
  std::copy(forward_reply.predicted_quaternion_wxyz, forward_reply.predicted_quaternion_wxyz + 4,
            inverse.desired_quaternion_wxyz);
  std::copy(forward.q_rad, forward.q_rad + 6, inverse.seed_q_rad);
  const correction_reply_t inverse_reply = serviceReply(service, inverse, 2);
  ASSERT_EQ(inverse_reply.status, int8_t(Status::kOk));
  JointVector q_target(kMessageJoints);
  for (int j = 0; j < kMessageJoints; ++j) q_target[j] = inverse_reply.q_target_rad[j];
  expectAccuracyOf(inverse_reply,
                   runtime::correctForward(*runtime_model, ws, q_target, decoded.terms,
                                           decoded.temp_c)
                       .accuracy,
                   1e-3);

  CalibratedModel without = model();
  without.accuracy.reset();
  Service old_model(runtime::RuntimeModel::fromModel(std::move(without), 22), "old.stepcal",
                    options);
  for (const correction_request_t& msg : {forward, inverse}) {
    const correction_reply_t reply = serviceReply(old_model, msg, 3);
    ASSERT_EQ(reply.status, int8_t(Status::kOk));
    EXPECT_TRUE(std::isnan(reply.position_rms_m));
    EXPECT_TRUE(std::isnan(reply.position_bound_m));
    EXPECT_TRUE(std::isnan(reply.orientation_rms_rad));
    EXPECT_TRUE(std::isnan(reply.orientation_bound_rad));
  }
}

TEST(LcmRequester, AKeyedDaemonsStatusSaysTheKeyIsMissingOrWrong) {
  const LcmPtr lcm(lcm_create("memq://"), &lcm_destroy);
  ServiceOptions options;
  options.key = key(5);
  Service service(runtime::RuntimeModel::fromModel(model(), 23), "model.stepcal", options);
  LcmServer server(lcm.get(), service);
  {
    LcmRequester keyless(lcm.get(), std::nullopt);
    correction_request_t msg = forwardRequest();
    EXPECT_FALSE(keyless.exchange(msg, 1, std::chrono::milliseconds(50)));
    EXPECT_FALSE(keyless.daemonHeard().heard);
    EXPECT_FALSE(keyless.keyRefused()) << "nothing heard yet: no daemon, as far as it knows";
    server.publishStatus(false);
    keyless.listenForStatus(kTimeout);
    ASSERT_TRUE(keyless.daemonHeard().heard);
    EXPECT_TRUE(keyless.daemonHeard().keyed);
    EXPECT_TRUE(keyless.keyRefused());
    const std::vector<std::string> reasons = keyless.explainSilence("--key-file");
    ASSERT_EQ(reasons.size(), 1u);
    EXPECT_NE(reasons[0].find("the key is missing; give the cell's key with --key-file"),
              std::string::npos) << reasons[0];
  }
  LcmRequester wrong_key(lcm.get(), key(6));
  correction_request_t msg = forwardRequest();
  EXPECT_FALSE(wrong_key.exchange(msg, 2, std::chrono::milliseconds(50)));
  server.publishStatus(false);
  wrong_key.listenForStatus(kTimeout);
  EXPECT_EQ(wrong_key.daemonHeard().forged_requests, 2);
  EXPECT_TRUE(wrong_key.keyRefused());
  const std::vector<std::string> reasons = wrong_key.explainSilence("--key-file");
  ASSERT_EQ(reasons.size(), 1u);
  EXPECT_NE(reasons[0].find("the key may be wrong; is --key-file the daemon's key?"),
            std::string::npos) << reasons[0];
}

TEST(LcmRequester, SealsWithTheKeyAndRefusesRepliesItDoesNotVouchFor) {
  const LcmPtr lcm(lcm_create("memq://"), &lcm_destroy);
  ServiceOptions options;
  options.key = key(3);
  Service service(runtime::RuntimeModel::fromModel(model(), 22), "model.stepcal", options);
  LcmServer server(lcm.get(), service);
  {
    LcmRequester requester(lcm.get(), key(3));
    EXPECT_TRUE(requester.authenticated());
    correction_request_t msg = forwardRequest();
    const std::optional<correction_reply_t> reply = requester.exchange(msg, 1, kTimeout);
    ASSERT_TRUE(reply) << "sealed, verified by the daemon; its reply verified here";
    EXPECT_EQ(reply->status, int8_t(Status::kOk));
    EXPECT_EQ(requester.counters().rejected_forged, 0);
  }
  // A client without the key: the daemon drops its request, it hears nothing.
  {
    LcmRequester outsider(lcm.get(), std::nullopt);
    correction_request_t msg = forwardRequest();
    EXPECT_FALSE(outsider.exchange(msg, 2, std::chrono::milliseconds(50)));
    EXPECT_EQ(service.counters().forged, 1);
  }
  // A client with another key beside one with the cell's: the daemon's replies fail its check,
  // counted as forged and never taken.
  LcmRequester genuine(lcm.get(), key(3));
  LcmRequester other_key(lcm.get(), key(4));
  std::vector<int64_t> heard;
  other_key.setListener([&](const correction_reply_t& r, LcmRequester::Clock::time_point) {
    heard.push_back(r.request_id);
  });
  correction_request_t msg = forwardRequest();
  ASSERT_TRUE(genuine.exchange(msg, 3, kTimeout));
  EXPECT_TRUE(heard.empty());
  EXPECT_EQ(other_key.counters().rejected_forged, 1);
  const std::vector<std::string> reasons = other_key.explainSilence("--key-file");
  ASSERT_EQ(reasons.size(), 1u);
  EXPECT_EQ(reasons[0],
            "rejected 1 replies whose code does not verify and 0 whose counter is not fresh "
            "(--key-file: is it the daemon's key?)");
}

}  // namespace
}  // namespace stepcal::service
