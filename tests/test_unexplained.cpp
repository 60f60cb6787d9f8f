// The verdict's "unexplained" part (Diagnosis::unexplained): on the paper's campaign with a load
// effect outside the catalogue, it names the variable the effect follows (a bearing's tilt: a
// moment perpendicular to its joint's axis in that joint's frame; a compliance that varies with
// the joint's angle: that joint's torque with its angle), not the time order the payload blocks
// follow; on a clean campaign, nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>

#include "stepcal/common/units.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/hidden_effects.hpp"

namespace stepcal::trainer {
namespace {

using namespace test_support;

// The strongest significant variable, or null.
const UnexplainedVariable* strongest(const Diagnosis& d) {
  const auto& v = d.unexplained.variables;
  return !v.empty() && v.front().significant ? &v.front() : nullptr;
}

const UnexplainedVariable* variableNamed(const Diagnosis& d, const std::string& name) {
  for (const UnexplainedVariable& v : d.unexplained.variables) {
    if (v.name == name) return &v;
  }
  return nullptr;
}

// The paper's campaign with the fit rows' loads mixed in time (TwinOptions::load_order): with
// the payloads in blocks a load effect outside the catalogue follows the time order too, and
// whether the diagnosis tells a drift of the tracker from it is the confound test's question
// (issue 43), not this one's.
Diagnosis diagnosedMixed(uint64_t seed, const nlohmann::json& effect) {
  twin::TwinOptions options = paperOptions(seed, {effect});
  options.load_order = "mixed";
  return diagnoseSimulation(options);
}

TEST(Unexplained, ACleanCampaignLeavesNothing) {
  const Diagnosis d = diagnoseSimulation(paperOptions(101, {}));
  const UnexplainedPart& u = d.unexplained;
  std::cout << "unexplained: " << u.text << "\n";
  EXPECT_FALSE(u.any) << u.text;
  EXPECT_EQ(u.residual_rows, "validation");
  EXPECT_LT(u.ratio, 1.3);
  EXPECT_EQ(strongest(d), nullptr) << u.variables.front().name;
  EXPECT_FALSE(u.learner_significant) << u.text;
  EXPECT_GT(u.variables_tested, 100);  // q, τ, τ·harmonics, load, seq, the wrench in 6 frames
  EXPECT_EQ(u.text.rfind("nothing unexplained", 0), 0u) << u.text;
}

// Joint 1's bearing tilts under the moment it carries (the payload's and the links' weight),
// about the axes perpendicular to its axis, by c = 1.7e-7 rad/(N·m) (the twin's bearing_tilt:
// 0.2 mm at the tip under 55 kg).
TEST(Unexplained, ABearingTiltIsThePayloadsWrenchNotTheTimeOrder) {
  constexpr int kJoint = 0;
  const Diagnosis d = diagnosedMixed(
      7, {{"name", "bearing_tilt"}, {"joint", kJoint + 1}, {"compliance_rad_per_nm", 1.7e-7}});
  const UnexplainedPart& u = d.unexplained;
  SCOPED_TRACE(u.text + "\nnamed: " + effectsText(d));
  std::cout << "named: " << effectsText(d) << "\nunexplained: " << u.text << "\n";
  EXPECT_TRUE(u.any);
  const UnexplainedVariable* top = strongest(d);
  ASSERT_NE(top, nullptr);
  // A component of the payload's wrench in a joint's frame. Which one is not determined: the
  // catalogue took part of the tilt (here as a nonlinear stiffness of joint 2 and a coupling),
  // and what it leaves follows the payload's weight along joint 3's and joint 2's z axes and
  // joint 2's moment about its x axis nearly alike (0.0020, 0.0020 and 0.0021 mm held out, z 8.7,
  // 8.5 and 8.1): the moment perpendicular to joint 1's axis or joint 2's must be among them.
  EXPECT_EQ(top->name.rfind("joint", 0), 0u) << top->name;
  bool perpendicular_moment_named = false;
  for (const UnexplainedVariable& v : u.variables) {
    perpendicular_moment_named = perpendicular_moment_named ||
                                 (v.significant && v.perpendicular_moment && v.joint <= kJoint + 1);
  }
  EXPECT_TRUE(perpendicular_moment_named);
  const UnexplainedVariable* seq = variableNamed(d, "seq");
  ASSERT_NE(seq, nullptr);
  EXPECT_FALSE(seq->significant);
  EXPECT_TRUE(u.learner_significant);
  EXPECT_EQ(u.text.rfind("nothing in the catalogue explains", 0), 0u);
}

// Joint 3's stiffness varies with its angle, Δθ₃ = ε cos(7 q₃ + φ) τ₃ / K₃ beyond its linear
// compliance (the twin's angle_dependent_stiffness, ε = 0.2).
TEST(Unexplained, AnAngleDependentStiffnessIsItsJointsTorqueWithItsAngle) {
  const Diagnosis d = diagnosedMixed(8, {{"name", "angle_dependent_stiffness"},
                                         {"joint", 3},
                                         {"harmonic", 7},
                                         {"amplitude", 0.2},
                                         {"phase_rad", 0.4}});
  const UnexplainedPart& u = d.unexplained;
  SCOPED_TRACE(u.text + "\nnamed: " + effectsText(d));
  std::cout << "named: " << effectsText(d) << "\nunexplained: " << u.text << "\n";
  EXPECT_TRUE(u.any);
  const UnexplainedVariable* top = strongest(d);
  ASSERT_NE(top, nullptr);
  EXPECT_EQ(top->name, "tau3_nm*h7(q3)");
  const UnexplainedVariable* seq = variableNamed(d, "seq");
  ASSERT_NE(seq, nullptr);
  EXPECT_FALSE(seq->significant);
  EXPECT_TRUE(u.learner_significant);
}

}  // namespace
}  // namespace stepcal::trainer
