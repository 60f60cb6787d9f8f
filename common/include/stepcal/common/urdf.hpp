// Builds a KinematicChain from a URDF robot description.
//
// The chain runs from base_link to tip_link: revolute (and continuous) joints become axes,
// fixed joints fold into the initial pose matrices. A joint's <origin> is its initial pose,
// its <axis> gives the twist s = (0, axis) (METHOD.md eq. 1). Any link whose path from
// base_link crosses only chain joints and fixed joints can be attached as a named frame.
#pragma once

#include <optional>
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

/// Mass and first moment of each moving body of the chain base_link → tip_link, from the URDF's
/// <inertial> elements: body k (1 … n) is every link that moves with joint k and no later
/// joint (fixed side branches included). Layout of a self_weight mechanism (mechanisms.hpp):
/// per body [m_k kg, h_k kg·m (3)], h_k = m_k · centre of mass in frame k (the frame after
/// joint k's motion). nullopt when no moving link has an <inertial> (the URDF gives no masses);
/// links without one are massless, as in URDF. Throws InputError as chainFromUrdf.
std::optional<std::vector<double>> bodyMassesFromUrdf(const std::string& urdf_xml,
                                                      const std::string& base_link,
                                                      const std::string& tip_link,
                                                      const std::string& source = "robot.urdf");

/// Reads a URDF file and calls chainFromUrdf. Throws InputError.
KinematicChain chainFromUrdfFile(const std::string& path, const std::string& base_link,
                                 const std::string& tip_link,
                                 const std::vector<std::string>& attached_links = {});

/// A pose as the attribute values of a URDF <origin>: xyz (m) and rpy (rad, R = Rz(yaw) ·
/// Ry(pitch) · Rx(roll)), each number the shortest text that reads back to it exactly.
struct UrdfOrigin {
  std::string xyz, rpy;
};
UrdfOrigin urdfOriginOf(const Pose& X);

/// Reads a whole text file; throws InputError naming the path when it cannot.
std::string readTextFile(const std::string& path);

}  // namespace stepcal
