// campaign_joint_zero: with several campaigns, each joint's zero in each later campaign against
// the first's (a joint re-mastered between them), one column per later campaign (families.hpp).
#include <algorithm>
#include <numeric>

#include "families.hpp"
#include "stepcal/common/mechanisms/campaign_joint_zero.hpp"

namespace stepcal::trainer::diagnosis {

void campaignJointZeroFamilies(const FamilyContext& c) {
  const int campaigns = 1 + std::accumulate(c.fit.rows.begin(), c.fit.rows.end(), 0,
                                            [](int most, const Measurement* row) {
                                              return std::max(most, row->session);
                                            });
  using Zeros = mechanism::CampaignJointZero<double>;
  for (int j = 0; j < c.n && campaigns > 1; ++j) {
    if (present(c.global, MechanismKind::kCampaignJointZero, j, -1) ||
        !c.wanted(MechanismKind::kCampaignJointZero, j)) {
      continue;
    }
    Family f;
    f.mechanism = blank(MechanismKind::kCampaignJointZero, c.n, j, -1, campaigns - 1);
    std::vector<Eigen::Index> columns;
    for (int k = 1; k < campaigns; ++k) {
      f.free.push_back(Zeros::offsetIndex(k));
      ScaledSource source;
      source.kind = ScaledSource::Kind::kCampaign;
      source.campaign = k;
      columns.push_back(c.sink.feature(j, std::move(source)));
    }
    std::vector<double> steps(columns.size(), typicalStep(f.mechanism, Zeros::offsetIndex(1)));
    c.addGlobal(std::move(f), std::move(columns), std::move(steps));
  }
}

}  // namespace stepcal::trainer::diagnosis
