// stepcal-client --sensor-command: one sensor_command_t (bias, clear-bias, reset) to the daemon's
// CAN sensor. It is fire-and-forget, but the daemon's STEPCAL_STATUS says whether it takes only
// keyed commands: a command sent without the key to such a daemon is an error, not "sent".
#include <iostream>

#include <stepcal_lcm/sensor_command_t.hpp>

#include "client.hpp"
#include "stepcal/service/lcm_requester.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::client {

int runSensorCommand(const Args& args) {
  stepcal_lcm::sensor_command_t command{};
  command.utime = unixMicroseconds();
  command.command = int8_t(1 + choice("--sensor-command", args.sensor_command,
                                      {"bias", "clear-bias", "reset"}));
  const Lcm lcm(args.lcm_url);
  const std::optional<service::CellKey> key = loadKey(args.key_file);
  std::optional<service::MessageSigner> signer;
  if (key) signer.emplace(*key);
  service::LcmRequester status_listener(lcm.get(), key);
  std::vector<uint8_t> bytes(size_t(command.getEncodedSize()));
  const int size = command.encode(bytes.data(), 0, int(bytes.size()));
  if (signer) signer->seal(bytes.data(), size);
  if (lcm_publish(lcm.get(), service::kSensorCommandChannel, bytes.data(), unsigned(size)) != 0) {
    throw InputError("--sensor-command: LCM could not publish on " +
                     std::string(service::kSensorCommandChannel));
  }
  // The daemon publishes its status at 10 Hz: three periods tell a keyed one.
  status_listener.listenForStatus(std::chrono::milliseconds(300));
  if (status_listener.daemonHeard().keyed && !signer) {
    std::cerr << "stepcal-client: the daemon on " << args.lcm_url
              << " takes only sensor commands sealed with its cell key (its STEPCAL_STATUS says "
                 "authenticated) and none was given: the key is missing, the command was "
                 "dropped; give the cell's key with --key-file\n";
    return kExitKeyRefused;
  }
  std::cout << "sent " << args.sensor_command << " on " << service::kSensorCommandChannel
            << (signer ? " (authenticated)" : "") << "\n";
  return 0;
}

}  // namespace stepcal::client
