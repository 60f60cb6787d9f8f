// Diagnosis (trainer/diagnose.hpp): a hidden mechanism is drawn at random, simulated into the
// paper's campaign, and the diagnosis — told nothing — must name it, its joint and its parameter,
// and gain on validation rows. Clean campaigns must give "none"; an effect outside the catalogue
// "unexplained". Seeds: STEPCAL_DIAGNOSE_SEEDS (default 6) hidden-effect cases; the seed and the
// drawn effect are printed on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/common/mechanisms/backlash.hpp"
#include "stepcal/common/mechanisms/joint_coupling.hpp"
#include "stepcal/common/mechanisms/nonlinear_stiffness.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/draws.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/command.hpp"
#include "support/hidden_effects.hpp"
#include "support/profiles.hpp"

namespace stepcal::trainer {
namespace {

using namespace test_support;

int seedCount() {
  const char* env = std::getenv("STEPCAL_DIAGNOSE_SEEDS");
  return env ? std::max(1, std::atoi(env)) : 6;
}

class HiddenEffect : public ::testing::TestWithParam<int> {};

TEST_P(HiddenEffect, IsNamedWithItsJointParameterAndGain) {
  const uint64_t seed = static_cast<uint64_t>(GetParam());
  const Hidden h = drawHidden(seed);
  SCOPED_TRACE("seed " + std::to_string(seed) + ", hidden " + h.effect.dump());
  Campaign campaign;
  const Diagnosis d = diagnoseSimulation(paperOptions(seed, {h.effect}), &campaign);

  ASSERT_EQ(d.verdict, Verdict::kFound) << "found: " << effectsText(d);
  const FoundEffect* e = findEffect(d, h);
  ASSERT_NE(e, nullptr) << "found instead: " << effectsText(d);
  EXPECT_EQ(d.effects.front().mechanism.kind, h.kind) << "first named: " << effectsText(d);
  EXPECT_EQ(d.effects.size(), 1u) << "named: " << effectsText(d);
  expectParametersFound(*e, h, d, campaign);

  // Validation: the extended model gains over the physical one on average, and brings every
  // load within 1.5× the tracker-noise floor; a load-dependent cause is also learnt better than
  // the GPR learns it, at the 55 kg extrapolation block.
  double before = 0.0, after = 0.0;
  for (const GainRow& g : d.gain) {
    SCOPED_TRACE("load " + std::to_string(g.load_kg) + " kg");
    before += g.before.mean_position_m;
    after += g.after.mean_position_m;
    EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
    if (h.load_dependent && g.load_kg == 55.0) {
      EXPECT_LT(g.after.mean_position_m, g.gpr.mean_position_m);
    }
  }
  EXPECT_LT(after, before);
}

INSTANTIATE_TEST_SUITE_P(Seeds, HiddenEffect, ::testing::Range(1, seedCount() + 1));

TEST(Diagnose, CleanCampaignsNameNothing) {
  for (uint64_t seed : {101u, 102u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Diagnosis d = diagnoseSimulation(paperOptions(seed, {}));
    EXPECT_EQ(d.verdict, Verdict::kNone) << "named: " << effectsText(d) << " trend "
                                         << d.unexplained_trend;
    EXPECT_TRUE(d.effects.empty());
    EXPECT_LT(d.before.noise_ratio, 1.2);
    for (const CandidateScore& c : d.candidates) EXPECT_FALSE(c.significant) << describe(c.mechanism);
  }
}

// An eccentric gear: harmonic 1 on joint 2, which the paper's campaign sweeps over 88° only.
// There a geometric error of the joint reproduces most of it, and an imbalance of the upper arm
// acting through joint 2's compliance the same sinusoid of q₂: the diagnosis may name either,
// but must say that the data cannot tell the two apart; the model reaches the noise at every
// load.
TEST(TransmissionError, SlowHarmonicOnANarrowArcIsReportedAsAmbiguous) {
  const nlohmann::json eccentric = {{"name", "transmission_error"}, {"joint", 2}, {"harmonic", 1},
                                    {"sin_rad", 8e-5},              {"cos_rad", -5e-5}};
  const Diagnosis d = diagnoseSimulation(paperOptions(17, {eccentric}));
  ASSERT_EQ(d.effects.size(), 1u) << "named: " << effectsText(d);
  const Mechanism& named = d.effects[0].mechanism;
  const bool profile = named.kind == MechanismKind::kTransmissionError && named.joint == 1;
  EXPECT_TRUE(profile || named.kind == MechanismKind::kSelfWeight) << effectsText(d);
  bool ambiguous = false;
  for (const Mechanism& other : d.effects[0].alternatives) {
    ambiguous = ambiguous || (profile ? other.kind == MechanismKind::kSelfWeight
                                      : other.kind == MechanismKind::kTransmissionError &&
                                            other.joint == 1);
  }
  EXPECT_TRUE(ambiguous) << "the other explanation is not reported as equivalent";
  for (const GainRow& g : d.gain) EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
}

TEST(Diagnose, TwoMechanismsAreBothFound) {
  const nlohmann::json backlash = {{"name", "backlash"}, {"joint", 3}, {"lost_motion_rad", 2.5e-4}};
  const nlohmann::json coupling = {{"name", "joint_coupling"}, {"joints", {5, 6}}, {"ratio", 1e-3}};
  const Diagnosis d = diagnoseSimulation(paperOptions(31, {backlash, coupling}));
  ASSERT_EQ(d.verdict, Verdict::kFound);
  Hidden b;
  b.kind = MechanismKind::kBacklash;
  b.joint = 2;
  Hidden c;
  c.kind = MechanismKind::kJointCoupling;
  c.joint = 5;
  c.source_joint = 4;
  const FoundEffect* fb = findEffect(d, b);
  const FoundEffect* fc = findEffect(d, c);
  ASSERT_NE(fb, nullptr) << effectsText(d);
  ASSERT_NE(fc, nullptr) << effectsText(d);
  EXPECT_EQ(d.effects.size(), 2u) << effectsText(d);
  const double lost_motion_rad = view<mechanism::Backlash>(fb->mechanism).lostMotion_rad();
  const double ratio = view<mechanism::JointCoupling>(fc->mechanism).ratio();
  EXPECT_NEAR(lost_motion_rad, 2.5e-4, 0.2 * 2.5e-4);
  EXPECT_NEAR(ratio, 1e-3, 0.2 * 1e-3);
  // Each effect's 1-σ is honest: the truth lies within 4σ.
  EXPECT_LT(std::abs(lost_motion_rad - 2.5e-4), 4 * fb->mechanism.sigma[0]);
  EXPECT_LT(std::abs(ratio - 1e-3), 4 * fc->mechanism.sigma[0]);
  for (const GainRow& g : d.gain) EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
}

// A few kilograms out of balance on the forearm beside a small sensor bias (from the stress run,
// tools/diagnose_stress): the lumped masses' single parameters are not identifiable, each lies
// within one σ of zero (σ ≈ 40 kg under the weak prior), while their gravity torques on the
// compliant joints are large and determined. The diagnosis used to abort here ("every parameter
// fitted for it lies within one σ of zero"); judged on what the data identify, both are named and
// every load comes to the floor.
TEST(Diagnose, SmallSelfWeightBesideASensorBiasIsJudgedOnItsTorques) {
  const nlohmann::json self_weight = {
      {"name", "self_weight"},
      {"links", {{{"link", 3}, {"mass_kg", 4.06}, {"com_m", {-0.067, 0.048, 0.085}}}}}};
  const nlohmann::json bias = {{"name", "sensor_bias"},
                               {"force_n", {-3.04, -0.15, 2.86}},
                               {"moment_nm", {-0.083, 0.156, -0.051}}};
  const Diagnosis d = diagnoseSimulation(paperOptions(15, {self_weight, bias}));
  ASSERT_EQ(d.verdict, Verdict::kFound);
  const FoundEffect* sw = nullptr;
  const FoundEffect* sb = nullptr;
  for (const FoundEffect& e : d.effects) {
    if (e.mechanism.kind == MechanismKind::kSelfWeight) sw = &e;
    if (e.mechanism.kind == MechanismKind::kSensorBias) sb = &e;
  }
  ASSERT_NE(sw, nullptr) << effectsText(d);
  ASSERT_NE(sb, nullptr) << effectsText(d);
  bool within_one_sigma = true;  // the old rule's condition: every parameter within 1σ
  for (size_t i = 0; i < sw->mechanism.parameters.size(); ++i) {
    within_one_sigma = within_one_sigma && std::abs(sw->mechanism.parameter(static_cast<int>(i))) <= sw->mechanism.sigma[i];
  }
  EXPECT_TRUE(within_one_sigma) << "this campaign no longer shows the case the old rule refused";
  for (int link = 1; link <= 6; ++link) {  // fitted within the bounds: no negative mass
    EXPECT_GE(sw->mechanism.parameter(4 * (link - 1)), -1e-3) << describe(sw->mechanism);
  }
  for (const FoundEffect* e : {sw, sb}) {
    EXPECT_GT(e->size_dof, 0) << describe(e->mechanism);
    EXPECT_GT(e->size_chi2, 10.0 * e->size_dof) << describe(e->mechanism);
  }
  for (const GainRow& g : d.gain) EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
}

// A load effect outside the catalogue (issue 43): the twin's angle-dependent stiffness of joint 2,
// the stress run's --foreign seed 18. Fitted without bounds a lumped self weight took it and was
// named with link masses of -38 kg and -9 kg. Within its physics' bounds (masses >= 0, each
// centre of mass within its link's reach) the rounds still find a self
// weight that explains part of it, but one whose masses are possible; the candidate whose
// unbounded fit broke them says so. About 30 s.
TEST(Diagnose, ASelfWeightNamedForAForeignLoadEffectIsPhysicallyPossible) {
  const twin::ForeignMix mix = twin::drawForeignMix(18);
  const Diagnosis d = diagnoseSimulation(paperOptions(18, mix.foreign));
  // Link k's reach, as the bounds define it: the way to the next joint's origin plus a quarter of
  // the arm's longest link.
  const KinematicChain& chain = d.extended_model.chain_Tracker;
  double longest = 0.0;
  for (int k = 1; k <= 6; ++k) longest = std::max(longest, chain.initialPose(k).translation().norm());
  for (const FoundEffect& e : d.effects) {
    if (e.mechanism.kind != MechanismKind::kSelfWeight) continue;
    for (int link = 1; link <= 6; ++link) {
      const double mass = e.mechanism.parameter(4 * (link - 1));
      const double reach_m = chain.initialPose(link).translation().norm() + 0.25 * longest;
      EXPECT_GE(mass, -1e-3) << "link " << link << ": " << describe(e.mechanism);
      for (int axis = 1; axis <= 3; ++axis) {
        EXPECT_LE(std::abs(e.mechanism.parameter(4 * (link - 1) + axis)), reach_m * mass + 2e-3)
            << "link " << link << ": " << describe(e.mechanism);
      }
    }
  }
  bool said = false;
  for (const CandidateScore& c : d.candidates) {
    said = said || (c.mechanism.kind == MechanismKind::kSelfWeight && c.unbounded_significant &&
                    !c.impossible_unbounded.empty());
  }
  EXPECT_TRUE(said) << "no self weight significant only beyond its bounds: the case is gone";
}

// Seed 92 of the stress run: a nonlinear stiffness on joint 3 beside a coupling 4 → 5 and a few
// kilograms out of balance. Backward elimination refits the model without the coupling; there the
// refit used to run down the valley where c τ τ₀/(τ₀ + |τ|) turns into the joint's compliance
// (τ₀ → 10⁷ N·m, joint 3's compliance −0.022 rad/(N·m)), the coupling was no longer significant
// beside that broken model and was dropped, and nothing was left (47× the floor). Under the
// bounds of the physics the refit stops where the compliance reaches zero: all three named, the
// stiffness near the truth, every load at the floor.
TEST(Diagnose, ATrialWithoutACauseKeepsTheCurvePhysical) {
  const nlohmann::json coupling = {{"name", "joint_coupling"}, {"joints", {4, 5}}, {"ratio", 1.857e-3}};
  const nlohmann::json self_weight = {
      {"name", "self_weight"},
      {"links", {{{"link", 2}, {"mass_kg", 5.546}, {"com_m", {0.2783, -0.0152, 0.0321}}},
                 {{"link", 3}, {"mass_kg", 4.770}, {"com_m", {0.1956, 0.0494, 0.1109}}}}}};
  const nlohmann::json stiffness = {{"name", "nonlinear_stiffness"},
                                    {"joint", 3},
                                    {"extra_compliance_rad_per_nm", 1.159e-6},
                                    {"saturation_torque_nm", 208.3}};
  const Diagnosis d = diagnoseSimulation(paperOptions(92, {coupling, self_weight, stiffness}));
  ASSERT_EQ(d.verdict, Verdict::kFound) << effectsText(d);
  const FoundEffect* nonlinear = nullptr;
  bool coupled = false, weight = false;
  for (const FoundEffect& e : d.effects) {
    if (e.mechanism.kind == MechanismKind::kNonlinearStiffness && e.mechanism.joint == 2) nonlinear = &e;
    coupled = coupled || (e.mechanism.kind == MechanismKind::kJointCoupling &&
                          e.mechanism.source_joint == 3 && e.mechanism.joint == 4);
    weight = weight || e.mechanism.kind == MechanismKind::kSelfWeight;
  }
  EXPECT_EQ(d.effects.size(), 3u) << effectsText(d);
  EXPECT_TRUE(coupled && weight) << effectsText(d);
  ASSERT_NE(nonlinear, nullptr) << effectsText(d);
  const mechanism::NonlinearStiffness<const double> found =
      view<mechanism::NonlinearStiffness>(nonlinear->mechanism);
  EXPECT_NEAR(found.extraCompliance_rad_per_nm(), 1.159e-6, 0.2 * 1.159e-6);
  EXPECT_NEAR(found.saturationTorque_nm(), 208.3, 0.5 * 208.3);
  EXPECT_GT(physicalModelOf(d.extended_model).compliance_rad_per_nm(2), 1e-6);
  for (const GainRow& g : d.gain) EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
}

// A cause of one parameter has the size of its z: χ² = (p / σ)² over one direction, σ the final
// joint fit's (the two variance estimates differ by the degrees of freedom counted).
TEST(Diagnose, AOneParameterCauseHasTheSizeOfItsSquaredZ) {
  const nlohmann::json backlash = {{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", 2e-4}};
  const Diagnosis d = diagnoseSimulation(paperOptions(3, {backlash}));
  ASSERT_EQ(d.effects.size(), 1u) << effectsText(d);
  const Mechanism& m = d.effects[0].mechanism;
  ASSERT_EQ(m.kind, MechanismKind::kBacklash);
  const double z = view<mechanism::Backlash>(m).lostMotion_rad() / m.sigma[0];
  EXPECT_EQ(d.effects[0].size_dof, 1);
  EXPECT_NEAR(d.effects[0].size_chi2, z * z, 0.15 * z * z);
}

// Seed 97 of the stress run: a torsion curve of joint 2 (lost motion 0.14 mrad, softer up to
// 83 N·m) beside a self weight of 4 kg on links 2 and 3. Round 1 names joint 2's curve (as a
// nonlinear stiffness), round 2 the lumped self weight (z 6.5 held out). Fitted within its bounds
// the self weight ends with link 2's first moment at its reach; there the linearised size of its
// estimate is χ² 8.3 on 9 directions and it used to be dropped as a cause without a size, though
// the fit without it is worse by ~100 times the residual variance (0 kg rows: 0.072 mm instead
// of 0.062). At a bound its size is what the fit loses without it: named, every load better than
// the physical model's. About 10 s.
TEST(Diagnose, ASelfWeightOnABoundHasTheSizeTheFitLosesWithoutIt) {
  const nlohmann::json curve = {{"name", "torsion_curve"},
                                {"joint", 2},
                                {"extra_compliance_rad_per_nm", {1.2180223282518116e-06}},
                                {"lost_motion_rad", 1.4037406956588018e-4},
                                {"segment_end_torque_nm", {82.6808922893128}}};
  const nlohmann::json self_weight = {
      {"name", "self_weight"},
      {"links", {{{"link", 2}, {"mass_kg", 4.0265}, {"com_m", {0.0518, -0.01387, -0.07061}}},
                 {{"link", 3}, {"mass_kg", 3.9760}, {"com_m", {0.19727, -0.0445, -0.00055}}}}}};
  const Diagnosis d = diagnoseSimulation(paperOptions(97, {self_weight, curve}));
  ASSERT_EQ(d.verdict, Verdict::kFound) << effectsText(d);
  const FoundEffect* sw = nullptr;
  bool curve_of_joint_2 = false;
  for (const FoundEffect& e : d.effects) {
    if (e.mechanism.kind == MechanismKind::kSelfWeight) sw = &e;
    const MechanismKind k = e.mechanism.kind;
    curve_of_joint_2 = curve_of_joint_2 ||
                       ((k == MechanismKind::kBacklash || k == MechanismKind::kNonlinearStiffness ||
                         k == MechanismKind::kTorsionCurve) && e.mechanism.joint == 1);
  }
  EXPECT_EQ(d.effects.size(), 2u) << effectsText(d);
  EXPECT_TRUE(curve_of_joint_2) << effectsText(d);
  ASSERT_NE(sw, nullptr) << effectsText(d);
  EXPECT_GT(sw->size_chi2, 2.0 * sw->size_dof) << describe(sw->mechanism);
  // The case: a link of some mass whose centre of mass is at its reach on an axis.
  const KinematicChain& chain = d.extended_model.chain_Tracker;
  double longest = 0.0;
  for (int k = 1; k <= 6; ++k) longest = std::max(longest, chain.initialPose(k).translation().norm());
  bool at_reach = false;
  for (int link = 1; link <= 6; ++link) {
    const double mass = sw->mechanism.parameter(4 * (link - 1));
    const double reach_m = chain.initialPose(link).translation().norm() + 0.25 * longest;
    for (int axis = 1; axis <= 3; ++axis) {
      at_reach = at_reach || (mass > 0.1 && std::abs(sw->mechanism.parameter(4 * (link - 1) + axis)) >
                                                reach_m * mass - 2e-3);
    }
  }
  EXPECT_TRUE(at_reach) << "no link at its reach: this campaign no longer shows the case "
                        << describe(sw->mechanism);
  ASSERT_FALSE(d.gain.empty());
  EXPECT_EQ(d.gain.front().load_kg, 0.0);
  EXPECT_LT(d.gain.front().after.mean_position_m, 0.85 * d.gain.front().before.mean_position_m);
  for (const GainRow& g : d.gain) EXPECT_LT(g.after.mean_position_m, g.before.mean_position_m);
}

// Lost motion and stiffness in segments on one joint are one curve of its torque: hidden as a
// backlash beside a nonlinear stiffness (the independent simulation: 0.012° of lost
// motion, a joint 1.7 times softer at small torque, fading over ~200 N·m), and as a gear
// catalogue gives it (the twin's torsion_curve: K1 up to T1, K2 up to T2, piecewise linear, a
// shape the model holds only approximately), and as both on joint 3 (seed 196 of the stress run),
// each beside a sensor bias. The diagnosis must find the joint's curve: its deflection C τ + d(τ)
// at the fit rows' torques as the truth's to 20 % of the truth's own curve (RMS), no torque
// mechanism on another joint, every load within 1.5× the floor. The 55 kg rows load the joint
// beyond the fit rows' torques: there the curve carries on with its stiffness at the largest one
// (its linear_above_nm); on seed 196 the fitted knee's formula, at 524 N·m beside joint 3's
// compliance held at zero, went flat above 474 N·m and missed them by 2.9× the floor.
struct TorqueCurveCase {
  const char* name;
  uint64_t seed;
  nlohmann::json effect;
};

class HiddenTorqueCurve : public ::testing::TestWithParam<TorqueCurveCase> {};

// The hidden curve beyond the linear compliance at torque tau, rad (twin's effects.hpp).
double hiddenCurve(const nlohmann::json& truth_effects, int joint, double tau) {
  double d = 0.0;
  for (const nlohmann::json& e : truth_effects) {
    if (!e.contains("joint") || e.at("joint").get<int>() != joint + 1) continue;
    const std::string name = e.at("name");
    if (name == "backlash" || name == "torsion_curve") {
      d += e.value("lost_motion_rad", 0.0) * std::tanh(tau / 1.0);
    }
    if (name == "nonlinear_stiffness") {
      const double c = e.at("extra_compliance_rad_per_nm"), t0 = e.at("saturation_torque_nm");
      d += c * tau * t0 / (t0 + std::abs(tau));
    }
    if (name == "torsion_curve") {
      const std::vector<double> extra = e.at("extra_compliance_rad_per_nm"),
                                ends = e.at("segment_end_torque_nm");
      double from = 0.0;
      for (size_t s = 0; s < extra.size(); ++s) {
        d += std::copysign(extra[s] * std::clamp(std::abs(tau) - from, 0.0, ends[s] - from), tau);
        from = ends[s];
      }
    }
  }
  return d;
}

TEST_P(HiddenTorqueCurve, IsTheJointsCurve) {
  const TorqueCurveCase& k = GetParam();
  const int joint = k.effect.is_array() ? k.effect[0].at("joint").get<int>() - 1
                                        : k.effect.at("joint").get<int>() - 1;
  std::vector<nlohmann::json> effects;
  for (const nlohmann::json& e : k.effect.is_array() ? k.effect : nlohmann::json::array({k.effect})) {
    effects.push_back(e);
  }
  effects.push_back({{"name", "sensor_bias"}, {"force_n", {5, -8, 3}}, {"moment_nm", {0.2, -0.1, 0.1}}});
  Campaign campaign;
  nlohmann::json truth;
  const Diagnosis d = diagnoseSimulation(paperOptions(k.seed, effects), &campaign, &truth);
  SCOPED_TRACE(std::string(k.name) + ": " + effectsText(d));
  ASSERT_EQ(d.verdict, Verdict::kFound);
  for (const FoundEffect& e : d.effects) {
    if (isTorqueDeflection(e.mechanism.kind)) {
      EXPECT_EQ(e.mechanism.joint, joint) << describe(e.mechanism);
    }
  }
  double true_compliance = 0.0;
  for (const nlohmann::json& e : truth.at("effects")) {
    if (e.at("name") == "joint_compliance") {
      true_compliance = 1.0 / e.at("stiffness_nm_per_rad")[static_cast<size_t>(joint)].get<double>();
    }
  }
  const PhysicalModel fitted = physicalModelOf(d.extended_model);
  ChainWorkspace ws;
  JointVector theta, tau;
  double off = 0.0, own = 0.0;
  int rows = 0;
  for (const Measurement& row : campaign.rows) {
    if (row.set == RowSet::kValidation) continue;
    physicalLinkAngles(fitted, row.q_rad, row.wrenchOrZero(), rowTemperature(row), {ws, theta, tau});
    const double t = tau(joint);
    double model_curve = fitted.compliance_rad_per_nm(joint) * t;
    for (const Mechanism& m : fitted.mechanisms) {
      if (isTorqueDeflection(m.kind) && m.joint == joint) model_curve += torqueDeflection(m, t);
    }
    const double hidden = hiddenCurve(truth.at("effects"), joint, t);
    off += std::pow(model_curve - (true_compliance * t + hidden), 2);
    own += hidden * hidden;
    ++rows;
  }
  const double off_rms = std::sqrt(off / rows), own_rms = std::sqrt(own / rows);
  double worst = 0.0;
  for (const GainRow& g : d.gain) worst = std::max(worst, g.after.mean_position_m / d.floor_position_m);
  std::printf("[ %s ] joint %d's curve off by %.1f %% of its own RMS (%.0f urad); worst load "
              "%.2fx the floor\n",
              k.name, joint + 1, 100.0 * off_rms / own_rms, 1e6 * own_rms, worst);
  EXPECT_LT(off_rms, 0.2 * own_rms);
  for (const GainRow& g : d.gain) EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, HiddenTorqueCurve,
    ::testing::Values(
        TorqueCurveCase{"backlash_and_nonlinear_stiffness", 24,
                        nlohmann::json::array({{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", 2.1e-4}},
                                               {{"name", "nonlinear_stiffness"},
                                                {"joint", 2},
                                                {"extra_compliance_rad_per_nm", 1.1e-6},
                                                {"saturation_torque_nm", 200.0}}})},
        TorqueCurveCase{"catalogue_segments", 21,
                        {{"name", "torsion_curve"},
                         {"joint", 2},
                         {"lost_motion_rad", 2e-4},
                         {"extra_compliance_rad_per_nm", {1.1e-6, 0.4e-6}},
                         {"segment_end_torque_nm", {150.0, 400.0}}}},
        TorqueCurveCase{"catalogue_segments_and_nonlinear_stiffness", 196,
                        nlohmann::json::array({{{"name", "torsion_curve"},
                                                {"joint", 3},
                                                {"lost_motion_rad", 1.08e-4},
                                                {"extra_compliance_rad_per_nm", {8.2e-7, 5.9e-7}},
                                                {"segment_end_torque_nm", {96.0, 429.0}}},
                                               {{"name", "nonlinear_stiffness"},
                                                {"joint", 3},
                                                {"extra_compliance_rad_per_nm", 1.13e-6},
                                                {"saturation_torque_nm", 169.0}}})}),
    [](const auto& info) { return std::string(info.param.name); });

// A tracker whose air conditioning cycles every 40 rows (a 0.05 mm wobble along its x) is no
// mechanism of the robot, and follows no smooth trend: the verdict is "unexplained", saying the
// residual is far above the stated tracker noise.
TEST(Diagnose, AnUncataloguedErrorIsUnexplained) {
  Campaign campaign = twin::simulateCampaign(paperOptions(41, {}), nullptr);
  for (Measurement& row : campaign.rows) {
    row.p_TipInTracker_m.x() += 5e-5 * std::sin(2.0 * kPi * static_cast<double>(row.seq) / 40.0);
  }
  const CalibratedModel model = modelFromOutcome(campaign, calibrateCampaign(campaign));
  const Diagnosis d = diagnose(campaign, model);
  EXPECT_EQ(d.verdict, Verdict::kUnexplained) << "named: " << effectsText(d);
  EXPECT_GT(d.before.noise_ratio, 1.3);
  EXPECT_NE(d.unexplained_trend.find("times the stated tracker noise"), std::string::npos)
      << d.unexplained_trend;
}

TEST(Diagnose, RefusesTooFewPosesNamingTheFile) {
  Campaign campaign = twin::simulateCampaign(paperOptions(5, {}), nullptr);
  const CalibratedModel model = modelFromOutcome(campaign, calibrateCampaign(campaign));
  std::vector<Measurement> few(campaign.rows.begin(), campaign.rows.begin() + 12);
  campaign.rows = few;
  try {
    diagnose(campaign, model);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("measurements.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("fit poses"), std::string::npos) << e.what();
  }
}

// Through the command: simulate with a hidden backlash, diagnose --json --out --report; the JSON
// carries the documented keys, the extended model holds the mechanism, bad input exits 2.
TEST(DiagnoseCommand, JsonModelAndReport) {
  namespace fs = std::filesystem;
  const std::string stepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";
  const fs::path dir = fs::temp_directory_path() / "stepcal_test_diagnose_cli";
  fs::remove_all(dir);
  const std::string campaign = (dir / "campaign").string();
  ASSERT_EQ(test::run(stepcal + " simulate --seed 3 --out " + campaign +
                      " --effect '{\"name\": \"backlash\", \"joint\": 2, \"lost_motion_rad\": 2e-4}'")
                .status,
            0);
  const std::string json_path = (dir / "diagnosis.json").string();
  const std::string model_path = (dir / "extended.stepcal").string();
  const std::string report_path = (dir / "diagnosis.html").string();
  const test::CommandResult r = test::run("(" + stepcal + " diagnose " + campaign +
                                          " --json --out " + model_path + " --report " +
                                          report_path + " > " + json_path + ")");
  ASSERT_EQ(r.status, 0) << r.out;
  std::ifstream in(json_path);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("verdict"), "found");
  ASSERT_EQ(j.at("effects").size(), 1u);
  const nlohmann::json& e = j.at("effects")[0];
  EXPECT_EQ(e.at("name"), "backlash");
  EXPECT_EQ(e.at("joint"), 2);
  EXPECT_TRUE(e.at("joints").is_null());
  EXPECT_TRUE(e.at("order").is_null());
  EXPECT_NEAR(e.at("parameters").at("lost_motion_rad").get<double>(), 2e-4, 0.2 * 2e-4);
  EXPECT_GT(e.at("uncertainty").at("lost_motion_rad").get<double>(), 0.0);
  EXPECT_GT(e.at("cv_gain_mm").get<double>(), 0.0);
  EXPECT_GT(j.at("candidates").size(), 100u);
  EXPECT_TRUE(j.at("unexplained_trend").is_null());
  bool saw_55 = false;
  for (const nlohmann::json& g : j.at("gain")) {
    for (const char* key : {"load_kg", "before_mean_position_mm", "after_mean_position_mm",
                            "gpr_mean_position_mm"}) {
      EXPECT_TRUE(g.contains(key)) << key;
    }
    if (g.at("load_kg") == 55.0) {
      saw_55 = true;
      EXPECT_LT(g.at("after_mean_position_mm").get<double>(),
                g.at("gpr_mean_position_mm").get<double>());
    }
  }
  EXPECT_TRUE(saw_55);

  const CalibratedModel extended = readModelFile(model_path);
  ASSERT_EQ(extended.mechanisms.size(), 1u);
  EXPECT_EQ(extended.mechanisms[0].kind, MechanismKind::kBacklash);
  EXPECT_EQ(extended.mechanisms[0].joint, 1);
  const test::CommandResult inspect = test::run(stepcal + " inspect " + model_path);
  EXPECT_NE(inspect.out.find("mechanism backlash (joint 2)"), std::string::npos) << inspect.out;

  std::ifstream report(report_path);
  const std::string html((std::istreambuf_iterator<char>(report)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("backlash (joint 2)"), std::string::npos);

  const test::CommandResult bad = test::run(stepcal + " diagnose " + (dir / "nowhere").string());
  EXPECT_EQ(bad.status, 2) << bad.out;
  EXPECT_NE(bad.out.find("nowhere"), std::string::npos) << bad.out;
}

}  // namespace
}  // namespace stepcal::trainer
