// ISO 9283 in the planner (trainer/iso9283_plan.hpp) and in the certificate
// (trainer/iso9283.hpp): the layout's geometry, and on the twin, which knows its truth and its
// noise, AP against the truth and RP against what the tracker's noise gives; bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/report/certificate.hpp"
#include "stepcal/trainer/iso9283.hpp"
#include "stepcal/trainer/iso9283_plan.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/command.hpp"

namespace stepcal {
namespace {

const std::string kIrb4400 = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";
const std::string kUr10 = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";

KinematicChain irb4400() {
  return chainFromUrdfFile(kIrb4400, "base_link", "tmac", {"ft_sensor"});
}

trainer::Iso9283Plan irbPlan() {
  trainer::Iso9283PlanOptions options;
  options.rated_load_kg = 60.0;
  return trainer::planIso9283(irb4400(), options);
}

TEST(IsoPoseId, RoundTripsAndRefusesOthers) {
  for (const trainer::IsoPoseId id : {trainer::IsoPoseId{1, 0, 1}, trainer::IsoPoseId{4, 'y', 30}}) {
    const auto back = trainer::parseIsoPoseId(trainer::isoPoseId(id));
    ASSERT_TRUE(back.has_value()) << trainer::isoPoseId(id);
    EXPECT_EQ(back->pose, id.pose);
    EXPECT_EQ(back->approach, id.approach);
    EXPECT_EQ(back->cycle, id.cycle);
  }
  for (const char* other : {"plan-001", "iso-P6-c01", "iso-P1-w-c01", "iso-P1-c01x", "iso-P0-c1"}) {
    EXPECT_FALSE(trainer::parseIsoPoseId(other).has_value()) << other;
  }
}

// The poses lie where ISO 9283 puts them in the cube, and the joints reach them with the one
// orientation (nominal forward kinematics).
TEST(IsoPlan, PosesLieInTheDiagonalPlaneAtTenPercentFromTheCorners) {
  const trainer::Iso9283Plan plan = irbPlan();
  ASSERT_GT(plan.edge_m, 0.3);
  const Vec3& centre = plan.p_CentreInBase_m;
  EXPECT_LT((plan.p_PoseInBase_m[0] - centre).norm(), 1e-12);
  const double half_diagonal_m = 0.5 * std::sqrt(3.0) * plan.edge_m;
  for (int k = 1; k < trainer::kIsoPoseCount; ++k) {
    const Vec3 d = plan.p_PoseInBase_m[static_cast<size_t>(k)] - centre;
    EXPECT_NEAR(d.x(), d.z(), 1e-9) << "P" << k + 1 << " in the plane x - x_c = z - z_c";
    // 10 % of the plane's diagonal (edge·√3) from its corner: 0.8 of the half diagonal out.
    EXPECT_NEAR(d.norm(), 0.8 * half_diagonal_m, 1e-9) << "P" << k + 1;
    EXPECT_NEAR(std::abs(d.y()), 0.4 * plan.edge_m, 1e-9) << "P" << k + 1;
  }
  const KinematicChain chain = irb4400();
  ChainWorkspace ws;
  for (int k = 0; k < trainer::kIsoPoseCount; ++k) {
    forwardKinematics(chain, plan.q_pose_rad[static_cast<size_t>(k)], ws);
    EXPECT_LT((tipPose(ws).translation() - plan.p_PoseInBase_m[static_cast<size_t>(k)]).norm(), 1e-6);
    EXPECT_LT(lie::angleBetween(tipPose(ws).linear(), plan.R_BaseTip), 1e-5);
  }
  // Per load: 5 poses × cycles, and P1, P2, P4 × 3 directions × cycles.
  EXPECT_EQ(plan.loads_kg, (std::vector<double>{0.0, 6.0, 60.0}));
  EXPECT_EQ(plan.rows.size(), 3u * (5u + 9u) * 30u);
}

TEST(IsoPlan, Ur10GetsACubeToo) {
  trainer::Iso9283PlanOptions options;
  const trainer::Iso9283Plan plan =
      trainer::planIso9283(chainFromUrdfFile(kUr10, "base_link", "tool0"), options);
  EXPECT_GT(plan.edge_m, 0.2);
  EXPECT_EQ(plan.loads_kg, std::vector<double>{0.0});
}

TEST(IsoPlan, RefusesTooFewCyclesAndANegativeLoad) {
  trainer::Iso9283PlanOptions options;
  options.cycles = 1;
  EXPECT_THROW(trainer::planIso9283(irb4400(), options), InputError);
  options.cycles = 30;
  options.rated_load_kg = -1.0;
  EXPECT_THROW(trainer::planIso9283(irb4400(), options), InputError);
}

/// A twin of seed 1 calibrated on its own protocol, and the same robot measured on its ISO plan:
/// the campaign, and the same rows at the true poses (no noise).
struct TwinCertification {
  CalibratedModel model;
  Campaign measured, truth;
  double position_sigma_m = 0.0, orientation_sigma_rad = 0.0;
};

TwinCertification certificationOf(twin::TwinOptions options,
                                  const std::vector<PlannedMeasurement>& plan_rows) {
  TwinCertification t;
  const Campaign own = twin::simulateCampaign(options, nullptr);
  t.model = trainer::modelFromOutcome(own, trainer::calibrateCampaign(own));
  options.planned_fit_rows = plan_rows;
  t.measured = twin::simulateCampaign(options, nullptr);
  t.position_sigma_m = options.tracker_position_sigma_m;
  t.orientation_sigma_rad = options.tracker_orientation_sigma_rad;
  const twin::TwinRobot robot(options);
  t.truth = t.measured;
  for (Measurement& row : t.truth.rows) {
    const Pose X = robot.X_TrackerTip(row.q_rad, row.load_kg);
    row.p_TipInTracker_m = X.translation();
    row.q_TrackerTip = Eigen::Quaterniond(X.linear());
  }
  return t;
}

/// The IRB 4400 (paper protocol; plan at 0, 6 and 60 kg).
const TwinCertification& twinCertification() {
  static const TwinCertification twin = certificationOf(twin::TwinOptions{}, irbPlan().rows);
  return twin;
}

/// The UR10 (no payload link: geometry protocol, plan unloaded).
const TwinCertification& ur10Certification() {
  static const TwinCertification twin = [] {
    twin::TwinOptions options = twin::twinOptionsForRobot(kUr10, "base_link", "tool0", "");
    options.protocol = "geometry";
    const trainer::Iso9283Plan plan = trainer::planIso9283(
        chainFromUrdfFile(kUr10, "base_link", "tool0"), trainer::Iso9283PlanOptions{});
    return certificationOf(options, plan.rows);
  }();
  return twin;
}

// AP as measured agrees with AP of the true poses to the noise of a barycentre of n cycles:
// |ē_measured − ē_true| ≤ ‖mean noise‖, which exceeds 4√3 σ/√n with a chance below 1e-6.
// RP against its expectation from the tracker's noise alone (the twin repeats exactly): with
// e_j − ē ~ N(0, σ²(1 − 1/n) I₃), l is σ√(1 − 1/n) times a χ₃ variable: mean 2√(2/π) σ′,
// standard deviation √(3 − 8/π) σ′, so RP = l̄ + 3 S_l ≈ 3.616 σ′; the average over the
// (pose, load) cells varies by about 3 % with 15 cells, 6 % with 5 (one cell's RP by ~12 %).
void expectApAgreesWithTheTruthAndRpWithTheNoise(const TwinCertification& t, size_t loads) {
  const trainer::IsoCertificate measured = trainer::certifyIso9283(t.model, t.measured);
  const trainer::IsoCertificate truth = trainer::certifyIso9283(t.model, t.truth);
  ASSERT_TRUE(measured.iso_plan_rows);
  ASSERT_EQ(measured.loads.size(), loads);
  double rp_sum_m = 0.0, rp_a_sum_rad = 0.0;
  int rp_cells = 0;
  for (size_t l = 0; l < measured.loads.size(); ++l) {
    for (size_t m = 0; m < 2; ++m) {
      const trainer::IsoMethodFigures& meas = measured.loads[l].methods[m];
      const trainer::IsoMethodFigures& tru = truth.loads[l].methods[m];
      ASSERT_EQ(meas.poses.size(), 5u);
      for (size_t p = 0; p < meas.poses.size(); ++p) {
        const double n = 30.0;  // the fewest cycles of a pose (P3, P5; P1, P2, P4 have 120)
        const double tolerance_m = 4.0 * std::sqrt(3.0) * t.position_sigma_m / std::sqrt(n);
        EXPECT_NEAR(*meas.poses[p].ap_position.value, *tru.poses[p].ap_position.value, tolerance_m)
            << meas.method << " " << meas.poses[p].label << " at " << measured.loads[l].load_kg;
        EXPECT_LT(*tru.poses[p].rp_position.value, 1e-9) << "the twin repeats exactly: "
            << meas.method << " " << meas.poses[p].label << " at " << measured.loads[l].load_kg;
        if (m == 0) {
          rp_sum_m += *meas.poses[p].rp_position.value;
          rp_a_sum_rad += meas.poses[p].rp_orientation_rad->x();
          ++rp_cells;
        }
      }
      EXPECT_GT(*tru.ap_position_max.value, 0.0);
    }
    // Uncorrected the robot misses by millimetres.
    EXPECT_GT(*measured.loads[l].methods[0].ap_position_max.value, 1e-3);
  }
  const double shrink = std::sqrt(1.0 - 1.0 / 30.0);
  const double expected_rp_m =
      (2.0 * std::sqrt(2.0 / kPi) + 3.0 * std::sqrt(3.0 - 8.0 / kPi)) * t.position_sigma_m * shrink;
  EXPECT_NEAR(rp_sum_m / rp_cells, expected_rp_m, 0.2 * expected_rp_m);
  // RP_a = 3 S_a, S_a the orientation noise about one axis.
  EXPECT_NEAR(rp_a_sum_rad / rp_cells, 3.0 * t.orientation_sigma_rad,
              0.2 * 3.0 * t.orientation_sigma_rad);
}

TEST(IsoCertify, TwinApAgreesWithTheTruthAndRpWithTheTrackerNoise) {
  expectApAgreesWithTheTruthAndRpWithTheNoise(twinCertification(), 3);
  // Corrected, the IRB 4400's model (compliance and GPR) lands within micrometres.
  const trainer::IsoCertificate c =
      trainer::certifyIso9283(twinCertification().model, twinCertification().measured);
  for (const trainer::IsoLoadFigures& load : c.loads) {
    EXPECT_LT(*load.methods[1].ap_position_max.value, 0.05e-3) << load.load_kg;
  }
}

TEST(IsoCertify, Ur10TwinApAgreesWithTheTruthAndRpWithTheTrackerNoise) {
  expectApAgreesWithTheTruthAndRpWithTheNoise(ur10Certification(), 1);
}

// Every characteristic of the plan is a number on its campaign: vAP at P1, P2, P4, AD and RD.
TEST(IsoCertify, ThePlansCampaignGivesEveryCharacteristic) {
  const trainer::IsoCertificate c = trainer::certifyIso9283(twinCertification().model,
                                                            twinCertification().measured);
  for (const trainer::IsoLoadFigures& load : c.loads) {
    for (const trainer::IsoMethodFigures& m : load.methods) {
      EXPECT_TRUE(m.vap_position_max.value.has_value());
      EXPECT_TRUE(m.ad_position.value.has_value());
      EXPECT_TRUE(m.rd_position.value.has_value());
      EXPECT_EQ(m.distance_cycles, 30);
    }
  }
  const nlohmann::json j = report::certificateJson(c);
  EXPECT_EQ(j["loads"][0]["methods"][0]["poses"].size(), 5u);
  EXPECT_NE(report::certificateHtml(c).find("svg class=\"chart"), std::string::npos);
}

// A campaign of poses measured once each (the paper protocol's validation rows): AP is a
// number, RP, vAP, AD and RD are not measurable, each with its reason.
TEST(IsoCertify, RowsWithoutCyclesGetNoRepeatability) {
  const TwinCertification& t = twinCertification();
  Campaign once = t.measured;
  once.rows.erase(std::remove_if(once.rows.begin(), once.rows.end(),
                                 [](const Measurement& row) {
                                   return trainer::parseIsoPoseId(row.pose_id).has_value() ||
                                          row.load_kg != 0.0;
                                 }),
                  once.rows.end());
  ASSERT_GT(once.rows.size(), 10u);
  const trainer::IsoCertificate c = trainer::certifyIso9283(t.model, once);
  ASSERT_EQ(c.loads.size(), 1u);
  for (const trainer::IsoMethodFigures& m : c.loads[0].methods) {
    EXPECT_TRUE(m.ap_position_max.value.has_value());
    EXPECT_FALSE(m.rp_position_max.value.has_value());
    EXPECT_NE(m.rp_position_max.not_measurable.find("repeated cycles"), std::string::npos);
    EXPECT_FALSE(m.vap_position_max.value.has_value());
    EXPECT_FALSE(m.ad_position.value.has_value());
    EXPECT_FALSE(m.rd_position.value.has_value());
  }
  const std::string text = report::formatCertificate(c);
  EXPECT_NE(text.find("not measurable from these rows"), std::string::npos);
  EXPECT_EQ(report::certificateJson(c)["loads"][0]["methods"][0]["rp_position_max_m"], nullptr);
}

TEST(IsoCertify, RefusesACampaignOfAnotherRobot) {
  const TwinCertification& t = twinCertification();
  twin::TwinOptions ur10 = twin::twinOptionsForRobot(kUr10, "base_link", "tool0", "");
  ur10.protocol = "geometry";
  const Campaign other = twin::simulateCampaign(ur10, nullptr);
  EXPECT_THROW(trainer::certifyIso9283(t.model, other), InputError);
}

TEST(IsoCertify, RefusesASetWithoutRows) {
  const TwinCertification& t = twinCertification();
  trainer::IsoCertifyOptions options;
  options.set = RowSet::kResidual;  // the plan's rows are geometry and stiffness
  EXPECT_THROW(trainer::certifyIso9283(t.model, t.measured, options), InputError);
}

// The command line: bad input exits 2 with what was expected.
TEST(IsoCommand, BadInputExitsTwoAndSaysWhy) {
  const std::string stepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";
  const std::string out = (std::filesystem::temp_directory_path() / "stepcal_iso_ur10.csv").string();
  const test::CommandResult loaded =
      test::run(stepcal + " plan --robot ur10 --iso9283 --rated-load-kg 10 --out " + out);
  EXPECT_EQ(loaded.status, 2) << loaded.out;
  EXPECT_NE(loaded.out.find("no F/T sensor link"), std::string::npos) << loaded.out;
  const test::CommandResult both =
      test::run(stepcal + " plan --robot ur10 --iso9283 --poses 5 --out " + out);
  EXPECT_EQ(both.status, 2) << both.out;
  const test::CommandResult none = test::run(stepcal + " plan --robot ur10 --out " + out);
  EXPECT_EQ(none.status, 2) << none.out;
  EXPECT_NE(none.out.find("--poses is missing"), std::string::npos) << none.out;
  const test::CommandResult missing = test::run(stepcal + " certify no-such.stepcal no-campaign");
  EXPECT_EQ(missing.status, 2) << missing.out;
  EXPECT_NE(missing.out.find("no-such.stepcal"), std::string::npos) << missing.out;
}

}  // namespace
}  // namespace stepcal
