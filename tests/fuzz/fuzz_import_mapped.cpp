// libFuzzer target for importMapped (`stepcal import mapped`: a mapping file, the tracker export
// and the joint log it names, and a tip link's transform): no input may crash it, hang, trip a
// sanitizer or throw anything but InputError. Not part of the CMake build (that uses g++); build
// and run with `tests/system/fuzz.sh import_mapped SECONDS`.
//
// An input is the mapping (YAML), a NUL byte, the tracker export, a NUL, the joint log, a NUL,
// the transform file; they are written as mapping.yaml, tracker.csv, joints.log and
// transform.txt into a scratch folder. A mapping with '/' or '\' (YAML's escapes) outside its
// format's name is skipped: its paths then stay in that folder (no other file of the machine is
// read) and its robot is a shipped one (robots/, STEPCAL_ROBOTS_DIR). What the importer accepts, `stepcal import mapped` writes as a
// campaign: writeCampaign must take it and readCampaign read it back with every row.
// Seeds: tests/fuzz/seeds/import_mapped (the layouts of tests/test_import_mapped.cpp, a few rows
// of the IPA set's Series D through its mapping).
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_files.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/importers/mapped.hpp"

namespace {

/// Whether the mapping has no '/' but in its format's name and no '\\': no path of it can then
/// leave the scratch folder (no absolute path, no "../"), nor be spelled with an escape.
bool pathsStayInTheScratchFolder(std::string mapping) {
  const std::string format = "stepcal-import-mapping/1";
  for (size_t at = mapping.find(format); at != std::string::npos; at = mapping.find(format, at)) {
    mapping.erase(at, format.size());
  }
  return mapping.find_first_of("/\\") == std::string::npos;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const stepcal::fuzz::ScratchFolder scratch;
  static const int robots_dir_set = ::setenv(stepcal::kRobotsDirEnv, STEPCAL_ROBOTS_DIR, 1);
  (void)robots_dir_set;
  const auto [mapping, files] = stepcal::fuzz::splitAtFirstNul(data, size);
  if (!pathsStayInTheScratchFolder(mapping)) return 0;
  const auto [tracker, more] = stepcal::fuzz::splitAtFirstNul(
      reinterpret_cast<const uint8_t*>(files.data()), files.size());
  const auto [joints, transform] = stepcal::fuzz::splitAtFirstNul(
      reinterpret_cast<const uint8_t*>(more.data()), more.size());
  const std::string mapping_path = scratch.write("mapping.yaml", mapping).string();
  scratch.write("tracker.csv", tracker);
  scratch.write("joints.log", joints);
  scratch.write("transform.txt", transform);
  stepcal::Campaign campaign;
  try {
    campaign = stepcal::importers::importMapped(mapping_path);
  } catch (const stepcal::InputError&) {
    return 0;
  }
  // Anything thrown from here on escapes, and libFuzzer reports it as a crash.
  const std::string folder = (scratch.path() / "campaign").string();
  stepcal::writeCampaign(campaign, folder);
  if (stepcal::readCampaign(folder).rows.size() != campaign.rows.size()) std::abort();
  return 0;
}
