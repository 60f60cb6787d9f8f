// A model file's calibrated geometry written back into the robot's URDF.
//
// The URDF the model was calibrated from is edited, not regenerated, so its link and joint
// names, limits, inertials, visuals, collisions and any other elements stay. What changes:
//   - each revolute joint's <origin> and <axis>: the calibrated T_{k,k+1}(0) (less the fixed
//     joints before it, which keep their nominal origins) and the twist's direction;
//   - a link `world` (the tracker frame) with a fixed joint to base_link holding X_TrackerBase,
//     so T_{0,1}(0) = X_TrackerBase · (fixed joints) · <origin of joint 1>;
//   - a link `tool` fixed to tip_link: the calibrated tip frame T_{n,n+1}(0), from which the
//     nominal fixed joints to tip_link are taken out.
// Forward kinematics world → tool of the result equals the model's chain (its geometric layer,
// eq. 5) to rounding. A twist (v, ω) with |ω| = 1 and no pitch (ω·v = 0) turns about the line
// through ω × v: the joint's origin goes onto that line and, when it is off the joint frame's
// origin, a link `<child>_on_axis` and a fixed joint put the child link back where the chain's
// frame is. Links above base_link are left out: `world` is the root.
#pragma once

#include <string>
#include <vector>

#include "stepcal/common/model_file.hpp"

namespace stepcal {

/// The robot description a model was calibrated from: URDF text and the chain's ends.
struct RobotDescription {
  std::string urdf_xml;
  std::string base_link, tip_link;
  std::string source;  ///< names the URDF in messages
};

/// The calibrated URDF and what of the original it left out.
struct CalibratedUrdf {
  std::string urdf_xml;
  std::vector<std::string> dropped_links;  ///< links not below base_link
};

/// Root link the export adds: the tracker frame.
inline const char* const kUrdfWorldLink = "world";
/// Link the export adds at the calibrated tip frame.
inline const char* const kUrdfToolLink = "tool";

/// The model's chain as robot's URDF (above). Throws InputError naming model_source when the
/// model cannot be a URDF (an extended model, a twist with pitch or a non-unit axis) and naming
/// robot.source when the URDF is not the robot the model was calibrated from or already uses a
/// name the export adds.
CalibratedUrdf calibratedUrdf(const CalibratedModel& model, const std::string& model_source,
                              const RobotDescription& robot);

}  // namespace stepcal
