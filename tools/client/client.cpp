// stepcal-client: sends correction requests to stepcal-runtime over LCM and measures the answers.
//
//   stepcal-client --forward q1 … q6 [--wrench fx fy fz mx my mz] [--temp-c T]
//                                                        one request, rad / N, N·m / °C
//   stepcal-client --forward q1 … q6 --count N --rate HZ [--json]
//                                                        the same request N times at HZ (live
//                                                        wrench unless --wrench): each reply's
//                                                        send time, status and wrench age;
//                                                        SIGINT/SIGTERM stops it early
//   stepcal-client --inverse x y z qw qx qy qz [--seed q1 … q6] [--wrench …] [--temp-c T]
//                                                        m, unit quaternion, in --frame
//   stepcal-client --campaign DIR [--set validation] [--mode forward|inverse] [--count N]
//                  [--rate HZ] [--truth truth.json] [--live-wrench [--wrench-channel C]] [--json]
//   stepcal-client --ping N [--json]     raw LCM round trips to a `stepcal-client --echo`
//   stepcal-client --echo                answers STEPCAL_PING on STEPCAL_PONG until SIGINT/SIGTERM
//   stepcal-client --sensor-command bias|clear-bias|reset
//                                        one sensor_command_t to the daemon's CAN sensor
//
// Single requests in the controller's terms (docs/runtime.md, "Integration"): --frame
// tracker|base|user [--user-frame x y z qw qx qy qz] (the user frame in the base frame, m),
// --tool x y z qw qx qy qz [--tool-from target|flange] (the TCP, m), --payload KG [--cog x y z]
// [--cog-frame flange|tool] (the load data: mass and centre of gravity, m) instead of --wrench.
// --key-file FILE: requests and sensor commands carry the cell key's code, and replies whose
// code does not verify or whose counter is not fresh are rejected (counted, never matched).
//
// Replies are matched to requests by request_id; a reply later than --timeout-ms counts as lost.
// Without --rate one request is in flight at a time (the next goes when the reply arrives or
// times out); with --rate requests leave on a fixed schedule. Campaign rows carry their measured
// wrench (wrench_source = given) and temperature (temp_c; NaN where the row has none), single
// requests --temp-c (default NaN: not measured). Accuracy counts OK replies only. Forward
// accuracy is against the rows' measured poses; inverse requests ask for the measured pose from
// a seed 2° off the row's joints (alternating sign), and their accuracy is against the twin's
// truth (where the true robot goes at q_target) when --truth is given, else the solver's own
// residual. Forward answers are also checked against the truth (where the true robot goes at q)
// when --truth is given.
//
// --live-wrench: the requests use the daemon's live sensor instead of the rows' wrenches. Before
// each request the client publishes the row's joints and payload as robot_state_t, waits until a
// simulated sensor (stepcal-ftsim --truth) echoes it as applied, then until the daemon has taken
// two samples stamped after the echo (wrench_t on --wrench-channel, where stepcal-runtime
// --sensor-republish puts each sample it took): the first may still be the reading the sensor
// made just before it applied the state. The report adds the latency from the CAN frame (the
// reply's wrench_stamp_ns) to the reply.
//
// --check-model FILE (repeatable): every reply is recomputed offline with the model file whose
// model_id it carries, through the daemon's own code (decodeRequest, the runtime's calls,
// service::writeAnswer); an inverse reply with the iteration cap set to the iterations it took,
// since the daemon's deadline may have cut it short. A reply whose values differ (more than
// 1e-12) or whose model_id is none of the files' is a torn answer: exit status 1.
#include <CLI/CLI.hpp>
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <optional>
#include <vector>

#include <lcm/lcm.h>
#include <nlohmann/json.hpp>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_reply_v1_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>
#include <stepcal_lcm/robot_state_t.hpp>
#include <stepcal_lcm/sensor_command_t.hpp>
#include <stepcal_lcm/wrench_t.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/can_socket.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/latency.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"
#include "stepcal/twin/twin.hpp"

namespace {

using namespace stepcal;
using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;
using Clock = std::chrono::steady_clock;

constexpr double kSeedOffsetRad = 2.0 * kRadPerDeg;
constexpr int kStatusCount = 7;

struct Args {
  std::string lcm_url = service::kDefaultLcmUrl;
  std::vector<double> forward_q_rad, inverse_pose, seed_q_rad, wrench;
  double temp_c = runtime::kUnknownTemperature_c;  ///< single requests, °C
  std::string campaign_dir, set = "validation", mode = "forward", truth_path;
  int count = 0;
  double rate_hz = 0.0;
  int ping_count = 0;
  bool echo = false;
  int deadline_us = 0;
  double timeout_ms = 100.0;
  bool json = false;
  bool live_wrench = false;
  std::string wrench_channel = service::kWrenchChannel;
  std::vector<std::string> check_models;
  // Single requests in the controller's terms.
  std::string frame = "tracker", tool_from = "target", cog_frame = "flange";
  std::vector<double> user_frame, tool, cog_m;
  double payload_kg = -1.0;  ///< < 0: no payload
  std::string sensor_command;
  std::string key_file;
};

int64_t bigEndian64(const uint8_t* bytes);

/// The cell key's signer and verifier (--key-file), or none.
struct Authentication {
  std::optional<service::MessageSigner> signer;
  std::optional<service::MessageVerifier> verifier;
  long rejected_forged = 0, rejected_replayed = 0;  ///< replies refused
  long old_version = 0;  ///< replies in message version 1: a daemon that predates this client

  explicit Authentication(const std::string& key_file) {
    if (key_file.empty()) return;
    const service::CellKey key = service::CellKey::load(key_file);
    signer.emplace(key);
    verifier.emplace(key);
  }
  /// Seals an encoded message when there is a key.
  void seal(uint8_t* bytes, int size) {
    if (signer) signer->seal(bytes, size);
  }
  /// Whether a received message may be used (always without a key); counts refusals.
  bool accept(const lcm_recv_buf_t* rbuf) {
    if (rbuf->data_size >= 8 && bigEndian64(static_cast<const uint8_t*>(rbuf->data)) ==
                                    stepcal_lcm::correction_reply_v1_t::getHash()) {
      ++old_version;
      return false;
    }
    if (!verifier) return true;
    const service::Verdict verdict = verifier->verify(static_cast<const uint8_t*>(rbuf->data),
                                                      int(rbuf->data_size), service::unixMicroseconds());
    if (verdict == service::Verdict::kForged) ++rejected_forged;
    if (verdict == service::Verdict::kReplayed) ++rejected_replayed;
    return verdict == service::Verdict::kAuthentic;
  }
  nlohmann::json toJson() const {
    return {{"key", signer.has_value()}, {"rejected_forged_replies", rejected_forged},
            {"rejected_replayed_replies", rejected_replayed},
            {"old_version_replies", old_version}};
  }
  /// Why no reply came, when the replies say (stderr).
  void explainSilence() const {
    if (old_version > 0) {
      std::cerr << "stepcal-client: the daemon answered in message version 1 "
                   "(correction_reply_v1_t): it predates this client's version 2; update "
                   "stepcal-runtime\n";
    }
    if (rejected_forged + rejected_replayed > 0) {
      std::cerr << "stepcal-client: rejected " << rejected_forged
                << " replies whose code does not verify and " << rejected_replayed
                << " whose counter is not fresh (--key-file: is it the daemon's key?)\n";
    }
  }
};

/// An LCM instance for the lifetime of the object.
class Lcm {
 public:
  explicit Lcm(const std::string& url) : lcm_(lcm_create(url.c_str())) {
    if (lcm_ == nullptr) throw InputError("--lcm-url '" + url + "': LCM cannot open it");
  }
  ~Lcm() { lcm_destroy(lcm_); }
  Lcm(const Lcm&) = delete;
  Lcm& operator=(const Lcm&) = delete;
  lcm_t* get() const { return lcm_; }

 private:
  lcm_t* lcm_;
};

int64_t bigEndian64(const uint8_t* bytes) {
  uint64_t value = 0;
  for (int i = 0; i < 8; ++i) value = (value << 8) | bytes[i];
  return static_cast<int64_t>(value);
}

using service::unixMicroseconds;

/// Round trips of `count` messages numbered 0..count−1: what was sent when, what came back.
struct Exchange {
  int64_t first_id = 0;  ///< message i carries id first_id + i
  double timeout_s = 0.1;
  std::vector<Clock::time_point> sent;
  std::vector<double> round_trip_us;  ///< NaN until answered in time
  int answered = 0;
  int late = 0;        ///< answers after the timeout (counted as lost)
  int duplicates = 0;  ///< second answers to one message
  /// Message id of a received payload, or nullopt when it is not one of ours.
  std::function<std::optional<int64_t>(const lcm_recv_buf_t*)> id_of;
  /// Called with the index and payload of every answer in time.
  std::function<void(size_t, const lcm_recv_buf_t*)> keep;

  void onAnswer(const lcm_recv_buf_t* rbuf) {
    const Clock::time_point now = Clock::now();
    const std::optional<int64_t> id = id_of(rbuf);
    if (!id || *id < first_id || *id - first_id >= int64_t(sent.size())) return;
    const auto i = static_cast<size_t>(*id - first_id);
    if (sent[i] == Clock::time_point{}) return;
    if (!std::isnan(round_trip_us[i])) {
      ++duplicates;
      return;
    }
    const double us = std::chrono::duration<double, std::micro>(now - sent[i]).count();
    if (us > timeout_s * 1e6) {
      ++late;
      return;
    }
    round_trip_us[i] = us;
    ++answered;
    keep(i, rbuf);
  }
};

void onAnswerMessage(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  static_cast<Exchange*>(user)->onAnswer(rbuf);
}

/// Set by SIGINT/SIGTERM where runRepeated installs onStopSignal: no further requests leave.
volatile std::sig_atomic_t stop_requested = 0;
void onStopSignal(int) { stop_requested = 1; }

/// Waits up to `until` for LCM traffic and dispatches it.
void handleUntil(lcm_t* lcm, Clock::time_point until) {
  const auto wait = std::max(Clock::duration::zero(), until - Clock::now());
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count();
  timespec timeout{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
  pollfd fd{lcm_get_fileno(lcm), POLLIN, 0};
  if (ppoll(&fd, 1, &timeout, nullptr) > 0) lcm_handle(lcm);
}

/// Sends count messages through send(i, id) and collects the answers on answer_channel: one in
/// flight at a time (rate_hz = 0) or on a fixed schedule.
void runExchange(lcm_t* lcm, const char* answer_channel, int count, double rate_hz,
                 Exchange& exchange, const std::function<void(size_t, int64_t)>& send) {
  exchange.first_id = int64_t(getpid()) << 32;
  exchange.sent.assign(size_t(count), Clock::time_point{});
  exchange.round_trip_us.assign(size_t(count), std::numeric_limits<double>::quiet_NaN());
  // Every client sees every client's replies: its queue must ride out stalls at their sum.
  lcm_subscription_t* subscription =
      service::subscribeQueued(lcm, answer_channel, &onAnswerMessage, &exchange);
  const auto timeout = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(exchange.timeout_s));
  const Clock::time_point start = Clock::now();
  const auto scheduled = [&](int i) {
    return start + std::chrono::duration_cast<Clock::duration>(
                       std::chrono::duration<double>(double(i) / rate_hz));
  };
  int next = 0;
  while (next < count && !stop_requested) {
    Clock::time_point due = Clock::now();
    if (rate_hz > 0.0) {
      due = scheduled(next);
    } else if (next > 0 && std::isnan(exchange.round_trip_us[size_t(next - 1)])) {
      due = exchange.sent[size_t(next - 1)] + timeout;
    }
    if (Clock::now() < due) {
      handleUntil(lcm, due);
      if (rate_hz > 0.0 || std::isnan(exchange.round_trip_us[size_t(next - 1)])) continue;
    }
    exchange.sent[size_t(next)] = Clock::now();
    send(size_t(next), exchange.first_id + next);
    ++next;
  }
  const Clock::time_point last_deadline = Clock::now() + timeout;
  while (exchange.answered < count && Clock::now() < last_deadline) handleUntil(lcm, last_deadline);
  lcm_unsubscribe(lcm, subscription);
}

nlohmann::json latencyJson(std::vector<double> samples_us) {
  samples_us.erase(std::remove_if(samples_us.begin(), samples_us.end(),
                                  [](double v) { return std::isnan(v); }),
                   samples_us.end());
  const service::LatencySummary s =
      service::summarizeLatencies(samples_us.data(), samples_us.size());
  return {{"samples", s.samples}, {"p50_us", s.p50_us}, {"p99_us", s.p99_us},
          {"p999_us", s.p999_us}, {"max_us", s.max_us}};
}

std::string latencyText(const nlohmann::json& j) {
  char line[200];
  std::snprintf(line, sizeof line, "p50 %.1f us, p99 %.1f us, p99.9 %.1f us, max %.1f us",
                j["p50_us"].get<double>(), j["p99_us"].get<double>(),
                j["p999_us"].get<double>(), j["max_us"].get<double>());
  return line;
}

// ---- requests ------------------------------------------------------------------------------

correction_request_t emptyRequest(const Args& args) {
  correction_request_t msg{};
  msg.message_version = correction_request_t::VERSION;
  msg.desired_quaternion_wxyz[0] = 1.0;
  msg.user_frame_quaternion_wxyz[0] = 1.0;
  msg.tool_quaternion_wxyz[0] = 1.0;
  msg.temp_c = runtime::kUnknownTemperature_c;
  msg.deadline_us = args.deadline_us;
  return msg;
}

/// One of `names` (the index), or an InputError naming the option and the choices.
int8_t choice(const std::string& option, const std::string& value,
              const std::vector<std::string>& names) {
  for (size_t i = 0; i < names.size(); ++i) {
    if (value == names[i]) return int8_t(i);
  }
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : " | ") + n;
  throw InputError(option + " '" + value + "': expected " + list);
}

/// x y z qw qx qy qz (m, unit quaternion) into a message's position and quaternion fields.
void setPose(const std::string& option, const std::vector<double>& v, double* position_m,
             double* quaternion_wxyz) {
  const double norm = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
  if (!(std::abs(norm - 1.0) <= service::kQuaternionNormTolerance)) {
    throw InputError(option + ": the quaternion qw qx qy qz has norm " + std::to_string(norm) +
                     "; expected a unit quaternion (within 1e-6)");
  }
  std::copy(v.begin(), v.begin() + 3, position_m);
  std::copy(v.begin() + 3, v.end(), quaternion_wxyz);
}

/// The frame, tool and payload options of a single request into its message.
void setTerms(const Args& args, correction_request_t& msg) {
  msg.frame = choice("--frame", args.frame, {"tracker", "base", "user"});
  if ((msg.frame == correction_request_t::FRAME_USER) != !args.user_frame.empty()) {
    throw InputError("--user-frame x y z qw qx qy qz goes with --frame user, and --frame user needs it");
  }
  if (!args.user_frame.empty()) {
    setPose("--user-frame", args.user_frame, msg.user_frame_position_m, msg.user_frame_quaternion_wxyz);
  }
  msg.tool_from = choice("--tool-from", args.tool_from, {"target", "flange"});
  if (!args.tool.empty()) setPose("--tool", args.tool, msg.tool_position_m, msg.tool_quaternion_wxyz);
  msg.payload_cog_frame = choice("--cog-frame", args.cog_frame, {"flange", "tool"});
  if (args.payload_kg >= 0.0) {
    if (!args.wrench.empty()) throw InputError("--payload and --wrench: give one load, not both");
    msg.wrench_source = correction_request_t::WRENCH_PAYLOAD;
    msg.payload_kg = args.payload_kg;
    if (!args.cog_m.empty()) std::copy(args.cog_m.begin(), args.cog_m.end(), msg.payload_cog_m);
  } else if (!args.cog_m.empty()) {
    throw InputError("--cog goes with --payload");
  }
}

void setWrench(correction_request_t& msg, const Vec6& wrench_Sensor) {
  msg.wrench_source = correction_request_t::WRENCH_GIVEN;
  for (int i = 0; i < 6; ++i) msg.wrench[i] = wrench_Sensor[i];
}

void setDesiredPose(correction_request_t& msg, const Pose& X_TrackerTip) {
  toPositionQuaternion(X_TrackerTip, msg.desired_position_m, msg.desired_quaternion_wxyz);
}

/// The requests for a campaign's rows (cycled up to count), and the rows they came from.
std::vector<correction_request_t> campaignRequests(const Args& args,
                                                   const std::vector<const Measurement*>& rows,
                                                   std::vector<const Measurement*>& row_of) {
  const bool inverse = args.mode == "inverse";
  std::vector<correction_request_t> requests;
  for (int i = 0; i < args.count; ++i) {
    const Measurement& row = *rows[size_t(i) % rows.size()];
    correction_request_t msg = emptyRequest(args);
    msg.mode = inverse ? correction_request_t::MODE_INVERSE : correction_request_t::MODE_FORWARD;
    if (!args.live_wrench) setWrench(msg, row.wrenchOrZero());
    if (row.temp_c) msg.temp_c = *row.temp_c;
    for (int j = 0; j < service::kMessageJoints; ++j) {
      msg.q_rad[j] = row.q_rad[j];
      msg.seed_q_rad[j] = row.q_rad[j] + (j % 2 ? -kSeedOffsetRad : kSeedOffsetRad);
    }
    if (inverse) setDesiredPose(msg, row.X_TrackerTip());
    requests.push_back(msg);
    row_of.push_back(&row);
  }
  return requests;
}

RowSet parseSet(const std::string& name) {
  for (RowSet set : {RowSet::kGeometry, RowSet::kStiffness, RowSet::kResidual,
                     RowSet::kValidation}) {
    if (name == toString(set)) return set;
  }
  throw InputError("--set '" + name + "': expected geometry, stiffness, residual or validation");
}

// ---- replies -------------------------------------------------------------------------------

JointVector jointsOf(const double* q_rad) {
  JointVector q(service::kMessageJoints);
  for (int i = 0; i < service::kMessageJoints; ++i) q[i] = q_rad[i];
  return q;
}

std::optional<int64_t> replyId(const lcm_recv_buf_t* rbuf) {
  correction_reply_t reply;
  if (reply.decode(rbuf->data, 0, int(rbuf->data_size)) < 0) return std::nullopt;
  return reply.request_id;
}

/// Requests sent with Exchange (sealed with the key, if any), their replies kept: only replies
/// that decode as version 2 and, with a key, verify. before_send(i), when given, runs before
/// request i leaves; its time does not count in the round trip.
std::vector<correction_reply_t> sendRequests(
    lcm_t* lcm, const Args& args, std::vector<correction_request_t> requests, Exchange& exchange,
    Authentication& auth, const std::function<void(size_t)>& before_send = nullptr) {
  std::vector<correction_reply_t> replies(requests.size());
  exchange.timeout_s = args.timeout_ms * 1e-3;
  exchange.id_of = [&auth](const lcm_recv_buf_t* rbuf) -> std::optional<int64_t> {
    if (!auth.accept(rbuf)) return std::nullopt;
    return replyId(rbuf);
  };
  exchange.keep = [&](size_t i, const lcm_recv_buf_t* rbuf) {
    replies[i].decode(rbuf->data, 0, int(rbuf->data_size));
  };
  std::vector<uint8_t> buffer(size_t(requests.front().getEncodedSize()));
  runExchange(lcm, service::kReplyChannel, int(requests.size()), args.rate_hz, exchange,
              [&](size_t i, int64_t id) {
                if (before_send) {
                  before_send(i);
                  exchange.sent[i] = Clock::now();
                }
                correction_request_t& msg = requests[i];
                msg.request_id = id;
                msg.utime = unixMicroseconds();
                const int size = msg.encode(buffer.data(), 0, int(buffer.size()));
                auth.seal(buffer.data(), size);
                lcm_publish(lcm, service::kRequestChannel, buffer.data(), unsigned(size));
              });
  return replies;
}

std::string vectorText(const double* v, int n, double scale = 1.0, const char* format = "%.6f") {
  std::string text = "[";
  char number[32];
  for (int i = 0; i < n; ++i) {
    if (i) text += ", ";
    std::snprintf(number, sizeof number, format, v[i] * scale);
    text += number;
  }
  return text + "]";
}

/// The joints (1-based) of a reply's uncovered_joints bits, e.g. [1, 4].
nlohmann::json uncoveredJoints(int32_t bits) {
  nlohmann::json joints = nlohmann::json::array();
  for (int j = 0; j < 32; ++j) {
    if ((static_cast<uint32_t>(bits) >> j) & 1u) joints.push_back(j + 1);
  }
  return joints;
}

/// A model id as printed by stepcal-runtime: 16 hex digits.
std::string modelIdText(int64_t model_id) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(model_id));
  return text;
}

nlohmann::json replyJson(const correction_reply_t& r, bool inverse) {
  const auto array = [](const double* v, int n) { return std::vector<double>(v, v + n); };
  nlohmann::json j = {
      {"request_id", r.request_id},
      {"status", runtime::toString(static_cast<runtime::Status>(r.status))},
      {"model_id", modelIdText(r.model_id)},
      {"compute_us", double(r.compute_ns) * 1e-3},
      {"predicted_position_m", array(r.predicted_position_m, 3)},
      {"predicted_quaternion_wxyz", array(r.predicted_quaternion_wxyz, 4)},
      {"gpr_std", array(r.gpr_std, 6)},
      {"wrench", array(r.wrench, 6)},
      {"uncovered_joints", uncoveredJoints(r.uncovered_joints)}};
  if (inverse) {
    j["q_target_rad"] = array(r.q_target_rad, 6);
    j["commanded_position_m"] = array(r.commanded_position_m, 3);
    j["commanded_quaternion_wxyz"] = array(r.commanded_quaternion_wxyz, 4);
    j["iterations"] = r.iterations;
    j["residual_position_m"] = r.residual_position_m;
    j["residual_orientation_rad"] = r.residual_orientation_rad;
  }
  return j;
}

void printReply(const correction_reply_t& r, double round_trip_us, bool inverse,
                const std::string& frame) {
  std::printf("request %lld: %s, model %016llx, compute %.1f us, round trip %.1f us\n",
              static_cast<long long>(r.request_id),
              runtime::toString(static_cast<runtime::Status>(r.status)),
              static_cast<unsigned long long>(r.model_id), double(r.compute_ns) * 1e-3,
              round_trip_us);
  if (inverse) {
    std::printf("q_target_rad              %s\n", vectorText(r.q_target_rad, 6).c_str());
    std::printf("q_target_deg              %s\n",
                vectorText(r.q_target_rad, 6, kDegPerRad).c_str());
    std::printf("commanded (%s) p_m %s  q_wxyz %s\n", frame == "user" ? "user   " : "base   ",
                vectorText(r.commanded_position_m, 3).c_str(),
                vectorText(r.commanded_quaternion_wxyz, 4).c_str());
  }
  std::printf("predicted (%-7s) p_m %s  q_wxyz %s\n", frame.c_str(),
              vectorText(r.predicted_position_m, 3).c_str(),
              vectorText(r.predicted_quaternion_wxyz, 4).c_str());
  std::printf("wrench used (N, N m)      %s\n", vectorText(r.wrench, 6, 1.0, "%.3f").c_str());
  std::printf("gpr_std (v m, w rad)      %s\n", vectorText(r.gpr_std, 6, 1.0, "%.3e").c_str());
  if (r.uncovered_joints != 0) {
    std::printf("outside the fitted angles of the profile of joint(s) %s\n",
                uncoveredJoints(r.uncovered_joints).dump().c_str());
  }
  if (inverse) {
    std::printf("iterations %d, residual %.4f mm, %.5f deg\n", r.iterations,
                r.residual_position_m * kMmPerM, r.residual_orientation_rad * kDegPerRad);
  }
}

/// The replies per status, by name (statuses never seen left out).
nlohmann::json statusesJson(const long (&status_counts)[kStatusCount]) {
  nlohmann::json statuses = nlohmann::json::object();
  for (int k = 0; k < kStatusCount; ++k) {
    if (status_counts[k]) statuses[runtime::toString(static_cast<runtime::Status>(k))] = status_counts[k];
  }
  return statuses;
}

/// When reply i arrived, CLOCK_MONOTONIC ns of this host (the daemon stamps wrenches on it too:
/// the two run side by side).
int64_t receivedNs(const Exchange& exchange, size_t i) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(exchange.sent[i].time_since_epoch())
             .count() +
         int64_t(exchange.round_trip_us[i] * 1e3);
}

/// The forward request of the command line, args.count times at args.rate_hz: per request when it
/// left and when its reply came (Unix time, to line up with faults logged elsewhere), its status,
/// the age of the live wrench it used on arrival and the predicted position. SIGINT/SIGTERM end it
/// early: the requests sent so far are reported. Exit status 1 when no reply came.
int runRepeated(const Args& args, const correction_request_t& msg) {
  std::signal(SIGINT, onStopSignal);
  std::signal(SIGTERM, onStopSignal);
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  const Clock::time_point steady_origin = Clock::now();
  const double unix_origin_s = double(unixMicroseconds()) * 1e-6;
  Authentication auth(args.key_file);
  const std::vector<correction_reply_t> replies =
      sendRequests(lcm.get(), args, std::vector<correction_request_t>(size_t(args.count), msg),
                   exchange, auth);
  nlohmann::json rows = nlohmann::json::array();
  long status_counts[kStatusCount] = {};
  int sent = 0;
  for (size_t i = 0; i < replies.size() && exchange.sent[i] != Clock::time_point{}; ++i, ++sent) {
    const double sent_unix_s =
        unix_origin_s + std::chrono::duration<double>(exchange.sent[i] - steady_origin).count();
    nlohmann::json& row = rows.emplace_back(nlohmann::json{
        {"sent_unix_s", sent_unix_s}, {"status", nullptr}, {"wrench_age_ms", nullptr}});
    if (std::isnan(exchange.round_trip_us[i])) continue;
    const correction_reply_t& r = replies[i];
    if (r.status >= 0 && r.status < kStatusCount) ++status_counts[r.status];
    row["received_unix_s"] = sent_unix_s + exchange.round_trip_us[i] * 1e-6;
    row["status"] = runtime::toString(static_cast<runtime::Status>(r.status));
    if (r.wrench_stamp_ns > 0) {
      row["wrench_age_ms"] = double(receivedNs(exchange, i) - r.wrench_stamp_ns) * 1e-6;
    }
    row["predicted_position_m"] =
        std::vector<double>(r.predicted_position_m, r.predicted_position_m + 3);
  }
  const nlohmann::json statuses = statusesJson(status_counts);
  const nlohmann::json report = {{"requests", sent},   {"replies", exchange.answered},
                                 {"lost", sent - exchange.answered},
                                 {"rate_hz", args.rate_hz},  {"statuses", statuses},
                                 {"authentication", auth.toJson()}, {"rows", rows}};
  if (exchange.answered == 0) auth.explainSilence();
  if (args.json) {
    std::cout << report.dump(1) << "\n";
  } else {
    std::cout << sent << " forward requests at " << args.rate_hz << " Hz: "
              << exchange.answered << " replies, statuses " << statuses.dump() << "\n";
  }
  return exchange.answered > 0 ? 0 : 1;
}

/// One request from the command line; exit status 1 when no reply came.
int runSingle(const Args& args) {
  const bool inverse = !args.inverse_pose.empty();
  correction_request_t msg = emptyRequest(args);
  if (!args.wrench.empty()) setWrench(msg, Vec6(args.wrench.data()));
  setTerms(args, msg);
  msg.temp_c = args.temp_c;
  if (inverse) {
    msg.mode = correction_request_t::MODE_INVERSE;
    std::copy(args.inverse_pose.begin(), args.inverse_pose.begin() + 3, msg.desired_position_m);
    std::copy(args.inverse_pose.begin() + 3, args.inverse_pose.end(), msg.desired_quaternion_wxyz);
    if (!args.seed_q_rad.empty()) std::copy(args.seed_q_rad.begin(), args.seed_q_rad.end(), msg.seed_q_rad);
  } else {
    msg.mode = correction_request_t::MODE_FORWARD;
    std::copy(args.forward_q_rad.begin(), args.forward_q_rad.end(), msg.q_rad);
    if (args.count > 0) return runRepeated(args, msg);
  }
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  Authentication auth(args.key_file);
  const std::vector<correction_reply_t> replies =
      sendRequests(lcm.get(), args, {msg}, exchange, auth);
  if (exchange.answered == 0) {
    std::cerr << "stepcal-client: no reply within " << args.timeout_ms
              << " ms (is stepcal-runtime running on " << args.lcm_url << "?)\n";
    auth.explainSilence();
    return 1;
  }
  if (args.json) {
    nlohmann::json j = replyJson(replies[0], inverse);
    j["round_trip_us"] = exchange.round_trip_us[0];
    std::cout << j.dump(2) << "\n";
  } else {
    printReply(replies[0], exchange.round_trip_us[0], inverse, args.frame);
  }
  return 0;
}

struct Accuracy {
  int poses = 0;
  double sum_position_m = 0, max_position_m = 0, sum_orientation_rad = 0;
  int orientations = 0;

  void add(double position_m, std::optional<double> orientation_rad) {
    ++poses;
    sum_position_m += position_m;
    max_position_m = std::max(max_position_m, position_m);
    if (orientation_rad) {
      sum_orientation_rad += *orientation_rad;
      ++orientations;
    }
  }
  nlohmann::json toJson(const std::string& against) const {
    return {{"against", against},
            {"poses", poses},
            {"mean_position_mm", poses ? sum_position_m / poses * kMmPerM : 0.0},
            {"max_position_mm", max_position_m * kMmPerM},
            {"mean_orientation_deg",
             orientations ? sum_orientation_rad / orientations * kDegPerRad : 0.0}};
  }
};

std::optional<twin::TwinRobot> readTruth(const std::string& path) {
  if (path.empty()) return std::nullopt;
  std::ifstream in(path);
  if (!in) throw InputError("--truth: cannot read the file", path);
  nlohmann::json truth;
  try {
    truth = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("--truth: not JSON: ") + e.what(), path);
  }
  return twin::TwinRobot::fromTruthJson(truth);
}

/// Waits for a simulated sensor's echo of one robot_state_t (by its utime).
struct StateEcho {
  int64_t wanted_utime = 0;
  bool seen = false;
  int missing = 0;  ///< states not echoed, or not read twice after, within 10 s (no simulator?)
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    auto* self = static_cast<StateEcho*>(user);
    stepcal_lcm::robot_state_t state{};
    if (state.decode(rbuf->data, 0, int(rbuf->data_size)) > 0 && state.utime == self->wanted_utime) {
      self->seen = true;
    }
  }
};

/// Counts the daemon's samples (wrench_t) stamped after a time: when it has two, its live wrench
/// is of the state applied before that time.
struct FreshSamples {
  int64_t after_ns = 0;  ///< CLOCK_MONOTONIC, as the samples' stamps
  int count = 0;
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    auto* self = static_cast<FreshSamples*>(user);
    stepcal_lcm::wrench_t sample{};
    if (sample.decode(rbuf->data, 0, int(rbuf->data_size)) > 0 && sample.stamp_ns > self->after_ns) {
      ++self->count;
    }
  }
};

/// Recomputes replies offline with the model each names (--check-model).
class ReplyChecker {
 public:
  /// Largest difference of any value from its offline recomputation. The daemon and this
  /// client run the same library code on the same inputs, so they agree to the last bit; the
  /// margin only forgives a client built with other flags than the daemon.
  static constexpr double kTolerance = 1e-12;

  explicit ReplyChecker(const std::vector<std::string>& model_paths) {
    for (const std::string& path : model_paths) {
      Known known{path, runtime::RuntimeModel::load(path), {}, 0};
      known.workspace = runtime::makeWorkspace(*known.model);
      models_.push_back(std::move(known));
    }
  }

  void check(const correction_request_t& request, const correction_reply_t& reply) {
    ++checked_;
    if (last_model_id_ != 0 && reply.model_id != last_model_id_) ++model_changes_;
    last_model_id_ = reply.model_id;
    Known* known = nullptr;
    for (Known& k : models_) {
      if (int64_t(k.model->model_id) == reply.model_id) known = &k;
    }
    if (known == nullptr) {
      ++unknown_model_;
      noteProblem(reply, "model " + modelIdText(reply.model_id) + " is none of --check-model's");
      return;
    }
    ++known->replies;
    if (reply.status >= 0 && reply.status < kStatusCount) ++known->status_counts[reply.status];
    const correction_reply_t expected = recompute(request, reply, *known);
    const double difference = maxDifference(expected, reply);
    max_difference_ = std::max(max_difference_, difference);
    if (expected.status != reply.status || expected.iterations != reply.iterations ||
        expected.uncovered_joints != reply.uncovered_joints || !(difference <= kTolerance)) {
      ++mismatched_;
      char what[160];
      std::snprintf(what, sizeof what,
                    "status %s, %d iterations offline with model %s; the reply: %s, %d, values "
                    "off by up to %.3g",
                    runtime::toString(runtime::Status(expected.status)), expected.iterations,
                    modelIdText(reply.model_id).c_str(),
                    runtime::toString(runtime::Status(reply.status)), reply.iterations, difference);
      noteProblem(reply, what);
    }
  }

  bool passed() const { return mismatched_ == 0 && unknown_model_ == 0; }

  nlohmann::json toJson() const {
    nlohmann::json models = nlohmann::json::array();
    for (const Known& k : models_) {
      models.push_back({{"path", k.path}, {"model_id", modelIdText(int64_t(k.model->model_id))},
                        {"replies", k.replies}, {"statuses", statusesJson(k.status_counts)}});
    }
    return {{"checked", checked_},         {"mismatched", mismatched_},
            {"unknown_model", unknown_model_}, {"max_difference", max_difference_},
            {"model_changes", model_changes_}, {"models", models},
            {"first_problem", first_problem_}};
  }

 private:
  struct Known {
    std::string path;
    std::unique_ptr<const runtime::RuntimeModel> model;
    runtime::Workspace workspace;
    long replies = 0;
    long status_counts[kStatusCount] = {};  ///< its replies per status
  };

  static correction_reply_t recompute(const correction_request_t& request,
                                      const correction_reply_t& reply, Known& known) {
    std::vector<uint8_t> bytes(size_t(request.getEncodedSize()));
    request.encode(bytes.data(), 0, int(bytes.size()));
    service::Request decoded;
    correction_reply_t expected{};
    expected.status = int8_t(service::decodeRequest(bytes.data(), int(bytes.size()), decoded));
    if (expected.status != int8_t(runtime::Status::kOk)) return expected;
    if (decoded.mode == service::Mode::kForward) {
      const runtime::ForwardResult r = runtime::correctForward(
          *known.model, known.workspace, decoded.q_rad, decoded.terms, decoded.temp_c);
      expected.status = int8_t(r.status);
      service::writeAnswer(r, expected);
      return expected;
    }
    runtime::InverseOptions options;
    options.max_iterations = reply.iterations;
    const runtime::InverseResult r = runtime::solveInverse(
        *known.model, known.workspace, decoded.X_FrameTcp_desired, decoded.terms,
        decoded.temp_c, decoded.seed_q_rad, runtime::Clock::time_point::max(), options);
    expected.status = int8_t(r.status);
    service::writeAnswer(r, expected);
    return expected;
  }

  static double maxDifference(const correction_reply_t& a, const correction_reply_t& b) {
    double largest = 0.0;
    const auto compare = [&](const double* x, const double* y, int n) {
      for (int i = 0; i < n; ++i) {
        const double d = std::abs(x[i] - y[i]);
        largest = std::isnan(d) ? std::numeric_limits<double>::infinity() : std::max(largest, d);
      }
    };
    compare(a.q_target_rad, b.q_target_rad, 6);
    compare(a.commanded_position_m, b.commanded_position_m, 3);
    compare(a.commanded_quaternion_wxyz, b.commanded_quaternion_wxyz, 4);
    compare(a.predicted_position_m, b.predicted_position_m, 3);
    compare(a.predicted_quaternion_wxyz, b.predicted_quaternion_wxyz, 4);
    compare(a.gpr_std, b.gpr_std, 6);
    compare(&a.residual_position_m, &b.residual_position_m, 1);
    compare(&a.residual_orientation_rad, &b.residual_orientation_rad, 1);
    return largest;
  }

  void noteProblem(const correction_reply_t& reply, const std::string& what) {
    if (first_problem_.empty()) {
      first_problem_ = "reply to request " + std::to_string(reply.request_id) + ": " + what;
    }
  }

  std::vector<Known> models_;
  long checked_ = 0, mismatched_ = 0, unknown_model_ = 0, model_changes_ = 0;
  int64_t last_model_id_ = 0;
  double max_difference_ = 0.0;
  std::string first_problem_;
};

/// A campaign's rows as requests: latency, lost replies, statuses, accuracy.
int runCampaign(Args args) {
  if (args.mode != "forward" && args.mode != "inverse") {
    throw InputError("--mode '" + args.mode + "': expected forward or inverse");
  }
  const bool inverse = args.mode == "inverse";
  if (args.live_wrench && args.rate_hz > 0.0) {
    throw InputError("--live-wrench sends one request at a time: drop --rate");
  }
  const Campaign campaign = readCampaign(args.campaign_dir);
  if (campaign.joint_count != service::kMessageJoints) {
    throw InputError("the campaign has " + std::to_string(campaign.joint_count) +
                         " joints; the LCM messages carry " +
                         std::to_string(service::kMessageJoints),
                     args.campaign_dir);
  }
  const std::vector<const Measurement*> rows = campaign.rowsIn(parseSet(args.set));
  if (rows.empty()) throw InputError("--set " + args.set + ": the campaign has no such rows", args.campaign_dir);
  if (inverse) {
    for (const Measurement* row : rows) {
      if (!row->has_orientation) {
        throw InputError("--mode inverse needs measured orientations; this row has none",
                         campaign.directory + "/" + campaign.measurements_file, row->source_line);
      }
    }
  }
  if (args.count <= 0) args.count = int(rows.size());
  const std::optional<twin::TwinRobot> truth = readTruth(args.truth_path);
  if (args.live_wrench && !args.check_models.empty()) {
    throw InputError("--check-model recomputes replies from the requests' wrenches: drop --live-wrench");
  }
  std::optional<ReplyChecker> checker;
  if (!args.check_models.empty()) checker.emplace(args.check_models);

  std::vector<const Measurement*> row_of;
  std::vector<correction_request_t> requests = campaignRequests(args, rows, row_of);
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  std::vector<uint8_t> state_buffer(size_t(stepcal_lcm::robot_state_t{}.getEncodedSize()));
  StateEcho echo;
  FreshSamples fresh;
  lcm_subscription_t* applied =
      service::subscribeQueued(lcm.get(), service::kRobotStateAppliedChannel, &StateEcho::on, &echo);
  lcm_subscription_t* samples =
      args.live_wrench
          ? service::subscribeQueued(lcm.get(), args.wrench_channel.c_str(), &FreshSamples::on,
                                     &fresh)
          : nullptr;
  const auto publishRobotState = [&](size_t i) {
    // Where the robot now is and what it carries, tagged with a fresh utime.
    stepcal_lcm::robot_state_t state{};
    state.utime = std::max(unixMicroseconds(), echo.wanted_utime + 1);
    for (int j = 0; j < service::kMessageJoints; ++j) state.q_rad[j] = row_of[i]->q_rad[j];
    state.payload_kg = row_of[i]->load_kg;
    echo.wanted_utime = state.utime;
    echo.seen = false;
    const int size = state.encode(state_buffer.data(), 0, int(state_buffer.size()));
    lcm_publish(lcm.get(), service::kRobotStateChannel, state_buffer.data(), unsigned(size));
    const Clock::time_point give_up = Clock::now() + std::chrono::seconds(10);
    while (!echo.seen && Clock::now() < give_up) handleUntil(lcm.get(), give_up);
    fresh.after_ns = runtime::steadyNowNs();
    fresh.count = 0;
    while (echo.seen && fresh.count < 2 && Clock::now() < give_up) handleUntil(lcm.get(), give_up);
    if (!echo.seen || fresh.count < 2) ++echo.missing;
  };
  Authentication auth(args.key_file);
  const std::vector<correction_reply_t> replies =
      sendRequests(lcm.get(), args, requests, exchange, auth,
                   args.live_wrench ? std::function<void(size_t)>(publishRobotState) : nullptr);
  if (exchange.answered == 0) auth.explainSilence();
  lcm_unsubscribe(lcm.get(), applied);
  if (samples) lcm_unsubscribe(lcm.get(), samples);

  long status_counts[kStatusCount] = {};
  std::vector<double> compute_us;
  Accuracy accuracy, forward_truth;
  std::vector<double> frame_to_reply_us;
  double iterations = 0;
  int64_t model_id = 0;
  // Per request: its row, status and GPR std (row by row comparisons of two runs).
  nlohmann::json per_row = nlohmann::json::array();
  for (size_t i = 0; i < replies.size(); ++i) {
    nlohmann::json& entry = per_row.emplace_back(nlohmann::json{
        {"line", row_of[i]->source_line}, {"load_kg", row_of[i]->load_kg}, {"status", nullptr}});
    if (std::isnan(exchange.round_trip_us[i])) continue;
    const correction_reply_t& r = replies[i];
    entry["status"] = runtime::toString(static_cast<runtime::Status>(r.status));
    entry["gpr_std"] = std::vector<double>(r.gpr_std, r.gpr_std + 6);
    if (r.status >= 0 && r.status < kStatusCount) ++status_counts[r.status];
    compute_us.push_back(double(r.compute_ns) * 1e-3);
    model_id = r.model_id;
    if (checker) checker->check(requests[i], r);
    if (r.wrench_stamp_ns > 0) {
      frame_to_reply_us.push_back(double(receivedNs(exchange, i) - r.wrench_stamp_ns) * 1e-3);
    }
    if (r.status != int8_t(runtime::Status::kOk)) continue;  // accuracy of plain answers
    const Measurement& row = *row_of[i];
    iterations += r.iterations;
    if (!inverse) {
      const Pose X = poseFromPositionQuaternion(r.predicted_position_m, r.predicted_quaternion_wxyz);
      accuracy.add((X.translation() - row.p_TipInTracker_m).norm(),
                   row.has_orientation ? std::optional<double>(lie::angleBetween(
                                             row.q_TrackerTip.toRotationMatrix(), X.linear()))
                                       : std::nullopt);
      if (truth) {
        const Pose X_true = truth->X_TrackerTip(row.q_rad, row.load_kg);
        forward_truth.add((X.translation() - X_true.translation()).norm(),
                          lie::angleBetween(X_true.linear(), X.linear()));
      }
    } else if (truth) {
      const Pose X_true = truth->X_TrackerTip(jointsOf(r.q_target_rad), row.load_kg);
      const Pose X_desired = row.X_TrackerTip();
      accuracy.add((X_true.translation() - X_desired.translation()).norm(),
                   lie::angleBetween(X_desired.linear(), X_true.linear()));
    } else {
      accuracy.add(r.residual_position_m, r.residual_orientation_rad);
    }
  }

  const nlohmann::json statuses = statusesJson(status_counts);
  nlohmann::json report = {
      {"mode", args.mode},
      {"requests", args.count},
      {"replies", exchange.answered},
      {"lost", args.count - exchange.answered},
      {"late", exchange.late},
      {"duplicates", exchange.duplicates},
      {"rate_hz", args.rate_hz},
      {"model_id", modelIdText(model_id)},
      {"round_trip_us", latencyJson(exchange.round_trip_us)},
      {"compute_us", latencyJson(compute_us)},
      {"statuses", statuses},
      {"accuracy",
       accuracy.toJson(inverse ? (truth ? "twin truth" : "solver residual") : "measured pose")}};
  report["authentication"] = auth.toJson();
  report["rows"] = per_row;
  if (inverse) {
    report["mean_iterations"] = accuracy.poses ? iterations / accuracy.poses : 0.0;
  } else if (truth) {
    report["accuracy_truth"] = forward_truth.toJson("twin truth");
  }
  report["wrench"] = args.live_wrench ? "live sensor" : "given (the rows' measured wrench)";
  if (args.live_wrench) {
    report["sensor_frame_to_reply_us"] = latencyJson(frame_to_reply_us);
    report["robot_states_not_applied"] = echo.missing;
  }
  if (checker) report["check"] = checker->toJson();
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << args.count << " " << args.mode << " requests (" << args.set << " rows of "
              << args.campaign_dir << "): " << exchange.answered << " replies, "
              << report["lost"] << " lost\n"
              << "round trip: " << latencyText(report["round_trip_us"]) << "\n"
              << "compute (daemon): " << latencyText(report["compute_us"]) << "\n"
              << "statuses: " << statuses.dump() << "\n";
    const nlohmann::json& a = report["accuracy"];
    std::printf("accuracy (%s, %d answers): mean %.4f mm, max %.4f mm, mean %.4f deg\n",
                a["against"].get<std::string>().c_str(), accuracy.poses,
                a["mean_position_mm"].get<double>(), a["max_position_mm"].get<double>(),
                a["mean_orientation_deg"].get<double>());
    if (report.contains("accuracy_truth")) {
      const nlohmann::json& t = report["accuracy_truth"];
      std::printf("accuracy (twin truth): mean %.4f mm, max %.4f mm, mean %.4f deg\n",
                  t["mean_position_mm"].get<double>(), t["max_position_mm"].get<double>(),
                  t["mean_orientation_deg"].get<double>());
    }
    if (args.live_wrench) {
      std::cout << "CAN frame to reply: " << latencyText(report["sensor_frame_to_reply_us"]) << "\n";
    }
    if (checker) {
      const nlohmann::json& c = report["check"];
      std::cout << "checked against their models: " << c["checked"] << " replies, "
                << c["mismatched"] << " differ, " << c["unknown_model"]
                << " from an unknown model, largest difference " << c["max_difference"] << "\n";
    }
  }
  if (checker && !checker->passed()) {
    std::cerr << "stepcal-client: torn answer: " << checker->toJson()["first_problem"].get<std::string>()
              << "\n";
    return 1;
  }
  return 0;
}

// ---- raw LCM ping-pong ---------------------------------------------------------------------

/// Ping payloads are as long as an encoded request, so both cross LCM alike.
int pingBytes() { return correction_request_t{}.getEncodedSize(); }

int runPing(const Args& args) {
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  exchange.timeout_s = args.timeout_ms * 1e-3;
  exchange.id_of = [](const lcm_recv_buf_t* rbuf) -> std::optional<int64_t> {
    if (rbuf->data_size < 8) return std::nullopt;
    return bigEndian64(static_cast<const uint8_t*>(rbuf->data));
  };
  exchange.keep = [](size_t, const lcm_recv_buf_t*) {};
  std::vector<uint8_t> payload(size_t(pingBytes()), 0);
  runExchange(lcm.get(), service::kPongChannel, args.ping_count, args.rate_hz, exchange,
              [&](size_t, int64_t id) {
                for (int b = 0; b < 8; ++b) payload[size_t(b)] = uint8_t(uint64_t(id) >> (56 - 8 * b));
                lcm_publish(lcm.get(), service::kPingChannel, payload.data(), unsigned(payload.size()));
              });
  const nlohmann::json report = {{"pings", args.ping_count},
                                 {"pongs", exchange.answered},
                                 {"lost", args.ping_count - exchange.answered},
                                 {"late", exchange.late},
                                 {"payload_bytes", payload.size()},
                                 {"round_trip_us", latencyJson(exchange.round_trip_us)}};
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << args.ping_count << " pings of " << payload.size() << " bytes: "
              << exchange.answered << " pongs, " << report["lost"] << " lost\n"
              << "round trip: " << latencyText(report["round_trip_us"]) << "\n";
  }
  if (exchange.answered == 0) {
    std::cerr << "stepcal-client: no pong (is `stepcal-client --echo` running on "
              << args.lcm_url << "?)\n";
    return 1;
  }
  return 0;
}

void onPing(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  lcm_publish(static_cast<lcm_t*>(user), service::kPongChannel, rbuf->data, rbuf->data_size);
}

/// Echoes pings until SIGINT or SIGTERM.
int runEcho(const Args& args) {
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  sigprocmask(SIG_BLOCK, &stop_signals, nullptr);
  const int signal_fd = signalfd(-1, &stop_signals, SFD_CLOEXEC);
  const Lcm lcm(args.lcm_url);
  service::subscribeQueued(lcm.get(), service::kPingChannel, &onPing, lcm.get());
  std::cerr << "stepcal-client: echoing " << service::kPingChannel << " on "
            << service::kPongChannel << " (" << args.lcm_url << ")\n";
  pollfd fds[2] = {{lcm_get_fileno(lcm.get()), POLLIN, 0}, {signal_fd, POLLIN, 0}};
  while (true) {
    if (poll(fds, 2, -1) < 0) continue;
    if (fds[1].revents & POLLIN) break;
    if (fds[0].revents & POLLIN) lcm_handle(lcm.get());
  }
  close(signal_fd);
  return 0;
}

// ---- sensor commands ------------------------------------------------------------------------

/// Publishes one sensor_command_t (sealed with the key, if any) to the daemon's CAN sensor.
int runSensorCommand(const Args& args) {
  stepcal_lcm::sensor_command_t command{};
  command.utime = unixMicroseconds();
  command.command = int8_t(1 + choice("--sensor-command", args.sensor_command,
                                      {"bias", "clear-bias", "reset"}));
  const Lcm lcm(args.lcm_url);
  Authentication auth(args.key_file);
  std::vector<uint8_t> bytes(size_t(command.getEncodedSize()));
  const int size = command.encode(bytes.data(), 0, int(bytes.size()));
  auth.seal(bytes.data(), size);
  if (lcm_publish(lcm.get(), service::kSensorCommandChannel, bytes.data(), unsigned(size)) != 0) {
    throw InputError("--sensor-command: LCM could not publish on " +
                     std::string(service::kSensorCommandChannel));
  }
  std::cout << "sent " << args.sensor_command << " on " << service::kSensorCommandChannel
            << (auth.signer ? " (authenticated)" : "") << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal-client: requests to stepcal-runtime over LCM; latency and accuracy"};
  Args args;
  app.add_option("--lcm-url", args.lcm_url, "LCM URL")->capture_default_str();
  app.add_option("--forward", args.forward_q_rad, "one forward request: joints q1..q6, rad")
      ->expected(6);
  app.add_option("--inverse", args.inverse_pose,
                 "one inverse request: TCP position x y z (m) and quaternion qw qx qy qz in "
                 "--frame (default: the tracker frame; the TCP is the measured target without "
                 "--tool)")
      ->expected(7);
  app.add_option("--seed", args.seed_q_rad, "inverse: joints to start from, rad (default 0)")
      ->expected(6);
  app.add_option("--wrench", args.wrench,
                 "given wrench on the sensor, fx fy fz (N) mx my mz (N m), sensor axes "
                 "(default: the daemon's live sensor)")
      ->expected(6);
  app.add_option("--temp-c", args.temp_c,
                 "structure temperature of a single request, °C, within -50 … 150 (default: not "
                 "measured, no thermal correction)");
  app.add_option("--campaign", args.campaign_dir, "send a campaign's rows");
  app.add_option("--set", args.set, "campaign rows: geometry | stiffness | residual | validation")
      ->capture_default_str();
  app.add_option("--mode", args.mode, "campaign requests: forward | inverse")->capture_default_str();
  app.add_option("--count", args.count,
                 "campaign requests to send (rows cycle; default: one per row); with --forward: "
                 "send it this many times (with --rate)");
  app.add_option("--rate", args.rate_hz, "requests per second (default: one in flight at a time)");
  app.add_option("--truth", args.truth_path, "the twin's truth.json to check answers against");
  app.add_flag("--live-wrench", args.live_wrench,
               "campaign: use the daemon's live sensor; publish each row's joints and payload as "
               "robot_state_t first");
  app.add_option("--wrench-channel", args.wrench_channel,
                 "--live-wrench: channel of the daemon's samples (stepcal-runtime --sensor-republish)")
      ->capture_default_str();
  app.add_option("--ping", args.ping_count, "raw LCM round trips to `stepcal-client --echo`");
  app.add_flag("--echo", args.echo, "answer STEPCAL_PING on STEPCAL_PONG until stopped");
  app.add_option("--deadline-us", args.deadline_us,
                 "request deadline, us (0: the daemon's budget)")->capture_default_str();
  app.add_option("--timeout-ms", args.timeout_ms, "a reply later than this is lost, ms")
      ->capture_default_str();
  app.add_flag("--json", args.json, "print JSON");
  app.add_option("--check-model", args.check_models,
                 "campaign: recompute every reply with the model file whose id it carries; "
                 "repeat for every model the daemon may serve")
      ->take_all();
  app.add_option("--frame", args.frame,
                 "single request: frame of its poses: tracker | base | user")->capture_default_str();
  app.add_option("--user-frame", args.user_frame,
                 "--frame user: the user frame in the robot base frame, x y z (m) qw qx qy qz")
      ->expected(7);
  app.add_option("--tool", args.tool, "single request: the TCP, x y z (m) qw qx qy qz, from "
                                      "--tool-from (default: none, the measured target)")
      ->expected(7);
  app.add_option("--tool-from", args.tool_from,
                 "what --tool is given from: target (the measured target) | flange (the "
                 "controller's tool data)")
      ->capture_default_str();
  app.add_option("--payload", args.payload_kg,
                 "single request: the payload's mass, kg (its weight replaces --wrench)");
  app.add_option("--cog", args.cog_m, "--payload: centre of gravity x y z, m, in --cog-frame")
      ->expected(3);
  app.add_option("--cog-frame", args.cog_frame, "--cog's frame: flange | tool")
      ->capture_default_str();
  app.add_option("--sensor-command", args.sensor_command,
                 "send one sensor_command_t: bias | clear-bias | reset");
  app.add_option("--key-file", args.key_file,
                 "the cell's key (32 bytes, mode 0600): seal requests and sensor commands, "
                 "verify replies");
  CLI11_PARSE(app, argc, argv);

  try {
    const int modes = int(!args.forward_q_rad.empty()) + int(!args.inverse_pose.empty()) +
                      int(!args.campaign_dir.empty()) + int(args.ping_count > 0) + int(args.echo) +
                      int(!args.sensor_command.empty());
    if (modes != 1) {
      throw InputError("choose exactly one of --forward, --inverse, --campaign, --ping N, --echo, "
                       "--sensor-command");
    }
    const bool single = !args.forward_q_rad.empty() || !args.inverse_pose.empty();
    if (!single && (args.frame != "tracker" || !args.user_frame.empty() || !args.tool.empty() ||
                    args.tool_from != "target" || args.payload_kg >= 0.0 || !args.cog_m.empty() ||
                    args.cog_frame != "flange")) {
      throw InputError("--frame, --user-frame, --tool, --tool-from, --payload, --cog and "
                       "--cog-frame go with --forward or --inverse");
    }
    if (!(args.timeout_ms > 0.0)) throw InputError("--timeout-ms must be > 0");
    if (!(args.rate_hz >= 0.0)) throw InputError("--rate must be ≥ 0");
    if (args.count > 0 && args.campaign_dir.empty() &&
        (args.forward_q_rad.empty() || !(args.rate_hz > 0.0))) {
      throw InputError("--count goes with --campaign, or with --forward and --rate");
    }
    if (!args.seed_q_rad.empty() && args.inverse_pose.empty()) {
      throw InputError("--seed goes with --inverse");
    }
    if (!args.wrench.empty() && args.forward_q_rad.empty() && args.inverse_pose.empty()) {
      throw InputError("--wrench goes with --forward or --inverse (campaign rows carry their own)");
    }
    if (!std::isnan(args.temp_c) &&
        (!runtime::validTemperature(args.temp_c) ||
         (args.forward_q_rad.empty() && args.inverse_pose.empty()))) {
      throw InputError("--temp-c goes with --forward or --inverse and lies within " +
                       std::to_string(int(runtime::kMinTemperature_c)) + " … " +
                       std::to_string(int(runtime::kMaxTemperature_c)) +
                       " °C (campaign rows carry their own)");
    }
    if (args.echo) return runEcho(args);
    if (!args.sensor_command.empty()) return runSensorCommand(args);
    if (args.ping_count > 0) return runPing(args);
    if (!args.campaign_dir.empty()) return runCampaign(args);
    return runSingle(args);
  } catch (const InputError& e) {
    std::cerr << "stepcal-client: error: " << e.what() << "\n";
    return 2;
  }
}
