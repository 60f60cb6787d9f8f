// Diagnosis with several causes at once: two or three mechanisms of different kinds, drawn at
// random at realistic sizes and joints, hidden together in the paper's campaign. Told nothing,
// the diagnosis must name every one with its parameters (or, where only a combination is
// identifiable, the combination) and bring every load within 1.5× the tracker-noise floor.
// Seeds: STEPCAL_MULTI_SEEDS (default 3); the seed and the drawn effects are printed on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <numeric>
#include <random>
#include <string>

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
  const Diagnosis d = diagnoseSimulation(paperOptions(1000 + seed, effects), &campaign);

  ASSERT_EQ(d.verdict, Verdict::kFound) << "found: " << effectsText(d);
  for (const Hidden& h : hidden) {
    const FoundEffect* e = findEffect(d, h);
    EXPECT_NE(e, nullptr) << h.effect.dump() << " not named; named: " << effectsText(d);
    if (e) expectParametersFound(*e, h, d, campaign);
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

}  // namespace
}  // namespace stepcal::trainer
