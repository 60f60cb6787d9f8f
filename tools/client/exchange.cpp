// LCM round trips every subcommand shares: messages out on a schedule, answers matched by id.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>

#include "client.hpp"
#include "stepcal/service/latency.hpp"

namespace stepcal::client {

std::optional<size_t> Exchange::onAnswer(int64_t id, Clock::time_point now) {
  if (id < first_id || id - first_id >= int64_t(sent.size())) return std::nullopt;
  const auto i = static_cast<size_t>(id - first_id);
  if (sent[i] == Clock::time_point{}) return std::nullopt;
  if (!std::isnan(round_trip_us[i])) {
    ++duplicates;
    return std::nullopt;
  }
  const double us = std::chrono::duration<double, std::micro>(now - sent[i]).count();
  if (us > timeout_s * 1e6) {
    ++late;
    return std::nullopt;
  }
  round_trip_us[i] = us;
  ++answered;
  return i;
}

volatile std::sig_atomic_t stop_requested = 0;
void onStopSignal(int) { stop_requested = 1; }

void runExchange(lcm_t* lcm, int count, double rate_hz, Exchange& exchange,
                 const std::function<void(size_t, int64_t)>& send) {
  exchange.first_id = int64_t(getpid()) << 32;
  exchange.sent.assign(size_t(count), Clock::time_point{});
  exchange.round_trip_us.assign(size_t(count), std::numeric_limits<double>::quiet_NaN());
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
      service::handleLcmUntil(lcm, due);
      if (rate_hz > 0.0 || std::isnan(exchange.round_trip_us[size_t(next - 1)])) continue;
    }
    exchange.sent[size_t(next)] = Clock::now();
    send(size_t(next), exchange.first_id + next);
    ++next;
  }
  const Clock::time_point last_deadline = Clock::now() + timeout;
  while (exchange.answered < count && Clock::now() < last_deadline) {
    service::handleLcmUntil(lcm, last_deadline);
  }
}

std::optional<service::CellKey> loadKey(const std::string& key_file) {
  if (key_file.empty()) return std::nullopt;
  return service::CellKey::load(key_file);
}

std::vector<correction_reply_t> sendRequests(lcm_t* lcm, const Args& args,
                                             std::vector<correction_request_t> requests,
                                             Exchange& exchange, service::LcmRequester& requester,
                                             const std::function<void(size_t)>& before_send) {
  std::vector<correction_reply_t> replies(requests.size());
  exchange.timeout_s = args.timeout_ms * 1e-3;
  requester.setListener([&](const correction_reply_t& reply, Clock::time_point received) {
    if (const std::optional<size_t> i = exchange.onAnswer(reply.request_id, received)) {
      replies[*i] = reply;
    }
  });
  runExchange(lcm, int(requests.size()), args.rate_hz, exchange, [&](size_t i, int64_t id) {
    if (before_send) {
      before_send(i);
      exchange.sent[i] = Clock::now();
    }
    requester.send(requests[i], id);
  });
  requester.setListener(nullptr);
  return replies;
}

int exitStatusOf(int requests, int answered, long ok, const char* what) {
  if (requests > 0 && answered == 0) return exit_code::kNoService;  // the caller says why
  const long not_ok = long(requests) - ok;
  if (not_ok <= 0) return exit_code::kDone;
  std::cerr << "stepcal-client: " << not_ok << " of " << requests << " " << what
            << " not corrected (" << (requests - answered) << " without a reply in time, "
            << (long(answered) - ok) << " with a status other than OK)\n";
  return exit_code::kDoneInPart;
}

nlohmann::json authenticationJson(const service::LcmRequester& requester) {
  const service::RequesterCounters& c = requester.counters();
  return {{"key", requester.authenticated()}, {"rejected_forged_replies", c.rejected_forged},
          {"rejected_replayed_replies", c.rejected_replayed},
          {"old_version_replies", c.old_version}};
}

void explainSilence(service::LcmRequester& requester, const std::string& lcm_url) {
  // The daemon publishes its status at 10 Hz: three periods tell a silent one from none.
  requester.listenForStatus(std::chrono::milliseconds(300));
  for (const std::string& reason : requester.explainSilence("--key-file")) {
    std::cerr << "stepcal-client: " << reason << "\n";
  }
  if (!requester.daemonHeard().heard) {
    std::cerr << "stepcal-client: no STEPCAL_STATUS from a daemon on " << lcm_url
              << " either: is stepcal-runtime running there? (one that runs with a cell key "
                 "drops requests sent without it or with another key: is --key-file missing or "
                 "wrong?)\n";
  }
}

int64_t receivedNs(const Exchange& exchange, size_t i) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(exchange.sent[i].time_since_epoch())
             .count() +
         int64_t(exchange.round_trip_us[i] * 1e3);
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

}  // namespace stepcal::client
