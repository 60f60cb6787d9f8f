// Builds a KinematicChain from a URDF robot description.
//
// The chain runs from base_link to tip_link: revolute (and continuous) joints become axes,
// fixed joints fold into the initial pose matrices. A joint's <origin> is its initial pose,
// its <axis> gives the twist s = (0, axis) (docs/method.md eq. 1). Any link whose path from
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

/// The ends of a URDF's serial chain, what a command takes when --base-link and --tip-link are
/// not given: the root link, and the leaf link below the most revolute joints (the arm's end,
/// past any fixed joints after the last axis: tool0 in robots/ur10.urdf, tmac in
/// robots/irb4400.urdf). Throws InputError as chainFromUrdf, and when several leaves lie below
/// equally many revolute joints (a tree that branches after its last axis), naming them.
struct UrdfChainEnds {
  std::string base_link, tip_link;
};
UrdfChainEnds urdfChainEnds(const std::string& urdf_xml, const std::string& source = "robot.urdf");

/// The name attribute of the URDF's <robot>. Throws InputError as chainFromUrdf.
std::string urdfRobotName(const std::string& urdf_xml, const std::string& source = "robot.urdf");

/// Whether the URDF text has a link of this name. Throws InputError as chainFromUrdf.
bool urdfHasLink(const std::string& urdf_xml, const std::string& link,
                 const std::string& source = "robot.urdf");

/// The <limit effort> of each revolute joint on the chain base_link → tip_link, N·m; 0 where
/// the URDF gives none (a continuous joint without <limit>, or effort="0"). Throws InputError
/// as chainFromUrdf.
std::vector<double> jointEffortLimits(const std::string& urdf_xml, const std::string& base_link,
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
