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
  // The IRB4400's description has no masses: no variable of the links' own weight.
  EXPECT_EQ(variableNamed(d, "weight2_nm"), nullptr);
}

// The UR10's description has its links' masses, and the twin deflects its joints under them: the
// diagnosis names the self weight, and each joint's torque from the arm's own weight (the self
// weight's masses) is a candidate variable of the unexplained part, tested through the joint's
// link angle; on a clean campaign it follows nothing.
TEST(Unexplained, TheArmsOwnWeightIsACandidateVariable) {
  const twin::TwinOptions options = twin::twinOptionsForRobot(
      std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf", "base_link", "tool0", "");
  twin::TwinOptions seeded = options;
  seeded.seed = 101;
  const Diagnosis d = diagnoseSimulation(seeded);
  const UnexplainedPart& u = d.unexplained;
  std::cout << "unexplained: " << u.text << "\n";
  for (const char* name : {"weight2_nm", "weight3_nm"}) {
    const UnexplainedVariable* weight = variableNamed(d, name);
    ASSERT_NE(weight, nullptr) << name;
    EXPECT_EQ(weight->joint, name[6] - '1');
    EXPECT_EQ(weight->description,
              "joint " + std::string(1, name[6]) + "'s torque from the arm's own weight");
    EXPECT_FALSE(weight->significant) << name << " z " << weight->z_statistic;
  }
  EXPECT_FALSE(u.any) << u.text;
}

// Joint 1's bearing tilts under the moment it carries (the payload's and the links' weight),
// about the axes perpendicular to its axis, by c = 1.7e-7 rad/(N·m) (the twin's bearing_tilt:
// 0.2 mm at the tip under 55 kg). Outside the catalogue (before off_axis_compliance) what it left
// followed the payload's wrench in joints 2 and 3's frames (z 8.1–8.7), never the time order; now
// the catalogue names it, and nothing is left: the unexplained part is the noise.
TEST(Unexplained, ABearingTiltNamedLeavesNothingUnexplained) {
  constexpr int kJoint = 0;
  const Diagnosis d = diagnosedMixed(
      7, {{"name", "bearing_tilt"}, {"joint", kJoint + 1}, {"compliance_rad_per_nm", 1.7e-7}});
  const UnexplainedPart& u = d.unexplained;
  SCOPED_TRACE(u.text + "\nnamed: " + effectsText(d));
  std::cout << "named: " << effectsText(d) << "\nunexplained: " << u.text << "\n";
  bool tilt_named = false;
  for (const FoundEffect& e : d.effects) {
    tilt_named = tilt_named ||
                 (e.mechanism.kind == MechanismKind::kOffAxisCompliance && e.mechanism.joint == kJoint);
  }
  EXPECT_TRUE(tilt_named);
  EXPECT_FALSE(u.any);
  EXPECT_LT(u.ratio, 1.3);
  EXPECT_EQ(strongest(d), nullptr) << u.variables.front().name;
  EXPECT_FALSE(u.learner_significant);
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

// The tool's mount gives along the F/T sensor's axis under the payload's force (the twin's
// tool_mount_compliance, c = 2e-7 m/N: the tool moves by c (z·F) z, up to 0.11 mm at 55 kg): a
// shift beyond the last joint. Outside the catalogue, what it left followed the payload's force
// along the wrist's axis first (joint 6's x axis on the IRB4400, the sensor's z; z 10.7), not
// the time order, and the search named a cause that is not there, joint 4's off_axis_compliance,
// which took part of it (0.0241 mm held out left, 1.5× the floor). Now the catalogue names it
// (tool_mount_compliance), no joint stands in for it, and nothing is left.
TEST(Unexplained, AToolMountNamedLeavesNothingUnexplained) {
  const Diagnosis d = diagnosedMixed(
      5, {{"name", "tool_mount_compliance"}, {"compliance_m_per_n", 2e-7}});
  const UnexplainedPart& u = d.unexplained;
  SCOPED_TRACE(u.text + "\nnamed: " + effectsText(d));
  std::cout << "named: " << effectsText(d) << "\nunexplained: " << u.text << "\n";
  bool mount_named = false;
  for (const FoundEffect& e : d.effects) {
    mount_named = mount_named || e.mechanism.kind == MechanismKind::kToolMountCompliance;
    EXPECT_NE(e.mechanism.kind, MechanismKind::kOffAxisCompliance);
    EXPECT_NE(e.mechanism.kind, MechanismKind::kRegistrationDrift);
  }
  EXPECT_TRUE(mount_named);
  EXPECT_FALSE(u.any);
  EXPECT_LT(u.ratio, 1.3);
  EXPECT_EQ(strongest(d), nullptr) << u.variables.front().name;
  EXPECT_FALSE(u.learner_significant);
}

}  // namespace
}  // namespace stepcal::trainer
