// campaign_joint_zero: joint j's zero in each later campaign against the first's (measurement,
// not robot).
#pragma once

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::mechanism {

/// [δ_1 rad, …, δ_order rad]: in campaign k (from 0, the first) joint j's recorded angle reads
/// δ_k less than the first campaign's at the same link angle (the joint re-mastered between
/// them): the model of that campaign's rows takes q_j + δ_k.
template <class Double>
struct CampaignJointZero {
  static constexpr MechanismKind kKind = MechanismKind::kCampaignJointZero;
  /// Index of campaign k's offset (k = 1..order).
  static constexpr int offsetIndex(int campaign) noexcept { return campaign - 1; }
  Double* p;
  int order;
  Double& offset_rad(int campaign) const noexcept { return p[offsetIndex(campaign)]; }
};

}  // namespace stepcal::mechanism
