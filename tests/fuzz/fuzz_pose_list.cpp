// libFuzzer target for readPoseList (poses.csv, six joints): no input may crash it, hang, trip a
// sanitizer or throw anything but InputError. Not part of the CMake build (that uses g++); build
// and run with `tests/system/fuzz.sh pose_list SECONDS`.
//
// A list that reads must also survive writePoseList: the written file must read back and write
// again to the same bytes. Seeds: tests/fuzz/seeds/pose_list, the header and first rows of a
// `stepcal plan` output.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "fuzz_files.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const stepcal::fuzz::ScratchFolder scratch;
  const std::string path =
      scratch.write("poses.csv", std::string(reinterpret_cast<const char*>(data), size)).string();
  std::vector<stepcal::PlannedMeasurement> rows;
  try {
    rows = stepcal::readPoseList(path, 6);
  } catch (const stepcal::InputError&) {
    return 0;
  }
  // Anything thrown from here on escapes, and libFuzzer reports it as a crash.
  const std::string written = (scratch.path() / "written.csv").string();
  const std::string rewritten = (scratch.path() / "rewritten.csv").string();
  stepcal::writePoseList(rows, written);
  stepcal::writePoseList(stepcal::readPoseList(written, 6), rewritten);
  if (scratch.read("written.csv") != scratch.read("rewritten.csv")) std::abort();
  return 0;
}
