#include "stepcal/common/model_robot.hpp"

#include <cstdio>

#include "stepcal/common/error.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal {

std::string jointNameList(const KinematicChain& chain) {
  std::string names;
  for (const ChainJoint& joint : chain.joints()) names += (names.empty() ? "" : ", ") + joint.name;
  return names;
}

namespace {

// How far the same robot's nominal chain may lie from the model's, per joint frame: loose enough
// for its calibrated description (`stepcal export urdf`, measured 1.3 mm and 0.06 deg off on the
// IRB4400 twin) and a description written again with fewer digits; robots of another type differ
// by centimetres at least.
constexpr double kSameRobotOffsetM = 20e-3;
constexpr double kSameRobotTurnRad = 0.05;
constexpr double kSameRobotTwistDifference = 0.05;

// Joints of the same names in another geometry (say two robots of one maker, both named joint_1
// … joint_6): the robot's own initial poses and twists, the tool's excepted, against the model's.
std::string geometryMismatch(const KinematicChain& model_nominal, const KinematicChain& campaign_nominal) {
  for (int k = 0; k < model_nominal.dof(); ++k) {
    const Pose& X_model = model_nominal.initialPose(k);
    const Pose& X_campaign = campaign_nominal.initialPose(k);
    const double offset_m = (X_model.translation() - X_campaign.translation()).norm();
    const double turn_rad =
        Eigen::AngleAxisd(X_model.linear().transpose() * X_campaign.linear()).angle();
    const Vec6& s_model = model_nominal.joints()[size_t(k)].twist_Local;
    const Vec6& s_campaign = campaign_nominal.joints()[size_t(k)].twist_Local;
    if (offset_m <= kSameRobotOffsetM && turn_rad <= kSameRobotTurnRad &&
        (s_model - s_campaign).norm() <= kSameRobotTwistDifference) {
      continue;
    }
    const std::string& joint = model_nominal.joints()[size_t(k)].name;
    char apart[96];
    std::snprintf(apart, sizeof apart, "%.1f mm and %.2f deg", offset_m * 1e3, turn_rad * kDegPerRad);
    return "the model's robot and the campaign's name their joints alike (" +
           jointNameList(model_nominal) + ") but differ in geometry: " + joint +
           "'s nominal frame lies " + apart + " from the model's, its axis (" +
           formatShortest(s_campaign[3]) + ", " + formatShortest(s_campaign[4]) + ", " +
           formatShortest(s_campaign[5]) + ") against the model's (" + formatShortest(s_model[3]) +
           ", " + formatShortest(s_model[4]) + ", " + formatShortest(s_model[5]) +
           "); expected the campaign of the robot the model was calibrated for";
  }
  return {};
}

}  // namespace

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
  if (same) return geometryMismatch(model.nominal_Base, campaign_nominal);
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
