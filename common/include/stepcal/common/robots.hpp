// Where the robot descriptions shipped with stepcal (robots/*.urdf) are, for tools that default
// to them.
#pragma once

#include <string>

namespace stepcal {

/// The folder of the shipped robot descriptions: $STEPCAL_ROBOTS_DIR when set; else
/// <prefix>/share/stepcal/robots when the running executable is <prefix>/bin/… and that folder
/// exists (an installed stepcal); else the source tree's robots/ (a build tree).
std::string shippedRobotsDir();

}  // namespace stepcal
