#include "stepcal/report/session_report.hpp"

#include <algorithm>
#include <cmath>

#include "stepcal/common/units.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

constexpr double kMicro = 1e6;

std::string nameOf(const Campaign& campaign, size_t s) { return campaign.sessions[s].directory; }

// The tested joint frames each campaign has its own, by name.
std::vector<std::string> ownFrameNames(const trainer::CalibrationOutcome& outcome) {
  std::vector<std::string> names;
  for (int k : outcome.poe.own_frames) {
    for (const trainer::SessionDifference& d : outcome.session_differences) {
      if (d.frame == k) names.push_back(d.name);
    }
  }
  return names;
}

// A session's compliance difference as a % of the shared value, and its 1-σ.
std::pair<double, double> percentOfShared(const trainer::ComplianceDifference& d, size_t s) {
  if (!(d.shared_rad_per_nm > 0.0)) return {NAN, NAN};
  return {100.0 * d.difference_rad_per_nm[s] / d.shared_rad_per_nm,
          100.0 * d.difference_sigma_rad_per_nm[s] / d.shared_rad_per_nm};
}

}  // namespace

std::string frameDifferenceText(const Campaign& campaign, const trainer::SessionDifference& d, size_t s) {
  const trainer::FrameDifference& f = d.against_first[s];
  std::string out;
  if (!f.zero_determined) {
    out = nameOf(campaign, s) + " against " + nameOf(campaign, 0) + ": " + d.joint +
          "'s zero not determined (it trades with each campaign's own tool)";
  } else if (d.significant) {
    out = format("%s's zero differs between %s and %s by %+.0f ± %.0f µrad", d.joint.c_str(),
                 nameOf(campaign, 0).c_str(), nameOf(campaign, s).c_str(),
                 f.zero_offset_rad * kMicro, f.zero_offset_sigma_rad * kMicro);
  } else {
    out = format("%s against %s: %s's zero %+.0f ± %.0f µrad", nameOf(campaign, s).c_str(),
                 nameOf(campaign, 0).c_str(), d.joint.c_str(), f.zero_offset_rad * kMicro,
                 f.zero_offset_sigma_rad * kMicro);
  }
  out += format("; the rest of the frame: rotation %.0f ± %.0f µrad, translation %.1f ± %.1f µm",
                f.other_rotation_rad * kMicro, f.other_rotation_sigma_rad * kMicro,
                f.translation_m * kMicro, f.translation_sigma_m * kMicro);
  if (f.undetermined_directions > 0) {
    out += format(" (%d direction%s trading with each campaign's own registration or tool left out)",
                  f.undetermined_directions, f.undetermined_directions > 1 ? "s" : "");
  }
  return out;
}

std::string frameVerdictText(const trainer::SessionDifference& d) {
  const double pct = 100.0 * trainer::heldOutShare(d);
  if (!d.significant) return "one serves all";
  if (d.kept_per_session) {
    return format("differs (z %.1f), removes %.1f %% of the held-out error: kept per campaign", d.z_statistic, pct);
  }
  return format("significant (z %.1f) but removes only %.1f %% of the held-out error: kept shared; "
                "a change of the robot removes most of it (kept per campaign from %.0f %%)",
                d.z_statistic, pct, 100.0 * trainer::kSessionDifferenceLeastShare);
}

std::string complianceDifferenceText(const Campaign& campaign,
                                     const trainer::ComplianceDifferences& all,
                                     const trainer::ComplianceDifference& d, size_t s) {
  const auto [pct, pct_sigma] = percentOfShared(d, s);
  return format("%s against %s: %+.3g ± %.2g rad/(N·m), %+.1f ± %.1f %% of the shared %.3g",
                nameOf(campaign, static_cast<size_t>(all.sessions[s])).c_str(),
                nameOf(campaign, static_cast<size_t>(all.sessions[0])).c_str(),
                d.difference_rad_per_nm[s], d.difference_sigma_rad_per_nm[s], pct, pct_sigma,
                d.shared_rad_per_nm);
}

std::string ownFramesText(const trainer::CalibrationOutcome& outcome) {
  const std::vector<std::string> names = ownFrameNames(outcome);
  if (names.empty()) return "the fit keeps every joint frame shared";
  std::string list;
  for (const std::string& name : names) list += (list.empty() ? "" : ", ") + name;
  return "the fit gives each campaign its own " + list +
         " (the data demand it), the other joint frames shared; the model file holds the first "
         "campaign's";
}

std::vector<std::string> untestedComplianceLines(const Campaign& campaign,
                                                 const trainer::ComplianceDifferences& all) {
  std::vector<std::string> lines;
  if (!all.tested) {
    lines.push_back("not tested: " + all.not_tested);
    return lines;
  }
  for (int s : all.untested_sessions) {
    lines.push_back("campaign " + std::to_string(s + 1) + " (" + nameOf(campaign, static_cast<size_t>(s)) +
                    ") not tested: fewer than 10 loaded poses (2 per fold)");
  }
  return lines;
}

std::string formatCampaignDifferences(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  std::string out =
      "  between the campaigns, per joint frame (held out, 5 folds of each campaign's poses: "
      "every frame shared against this one each campaign's own; each campaign against the "
      "first, fitted on every row, ± 1-sigma):\n";
  if (outcome.session_differences.empty()) {
    out += "    not tested: a campaign has fewer than 10 fit poses (2 per fold)\n";
  }
  for (const trainer::SessionDifference& d : outcome.session_differences) {
    out += format("    %-24s own frames remove %.4f mm of %.4f held out, z = %.1f: %s\n", d.name.c_str(),
                  d.held_out_gain_m * kMmPerM, d.shared_held_out_m * kMmPerM, d.z_statistic,
                  frameVerdictText(d).c_str());
    for (size_t s = 1; s < d.against_first.size(); ++s) {
      out += "      " + frameDifferenceText(campaign, d, s) + "\n";
    }
  }
  out += "    (" + ownFramesText(outcome) +
         ": a frame that differs is the robot changed between the campaigns, or a cause the "
         "geometry cannot take; kept per campaign only where it is significant and removes at "
         "least " + format("%.0f", 100.0 * trainer::kSessionDifferenceLeastShare) +
         " % of the held-out error)\n";
  const trainer::ComplianceDifferences& compliance = outcome.compliance_differences;
  out += "  between the campaigns, per joint compliance (held out, 5 folds of each campaign's "
         "loaded poses: every compliance shared against this one each campaign's own):\n";
  for (const std::string& line : untestedComplianceLines(campaign, compliance)) out += "    " + line + "\n";
  for (const trainer::ComplianceDifference& d : compliance.joints) {
    out += format("    %-14s %s: own compliances remove %.4f mm, z = %.1f\n", d.joint.c_str(),
                  d.significant ? "differs" : "one serves all", d.held_out_gain_m * kMmPerM, d.z_statistic);
    for (size_t s = 1; s < d.difference_rad_per_nm.size(); ++s) {
      out += "      " + complianceDifferenceText(campaign, compliance, d, s) + "\n";
    }
  }
  if (outcome.has_stiffness) out += "    (step 2 keeps one compliance per joint for the robot)\n";
  return out;
}

nlohmann::json sessionDifferencesJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  nlohmann::json differences = nlohmann::json::array();
  for (const trainer::SessionDifference& d : outcome.session_differences) {
    nlohmann::json against_first = nlohmann::json::array();
    for (size_t s = 0; s < d.differences.size(); ++s) {
      const Vec6& v = d.differences[s];
      const trainer::FrameDifference& f = d.against_first[s];
      against_first.push_back(
          {{"campaign", nameOf(campaign, s)},
           {"translation_um", v.head<3>().norm() * 1e6},
           {"rotation_urad", v.tail<3>().norm() * 1e6},
           {"twist_m_rad", {v(0), v(1), v(2), v(3), v(4), v(5)}},
           {"zero_offset_urad", f.zero_determined ? nlohmann::json(f.zero_offset_rad * kMicro) : nlohmann::json()},
           {"zero_offset_sigma_urad",
            f.zero_determined ? nlohmann::json(f.zero_offset_sigma_rad * kMicro) : nlohmann::json()},
           {"other_rotation_urad", f.other_rotation_rad * kMicro},
           {"other_rotation_sigma_urad", f.other_rotation_sigma_rad * kMicro},
           {"rest_translation_um", f.translation_m * kMicro},
           {"rest_translation_sigma_um", f.translation_sigma_m * kMicro},
           {"undetermined_directions", f.undetermined_directions}});
    }
    differences.push_back({{"frame", d.name},
                           {"joint", d.joint},
                           {"held_out_gain_mm", d.held_out_gain_m * kMmPerM},
                           {"shared_held_out_mm", d.shared_held_out_m * kMmPerM},
                           {"held_out_share", trainer::heldOutShare(d)},
                           {"z_statistic", d.z_statistic},
                           {"differs", d.significant},
                           {"own_per_campaign",
                            std::find(outcome.poe.own_frames.begin(), outcome.poe.own_frames.end(),
                                      d.frame) != outcome.poe.own_frames.end()},
                           {"verdict", frameVerdictText(d)},
                           {"against_first", against_first}});
  }
  return differences;
}

void addCampaignDifferencesJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome,
                                nlohmann::json& report) {
  if (campaign.sessions.empty()) return;
  report["per_campaign_frames"] = ownFrameNames(outcome);
  const trainer::ComplianceDifferences& all = outcome.compliance_differences;
  nlohmann::json joints = nlohmann::json::array();
  for (const trainer::ComplianceDifference& d : all.joints) {
    nlohmann::json against_first = nlohmann::json::array();
    for (size_t s = 0; s < d.difference_rad_per_nm.size(); ++s) {
      const auto [pct, pct_sigma] = percentOfShared(d, s);
      against_first.push_back({{"campaign", nameOf(campaign, static_cast<size_t>(all.sessions[s]))},
                               {"difference_rad_per_nm", d.difference_rad_per_nm[s]},
                               {"sigma_rad_per_nm", d.difference_sigma_rad_per_nm[s]},
                               {"difference_pct_of_shared", std::isfinite(pct) ? nlohmann::json(pct) : nlohmann::json()},
                               {"sigma_pct_of_shared", std::isfinite(pct_sigma) ? nlohmann::json(pct_sigma) : nlohmann::json()}});
    }
    joints.push_back({{"joint", d.joint},
                      {"shared_rad_per_nm", d.shared_rad_per_nm},
                      {"held_out_gain_mm", d.held_out_gain_m * kMmPerM},
                      {"z_statistic", d.z_statistic},
                      {"differs", d.significant},
                      {"against_first", against_first}});
  }
  nlohmann::json untested = nlohmann::json::array();
  for (int s : all.untested_sessions) untested.push_back(nameOf(campaign, static_cast<size_t>(s)));
  report["compliance_differences"] = {{"tested", all.tested},
                                      {"not_tested", all.tested ? nlohmann::json() : nlohmann::json(all.not_tested)},
                                      {"untested_campaigns", untested},
                                      {"joints", joints}};
}

}  // namespace stepcal::report
