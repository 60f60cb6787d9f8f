// The diagnosis where its catalogue ends (issue 43, docs/diagnosis.md "The extended model"): on
// the twin's paper campaign with a load effect no mechanism describes (angle_dependent_stiffness:
// joint 2's compliance varies with its angle), the extended model is never worse than the model
// under it at any load: on the unloaded validation rows no worse than the paper's step 1 (the
// geometry pinned by the unloaded rows; its GPR, learnt per payload force, moves them not at
// all), on the loaded rows within the training loads no worse than the paper's three steps; and
// with a bearing tilt, which the catalogue now holds, near the floor at every load. Prints every
// load's figures, the 55 kg block outside the training loads too.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/report/family_pairs_report.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/hidden_effects.hpp"

namespace stepcal::trainer {
namespace {

using namespace test_support;

// Margins, far from the seeds' figures (printed): the extended model on the unloaded rows against
// step 1 (the same geometry identified from fewer rows may lose a little to noise), the loaded
// rows against the paper's POE + stiffness + GPR, and the floor within the training loads.
constexpr double kUnloadedMargin = 1.1;
constexpr double kLoadedMargin = 1.0;
constexpr double kFloorMargin = 1.6;

void printGain(const Diagnosis& d) {
  std::printf("  load  rows  step1/poe+stiff  extended  extended+gpr  poe+stiff+gpr  floor (mm)\n");
  for (const GainRow& g : d.gain) {
    std::printf("  %4g  %4d  %15.4f  %8.4f  %12.4f  %13.4f  %.4f\n", g.load_kg, g.rows,
                g.before.mean_position_m * 1e3, g.after.mean_position_m * 1e3,
                g.after_gpr.mean_position_m * 1e3, g.gpr.mean_position_m * 1e3,
                d.floor_position_m * 1e3);
  }
  std::printf("  geometry pinned: %s (F = %.2f, rank %d, %d unloaded rows; the tip moved by "
              "%.4f mm RMS, %.4f most); GPR taken: %s\n",
              d.geometry_pin.pinned ? "yes" : "no", d.geometry_pin.f_statistic,
              d.geometry_pin.rank, d.geometry_pin.unloaded_rows,
              1e3 * d.geometry_pin.tip_shift_rms_m, 1e3 * d.geometry_pin.tip_shift_max_m,
              d.extended_gpr_taken ? "yes" : "no");
}

// The campaign measured in a random order of its rows (seq permuted): a load effect in payload
// blocks is otherwise confounded with a trend in time order, which is another question (issue
// 43, item 1) than the one this test asks.
Diagnosis diagnoseInMixedOrder(const twin::TwinOptions& options) {
  Campaign campaign = twin::simulateCampaign(options, nullptr);
  std::vector<int64_t> seq;
  for (const Measurement& row : campaign.rows) seq.push_back(row.seq);
  std::mt19937_64 rng(options.seed);
  std::shuffle(seq.begin(), seq.end(), rng);
  for (size_t i = 0; i < seq.size(); ++i) campaign.rows[i].seq = seq[i];
  const CalibratedModel model = modelFromOutcome(campaign, calibrateCampaign(campaign));
  return diagnose(campaign, model);
}

// Every load against the models under it: unloaded, no worse than step 1 (the GPR, learnt per
// payload force, moves them by the force the sensor's noise reads there, ~0.3 N of ~300:
// nothing); loaded within the training loads, no worse than the paper's three steps.
void expectNeverWorse(const Diagnosis& d) {
  ASSERT_FALSE(d.gain.empty());
  for (const GainRow& g : d.gain) {
    SCOPED_TRACE("load " + std::to_string(g.load_kg) + " kg");
    if (g.load_kg == 0.0) {
      EXPECT_LT(g.after.mean_position_m, kUnloadedMargin * g.before.mean_position_m);
      EXPECT_NEAR(g.after_gpr.mean_position_m, g.after.mean_position_m,
                  0.01 * g.after.mean_position_m);
    } else if (g.load_kg <= 40.0) {
      EXPECT_LT(g.after_gpr.mean_position_m, kLoadedMargin * g.gpr.mean_position_m);
    }
  }
}

// Outside the catalogue: a stiffness of joint 2 that varies with its angle (±15 % at harmonic 6).
// Nothing names it, so the GPR per payload force takes what is left within the training loads.
TEST(DiagnoseBeyondTheCatalogue, AnAngleDependentStiffnessLeavesNoLoadWorseThanThePaper) {
  const nlohmann::json stiffness = {{"name", "angle_dependent_stiffness"}, {"joint", 2},
                                    {"harmonic", 6}, {"amplitude", 0.15}, {"phase_rad", 0.0}};
  const Diagnosis d = diagnoseInMixedOrder(paperOptions(3, {stiffness}));
  printGain(d);
  // The unloaded rows reject the global fit's geometry, and the verdict says how far theirs moved
  // the tip.
  EXPECT_TRUE(d.geometry_pin.pinned);
  EXPECT_GT(d.geometry_pin.tip_shift_rms_m, 0.0);
  EXPECT_GE(d.geometry_pin.tip_shift_max_m, d.geometry_pin.tip_shift_rms_m);
  EXPECT_EQ(report::geometryPinText(d.geometry_pin).rfind("pinned by the ", 0), 0u)
      << report::geometryPinText(d.geometry_pin);
  EXPECT_TRUE(d.extended_gpr_taken);
  ASSERT_TRUE(d.extended_model.gpr.has_value());
  EXPECT_GT(d.extended_model.gpr->payload_force_reference_n, 0.0);
  expectNeverWorse(d);
}

// Once in the catalogue (off_axis_compliance), the bearing tilt is named and corrected: every
// load near the floor, the unloaded rows no worse than step 1.
TEST(DiagnoseBeyondTheCatalogue, ABearingTiltLeavesNoLoadWorseThanThePaper) {
  const nlohmann::json tilt = {
      {"name", "bearing_tilt"}, {"joint", 1}, {"compliance_rad_per_nm", 1.6e-7}};
  const Diagnosis d = diagnoseInMixedOrder(paperOptions(3, {tilt}));
  printGain(d);
  expectNeverWorse(d);
  for (const GainRow& g : d.gain) {
    SCOPED_TRACE("load " + std::to_string(g.load_kg) + " kg");
    EXPECT_LT(g.after_gpr.mean_position_m, kFloorMargin * d.floor_position_m);
  }
}

// Both beside each other, payloads in time blocks as the paper measures them (the foreign stress
// run's seed 44): the bearing tilt named, the varying stiffness left to the residual. The unloaded
// rows pin the geometry on the directions they identify (30 here); the two the off-axis
// compliance's frames lift to 3e-8 of the largest singular value carry no information, and a
// step along them once ran the refit off (F = 0, the unloaded rows 1.5x step 1's).
TEST(DiagnoseBeyondTheCatalogue, ABearingTiltBesideAVaryingStiffnessInBlocksLeavesNoLoadWorse) {
  const nlohmann::json tilt = {
      {"name", "bearing_tilt"}, {"joint", 1}, {"compliance_rad_per_nm", 1.55e-7}};
  const nlohmann::json stiffness = {{"name", "angle_dependent_stiffness"}, {"joint", 2},
                                    {"harmonic", 6}, {"amplitude", 0.15}, {"phase_rad", -2.42}};
  const Diagnosis d = diagnoseSimulation(paperOptions(44, {tilt, stiffness}));
  printGain(d);
  EXPECT_TRUE(d.geometry_pin.pinned);
  EXPECT_EQ(d.geometry_pin.rank, 30);
  expectNeverWorse(d);
}

}  // namespace
}  // namespace stepcal::trainer
