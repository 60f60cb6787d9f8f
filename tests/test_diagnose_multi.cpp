// Diagnosis with several causes at once: two or three mechanisms of different kinds, drawn at
// random at realistic sizes and joints, hidden together in the paper's campaign. Told nothing,
// the diagnosis must name every one with its parameters (or, where only a combination is
// identifiable, the combination) and bring every load within 1.5× the tracker-noise floor.
// Seeds: STEPCAL_MULTI_SEEDS (default 3), and seed 10 always; the seed and the drawn effects are
// printed on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <numeric>
#include <optional>
#include <random>
#include <string>

#include "stepcal/common/model_file.hpp"
#include "support/hidden_effects.hpp"

namespace stepcal::trainer {
namespace {

using namespace test_support;

// Backlash and nonlinear stiffness on one joint are one curve of its torque seen twice (a small
// τ₀ imitates lost motion): drawn on different joints.
bool sameTorqueCurve(const Hidden& a, const Hidden& b) {
  const auto torque_driven = [](MechanismKind k) {
    return k == MechanismKind::kBacklash || k == MechanismKind::kNonlinearStiffness;
  };
  return torque_driven(a.kind) && torque_driven(b.kind) && a.joint == b.joint;
}

std::vector<Hidden> drawSeveral(uint64_t seed) {
  std::mt19937_64 rng(seed * 104729 + 7);
  const int count = std::uniform_int_distribution<int>(2, 3)(rng);
  std::vector<int> kinds(kHiddenKinds);
  std::iota(kinds.begin(), kinds.end(), 0);
  std::shuffle(kinds.begin(), kinds.end(), rng);
  std::vector<Hidden> hidden;
  for (int i = 0; i < count; ++i) {
    Hidden h = drawOfKind(kinds[static_cast<size_t>(i)], rng);
    while (std::any_of(hidden.begin(), hidden.end(),
                       [&](const Hidden& other) { return sameTorqueCurve(h, other); })) {
      h = drawOfKind(kinds[static_cast<size_t>(i)], rng);
    }
    hidden.push_back(std::move(h));
  }
  return hidden;
}

// The hidden mechanisms that move the link angles through the torques, as the model holds them,
// on the fitted chain with the twin's true compliance: nonlinear stiffness, self weight, sensor
// bias, coupling. Empty when another kind that moves the link angles is hidden.
std::optional<PhysicalModel> trueDeflectionModel(const Diagnosis& d, const nlohmann::json& truth,
                                                 const std::vector<Hidden>& hidden) {
  PhysicalModel model = physicalModelOf(d.extended_model);
  model.mechanisms.clear();
  for (const nlohmann::json& e : truth.at("effects")) {
    if (e.at("name") != "joint_compliance") continue;
    const std::vector<double> k = e.at("stiffness_nm_per_rad");
    for (size_t j = 0; j < k.size(); ++j) model.compliance_rad_per_nm(static_cast<Eigen::Index>(j)) = 1.0 / k[j];
  }
  for (const Hidden& h : hidden) {
    Mechanism m;
    m.kind = h.kind;
    m.joint = h.joint;
    m.source_joint = h.source_joint;
    if (h.kind == MechanismKind::kNonlinearStiffness) {
      m.parameters = {h.effect.at("extra_compliance_rad_per_nm"), h.effect.at("saturation_torque_nm"), 0.0};
    } else if (h.kind == MechanismKind::kSelfWeight) {
      m.parameters = h.self_weight_truth;
    } else if (h.kind == MechanismKind::kSensorBias) {
      const std::vector<double> f = h.effect.at("force_n"), t = h.effect.at("moment_nm");
      m.parameters = {f[0], f[1], f[2], t[0], t[1], t[2]};
    } else if (h.kind == MechanismKind::kJointCoupling) {
      m.parameters = {h.truth};
    } else if (h.kind == MechanismKind::kThermalExpansion) {
      continue;  // moves the links, not their angles
    } else {
      return std::nullopt;
    }
    m.sigma.assign(m.parameters.size(), 0.0);
    model.mechanisms.push_back(std::move(m));
  }
  return model;
}

// A nonlinear stiffness hidden beside a self weight: the lumped masses' gravity torque through the
// joint's compliance and the nonlinear stiffness both deflect the joint under the arm's own
// weight, and only their sum is determined. That sum, the joint's link angle on the fit rows as
// fitted and as true, up to a constant (a joint offset the geometry holds), to 20 % of the
// nonlinear stiffness's own deflection (RMS).
void expectJointDeflectionFound(const Diagnosis& d, const Campaign& campaign,
                                const PhysicalModel& truth, const Hidden& h) {
  const PhysicalModel fitted = physicalModelOf(d.extended_model);
  const double c = h.effect.at("extra_compliance_rad_per_nm"), t0 = h.effect.at("saturation_torque_nm");
  ChainWorkspace ws;
  JointVector theta_fit, theta_true, tau;
  std::vector<double> difference, own;
  for (const Measurement& row : campaign.rows) {
    if (row.set == RowSet::kValidation) continue;
    const double temp_c = rowTemperature(row);
    physicalLinkAngles(fitted, row.q_rad, row.wrenchOrZero(), temp_c, {ws, theta_fit, tau});
    physicalLinkAngles(truth, row.q_rad, row.wrenchOrZero(), temp_c, {ws, theta_true, tau});
    difference.push_back(theta_fit(h.joint) - theta_true(h.joint));
    own.push_back(c * tau(h.joint) * t0 / (t0 + std::abs(tau(h.joint))));
  }
  const auto rms_about_mean = [](const std::vector<double>& v) {
    double mean = 0.0, sum = 0.0;
    for (double x : v) mean += x / static_cast<double>(v.size());
    for (double x : v) sum += (x - mean) * (x - mean);
    return std::sqrt(sum / static_cast<double>(v.size()));
  };
  const double off = rms_about_mean(difference), size = rms_about_mean(own);
  std::printf("[ hidden nonlinear_stiffness beside self_weight ] joint %d's deflection off by %.1f %%\n",
              h.joint + 1, 100.0 * off / size);
  EXPECT_LT(off, 0.2 * size) << "joint " << h.joint + 1 << "'s deflection under its own weight";
}

int seedCount() {
  const char* env = std::getenv("STEPCAL_MULTI_SEEDS");
  return env ? std::max(1, std::atoi(env)) : 3;
}

class HiddenEffects : public ::testing::TestWithParam<int> {};

TEST_P(HiddenEffects, AreEachNamedWithTheirParametersAndReachTheFloor) {
  const uint64_t seed = static_cast<uint64_t>(GetParam());
  const std::vector<Hidden> hidden = drawSeveral(seed);
  std::vector<nlohmann::json> effects;
  std::string drawn;
  for (const Hidden& h : hidden) {
    effects.push_back(h.effect);
    drawn += h.effect.dump() + " ";
  }
  SCOPED_TRACE("seed " + std::to_string(seed) + ", hidden " + drawn);
  Campaign campaign;
  nlohmann::json truth;
  const Diagnosis d = diagnoseSimulation(paperOptions(1000 + seed, effects), &campaign, &truth);

  ASSERT_EQ(d.verdict, Verdict::kFound) << "found: " << effectsText(d);
  const bool self_weight = std::any_of(hidden.begin(), hidden.end(), [](const Hidden& h) {
    return h.kind == MechanismKind::kSelfWeight;
  });
  const std::optional<PhysicalModel> deflection = trueDeflectionModel(d, truth, hidden);
  for (const Hidden& h : hidden) {
    const FoundEffect* e = findEffect(d, h);
    EXPECT_NE(e, nullptr) << h.effect.dump() << " not named; named: " << effectsText(d);
    if (!e) continue;
    if (h.kind == MechanismKind::kNonlinearStiffness && self_weight && deflection) {
      expectJointDeflectionFound(d, campaign, *deflection, h);
    } else {
      expectParametersFound(*e, h, d, campaign);
    }
  }
  EXPECT_EQ(d.effects.size(), hidden.size()) << "named: " << effectsText(d);
  for (const GainRow& g : d.gain) {
    std::printf("[ %g kg ] %.4f -> %.4f mm, floor %.4f mm\n", g.load_kg,
                1e3 * g.before.mean_position_m, 1e3 * g.after.mean_position_m,
                1e3 * d.floor_position_m);
    EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m) << "load " << g.load_kg << " kg";
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, HiddenEffects, ::testing::Range(1, seedCount() + 1));
// Seed 10 (sensor bias, self weight, a harmonic 10 on joint 2 over a 99° arc) named a profile on
// joint 4 that is not there while the global part and the profiles were fitted in turn
// (docs/diagnosis.md, "Why joint"): always run.
INSTANTIATE_TEST_SUITE_P(Regression, HiddenEffects, ::testing::Values(10));

}  // namespace
}  // namespace stepcal::trainer
