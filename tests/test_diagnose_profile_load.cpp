// A joint's transmission profile against the same profile modulated by the joint's torque
// (profile_load_check.cpp): a stiffness that varies with the angle (the twin's
// angle_dependent_stiffness, outside the catalogue) is not named as a transmission error, and the
// verdict says why in one line; a real transmission error beside loads still is.
#include <gtest/gtest.h>

#include <string>

#include "stepcal/report/diagnosis_report.hpp"
#include "support/hidden_effects.hpp"

namespace stepcal::trainer {
namespace {

using namespace test_support;

bool transmissionErrorNamed(const Diagnosis& d, int joint) {
  for (const FoundEffect& e : d.effects) {
    if (e.mechanism.kind == MechanismKind::kTransmissionError && e.mechanism.joint == joint) {
      return true;
    }
  }
  return false;
}

// Joint 2's compliance varying by ±15 % at harmonic 6 of its angle, under the paper's payloads
// and the arm's weight.
TEST(ProfileOrLoad, AStiffnessVaryingWithTheAngleIsNotNamedATransmissionError) {
  const nlohmann::json effect = {{"name", "angle_dependent_stiffness"}, {"joint", 2},
                                 {"harmonic", 6}, {"amplitude", 0.15}, {"phase_rad", 0.4}};
  const Diagnosis d = diagnoseSimulation(paperOptions(2, {effect}));
  EXPECT_FALSE(transmissionErrorNamed(d, 1)) << effectsText(d);
  ASSERT_EQ(d.load_modulated_profiles.size(), 1u) << effectsText(d);
  const LoadModulatedProfile& f = d.load_modulated_profiles.front();
  EXPECT_EQ(f.joint, 1);
  EXPECT_FALSE(f.profile_named);
  EXPECT_LT(f.modulated_p, 0.01);
  EXPECT_GT(f.modulated_reduction, 0.01);
  const std::string text = report::formatDiagnosis(d, 0.0);
  EXPECT_NE(text.find("no transmission_error named on joint 2: its error follows the angle in "
                      "proportion to the joint's torque"),
            std::string::npos)
      << text;
  const nlohmann::json j = report::diagnosisJson(d, 0.0);
  ASSERT_TRUE(j.contains("load_modulated_profiles"));
  EXPECT_EQ(j["load_modulated_profiles"][0]["joint"], 2);
  EXPECT_FALSE(j["load_modulated_profiles"][0]["profile_named"].get<bool>());
}

// The README's transmission error (joint 3, harmonic 2) on the same loaded campaign: named, and
// not set aside as a load effect.
TEST(ProfileOrLoad, ATransmissionErrorIsStillNamed) {
  const nlohmann::json effect = {{"name", "transmission_error"}, {"joint", 3}, {"harmonic", 2},
                                 {"sin_rad", 1e-4}, {"cos_rad", -5e-5}};
  const Diagnosis d = diagnoseSimulation(paperOptions(4, {effect}));
  EXPECT_TRUE(transmissionErrorNamed(d, 2)) << effectsText(d);
  for (const LoadModulatedProfile& f : d.load_modulated_profiles) {
    EXPECT_TRUE(f.joint != 2 || f.profile_named) << report::loadModulatedProfileText(f);
  }
}

}  // namespace
}  // namespace stepcal::trainer
