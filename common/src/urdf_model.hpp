// urdfdom's side of the URDF readers (chain loader, calibrated export), shared inside common.
#pragma once

#include <urdf_model/model.h>
#include <urdf_world/types.h>

#include <string>
#include <vector>

#include "stepcal/common/types.hpp"

namespace stepcal {

/// urdfdom's model of URDF text; throws InputError naming source, with urdfdom's reasons.
urdf::ModelInterfaceSharedPtr parseUrdfOrThrow(const std::string& urdf_xml,
                                               const std::string& source);

/// A urdfdom pose (translation m, unit quaternion) as a rigid transform.
Pose poseFromUrdf(const urdf::Pose& p);

/// Joints from base down to link, in chain order; throws InputError naming source when link
/// (called role in the message) is no link of the model or not below base.
std::vector<urdf::JointConstSharedPtr> urdfPathFromBase(const urdf::ModelInterface& model,
                                                         const std::string& base,
                                                         const std::string& link,
                                                         const std::string& source,
                                                         const std::string& role);

}  // namespace stepcal
