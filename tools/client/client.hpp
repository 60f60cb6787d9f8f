// stepcal-client's parts (main.cpp lists the subcommands): the options, the LCM round trips
// every subcommand shares (exchange.cpp), the replies as text and JSON (replies.cpp), and one
// entry per subcommand: single requests (single.cpp), campaign replays (campaign.cpp, their
// offline checks in checks.cpp), ping/echo (ping.cpp) and sensor commands (sensor_command.cpp).
#pragma once

#include <chrono>
#include <csignal>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm.h>
#include <nlohmann/json.hpp>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/common/exit_codes.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/types.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_requester.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::client {

using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;
using Clock = std::chrono::steady_clock;
using service::unixMicroseconds;

constexpr double kSeedOffsetRad = 2.0 * kRadPerDeg;
constexpr int kStatusCount = 7;

struct Args {
  std::string lcm_url = service::kDefaultLcmUrl;
  // Command lines take mm and degrees (as `stepcal correct` does); messages carry SI.
  std::vector<double> forward_q_deg, inverse_pose, seed_q_deg, wrench;  ///< poses: x y z mm, qw … qz
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
  std::vector<double> user_frame, tool, cog_mm;  ///< x y z in mm (and qw qx qy qz)
  double payload_kg = -1.0;  ///< < 0: no payload
  std::string sensor_command;
  std::string key_file;
};

// ---- the subcommands ---------------------------------------------------------------------------

/// --forward / --inverse: one request (or --forward --count N --rate HZ); exit status 4 when no
/// reply came, 3 when a reply's status is not OK (exitStatusOf).
int runSingle(const Args& args);
/// --campaign: a campaign's rows as requests: latency, lost replies, statuses, accuracy; exit
/// status as exitStatusOf, 1 for a torn answer.
int runCampaign(Args args);
/// --ping N: raw LCM round trips to a `stepcal-client --echo`.
int runPing(const Args& args);
/// --echo: answers pings until SIGINT or SIGTERM.
int runEcho(const Args& args);
/// --sensor-command: one sensor_command_t (sealed with the key, if any) to the daemon's sensor,
/// confirmed by its sensor_status_t counters; exit status 4 when refused or not confirmed.
int runSensorCommand(const Args& args);

// ---- requests (single.cpp) ------------------------------------------------------------------------

/// A request with nothing asked yet (service::blankRequest) and --deadline-us.
correction_request_t emptyRequest(const Args& args);
/// A given wrench (wrench_source = given).
void setWrench(correction_request_t& msg, const Vec6& wrench_Sensor);

// ---- LCM round trips (exchange.cpp) --------------------------------------------------------------

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

/// Round trips of `count` messages numbered 0..count−1: what was sent when, what came back.
struct Exchange {
  int64_t first_id = 0;  ///< message i carries id first_id + i
  double timeout_s = 0.1;
  std::vector<Clock::time_point> sent;
  std::vector<double> round_trip_us;  ///< NaN until answered in time
  int answered = 0;
  int late = 0;        ///< answers after the timeout (counted as lost)
  int duplicates = 0;  ///< second answers to one message

  /// Records an answer to message id received at now: its index when it is the first answer in
  /// time to one of ours, else nullopt (counted as late or duplicate where it is one).
  std::optional<size_t> onAnswer(int64_t id, Clock::time_point now);
};

/// Set by SIGINT/SIGTERM where runRepeated installs onStopSignal: no further requests leave.
extern volatile std::sig_atomic_t stop_requested;
void onStopSignal(int);

/// Sends count messages through send(i, id), one in flight at a time (rate_hz = 0) or on a fixed
/// schedule, while the answers (on a channel the caller subscribed to) reach exchange.onAnswer.
void runExchange(lcm_t* lcm, int count, double rate_hz, Exchange& exchange,
                 const std::function<void(size_t, int64_t)>& send);

/// The cell key of --key-file, or none without it.
std::optional<service::CellKey> loadKey(const std::string& key_file);

/// Requests sent with Exchange through requester (sealed with the key, if any), their replies
/// kept: only replies the requester accepts. before_send(i), when given, runs before request i
/// leaves; its time does not count in the round trip.
std::vector<correction_reply_t> sendRequests(
    lcm_t* lcm, const Args& args, std::vector<correction_request_t> requests, Exchange& exchange,
    service::LcmRequester& requester, const std::function<void(size_t)>& before_send = nullptr);

/// The exit status of `requests` messages of which `answered` got a reply in time and `ok` of
/// those the status OK (exit_codes.hpp): 4 when none was answered, 3 when some were lost or not
/// OK (said on stderr, with `what`: "requests", "pings"), else 0.
int exitStatusOf(int requests, int answered, long ok, const char* what);

/// The requester's key and refused replies, for the reports.
nlohmann::json authenticationJson(const service::LcmRequester& requester);
/// Why no reply came (stderr): the refused replies and the daemon's STEPCAL_STATUS, listened for
/// a moment more when none was heard yet.
void explainSilence(service::LcmRequester& requester, const std::string& lcm_url);

/// When reply i arrived, CLOCK_MONOTONIC ns of this host (the daemon stamps wrenches on it too:
/// the two run side by side).
int64_t receivedNs(const Exchange& exchange, size_t i);

nlohmann::json latencyJson(std::vector<double> samples_us);
std::string latencyText(const nlohmann::json& j);

// ---- replies as text and JSON (replies.cpp) ------------------------------------------------------

JointVector jointsOf(const double* q_rad);
/// A model id as printed by stepcal-runtime: 16 hex digits.
std::string modelIdText(int64_t model_id);
/// A reply's predicted accuracy (RMS and 95 % bound, position m and orientation rad); null where
/// the model states none.
nlohmann::json accuracyJson(const correction_reply_t& r);
nlohmann::json replyJson(const correction_reply_t& r, bool inverse);
void printReply(const correction_reply_t& r, double round_trip_us, bool inverse,
                const std::string& frame);
/// The replies per status, by name (statuses never seen left out).
nlohmann::json statusesJson(const long (&status_counts)[kStatusCount]);

/// One of `names` (the index), or an InputError naming the option and the choices.
int8_t choice(const std::string& option, const std::string& value,
              const std::vector<std::string>& names);

}  // namespace stepcal::client
