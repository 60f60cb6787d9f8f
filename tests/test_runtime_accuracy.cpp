// Inversion against the twin's truth: joint targets for each validation pose, run through the
// true robot under the row's payload, must land within 1.5× the trainer's validation error of
// the desired pose, at every load (the 55 kg extrapolation block included).
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal {
namespace {

TEST(RuntimeAccuracy, InvertedValidationPosesLandOnTheTruth) {
  twin::TwinOptions options;
  options.protocol = "paper";
  options.seed = 4;
  const Campaign campaign = twin::simulateCampaign(options, nullptr);
  const twin::TwinRobot truth(options);
  const trainer::CalibrationOutcome outcome = trainer::calibrateCampaign(campaign);
  const auto model = runtime::RuntimeModel::fromModel(trainer::modelFromOutcome(campaign, outcome), 1);
  runtime::Workspace ws = runtime::makeWorkspace(*model);

  std::map<double, std::pair<double, int>> landed_by_load;  // sum of errors, rows
  for (const Measurement* row : campaign.rowsIn(RowSet::kValidation)) {
    JointVector seed = row->q_rad;
    for (Eigen::Index j = 0; j < seed.size(); ++j) seed(j) += (j % 2 ? 2.0 : -2.0) * kRadPerDeg;
    const runtime::InverseResult r = runtime::solveInverse(
        *model, ws, row->X_TrackerTip(), row->wrenchOrZero(), runtime::kUnknownTemperature_c, seed,
        runtime::Clock::time_point::max());  // accuracy, not time: the step limit ends it
    ASSERT_TRUE(r.status == runtime::Status::kOk || r.status == runtime::Status::kOutOfDomain)
        << runtime::toString(r.status) << " at seq " << row->seq;
    const Pose reached = truth.X_TrackerTip(r.q_target_rad, row->load_kg);
    auto& [sum, count] = landed_by_load[row->load_kg];
    sum += (reached.translation() - row->p_TipInTracker_m).norm();
    ++count;
  }
  ASSERT_EQ(landed_by_load.size(), 5u);
  for (const auto& [load, sum_count] : landed_by_load) {
    const double landed_m = sum_count.first / sum_count.second;
    double trainer_m = -1.0;
    for (const auto& s : outcome.accuracy) {
      if (s.method == trainer::kMethodPoeStiffnessGpr && s.set == RowSet::kValidation &&
          s.load_kg == load) {
        trainer_m = s.mean_position_m;
      }
    }
    std::printf("%4.0f kg: inverted targets land %.4f mm from the desired pose (trainer's validation "
                "error %.4f mm)\n", load, landed_m * 1e3, trainer_m * 1e3);
    EXPECT_LE(landed_m, 1.5 * trainer_m) << load << " kg";
  }
}

}  // namespace
}  // namespace stepcal
