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

std::vector<Eigen::Index> leading(const std::vector<Eigen::Index>& columns, int order) {
  return std::vector<Eigen::Index>(columns.begin(), columns.begin() + 2 * order);
}

// The profile at its order and the modulated columns at every order tried (their own, as a
// profile's: a stiffness varying at harmonic 6 is not held by a profile of order 4), fitted in
// the profiles' stage with the profile's ridge; at the modulated order whose fit alone is best
// held out, the modulated block beside the profile and the profile beside it.
struct Additions {
  Addition modulated, profile;  // each beside the other
  int modulated_order = 0;
};

Additions additions(const Family& family, int order, double lambda,
                                        const CrossValidation& cv, const DiagnoseOptions& options) {
  const std::vector<Eigen::Index> profile = leading(family.columns, order);
  const CrossValidation::Correction profile_alone =
      cv.withProfile(cv.prepareProfile(profile), 2 * order, lambda);
  std::vector<CrossValidation::Correction> alone, both;  // per modulated order
  std::vector<int> orders;
  const size_t width = std::max(family.torque_modulated.size(), family.weight_modulated.size());
  for (int m : options.profile_orders) {
    if (2 * m > static_cast<int>(width)) continue;
    orders.push_back(m);
    std::vector<Eigen::Index> columns;
    for (const std::vector<Eigen::Index>* block : {&family.torque_modulated, &family.weight_modulated}) {
      if (!block->empty()) {
        const std::vector<Eigen::Index> head = leading(*block, m);
        columns.insert(columns.end(), head.begin(), head.end());
      }
    }
    const int modulated_width = static_cast<int>(columns.size());
    columns.insert(columns.end(), profile.begin(), profile.end());
    const CrossValidation::ProfileCandidate prepared = cv.prepareProfile(columns);
    alone.push_back(cv.withProfile(prepared, modulated_width, lambda));
    both.push_back(cv.withProfile(prepared, modulated_width + 2 * order, lambda));
  }
  std::vector<const CrossValidation::Correction*> corrections = {&cv.base(), &profile_alone};
  for (size_t i = 0; i < alone.size(); ++i) {
    corrections.push_back(&alone[i]);
    corrections.push_back(&both[i]);
  }
  const std::vector<CrossValidation::Outcome> o = cv.heldOut(corrections);
  size_t best = 2;
  for (size_t i = 4; i < o.size(); i += 2) {
    if (o[i].total() < o[best].total()) best = i;
  }
  return {addition(o[0], o[1], o[best + 1]), addition(o[0], o[best], o[best + 1]),
          orders[(best - 2) / 2]};
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
        (family.torque_modulated.empty() && family.weight_modulated.empty())) {
      kept.push_back(k);
      continue;
    }
    const int joint = family.mechanism.joint;
    const int order = scored[k].score.mechanism.order;
    const Additions a = additions(family, order, scored[k].lambda, cv, options);
    const Addition& modulated = a.modulated;
    const Addition& profile = a.profile;
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
    f.modulated_order = a.modulated_order;
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
