// session_frames: a later campaign's own tracker station and tool (measurement, not robot).
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [station: t m (3), r rad (3); tool: t m (3), r rad (3)]: a row of campaign `order` is
/// measured at X_Station · X · X_Tool, X the tip in the first campaign's tracker with its tool,
/// X_Station = (exp r̂, t) the first campaign's tracker axes in this campaign's tracker, X_Tool
/// = (exp r̂, t) this campaign's tool in the first campaign's (stationAndTool).
template <class Double>
struct SessionFrames {
  static constexpr MechanismKind kKind = MechanismKind::kSessionFrames;
  static constexpr int kStation = 0, kTool = 6;  ///< first index of each frame's six
  Double* p;
  int order;
  /// The campaign's index among those fitted together (≥ 1).
  int campaign() const noexcept { return order; }
  /// Entry i = 0 … 5 (t x, y, z, then r x, y, z) of the station or of the tool.
  Double& station(int i) const noexcept { return p[kStation + i]; }
  Double& tool(int i) const noexcept { return p[kTool + i]; }
};

}  // namespace stepcal::mechanism
