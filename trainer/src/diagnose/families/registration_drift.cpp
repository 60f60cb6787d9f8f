// registration_drift: the tracker's registration moving in time order (families.hpp). What
// drifts while a campaign is measured: the tracker's registration in time order (a tripod
// settling, the floor warming: 6 DOF, a polynomial of the time order per degree tried), and each
// joint's zero with temperature (a motor's or gearbox's heat, joint_zero_drift). The first is
// the measurement's, the second the robot's: told apart by how they move the tip (the whole
// frame, one joint), not by when.
#include <algorithm>

#include "../confounds.hpp"
#include "families.hpp"
#include "stepcal/common/mechanisms/registration_drift.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Degrees of the registration drifts tried: a steady drift, a cubic like the trend test's, and
// one that bends more often over a long campaign.
constexpr int kDriftDegrees[] = {1, 3, 6};

}  // namespace

void registrationDriftFamilies(const FamilyContext& c) {
  if (present(c.global, MechanismKind::kRegistrationDrift, -1, -1) ||
      !c.wanted(MechanismKind::kRegistrationDrift)) {
    return;
  }
  double first_seq = 0.0, last_seq = 0.0;
  for (size_t i = 0; i < c.fit.rows.size(); ++i) {
    const double seq = static_cast<double>(c.fit.rows[i]->seq);
    first_seq = i == 0 ? seq : std::min(first_seq, seq);
    last_seq = i == 0 ? seq : std::max(last_seq, seq);
  }
  const bool several_campaigns =
      std::any_of(c.fit.rows.begin(), c.fit.rows.end(),
                  [](const Measurement* row) { return row->session > 0; });
  // A campaign's seq is unique (the reader refuses repeats); one built in memory may not be.
  if (several_campaigns) {
    c.s.untestable.push_back({"registration_drift",
                              "the fit rows are several campaigns, each with its own tracker "
                              "station; a drift within one of them is not modelled"});
    return;
  }
  if (!(last_seq > first_seq)) {
    c.s.untestable.push_back({"registration_drift", "every fit row has the same seq"});
    return;
  }
  using Drift = mechanism::RegistrationDrift<double>;
  // What moves with the time order: each re-makes the drift (the registration's twist) as a
  // function of itself, the nuisance the drift must be told apart from (confounds.hpp).
  std::vector<Family::Confound> confounds;
  for (const Confounder& moving : confoundersOf(confounderVariables(c.fit, c.start), "seq")) {
    Family::Confound confound{moving.variable->name, moving.r, {}};
    for (Eigen::Index k = 0; k < 6; ++k) {
      for (int f = 0; f < moving.variable->functions(); ++f) {
        confound.columns.push_back(c.sink.variableScaled(k, moving.variable, f));
      }
    }
    confounds.push_back(std::move(confound));
  }
  for (const int degree : kDriftDegrees) {
    Family f;
    f.mechanism = blank(MechanismKind::kRegistrationDrift, c.n, -1, -1, degree);
    view<mechanism::RegistrationDrift>(f.mechanism).firstSeq() = first_seq;
    view<mechanism::RegistrationDrift>(f.mechanism).lastSeq() = last_seq;
    std::vector<Eigen::Index> columns;
    for (int d = 1; d <= degree; ++d) {
      for (Eigen::Index k = 0; k < 6; ++k) {  // the degree's twist
        f.free.push_back(Drift::termIndex(d) + static_cast<int>(k));
        columns.push_back(c.sink.timeScaled(k, d, first_seq, last_seq));
      }
    }
    f.driver = "seq";
    f.confounds = confounds;
    std::vector<double> steps(columns.size(), typicalStep(f.mechanism, Drift::termIndex(1)));
    c.addGlobal(std::move(f), std::move(columns), std::move(steps));
  }
}

const KindFit& registrationDriftFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kRegistrationDrift};
    f.typical_step = [](const Mechanism&, int) { return 1e-5; };  // m or rad of a degree's twist
    f.free_parameters = [](const Mechanism& m) {  // the twists, not the time span
      std::vector<int> free;
      for (int i = mechanism::RegistrationDrift<double>::termIndex(1);
           i < static_cast<int>(m.parameters.size()); ++i) {
        free.push_back(i);
      }
      return free;
    };
    return f;
  }();
  return fit;
}

}  // namespace stepcal::trainer::diagnosis
