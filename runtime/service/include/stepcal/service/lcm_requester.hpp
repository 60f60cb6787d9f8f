// The controller's side of the daemon's wire, shared by stepcal-client, the Python client
// (stepcal.Client) and the tests: requests sealed with the cell key (when given) and published on
// STEPCAL_REQUEST; every message on STEPCAL_REPLY judged before it may count as an answer: a
// daemon of message version 1 or 2 is told apart by name (its correction_reply_v1_t or
// correction_reply_v2_t), and with a key a
// reply whose code does not verify or whose counter is not fresh is refused. Refusals are counted,
// never matched to a request. The daemon's STEPCAL_STATUS is heard too: it tells a silence of a
// keyed daemon (its requests dropped for want of the key) from one of no daemon at all.
//
// One thread: the one that sends and calls lcm_handle on the LCM instance.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm.h>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>

#include "stepcal/service/auth.hpp"
#include "stepcal/service/reply.hpp"

namespace stepcal::service {

/// What became of one message on the reply channel.
enum class ReplyVerdict : int8_t {
  kAccepted = 0,    ///< a version-3 reply (with a key: its code verifies, its counter is fresh)
  kOldVersion = 1,  ///< a correction_reply_v1_t or _v2_t: the daemon predates message version 3
  kForged = 2,      ///< with a key: the code does not verify (another key, none, a change)
  kReplayed = 3,    ///< with a key: the code verifies but the counter is not fresh
  kMalformed = 4,   ///< not a reply (another type, truncated, too long)
};

/// Replies refused since the requester was made.
struct RequesterCounters {
  long rejected_forged = 0;    ///< kForged
  long rejected_replayed = 0;  ///< kReplayed
  long old_version = 0;        ///< kOldVersion: replies of a daemon that predates this client
  int old_version_seen = 0;    ///< the message version of the latest of them (1 or 2)
};

/// The latest runtime_status_t heard on kStatusChannel since the requester was made.
struct DaemonHeard {
  bool heard = false;
  bool keyed = false;           ///< authenticated = 1: it takes only requests sealed with its key
  int64_t forged_requests = 0;  ///< requests it dropped since its start: their code did not verify
};

class LcmRequester {
 public:
  using Clock = std::chrono::steady_clock;
  /// Called with every accepted reply and when LCM handed it over.
  using Listener = std::function<void(const stepcal_lcm::correction_reply_t&, Clock::time_point)>;

  /// Subscribes to kReplyChannel on lcm (not owned; must outlive the requester) with
  /// subscribeQueued's queue: every client sees every client's replies, so its queue must ride
  /// out stalls at their sum; and to kStatusChannel (daemonHeard). key: seal requests and verify
  /// replies; none: neither.
  LcmRequester(lcm_t* lcm, const std::optional<CellKey>& key);
  ~LcmRequester();
  LcmRequester(const LcmRequester&) = delete;
  LcmRequester& operator=(const LcmRequester&) = delete;

  bool authenticated() const noexcept { return signer_.has_value(); }
  const RequesterCounters& counters() const noexcept { return counters_; }
  const DaemonHeard& daemonHeard() const noexcept { return daemon_; }
  /// Handles LCM for `wait` at most, until a daemon's status has been heard (10 Hz).
  void listenForStatus(std::chrono::nanoseconds wait);
  /// True when what was heard says the cell key is the trouble: a keyed daemon and no key here,
  /// a keyed daemon that has dropped forged requests, or replies whose code does not verify.
  bool keyRefused() const noexcept;

  /// Stamps request with request_id and utime (now, µs since the Unix epoch), encodes it, seals
  /// it with the key (if any) and publishes it on kRequestChannel. False when LCM refused it.
  bool send(stepcal_lcm::correction_request_t& request, int64_t request_id);

  /// Every accepted reply from now on goes to listener (nullptr: none).
  void setListener(Listener listener) { listener_ = std::move(listener); }

  /// Sends request (send) and handles LCM until the accepted reply with its id arrives or
  /// timeout has passed: that reply, or nullopt (other replies go to the listener as ever).
  /// Throws InputError when LCM refused the request.
  std::optional<stepcal_lcm::correction_reply_t> exchange(stepcal_lcm::correction_request_t& request,
                                                          int64_t request_id,
                                                          std::chrono::nanoseconds timeout);

  /// The verdict on the bytes of one message on the reply channel, reply filled when kAccepted;
  /// refusals counted. The old version is told apart before any key is checked: a version-1
  /// daemon can carry no code (and an old reply is never an answer, whoever sealed it).
  ReplyVerdict judge(const void* data, int size, stepcal_lcm::correction_reply_t& reply) noexcept;

  /// Why no reply came, when the replies refused since `since` (a snapshot of counters()) say;
  /// none: empty. One sentence each; key_option names where the key was given (e.g.
  /// "--key-file").
  std::vector<std::string> explainSilence(const std::string& key_option,
                                          const RequesterCounters& since = {}) const;

 private:
  static void onReply(const lcm_recv_buf_t* rbuf, const char* channel, void* user);
  static void onStatus(const lcm_recv_buf_t* rbuf, const char* channel, void* user);

  lcm_t* lcm_;
  lcm_subscription_t* subscription_ = nullptr;
  lcm_subscription_t* status_subscription_ = nullptr;
  DaemonHeard daemon_;
  std::optional<MessageSigner> signer_;
  std::optional<MessageVerifier> verifier_;
  RequesterCounters counters_;
  std::vector<uint8_t> buffer_;
  Listener listener_;
  int64_t awaited_id_ = 0;
  std::optional<stepcal_lcm::correction_reply_t> awaited_reply_;
  bool awaiting_ = false;
};

/// Waits until `until` at most for traffic on lcm and dispatches it (one lcm_handle).
void handleLcmUntil(lcm_t* lcm, std::chrono::steady_clock::time_point until);

}  // namespace stepcal::service
