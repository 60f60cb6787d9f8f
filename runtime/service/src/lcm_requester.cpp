#include "stepcal/service/lcm_requester.hpp"

#include <poll.h>
#include <time.h>

#include <algorithm>

#include <stepcal_lcm/runtime_status_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::service {

using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;

void handleLcmUntil(lcm_t* lcm, std::chrono::steady_clock::time_point until) {
  const auto wait =
      std::max(std::chrono::steady_clock::duration::zero(), until - std::chrono::steady_clock::now());
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count();
  timespec timeout{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
  pollfd fd{lcm_get_fileno(lcm), POLLIN, 0};
  if (ppoll(&fd, 1, &timeout, nullptr) > 0) lcm_handle(lcm);
}

LcmRequester::LcmRequester(lcm_t* lcm, const std::optional<CellKey>& key)
    : lcm_(lcm), buffer_(size_t(requestBytes())) {
  if (key) {
    signer_.emplace(*key);
    verifier_.emplace(*key);
  }
  subscription_ = subscribeQueued(lcm_, kReplyChannel, &LcmRequester::onReply, this);
  status_subscription_ = lcm_subscribe(lcm_, kStatusChannel, &LcmRequester::onStatus, this);
  if (status_subscription_ == nullptr) {
    lcm_unsubscribe(lcm_, subscription_);
    throw InputError(std::string("cannot subscribe to ") + kStatusChannel);
  }
}

LcmRequester::~LcmRequester() {
  lcm_unsubscribe(lcm_, status_subscription_);
  lcm_unsubscribe(lcm_, subscription_);
}

void LcmRequester::onStatus(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  stepcal_lcm::runtime_status_t status;
  if (status.decode(rbuf->data, 0, int(rbuf->data_size)) < 0) return;
  DaemonHeard& daemon = static_cast<LcmRequester*>(user)->daemon_;
  daemon.heard = true;
  daemon.keyed = status.authenticated != 0;
  daemon.forged_requests = status.forged_requests;
}

void LcmRequester::listenForStatus(std::chrono::nanoseconds wait) {
  const Clock::time_point until = Clock::now() + wait;
  while (!daemon_.heard && Clock::now() < until) handleLcmUntil(lcm_, until);
}

bool LcmRequester::keyRefused() const noexcept {
  const bool keyed_daemon_refused =
      daemon_.keyed && (!authenticated() || daemon_.forged_requests > 0);
  return keyed_daemon_refused || counters_.rejected_forged > 0;
}

bool LcmRequester::send(correction_request_t& request, int64_t request_id) {
  request.request_id = request_id;
  request.utime = unixMicroseconds();
  const int size = encodeRequest(request, buffer_.data(), int(buffer_.size()));
  if (signer_) signer_->seal(buffer_.data(), size);
  return lcm_publish(lcm_, kRequestChannel, buffer_.data(), unsigned(size)) == 0;
}

ReplyVerdict LcmRequester::judge(const void* data, int size, correction_reply_t& reply) noexcept {
  const ReplyKind kind = decodeReply(data, size, reply);
  if (kind == ReplyKind::kOldVersion) {
    ++counters_.old_version;
    counters_.old_version_seen = oldReplyVersion(data, size);
    return ReplyVerdict::kOldVersion;
  }
  if (verifier_) {
    const Verdict verdict =
        verifier_->verify(static_cast<const uint8_t*>(data), size, unixMicroseconds());
    if (verdict == Verdict::kForged) {
      ++counters_.rejected_forged;
      return ReplyVerdict::kForged;
    }
    if (verdict == Verdict::kReplayed) {
      ++counters_.rejected_replayed;
      return ReplyVerdict::kReplayed;
    }
  }
  return kind == ReplyKind::kReply ? ReplyVerdict::kAccepted : ReplyVerdict::kMalformed;
}

void LcmRequester::onReply(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  const Clock::time_point received = Clock::now();
  auto* self = static_cast<LcmRequester*>(user);
  correction_reply_t reply;
  if (self->judge(rbuf->data, int(rbuf->data_size), reply) != ReplyVerdict::kAccepted) return;
  if (self->awaiting_ && reply.request_id == self->awaited_id_) self->awaited_reply_ = reply;
  if (self->listener_) self->listener_(reply, received);
}

std::optional<correction_reply_t> LcmRequester::exchange(correction_request_t& request,
                                                         int64_t request_id,
                                                         std::chrono::nanoseconds timeout) {
  awaited_reply_.reset();
  awaited_id_ = request_id;
  awaiting_ = true;
  if (!send(request, request_id)) {
    awaiting_ = false;
    throw InputError("the request could not be sent (LCM refused it)");
  }
  const Clock::time_point until = Clock::now() + timeout;
  while (!awaited_reply_ && Clock::now() < until) handleLcmUntil(lcm_, until);
  awaiting_ = false;
  return awaited_reply_;
}

std::vector<std::string> LcmRequester::explainSilence(const std::string& key_option,
                                                      const RequesterCounters& since) const {
  const long old_version = counters_.old_version - since.old_version;
  const long forged = counters_.rejected_forged - since.rejected_forged;
  const long replayed = counters_.rejected_replayed - since.rejected_replayed;
  std::vector<std::string> reasons;
  if (old_version > 0) {
    const std::string version = std::to_string(counters_.old_version_seen);
    reasons.push_back("the daemon answered in message version " + version + " (correction_reply_v" +
                      version + "_t): it predates this client's version " +
                      std::to_string(correction_reply_t::VERSION) + "; update stepcal-runtime");
  }
  if (forged + replayed > 0) {
    reasons.push_back("rejected " + std::to_string(forged) +
                      " replies whose code does not verify and " + std::to_string(replayed) +
                      " whose counter is not fresh (" + key_option + ": is it the daemon's key?)");
  }
  if (daemon_.keyed && !authenticated()) {
    reasons.push_back("the daemon takes only requests sealed with its cell key (its STEPCAL_STATUS "
                      "says authenticated) and none was given: the key is missing; give the "
                      "cell's key with " + key_option);
  } else if (daemon_.keyed && daemon_.forged_requests > 0) {
    reasons.push_back("the daemon has dropped " + std::to_string(daemon_.forged_requests) +
                      " requests whose code does not verify since it started (STEPCAL_STATUS "
                      "forged_requests): the key may be wrong; is " + key_option +
                      " the daemon's key?");
  }
  return reasons;
}

}  // namespace stepcal::service
