// Whether one profile serves every campaign (search.hpp, judgeCampaignProfiles): each current
// profile's difference in each later campaign, screened held out like a candidate and reported,
// never added to the model.
#include <chrono>
#include <cmath>

#include "model_fits.hpp"
#include "scoring.hpp"
#include "search.hpp"

namespace stepcal::trainer::diagnosis {

void judgeCampaignProfiles(Search& search) {
  Diagnosis& d = search.d;
  if (d.campaigns.size() < 2 || search.model.profiles.empty()) return;
  const auto clock = std::chrono::steady_clock::now();
  const FitRows& fit = search.fit;
  const DiagnoseOptions& options = search.options;
  // On a copy: the screening's joint step moves the model it is built at.
  DiagnosisModel model = search.model;
  JointVector sigma = search.compliance_sigma;
  for (size_t k = 1; k < d.campaigns.size(); ++k) {
    Screening sc;
    std::unique_ptr<FoldGrams> grams;
    ScreeningScope scope;
    scope.families = false;
    scope.campaign_profiles = static_cast<int>(k);
    buildScreening(model, fit, options, search.body_masses, sc, grams, sigma, scope);
    const CrossValidation cv(*grams, fit, sc.stage1, sc.stage2, sc.ridge, sc.current);
    int tried = 0;
    for (const Family& family : sc.families) tried += configurations(family, options);
    const auto isSignificant = [&](const CandidateScore& s) {
      return s.p_value < options.family_alpha / std::max(1, tried) &&
             s.relative_reduction >= options.min_relative_reduction;
    };
    for (Scored& s : scoreFamilies(sc.families, cv, sc.stage1.size(), *grams, options, fit,
                                   [](const CandidateScore&) { return false; })) {
      CampaignProfileDifference difference;
      difference.score = std::move(s.score);
      difference.score.significant = isSignificant(difference.score);
      const Mechanism& m = difference.score.mechanism;
      double sum2 = 0.0;
      int rows = 0;
      for (const Measurement* row : fit.rows) {
        if (row->session != static_cast<int>(k)) continue;
        const double offset = transmissionOffset(m, row->q_rad(m.joint));
        sum2 += offset * offset;
        ++rows;
      }
      difference.rms_rad = rows > 0 ? std::sqrt(sum2 / rows) : 0.0;
      d.campaigns[k].profile_differences.push_back(std::move(difference));
    }
  }
  d.seconds_screening +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
}

}  // namespace stepcal::trainer::diagnosis
