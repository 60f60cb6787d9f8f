#include "stepcal/common/model_robot.hpp"

#include "stepcal/common/error.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal {

std::string jointNameList(const KinematicChain& chain) {
  std::string names;
  for (const ChainJoint& joint : chain.joints()) names += (names.empty() ? "" : ", ") + joint.name;
  return names;
}

std::string campaignRobotMismatch(const CalibratedModel& model, const Campaign& campaign) {
  const std::string source =
      campaign.directory.empty() ? campaign.robot_file : campaign.directory + "/" + campaign.robot_file;
  const KinematicChain campaign_nominal =
      chainFromUrdf(campaign.urdf_xml, campaign.base_link, campaign.tip_link, {}, source);
  // The model's own robot: nominal_Base, whose joints are chain_Tracker's (parseModel checks).
  const std::vector<ChainJoint>& a = model.nominal_Base.joints();
  const std::vector<ChainJoint>& b = campaign_nominal.joints();
  bool same = a.size() == b.size();
  for (size_t i = 0; same && i < a.size(); ++i) same = a[i].name == b[i].name;
  if (same) return {};
  return "the model's joints (" + jointNameList(model.nominal_Base) + ") are not the campaign's (" +
         jointNameList(campaign_nominal) + ", " + campaign.base_link + " -> " + campaign.tip_link +
         "); expected the campaign of the robot the model was calibrated for";
}

void requireCampaignOfModelRobot(const CalibratedModel& model, const Campaign& campaign,
                                 const std::string& model_path) {
  const std::string mismatch = campaignRobotMismatch(model, campaign);
  if (mismatch.empty()) return;
  throw InputError(mismatch + " (hint: a model corrects only the robot it was calibrated for; "
                              "calibrate this robot from its own campaign with `stepcal calibrate`)",
                   model_path);
}

}  // namespace stepcal
