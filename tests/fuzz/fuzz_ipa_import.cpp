// libFuzzer target for importIpaSeries (the IPA UR10 series CSV and its Trafo_TM_F_init.txt):
// no input may crash it, hang, trip a sanitizer or throw anything but InputError. Not part of
// the CMake build (that uses g++); build and run with `tests/system/fuzz.sh ipa_import SECONDS`.
//
// An input is the series CSV, a NUL byte, then Trafo_TM_F_init.txt; the robot is
// robots/ur10.urdf (STEPCAL_ROBOTS_DIR). What the importer accepts, `stepcal import` writes as
// a campaign: writeCampaign must take it and readCampaign read it back with every row.
// Seeds: the first rows of each series in tests/data/ipa-robot-accuracy (fuzz.sh makes them).
#include <cstdint>
#include <cstdlib>

#include "fuzz_files.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/importers/ipa.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const stepcal::fuzz::ScratchFolder scratch;
  static const std::string ur10_urdf = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";
  const auto [series, transform] = stepcal::fuzz::splitAtFirstNul(data, size);
  const std::string series_csv = scratch.write("measurements.csv", series).string();
  scratch.write("Trafo_TM_F_init.txt", transform);
  stepcal::Campaign campaign;
  try {
    campaign = stepcal::importers::importIpaSeries(series_csv, -1, ur10_urdf);
  } catch (const stepcal::InputError&) {
    return 0;
  }
  // Anything thrown from here on escapes, and libFuzzer reports it as a crash.
  const std::string folder = (scratch.path() / "campaign").string();
  stepcal::writeCampaign(campaign, folder);
  if (stepcal::readCampaign(folder).rows.size() != campaign.rows.size()) std::abort();
  return 0;
}
