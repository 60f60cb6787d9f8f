// off_axis_compliance found by the diagnosis: the twin's bearing_tilt (tools/twin, an effect
// written apart from stepcal's model: joint j's frame turned by c M⊥) hidden in the paper's
// campaign, payloads in blocks, at the sizes the stress run draws (twin::drawBearingTilt). The
// diagnosis must name off_axis_compliance on that joint, first and alone, with both its
// compliances at the truth's within the tolerance below, and bring every validation load within
// 1.5× the tracker-noise floor.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/common/mechanisms/off_axis_compliance.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "support/hidden_effects.hpp"

namespace stepcal::trainer {
namespace {

using namespace test_support;

struct TiltCase {
  int joint;             // 1-based, as the twin names it
  double compliance;     // rad/(N·m)
  uint64_t seed;
};

class HiddenBearingTilt : public ::testing::TestWithParam<TiltCase> {};

TEST_P(HiddenBearingTilt, IsNamedOnItsJointWithItsCompliance) {
  const TiltCase t = GetParam();
  const nlohmann::json tilt = {
      {"name", "bearing_tilt"}, {"joint", t.joint}, {"compliance_rad_per_nm", t.compliance}};
  SCOPED_TRACE("seed " + std::to_string(t.seed) + ", hidden " + tilt.dump());
  const Diagnosis d = diagnoseSimulation(paperOptions(t.seed, {tilt}));
  ASSERT_EQ(d.verdict, Verdict::kFound) << "found: " << effectsText(d);
  ASSERT_EQ(d.effects.size(), 1u) << "named: " << effectsText(d);
  const Mechanism& m = d.effects.front().mechanism;
  ASSERT_EQ(m.kind, MechanismKind::kOffAxisCompliance) << "named: " << effectsText(d);
  EXPECT_EQ(m.joint, t.joint - 1);
  // Both directions of an isotropic bearing, each to 10 % of the truth.
  const mechanism::OffAxisCompliance<const double> found = view<mechanism::OffAxisCompliance>(m);
  EXPECT_NEAR(found.tiltU_rad_per_nm(), t.compliance, 0.1 * t.compliance);
  EXPECT_NEAR(found.tiltV_rad_per_nm(), t.compliance, 0.1 * t.compliance);
  double worst = 0.0;
  for (const GainRow& g : d.gain) {
    SCOPED_TRACE("load " + std::to_string(g.load_kg) + " kg");
    EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
    worst = std::max(worst, g.after.mean_position_m / d.floor_position_m);
  }
  std::printf("[ bearing_tilt ] joint %d, c %.3g: found c_u %.4g ± %.2g, c_v %.4g ± %.2g "
              "rad/(N·m), worst load %.2f× the floor\n",
              t.joint, t.compliance, found.tiltU_rad_per_nm(), m.sigma[0],
              found.tiltV_rad_per_nm(), m.sigma[1], worst);
}

// Joint 1 (the base bearing: the arm's whole tipping moment) and joint 2 (the shoulder: only the
// payload's moment out of the arm's plane), at the middle of the stress run's ranges.
INSTANTIATE_TEST_SUITE_P(PaperProtocol, HiddenBearingTilt,
                         ::testing::Values(TiltCase{1, 1.7e-7, 201}, TiltCase{2, 1.2e-6, 202}));

}  // namespace
}  // namespace stepcal::trainer
