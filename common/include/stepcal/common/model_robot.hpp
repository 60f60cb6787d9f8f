// Whether a campaign is of the robot a model was calibrated for: the model file keeps its robot's
// nominal chain (model_file.hpp, "NOMI"), its joints named as in the campaign's robot description.
#pragma once

#include <string>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"

namespace stepcal {

/// Comma-separated joint names of a chain, in order: "joint_1, joint_2, …".
std::string jointNameList(const KinematicChain& chain);

/// Empty when the campaign's robot (its description from base_link to tip_link) has the model's
/// joints: the same count and names, in order, and each joint's nominal frame and axis where the
/// model's is (within 20 mm, 0.05 rad; the tool frame may differ). Else one line naming both
/// robots' joints, or the first joint whose geometry differs.
std::string campaignRobotMismatch(const CalibratedModel& model, const Campaign& campaign);

/// Throws InputError naming model_path when campaignRobotMismatch is not empty, with a hint that
/// the model applies only to the robot it was calibrated for.
void requireCampaignOfModelRobot(const CalibratedModel& model, const Campaign& campaign,
                                 const std::string& model_path);

}  // namespace stepcal
