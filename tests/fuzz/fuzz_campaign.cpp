// libFuzzer target for readCampaign (campaign.yaml + measurements.csv): no input may crash it,
// hang, trip a sanitizer or throw anything but InputError. Not part of the CMake build (that
// uses g++); build and run with `tests/system/fuzz.sh campaign SECONDS`.
//
// An input is campaign.yaml, a NUL byte, then measurements.csv; robot.urdf beside them is a
// fixed stub (the reader keeps the description's text, the URDF has its own target). A campaign
// that reads must also survive writeCampaign: when the writer takes it (it may refuse what its
// format cannot hold), the written folder must read back and write again to the same bytes.
// Seeds: tests/fuzz/seeds/campaign, the campaign.yaml and the header and first rows of each set of
// `stepcal simulate --seed 1` and of `stepcal import ipa` of Series C.
#include <cstdint>
#include <cstdlib>

#include "fuzz_files.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const stepcal::fuzz::ScratchFolder scratch;
  const auto [yaml, csv] = stepcal::fuzz::splitAtFirstNul(data, size);
  scratch.write("robot.urdf", "<robot name=\"fuzz\"/>\n");
  scratch.write("campaign.yaml", yaml);
  scratch.write("measurements.csv", csv);
  stepcal::Campaign campaign;
  try {
    campaign = stepcal::readCampaign(scratch.path().string());
  } catch (const stepcal::InputError&) {
    return 0;
  }
  const std::string written = (scratch.path() / "written").string();
  try {
    stepcal::writeCampaign(campaign, written);
  } catch (const stepcal::InputError&) {
    return 0;
  }
  // Anything thrown from here on escapes, and libFuzzer reports it as a crash.
  const std::string rewritten = (scratch.path() / "rewritten").string();
  stepcal::writeCampaign(stepcal::readCampaign(written), rewritten);
  for (const char* file : {"campaign.yaml", "measurements.csv", "robot.urdf"}) {
    if (scratch.read(std::string("written/") + file) !=
        scratch.read(std::string("rewritten/") + file)) {
      std::abort();
    }
  }
  return 0;
}
