#include "profile_load_check.hpp"

#include <algorithm>

#include "candidates.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// What one block adds beside the other, against the error the round started from.
struct Addition {
  Comparison comparison;
  double reduction_of_base = 0.0;
};

Addition addition(const CrossValidation::Outcome& base, const CrossValidation::Outcome& without,
                  const CrossValidation::Outcome& with) {
  Addition a;
  a.comparison = compare(without, with);
  a.reduction_of_base = (without.total() - with.total()) / std::max(base.total(), 1e-300);
  return a;
}

// The profile's leading 2·order columns and as many modulated ones, fitted in the profiles'
// stage with the profile's ridge: the modulated block beside the profile, the profile beside it.
std::pair<Addition, Addition> additions(const Family& family, int order, double lambda,
                                        const CrossValidation& cv) {
  const auto head = [order](const std::vector<Eigen::Index>& columns) {
    return std::vector<Eigen::Index>(columns.begin(), columns.begin() + 2 * order);
  };
  const std::vector<Eigen::Index> profile = head(family.columns);
  const std::vector<Eigen::Index> modulated = head(family.torque_modulated);
  std::vector<Eigen::Index> profile_first = profile, modulated_first = modulated;
  profile_first.insert(profile_first.end(), modulated.begin(), modulated.end());
  modulated_first.insert(modulated_first.end(), profile.begin(), profile.end());
  const CrossValidation::ProfileCandidate pm = cv.prepareProfile(profile_first);
  const CrossValidation::ProfileCandidate mp = cv.prepareProfile(modulated_first);
  const CrossValidation::Correction profile_alone = cv.withProfile(pm, 2 * order, lambda);
  const CrossValidation::Correction both = cv.withProfile(pm, 4 * order, lambda);
  const CrossValidation::Correction modulated_alone = cv.withProfile(mp, 2 * order, lambda);
  const std::vector<CrossValidation::Outcome> o =
      cv.heldOut({&cv.base(), &profile_alone, &modulated_alone, &both});
  return {addition(o[0], o[1], o[3]), addition(o[0], o[2], o[3])};
}

}  // namespace

void setAsideLoadModulatedProfiles(const std::vector<Scored>& scored,
                                   std::vector<size_t>& significant, const CrossValidation& cv,
                                   const DiagnosisModel& model, const DiagnoseOptions& options,
                                   int round, Diagnosis& d) {
  std::vector<LoadModulatedProfile>& found = d.load_modulated_profiles;
  const auto profiled = [&](int joint) {
    return std::any_of(model.profiles.begin(), model.profiles.end(),
                       [joint](const Profile& p) { return p.mechanism.joint == joint; });
  };
  found.erase(std::remove_if(found.begin(), found.end(),
                             [&](const LoadModulatedProfile& f) {
                               return f.profile_named && !profiled(f.joint);
                             }),
              found.end());
  const auto adds = [&](const Addition& a) {
    return a.comparison.p < options.family_alpha &&
           a.reduction_of_base >= options.min_relative_reduction;
  };
  std::vector<size_t> kept;
  for (size_t k : significant) {
    const Family& family = *scored[k].family;
    if (family.stage != Stage::kProfile || family.campaign != 0 ||
        family.torque_modulated.empty()) {
      kept.push_back(k);
      continue;
    }
    const int joint = family.mechanism.joint;
    const int order = scored[k].score.mechanism.order;
    const auto [modulated, profile] = additions(family, order, scored[k].lambda, cv);
    found.erase(std::remove_if(found.begin(), found.end(),
                               [joint](const LoadModulatedProfile& f) { return f.joint == joint; }),
                found.end());
    // Nothing beside the profile (the rows cannot tell them apart, or the profile is all):
    // named as it is.
    const bool profile_adds = adds(profile);
    if (!adds(modulated) || profile_adds) kept.push_back(k);
    if (!adds(modulated)) continue;
    LoadModulatedProfile f;
    f.joint = joint;
    f.order = order;
    f.round = round;
    f.profile_named = profile_adds;
    f.torque_std_nm = family.torque_std_nm;
    f.modulated_gain_mm = modulated.comparison.gain_mm;
    f.modulated_reduction = modulated.reduction_of_base;
    f.modulated_z = modulated.comparison.z;
    f.modulated_p = modulated.comparison.p;
    f.profile_gain_mm = profile.comparison.gain_mm;
    f.profile_reduction = profile.reduction_of_base;
    f.profile_z = profile.comparison.z;
    f.profile_p = profile.comparison.p;
    found.push_back(f);
  }
  significant = std::move(kept);
}

}  // namespace stepcal::trainer::diagnosis
