// libFuzzer target for the URDF loader (chainFromUrdf, bodyMassesFromUrdf): no input may crash
// it, hang, trip a sanitizer, fail an invariant of KinematicChain or throw anything but
// InputError. Not part of the CMake build (that uses g++); build and run with
// `tests/system/fuzz.sh urdf SECONDS`.
//
// An input's first line names base_link, tip_link and any links to attach, separated by spaces;
// the rest is the URDF text. Seeds: robots/*.urdf with their chains' names (fuzz.sh makes them).
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "stepcal/common/error.hpp"
#include "stepcal/common/urdf.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const size_t newline = text.find('\n');
  if (newline == std::string::npos) return 0;
  std::istringstream names(text.substr(0, newline));
  std::string base_link, tip_link, link;
  names >> base_link >> tip_link;
  std::vector<std::string> attached;
  while (names >> link) attached.push_back(link);
  const std::string urdf_xml = text.substr(newline + 1);
  try {
    stepcal::chainFromUrdf(urdf_xml, base_link, tip_link, attached, "fuzz.urdf");
    stepcal::bodyMassesFromUrdf(urdf_xml, base_link, tip_link, "fuzz.urdf");
  } catch (const stepcal::InputError&) {
  }
  return 0;
}
