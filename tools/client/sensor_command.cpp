// stepcal-client --sensor-command: one sensor_command_t (bias, clear-bias, reset) to the daemon's
// CAN sensor.
#include <iostream>

#include <stepcal_lcm/sensor_command_t.hpp>

#include "client.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::client {

int runSensorCommand(const Args& args) {
  stepcal_lcm::sensor_command_t command{};
  command.utime = unixMicroseconds();
  command.command = int8_t(1 + choice("--sensor-command", args.sensor_command,
                                      {"bias", "clear-bias", "reset"}));
  const Lcm lcm(args.lcm_url);
  std::optional<service::MessageSigner> signer;
  if (const std::optional<service::CellKey> key = loadKey(args.key_file)) signer.emplace(*key);
  std::vector<uint8_t> bytes(size_t(command.getEncodedSize()));
  const int size = command.encode(bytes.data(), 0, int(bytes.size()));
  if (signer) signer->seal(bytes.data(), size);
  if (lcm_publish(lcm.get(), service::kSensorCommandChannel, bytes.data(), unsigned(size)) != 0) {
    throw InputError("--sensor-command: LCM could not publish on " +
                     std::string(service::kSensorCommandChannel));
  }
  std::cout << "sent " << args.sensor_command << " on " << service::kSensorCommandChannel
            << (signer ? " (authenticated)" : "") << "\n";
  return 0;
}

}  // namespace stepcal::client
