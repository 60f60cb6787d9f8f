// The request handling of stepcal-runtime, without sockets: bytes of a correction_request_t in,
// bytes of a correction_reply_t out, the live wrench and the model in service handed over
// lock-free (runtime/handoff.hpp). The daemon binds it to LCM (lcm_server.hpp); tests drive it
// directly or through an in-process memq:// LCM.
//
// Threads: one serving thread calls handleRequest and status; one sensor thread (or the serving
// thread itself) calls publishWrench; any other thread calls reload. handleRequest allocates
// nothing, locks nothing and never throws.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/runtime_status_t.hpp>

#include "stepcal/runtime/corrector.hpp"
#include "stepcal/runtime/handoff.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/request.hpp"

namespace stepcal::service {

struct ServiceOptions {
  /// Longest time from receiving a request to its reply: solveInverse's deadline is the
  /// receive time plus min(request deadline, budget), ns.
  int64_t budget_ns = 200'000;
  /// A live wrench older than this (on the serving thread's steady clock) gives STALE_WRENCH, ns.
  int64_t max_wrench_age_ns = 20'000'000;
  /// The cell's key (--key-file): requests must carry its code and a fresh counter, replies
  /// carry the daemon's. None: no authentication (anyone who reaches the LCM group may ask).
  std::optional<CellKey> key;
  /// How far a counter may lie from the daemon's clock, µs (--auth-window-ms).
  int64_t auth_window_us = kDefaultAuthWindowUs;
};

/// Counters since start; read on the serving thread.
struct ServiceCounters {
  int64_t requests = 0;         ///< messages handled, decodable or not
  int64_t replies = 0;          ///< replies encoded
  /// Messages without a request's fingerprint and id (other types, garbage, < 16 bytes): no
  /// reply. Malformed requests with a readable id get a BAD_REQUEST reply instead.
  int64_t unaddressable = 0;
  std::array<int64_t, 7> status_counts{};  ///< replies per runtime::Status value
  int64_t old_version = 0;  ///< requests in message version 1 or 2, refused by name
  int64_t forged = 0;       ///< with a key: dropped, their code did not verify
  int64_t replayed = 0;     ///< with a key: dropped, their counter was not fresh
};

/// Answers correction requests with the model in service.
class Service {
 public:
  /// Requests are served on ModelHandle reader slot 0.
  static constexpr int kServingReaderSlot = 0;
  /// Samples kept per status window for the percentiles (the maximum counts every request).
  static constexpr size_t kWindowSamples = 4096;

  /// Serves model, read from model_path (for the status message). Throws InputError when the
  /// model does not have kMessageJoints joints.
  Service(std::unique_ptr<const runtime::RuntimeModel> model, std::string model_path,
          ServiceOptions options);
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  /// Bytes of one encoded correction_reply_t.
  static int replyBytes() noexcept;

  /// Handles the LCM bytes of one request received at `received` (steady clock) and encodes its
  /// reply into reply[0 .. capacity). Returns the reply's size in bytes, or 0 when no reply is due
  /// (the bytes are not a correction_request_t; with a key, they fail its check) or capacity <
  /// replyBytes(). A version-1 request gets a correction_reply_v1_t BAD_REQUEST (none with a key:
  /// it can carry no code), a version-2 request a correction_reply_v2_t BAD_REQUEST (with a key,
  /// once its code verifies, sealed).
  /// With a key the reply is sealed (auth.hpp). Serving thread only; allocation-free, lock-free,
  /// never throws.
  int handleRequest(const void* data, int size, runtime::Clock::time_point received,
                    uint8_t* reply, int capacity) noexcept;

  /// Hands a live sensor sample to the requests (stamp_ns on runtime::Clock). One thread only.
  void publishWrench(const runtime::WrenchSample& sample) noexcept { wrench_.publish(sample); }

  /// Puts next in service, read from path; the model in service keeps answering until then and
  /// is freed once no request uses it. Throws InputError (nothing changes) when next does not
  /// have kMessageJoints joints. Any thread but the serving one; reloads are serialised.
  void reload(std::unique_ptr<const runtime::RuntimeModel> next, const std::string& path);
  /// Loads path and puts it in service. Throws InputError naming the file (nothing changes).
  void reloadFile(const std::string& path);

  /// model_id of the model in service.
  uint64_t modelId() const noexcept { return models_.currentModelId(); }
  const ServiceCounters& counters() const noexcept { return counters_; }
  const ServiceOptions& options() const noexcept { return options_; }

  /// The status message now: counters, compute-time percentiles over the requests since the
  /// previous call (then a new window starts), the model in service. Serving thread only;
  /// allocates only when the model's path changed.
  const stepcal_lcm::runtime_status_t& status(bool realtime);

 private:
  /// A workspace sized for one model, tagged with it. The serving thread uses the slot whose tag
  /// is the model it holds; reload fills the untagged slot before the swap and clears the old
  /// model's slot after it (when no request holds the old model any more).
  struct WorkspaceSlot {
    std::atomic<const runtime::RuntimeModel*> model{nullptr};
    runtime::Workspace workspace;
    std::string model_path;
  };

  /// Computes the reply of a decoded, valid request into reply_; returns its status.
  runtime::Status answer(const Request& request, const runtime::RuntimeModel& model,
                         runtime::Workspace& ws, runtime::Clock::time_point received) noexcept;
  WorkspaceSlot& slotOf(const runtime::RuntimeModel* model) noexcept;
  void recordCompute(double compute_us) noexcept;

  /// A BAD_REQUEST reply of message version `version` (1 or 2) to request_id into reply
  /// (capacity ≥ replyBytes()).
  int refuseOldVersion(int version, int64_t request_id, uint8_t* reply, int capacity) noexcept;

  ServiceOptions options_;
  std::optional<MessageVerifier> verifier_;  ///< with a key
  std::optional<MessageSigner> signer_;      ///< with a key
  runtime::ModelHandle models_;
  runtime::WrenchSlot wrench_;
  std::array<WorkspaceSlot, 2> slots_;
  std::mutex reload_mutex_;

  // Serving thread only.
  ServiceCounters counters_;
  stepcal_lcm::correction_reply_t reply_{};
  std::array<double, kWindowSamples> window_us_{};
  std::array<double, kWindowSamples> window_sorted_us_{};
  size_t window_count_ = 0;  ///< requests in the window (may exceed kWindowSamples)
  double window_max_us_ = 0.0;
  stepcal_lcm::runtime_status_t status_{};
};

/// Writes a result's answer (poses, joints, GPR std, coverage, accuracy, iterations) into a reply, as the
/// daemon sends it; nothing for results without one (BAD_REQUEST, STALE_WRENCH). Offline checkers
/// recompute replies through them. Allocation-free.
void writeAnswer(const runtime::ForwardResult& r, stepcal_lcm::correction_reply_t& reply) noexcept;
void writeAnswer(const runtime::InverseResult& r, stepcal_lcm::correction_reply_t& reply) noexcept;

/// Now, µs since the Unix epoch (the utime fields of the messages).
int64_t unixMicroseconds() noexcept;

/// Throws InputError unless the model has kMessageJoints joints; source names it.
void checkMessageJoints(const runtime::RuntimeModel& model, const std::string& source);

}  // namespace stepcal::service
