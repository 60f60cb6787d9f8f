// Builds a KinematicChain from a URDF robot description.
//
// The chain runs from base_link to tip_link: revolute (and continuous) joints become axes,
// fixed joints fold into the initial pose matrices. A joint's <origin> is its initial pose,
// its <axis> gives the twist s = (0, axis) (METHOD.md eq. 1). Any link whose path from
// base_link crosses only chain joints and fixed joints can be attached as a named frame.
#pragma once

#include <string>
#include <vector>

#include "stepcal/common/chain.hpp"

namespace stepcal {

/// Parses URDF text (source names the file in error messages) and extracts the chain
/// base_link → tip_link with the extra links attached as frames. Throws InputError.
KinematicChain chainFromUrdf(const std::string& urdf_xml, const std::string& base_link,
                             const std::string& tip_link,
                             const std::vector<std::string>& attached_links = {},
                             const std::string& source = "robot.urdf");

/// Reads a URDF file and calls chainFromUrdf. Throws InputError.
KinematicChain chainFromUrdfFile(const std::string& path, const std::string& base_link,
                                 const std::string& tip_link,
                                 const std::vector<std::string>& attached_links = {});

/// Reads a whole text file; throws InputError naming the path when it cannot.
std::string readTextFile(const std::string& path);

}  // namespace stepcal
