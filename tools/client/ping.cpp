// stepcal-client --ping / --echo: raw LCM round trips, to tell LCM's own latency from the
// daemon's.
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <iostream>

#include "client.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/request.hpp"

namespace stepcal::client {
namespace {

int64_t bigEndian64(const uint8_t* bytes) {
  uint64_t value = 0;
  for (int i = 0; i < 8; ++i) value = (value << 8) | bytes[i];
  return static_cast<int64_t>(value);
}

/// A pong: the ping's id in its first 8 bytes.
void onPong(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  const Clock::time_point now = Clock::now();
  if (rbuf->data_size < 8) return;
  static_cast<Exchange*>(user)->onAnswer(bigEndian64(static_cast<const uint8_t*>(rbuf->data)), now);
}

/// Ping payloads are as long as an encoded request, so both cross LCM alike.
int pingBytes() { return service::requestBytes(); }

}  // namespace

int runPing(const Args& args) {
  const Lcm lcm(args.lcm_url);
  Exchange exchange;
  exchange.timeout_s = args.timeout_ms * 1e-3;
  std::vector<uint8_t> payload(size_t(pingBytes()), 0);
  lcm_subscription_t* pongs =
      service::subscribeQueued(lcm.get(), service::kPongChannel, &onPong, &exchange);
  runExchange(lcm.get(), args.ping_count, args.rate_hz, exchange, [&](size_t, int64_t id) {
    for (int b = 0; b < 8; ++b) payload[size_t(b)] = uint8_t(uint64_t(id) >> (56 - 8 * b));
    lcm_publish(lcm.get(), service::kPingChannel, payload.data(), unsigned(payload.size()));
  });
  lcm_unsubscribe(lcm.get(), pongs);
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
  }
  return exitStatusOf(args.ping_count, exchange.answered, exchange.answered, "pings");
}

namespace {

void onPing(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  lcm_publish(static_cast<lcm_t*>(user), service::kPongChannel, rbuf->data, rbuf->data_size);
}

}  // namespace

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

}  // namespace stepcal::client
