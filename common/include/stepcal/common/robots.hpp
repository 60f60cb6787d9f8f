// The robot descriptions stepcal ships (robots/*.urdf), found at run time.
//
// No path is compiled into a binary: the shipped URDFs are looked for in
//   1. $STEPCAL_ROBOTS_DIR, when set;
//   2. <folder of the running executable>/../share/stepcal/robots, which is where an install
//      puts them (prefix/bin/stepcal, prefix/share/stepcal/robots) and where the build copies
//      them (build/bin/stepcal, build/share/stepcal/robots).
// A command's --robot takes either a URDF file or the name of a shipped robot: an argument
// that contains '/' or ends in ".urdf" is a file, anything else a name ("irb4400", "ur10").
#pragma once

#include <string>
#include <vector>

namespace stepcal {

/// Environment variable that, when set, names the folder of the shipped robots first.
inline constexpr const char* kRobotsDirEnv = "STEPCAL_ROBOTS_DIR";

/// The folders searched for shipped robots, in order (those that exist or not).
std::vector<std::string> robotSearchFolders();

/// Names of the shipped robots found (file names without ".urdf", sorted, no repeats).
std::vector<std::string> shippedRobots();

/// The URDF file of a --robot argument: a path as given when it is one (it must be a readable
/// file), else the shipped robot of that name from the first folder that has it. Throws
/// InputError naming the argument, what was searched and the robots found.
std::string robotDescriptionPath(const std::string& robot);

/// Whether a --robot argument is a file path rather than a shipped robot's name.
bool isRobotPath(const std::string& robot);

}  // namespace stepcal
