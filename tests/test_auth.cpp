// Only the cell may talk to the daemon (runtime/service/auth.hpp): the key file is checked at
// start; with a key, a forged request, a replayed request, a forged reply and a forged or
// replayed sensor command are each refused and counted while genuine traffic passes, through an
// in-process memq:// LCM (the service, the CAN feed with the simulated sensor on a socketpair)
// and through the real daemon and client over UDP multicast (AuthUdpm, in a private network
// namespace: ctest net_auth).
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <optional>
#include <thread>
#include <vector>

#include <lcm/lcm.h>
#include <nlohmann/json.hpp>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>
#include <stepcal_lcm/runtime_status_t.hpp>
#include <stepcal_lcm/sensor_command_t.hpp>
#include <stepcal_lcm/sensor_status_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/ftsim/simulator.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/can_feed.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/reply.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "stepcal/allocation_counter.hpp"
#include "support/command.hpp"
#include "support/files.hpp"

namespace stepcal::service {
namespace {

using runtime::Status;
using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;

struct Paper {
  Campaign campaign;
  CalibratedModel model;
};

const Paper& paper() {
  static const Paper p = [] {
    twin::TwinOptions options;
    options.seed = 2;
    Paper result;
    result.campaign = twin::simulateCampaign(options, nullptr);
    result.model = trainer::modelFromOutcome(result.campaign,
                                             trainer::calibrateCampaign(result.campaign));
    return result;
  }();
  return p;
}

CellKey key(uint8_t fill) {
  std::array<uint8_t, kKeyBytes> bytes{};
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = uint8_t(fill + 31 * i);
  return CellKey::fromBytes(bytes);
}

const Measurement& row(size_t i = 0) {
  const auto rows = paper().campaign.rowsIn(RowSet::kValidation);
  return *rows[i % rows.size()];
}

std::vector<uint8_t> forwardBytes(const Measurement& r, int64_t id) {
  correction_request_t msg = blankRequest();
  msg.request_id = id;
  msg.wrench_source = correction_request_t::WRENCH_GIVEN;
  for (int j = 0; j < 6; ++j) msg.q_rad[j] = r.q_rad[j];
  for (int j = 0; j < 6; ++j) msg.wrench[j] = r.wrenchOrZero()[j];
  return encodeRequest(msg);
}

std::vector<uint8_t> sealed(std::vector<uint8_t> bytes, MessageSigner& signer) {
  signer.seal(bytes.data(), int(bytes.size()));
  return bytes;
}

ServiceOptions keyed(const CellKey& k) {
  ServiceOptions options;
  options.budget_ns = 1'000'000'000;
  options.key = k;
  return options;
}

TEST(Auth, KeyFileIsCheckedAtStart) {
  const test::TempDir dir;
  const std::string path = (dir.path() / "cell.key").string();
  EXPECT_THROW(
      {
        try {
          CellKey::load(path);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
          EXPECT_NE(std::string(e.what()).find("head -c 32 /dev/urandom"), std::string::npos);
          throw;
        }
      },
      InputError);
  test::writeText(path, std::string(32, 'k'));
  ASSERT_EQ(chmod(path.c_str(), 0644), 0);
  try {
    CellKey::load(path);
    ADD_FAILURE() << "a key others may read was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mode 0644"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("chmod 600"), std::string::npos) << e.what();
  }
  ASSERT_EQ(chmod(path.c_str(), 0600), 0);
  EXPECT_NO_THROW(CellKey::load(path));
  ASSERT_EQ(chmod(path.c_str(), 0400), 0);
  EXPECT_NO_THROW(CellKey::load(path));
  test::writeText(path + ".short", std::string(31, 'k'));
  ASSERT_EQ(chmod((path + ".short").c_str(), 0600), 0);
  try {
    CellKey::load(path + ".short");
    ADD_FAILURE() << "a 31-byte key was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("31 bytes; expected exactly 32"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(CellKey::load(dir.path().string()), InputError);

  // The daemon refuses it at start, naming the file (exit status 2).
  const std::string model = (dir.path() / "model.stepcal").string();
  writeModelFile(paper().model, model);
  ASSERT_EQ(chmod(path.c_str(), 0640), 0);
  const test::CommandResult r = test::run(std::string(STEPCAL_BIN_DIR) +
                                          "/stepcal-runtime --lcm-url memq:// --model " + model +
                                          " --key-file " + path);
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find(path), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("mode 0640"), std::string::npos) << r.out;

  // Started by systemd with the credential cell-key (LoadCredential=) and no --key-file: the
  // daemon reads $CREDENTIALS_DIRECTORY/cell-key, and names it when refusing it.
  const std::filesystem::path credentials = dir.path() / "credentials";
  std::filesystem::create_directory(credentials);
  const std::string credential = (credentials / "cell-key").string();
  test::writeText(credential, std::string(32, 'c'));
  ASSERT_EQ(chmod(credential.c_str(), 0644), 0);
  const std::string daemon = "CREDENTIALS_DIRECTORY=" + credentials.string() + " timeout 1 " +
                             std::string(STEPCAL_BIN_DIR) +
                             "/stepcal-runtime --lcm-url memq:// --model " + model;
  const test::CommandResult open_credential = test::run(daemon);
  EXPECT_EQ(open_credential.status, 2) << open_credential.out;
  EXPECT_NE(open_credential.out.find(credential + ": credential cell-key: mode 0644"),
            std::string::npos) << open_credential.out;
  ASSERT_EQ(chmod(credential.c_str(), 0400), 0);
  const test::CommandResult keyed = test::run(daemon);
  EXPECT_NE(keyed.out.find("cell key " + credential + " (credential cell-key;"), std::string::npos)
      << keyed.out;
  // An explicit --key-file wins over the credential; the credential "none" (the unit's
  // SetCredential= fallback without a key file) is no key.
  ASSERT_EQ(chmod(path.c_str(), 0600), 0);
  const test::CommandResult explicit_key = test::run(daemon + " --key-file " + path);
  EXPECT_NE(explicit_key.out.find("cell key " + path + " (--key-file;"), std::string::npos)
      << explicit_key.out;
  ASSERT_EQ(chmod(credential.c_str(), 0600), 0);
  test::writeText(credential, "none");
  EXPECT_NE(test::run(daemon).out.find("no cell key"), std::string::npos);
}

TEST(Auth, VerifierRefusesForgedAndReplayedMessages) {
  const CellKey k = key(1);
  MessageSigner signer(k), other_sender(k), outsider(key(2));
  MessageVerifier verifier(k, 2'000'000);
  const std::vector<uint8_t> plain = forwardBytes(row(), 1);
  const std::vector<uint8_t> first = sealed(plain, signer);
  const int64_t now = unixMicroseconds();
  EXPECT_EQ(verifier.verify(first.data(), int(first.size()), now), Verdict::kAuthentic);
  EXPECT_EQ(verifier.verify(first.data(), int(first.size()), now), Verdict::kReplayed);
  const std::vector<uint8_t> second = sealed(plain, signer);
  EXPECT_EQ(verifier.verify(second.data(), int(second.size()), now), Verdict::kAuthentic);
  EXPECT_EQ(verifier.verify(first.data(), int(first.size()), now), Verdict::kReplayed)
      << "an older counter of the same sender";
  const std::vector<uint8_t> from_other = sealed(plain, other_sender);
  EXPECT_EQ(verifier.verify(from_other.data(), int(from_other.size()), now), Verdict::kAuthentic);
  // A changed byte anywhere, another key, no code at all, too short: forged.
  for (size_t b = 0; b < first.size(); b += 13) {
    std::vector<uint8_t> changed = sealed(plain, signer);
    changed[b] ^= 0x10;
    EXPECT_EQ(verifier.verify(changed.data(), int(changed.size()), now), Verdict::kForged) << b;
  }
  const std::vector<uint8_t> foreign = sealed(plain, outsider);
  EXPECT_EQ(verifier.verify(foreign.data(), int(foreign.size()), now), Verdict::kForged);
  EXPECT_EQ(verifier.verify(plain.data(), int(plain.size()), now), Verdict::kForged);
  EXPECT_EQ(verifier.verify(plain.data(), kAuthBytes - 1, now), Verdict::kForged);
  // Outside the window: a genuine message kept and sent again 3 s later, or from a clock 3 s
  // ahead, is not fresh.
  MessageVerifier fresh(k, 2'000'000);
  const std::vector<uint8_t> kept = sealed(plain, signer);
  EXPECT_EQ(fresh.verify(kept.data(), int(kept.size()), now + 3'000'000), Verdict::kReplayed);
  EXPECT_EQ(fresh.verify(kept.data(), int(kept.size()), now - 3'000'000), Verdict::kReplayed);
}

/// Every message on one channel of an LCM instance, as bytes.
struct ChannelLog {
  std::vector<std::vector<uint8_t>> messages;
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    const auto* data = static_cast<const uint8_t*>(rbuf->data);
    static_cast<ChannelLog*>(user)->messages.emplace_back(data, data + rbuf->data_size);
  }
};

void pump(lcm_t* lcm) {
  while (lcm_handle_timeout(lcm, 5) > 0) {
  }
}

// With a key, over memq://: a genuine request is answered with a sealed reply; a forged request
// (no code, another key) and a replayed one get nothing and are counted; a forged reply (an
// impostor answering first) fails the client's check while the genuine one passes; sensor
// commands likewise: a forged BIAS and a replayed CLEAR_BIAS change nothing and are counted.
TEST(Auth, ForgedAndReplayedTrafficIsRefusedAndCounted) {
  const CellKey k = key(7);
  const std::unique_ptr<lcm_t, void (*)(lcm_t*)> lcm(lcm_create("memq://"), &lcm_destroy);
  ServiceOptions options = keyed(k);
  options.max_wrench_age_ns = 1'000'000'000;
  Service service(runtime::RuntimeModel::fromModel(paper().model, 11), "paper.stepcal", options);
  LcmServer server(lcm.get(), service);
  ChannelLog replies, statuses, sensor_statuses;
  lcm_subscribe(lcm.get(), kReplyChannel, &ChannelLog::on, &replies);
  lcm_subscribe(lcm.get(), kStatusChannel, &ChannelLog::on, &statuses);
  lcm_subscribe(lcm.get(), kSensorStatusChannel, &ChannelLog::on, &sensor_statuses);
  MessageSigner controller(k), impostor(key(8));
  MessageVerifier client_check(k);
  const auto publish = [&](const char* channel, const std::vector<uint8_t>& bytes) {
    ASSERT_EQ(lcm_publish(lcm.get(), channel, bytes.data(), unsigned(bytes.size())), 0);
    pump(lcm.get());
  };

  // Genuine: answered, and the reply verifies.
  const std::vector<uint8_t> genuine = sealed(forwardBytes(row(), 1), controller);
  publish(kRequestChannel, genuine);
  ASSERT_EQ(replies.messages.size(), 1u);
  const std::vector<uint8_t> genuine_reply = replies.messages[0];
  EXPECT_EQ(client_check.verify(genuine_reply.data(), int(genuine_reply.size()), unixMicroseconds()),
            Verdict::kAuthentic);
  correction_reply_t reply{};
  ASSERT_EQ(decodeReply(genuine_reply.data(), int(genuine_reply.size()), reply), ReplyKind::kReply);
  EXPECT_EQ(reply.status, int8_t(Status::kOk));
  EXPECT_EQ(reply.request_id, 1);

  // Forged requests (no code; another key) and a replayed one: no reply, counted.
  publish(kRequestChannel, forwardBytes(row(), 2));
  publish(kRequestChannel, sealed(forwardBytes(row(), 3), impostor));
  publish(kRequestChannel, genuine);
  EXPECT_EQ(replies.messages.size(), 1u);
  EXPECT_EQ(service.counters().forged, 2);
  EXPECT_EQ(service.counters().replayed, 1);
  // Genuine traffic still passes.
  publish(kRequestChannel, sealed(forwardBytes(row(1), 4), controller));
  ASSERT_EQ(replies.messages.size(), 2u);
  EXPECT_EQ(client_check.verify(replies.messages[1].data(), int(replies.messages[1].size()),
                                unixMicroseconds()),
            Verdict::kAuthentic);

  // A forged reply to request 5 (joint targets a robot would move to), published before the
  // daemon's: the client's check refuses it and takes the daemon's; a replayed reply too.
  correction_reply_t spoof = reply;
  spoof.request_id = 5;
  spoof.predicted_position_m[0] += 0.1;
  std::vector<uint8_t> spoof_bytes(size_t(spoof.getEncodedSize()));
  ASSERT_EQ(encodeReply(spoof, spoof_bytes.data(), int(spoof_bytes.size())),
            int(spoof_bytes.size()));
  const std::vector<uint8_t> spoof_sealed = sealed(spoof_bytes, impostor);
  publish(kReplyChannel, spoof_bytes);
  publish(kReplyChannel, spoof_sealed);
  publish(kRequestChannel, sealed(forwardBytes(row(2), 5), controller));
  ASSERT_EQ(replies.messages.size(), 5u);
  int forged = 0, authentic = 0;
  for (size_t i = 2; i < replies.messages.size(); ++i) {
    const Verdict v = client_check.verify(replies.messages[i].data(),
                                          int(replies.messages[i].size()), unixMicroseconds());
    forged += v == Verdict::kForged;
    authentic += v == Verdict::kAuthentic;
  }
  EXPECT_EQ(forged, 2);
  EXPECT_EQ(authentic, 1);
  EXPECT_EQ(client_check.verify(genuine_reply.data(), int(genuine_reply.size()), unixMicroseconds()),
            Verdict::kReplayed);

  // Sensor commands through the CAN feed (the simulated sensor on a socketpair).
  int ends[2];
  ASSERT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, ends), 0);
  runtime::CanSocket sensor_end = runtime::CanSocket::adopt(ends[1], "socketpair");
  ftsim::SensorSimulator simulator({});
  simulator.setWrench(row().wrenchOrZero());
  std::atomic<bool> stop{false};
  std::thread sensor([&] { simulator.serve(sensor_end, stop); });
  {
    runtime::FtSensorOptions sensor_options;
    sensor_options.bias_samples = 2;
    sensor_options.poll_hz = 200.0;
    CanWrenchFeed feed(lcm.get(), runtime::CanSocket::adopt(ends[0], "socketpair"),
                       sensor_options, "", service);
    while (feed.driver().counters().samples < 3) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const auto command = [](int8_t which) {
      stepcal_lcm::sensor_command_t c{};
      c.command = which;
      std::vector<uint8_t> bytes(size_t(c.getEncodedSize()));
      c.encode(bytes.data(), 0, int(bytes.size()));
      return bytes;
    };
    // A tare while a payload hangs on the sensor: forged, refused.
    publish(kSensorCommandChannel, command(stepcal_lcm::sensor_command_t::COMMAND_BIAS));
    publish(kSensorCommandChannel,
            sealed(command(stepcal_lcm::sensor_command_t::COMMAND_BIAS), impostor));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_FALSE(feed.driver().biased());
    EXPECT_EQ(feed.forgedCommands(), 2);
    // Genuine: applied; replayed: counted, not applied again.
    publish(kSensorCommandChannel,
            sealed(command(stepcal_lcm::sensor_command_t::COMMAND_BIAS), controller));
    while (!feed.driver().biased()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const std::vector<uint8_t> clear =
        sealed(command(stepcal_lcm::sensor_command_t::COMMAND_CLEAR_BIAS), controller);
    publish(kSensorCommandChannel, clear);
    EXPECT_FALSE(feed.driver().biased());
    publish(kSensorCommandChannel,
            sealed(command(stepcal_lcm::sensor_command_t::COMMAND_BIAS), controller));
    while (!feed.driver().biased()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    publish(kSensorCommandChannel, clear);  // the earlier CLEAR_BIAS again
    EXPECT_TRUE(feed.driver().biased()) << "a replayed command changed the sensor";
    EXPECT_EQ(feed.replayedCommands(), 1);
    EXPECT_EQ(feed.refusedCommands(), 0);
    feed.publishStatus();
    pump(lcm.get());
    ASSERT_EQ(sensor_statuses.messages.size(), 1u);
    stepcal_lcm::sensor_status_t s{};
    s.decode(sensor_statuses.messages[0].data(), 0, int(sensor_statuses.messages[0].size()));
    EXPECT_EQ(s.forged_commands, 2);
    EXPECT_EQ(s.replayed_commands, 1);
  }
  stop = true;
  sensor.join();

  server.publishStatus(false);
  pump(lcm.get());
  ASSERT_EQ(statuses.messages.size(), 1u);
  stepcal_lcm::runtime_status_t status{};
  status.decode(statuses.messages[0].data(), 0, int(statuses.messages[0].size()));
  EXPECT_EQ(status.authenticated, 1);
  EXPECT_EQ(status.forged_requests, 2);
  EXPECT_EQ(status.replayed_requests, 1);
  EXPECT_EQ(status.replies, 3);
}

TEST(Auth, CheckingAndSealingAllocateNothing) {
  const CellKey k = key(9);
  Service service(runtime::RuntimeModel::fromModel(paper().model, 12), "paper.stepcal", keyed(k));
  MessageSigner controller(k);
  std::vector<std::vector<uint8_t>> requests;
  for (int i = 0; i < 40; ++i) requests.push_back(sealed(forwardBytes(row(size_t(i)), i), controller));
  requests.push_back(forwardBytes(row(), 99));  // forged
  requests.push_back(requests[0]);              // replayed
  std::vector<uint8_t> reply(size_t(Service::replyBytes()));
  service.handleRequest(requests[0].data(), int(requests[0].size()), runtime::Clock::now(),
                        reply.data(), int(reply.size()));
  long allocations = 0;
  int answered = 0;
  {
    const test::AllocationCounter counter;
    for (size_t i = 1; i < requests.size(); ++i) {
      answered += service.handleRequest(requests[i].data(), int(requests[i].size()),
                                        runtime::Clock::now(), reply.data(), int(reply.size())) > 0;
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(answered, 39);
  EXPECT_EQ(service.counters().forged, 1);
  EXPECT_EQ(service.counters().replayed, 1);
}

// ---- the real daemon and client over UDP multicast (ctest net_auth) --------------------------

const std::string kBin = STEPCAL_BIN_DIR;

/// The latest runtime_status_t with authentication on that an LCM instance has received, within
/// 3 s.
std::optional<stepcal_lcm::runtime_status_t> keyedStatus(lcm_t* lcm, ChannelLog& log) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  while (std::chrono::steady_clock::now() < give_up) {
    while (lcm_handle_timeout(lcm, 20) > 0) {  // every queued message: the latest status last
    }
    for (auto it = log.messages.rbegin(); it != log.messages.rend(); ++it) {
      stepcal_lcm::runtime_status_t s{};
      if (s.decode(it->data(), 0, int(it->size())) > 0 && s.authenticated == 1) return s;
    }
  }
  return std::nullopt;
}

// The attack the issue names, with the real processes: a daemon with the cell key, an impostor
// daemon without it answering every request too, clients with the key, without it and with
// another, and a request captured off the wire and sent again.
TEST(AuthUdpm, TheRealDaemonAndClientRefuseWhatTheKeyDoesNotVouchFor) {
  if (std::getenv("STEPCAL_NETNS") == nullptr) {
    GTEST_SKIP() << "needs a private network namespace with multicast on its loopback "
                    "(tests/system/in_netns.sh; ctest -R net_auth)";
  }
  const test::TempDir dir;
  const std::string model = (dir.path() / "model.stepcal").string();
  writeModelFile(paper().model, model);
  const std::string key_file = (dir.path() / "cell.key").string(),
                    other_key = (dir.path() / "other.key").string();
  ASSERT_EQ(test::run("head -c 32 /dev/urandom > " + key_file + " && chmod 600 " + key_file +
                      " && head -c 32 /dev/urandom > " + other_key + " && chmod 600 " + other_key)
                .status,
            0);
  const std::string url = "udpm://239.255.76.68:7668?ttl=0";
  const std::string daemon_log = (dir.path() / "daemon.log").string();
  const std::string impostor_log = (dir.path() / "impostor.log").string();
  ASSERT_EQ(test::run(kBin + "/stepcal-runtime --model " + model + " --lcm-url '" + url +
                      "' --key-file " + key_file + " >/dev/null 2>" + daemon_log + " & echo $! > " +
                      (dir.path() / "daemon.pid").string())
                .status,
            0);
  const auto stop = [&](const std::string& pid_file) {
    test::run("kill -TERM $(cat " + pid_file + ") 2>/dev/null; sleep 0.2");
  };
  struct Stopper {
    std::function<void()> f;
    ~Stopper() { f(); }
  } stop_all{[&] {
    stop((dir.path() / "daemon.pid").string());
    stop((dir.path() / "impostor.pid").string());
  }};
  const std::string forward = " --forward 5.729577951308233 -17.188733853924695 22.918311805232932 0 "
                              "45.836623610465864 0 --wrench 0 0 -196 0 0 0 --json "
                              "--timeout-ms 1000 --lcm-url '" + url + "'";
  test::CommandResult genuine;
  for (int attempt = 0; attempt < 50; ++attempt) {  // until the daemon serves
    genuine = test::run(kBin + "/stepcal-client --key-file " + key_file + forward);
    if (genuine.status == 0) break;
  }
  ASSERT_EQ(genuine.status, 0) << genuine.out << test::run("cat " + daemon_log).out;
  EXPECT_NE(genuine.out.find("\"status\": \"OK\""), std::string::npos) << genuine.out;

  // Without the key, or with another: the daemon drops the requests; no reply.
  // Its STEPCAL_STATUS tells the client why: the key is missing or may be wrong (exit 4).
  const test::CommandResult keyless = test::run(kBin + "/stepcal-client" + forward);
  EXPECT_EQ(keyless.status, 4) << keyless.out;
  EXPECT_NE(keyless.out.find("the key is missing"), std::string::npos) << keyless.out;
  const test::CommandResult wrong = test::run(kBin + "/stepcal-client --key-file " + other_key + forward);
  EXPECT_EQ(wrong.status, 4) << wrong.out;
  EXPECT_NE(wrong.out.find("the key may be wrong"), std::string::npos) << wrong.out;

  // An impostor answers every request too, without the key: the client takes the daemon's reply
  // and rejects the impostor's.
  ASSERT_EQ(test::run(kBin + "/stepcal-runtime --model " + model + " --lcm-url '" + url + "' >/dev/null 2>" +
                      impostor_log + " & echo $! > " + (dir.path() / "impostor.pid").string())
                .status,
            0);
  test::run("for i in $(seq 50); do grep -q serving " + impostor_log + " && break; sleep 0.1; done");
  // Capture the genuine client's request off the wire meanwhile.
  const std::unique_ptr<lcm_t, void (*)(lcm_t*)> wire(lcm_create(url.c_str()), &lcm_destroy);
  ASSERT_TRUE(wire);
  ChannelLog captured, statuses;
  subscribeQueued(wire.get(), kRequestChannel, &ChannelLog::on, &captured);
  subscribeQueued(wire.get(), kStatusChannel, &ChannelLog::on, &statuses);
  // 20 requests 20 ms apart: each impostor's reply arrives while the client waits for the next.
  const test::CommandResult attacked = test::run(
      kBin + "/stepcal-client --key-file " + key_file + " --count 20 --rate 50" + forward);
  ASSERT_EQ(attacked.status, 0) << attacked.out;
  const nlohmann::json report = nlohmann::json::parse(attacked.out.substr(attacked.out.find('{')));
  EXPECT_EQ(report["replies"], 20) << attacked.out;
  EXPECT_EQ(report["statuses"]["OK"], 20) << attacked.out;
  EXPECT_GE(report["authentication"]["rejected_forged_replies"].get<int>(), 1) << attacked.out;
  EXPECT_EQ(report["authentication"]["rejected_replayed_replies"], 0) << attacked.out;
  pump(wire.get());
  ASSERT_FALSE(captured.messages.empty());
  // The captured request, sent again: dropped as a replay.
  const std::vector<uint8_t> replay = captured.messages.back();
  ASSERT_EQ(lcm_publish(wire.get(), kRequestChannel, replay.data(), unsigned(replay.size())), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const std::optional<stepcal_lcm::runtime_status_t> status = keyedStatus(wire.get(), statuses);
  ASSERT_TRUE(status) << "no status message from the keyed daemon";
  EXPECT_EQ(status->forged_requests, 2) << "the keyless and the wrong-key client's requests";
  EXPECT_EQ(status->replayed_requests, 1);
  EXPECT_GE(status->replies, 2);
  const std::string log = test::run("cat " + daemon_log).out;
  EXPECT_NE(log.find("cell key " + key_file), std::string::npos) << log;
  EXPECT_NE(log.find("dropped a request whose authentication code does not verify"),
            std::string::npos) << log;
  EXPECT_NE(log.find("dropped a request whose counter is not fresh"), std::string::npos) << log;
}

}  // namespace
}  // namespace stepcal::service
