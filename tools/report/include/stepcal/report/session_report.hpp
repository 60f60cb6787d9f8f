// The words of a merged calibration's campaigns (several sessions of one robot): what differs
// between them, joint frame by joint frame and compliance by compliance, with 1-σ, as text lines
// and JSON, for the text, JSON and HTML reports.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::report {

/// Session s's frame difference in the joint's terms, e.g. "joint_3's zero differs between A and
/// B by +300 ± 4 µrad; the rest of the frame: rotation 4 ± 5 µrad, translation 2 ± 3 µm".
std::string frameDifferenceText(const Campaign& campaign, const trainer::SessionDifference& d, size_t s);

/// The frame test's verdict in words: "one serves all", "differs (z 10.9), removes 70.1 % of the
/// held-out error: kept per campaign", or, significant below trainer::kSessionDifferenceLeastShare,
/// "significant (z 6.8) but removes only 2.0 % of the held-out error: kept shared; a change of the
/// robot removes most of it (…)".
std::string frameVerdictText(const trainer::SessionDifference& d);

/// Session s's compliance difference (its index among ComplianceDifferences::sessions), e.g.
/// "B against A: +1.2e-07 ± 3.1e-09 rad/(N·m), +48.1 ± 1.2 % of the shared 2.5e-07".
std::string complianceDifferenceText(const Campaign& campaign,
                                     const trainer::ComplianceDifferences& all,
                                     const trainer::ComplianceDifference& d, size_t s);

/// Which joint frames the fit gives each campaign its own, e.g. "T(joint_2->joint_3) each
/// campaign's own, the other joint frames shared", or that it shares every one.
std::string ownFramesText(const trainer::CalibrationOutcome& outcome);

/// Why a campaign's compliance was not tested, one line per such campaign (or why none was).
std::vector<std::string> untestedComplianceLines(const Campaign& campaign,
                                                 const trainer::ComplianceDifferences& all);

/// The text report's lines on the campaigns' differences (frames, then compliances).
std::string formatCampaignDifferences(const Campaign& campaign, const trainer::CalibrationOutcome& outcome);

/// `session_differences`: per joint frame, its test and each campaign against the first.
nlohmann::json sessionDifferencesJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome);

/// Adds a merged calibration's `per_campaign_frames` and `compliance_differences` (nothing with
/// one campaign).
void addCampaignDifferencesJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome,
                                nlohmann::json& report);

}  // namespace stepcal::report
