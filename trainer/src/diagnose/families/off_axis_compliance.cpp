// off_axis_compliance: a joint's frame tilting across its axis under the moment it carries
// (families.hpp). One family per joint, its two compliances as finite-difference columns of the
// whole model (the tilt acts inside the fixed point, on the frames, not on a link angle).
#include "families.hpp"
#include "stepcal/common/mechanisms/off_axis_compliance.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// rad/(N·m): a bearing 5e6 N·m/rad stiff, which a 55 kg payload at ~1.5 m turns by ~1.6e-4 rad.
constexpr double kTypicalTiltCompliance = 2e-7;

bool anyLoadedRow(const FitRows& fit) {
  for (const Measurement* row : fit.rows) {
    if (row->has_wrench && row->wrenchOrZero().head<3>().norm() > 0.0) return true;
  }
  return false;
}

}  // namespace

void offAxisComplianceFamilies(const FamilyContext& c) {
  const bool testable = c.global.sensor_frame >= 0 && anyLoadedRow(c.fit);
  for (int j = 0; j < c.n; ++j) {
    if (present(c.global, MechanismKind::kOffAxisCompliance, j, -1) ||
        !c.wanted(MechanismKind::kOffAxisCompliance, j)) {
      continue;
    }
    if (!testable) {
      c.s.untestable.push_back({"off_axis_compliance (joint " + std::to_string(j + 1) + ")",
                                "no F/T sensor frame or no loaded row: no moment to tilt a joint"});
      continue;
    }
    Family f;
    f.mechanism = blank(MechanismKind::kOffAxisCompliance, c.n, j);
    PhysicalModel with = c.whole;
    with.mechanisms.push_back(f.mechanism);
    const int index = static_cast<int>(with.mechanisms.size()) - 1;
    std::vector<Eigen::Index> columns;
    std::vector<double> steps;
    for (int i : {mechanism::OffAxisCompliance<double>::kTiltU,
                  mechanism::OffAxisCompliance<double>::kTiltV}) {
      f.free.push_back(i);
      const Parameter p{index, i, kTypicalTiltCompliance};
      columns.push_back(c.sink.difference(with, p, 0.0));
      steps.push_back(p.step);
    }
    c.addGlobal(std::move(f), std::move(columns), std::move(steps));
  }
}

const KindFit& offAxisComplianceFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kOffAxisCompliance};
    f.typical_step = [](const Mechanism&, int) { return kTypicalTiltCompliance; };
    // Both are compliances: a frame turning against its moment is no bearing.
    f.sign_constrained = [](const Mechanism&) {
      return std::vector<int>{mechanism::OffAxisCompliance<double>::kTiltU,
                              mechanism::OffAxisCompliance<double>::kTiltV};
    };
    // A direction held at zero is a stiff direction, not a wrong sign: the other is kept.
    f.parts_independent = true;
    return f;
  }();
  return fit;
}

}  // namespace stepcal::trainer::diagnosis
