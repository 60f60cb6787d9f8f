#include "stepcal/common/mechanisms/campaign_joint_zero.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {

const MechanismTraits& campaignJointZeroTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kCampaignJointZero, "campaign_joint_zero"};
    t.measurement_only = true;
    t.uses_joint = true;
    t.order_fits = [](int order) { return order >= 1; };
    t.parameter_names = [](int, int order) {
      std::vector<std::string> names;
      for (int k = 1; k <= order; ++k) names.push_back("campaign" + std::to_string(k + 1) + "_rad");
      return names;
    };
    t.describe_suffix = jointSuffix;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
