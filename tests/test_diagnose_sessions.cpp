// Several campaigns of one robot diagnosed together (diagnose.hpp, session_frames,
// campaign_joint_zero): the twin's robot with a hidden backlash, measured from two tracker
// stations, the target remounted and joint 3 re-mastered for the second. The diagnosis names the
// backlash once for both and the moved zero, recovers the second campaign's station and tool,
// brings each campaign to the noise floor and writes a model in the first campaign's frames and
// readings without them; `stepcal diagnose DIR DIR` reports each campaign.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <set>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms/backlash.hpp"
#include "stepcal/common/mechanisms/campaign_joint_zero.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/diagnosis_report.hpp"
#include "support/command.hpp"
#include "support/files.hpp"
#include "support/hidden_effects.hpp"

namespace stepcal {
namespace {

using trainer::Diagnosis;

constexpr double kLostMotionRad = 3e-4;
constexpr double kMovedZeroRad = 300e-6;  // joint 3 reads that much less in the second campaign

twin::TwinOptions stationOptions(int station) {
  twin::TwinOptions options = trainer::test_support::paperOptions(
      5, {{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", kLostMotionRad}}});
  options.station = station;
  return options;
}

// The target remounted for the second campaign: its tool is this one in the first's tool frame.
Pose remountedTool() {
  Pose X = Pose::Identity();
  X.linear() = lie::expSO3(Vec3(0.004, -0.006, 0.009));
  X.translation() = Vec3(0.005, -0.003, 0.008);
  return X;
}

struct Together {
  Campaign merged;
  Pose X_Tracker0Base, X_Tracker1Base;  // the truth
  Diagnosis d;
};

const Together& together() {
  static const Together t = [] {
    Together out;
    std::vector<Campaign> campaigns;
    for (int station : {0, 1}) {
      campaigns.push_back(twin::simulateCampaign(stationOptions(station), nullptr));
      campaigns.back().directory = "station" + std::to_string(station);
    }
    for (Measurement& row : campaigns[1].rows) {
      row.q_rad(2) -= kMovedZeroRad;
      const Pose X = row.X_TrackerTip() * remountedTool();
      row.p_TipInTracker_m = X.translation();
      row.q_TrackerTip = Eigen::Quaterniond(X.linear());
    }
    out.X_Tracker0Base = twin::TwinRobot(stationOptions(0)).X_TrackerBase();
    out.X_Tracker1Base = twin::TwinRobot(stationOptions(1)).X_TrackerBase();
    out.merged = mergeCampaigns(std::move(campaigns));
    const CalibratedModel model =
        modelFromOutcome(out.merged, trainer::calibrateCampaign(out.merged));
    out.d = trainer::diagnose(out.merged, model);
    return out;
  }();
  return t;
}

const trainer::FoundEffect* effectOf(const Diagnosis& d, MechanismKind kind) {
  for (const trainer::FoundEffect& e : d.effects) {
    if (e.mechanism.kind == kind) return &e;
  }
  return nullptr;
}

TEST(DiagnoseSessions, OneBacklashForBothAndTheMovedZeroAreNamed) {
  const Diagnosis& d = together().d;
  SCOPED_TRACE("named: " + trainer::test_support::effectsText(d));
  EXPECT_EQ(d.effects.size(), 2u);
  // Joint 2's torque–deflection curve: a backlash (0.3008 ± 0.0008 mrad for a truth of 0.3 before
  // issue 43's bounded screening), or a torsion curve whose one knee takes up the same lost
  // motion over a few tens of N·m (since: 8.58e-6 rad/(N·m) up to a knee at 35.0 N·m, 0.300
  // mrad). On one joint the two are one curve of its torque (docs/diagnosis.md), judged here by
  // the motion it takes up at 500 N·m, beyond the knee and the smoothing, below τ_lin.
  const trainer::FoundEffect* backlash = effectOf(d, MechanismKind::kBacklash);
  const trainer::FoundEffect* curve = effectOf(d, MechanismKind::kTorsionCurve);
  ASSERT_TRUE(backlash != nullptr || curve != nullptr);
  const Mechanism& b = backlash != nullptr ? backlash->mechanism : curve->mechanism;
  EXPECT_EQ(b.joint, 1);
  EXPECT_NEAR(torqueDeflection(b, 500.0), kLostMotionRad, 0.1 * kLostMotionRad);
  const trainer::FoundEffect* zero = effectOf(d, MechanismKind::kCampaignJointZero);
  ASSERT_NE(zero, nullptr);
  const Mechanism& z = zero->mechanism;
  EXPECT_EQ(z.joint, 2);
  ASSERT_EQ(z.order, 1);
  // Measured +302.3 ± 1.4 µrad.
  EXPECT_NEAR(view<mechanism::CampaignJointZero>(z).offset_rad(1), kMovedZeroRad, 0.05 * kMovedZeroRad);
  EXPECT_NEAR(view<mechanism::CampaignJointZero>(z).offset_rad(1), kMovedZeroRad, 4.0 * z.sigma[0] + 1e-6);
  const std::string text = report::formatDiagnosis(d, 0.0);
  EXPECT_NE(text.find("joint 3's zero differs from the first campaign's by +30"), std::string::npos)
      << text;
  // The poses are counted per campaign: both campaigns use the same pose_ids.
  std::set<std::pair<int, std::string>> poses;
  for (const Measurement& row : together().merged.rows) {
    if (row.set != RowSet::kValidation) poses.emplace(row.session, row.pose_id);
  }
  EXPECT_EQ(d.fit_poses, static_cast<int>(poses.size()));
  EXPECT_EQ(d.fit_rows, 1400);
  // No profile: nothing to compare between the campaigns.
  for (const trainer::DiagnosedCampaign& c : d.campaigns) EXPECT_TRUE(c.profile_differences.empty());
}

TEST(DiagnoseSessions, TheSecondStationAndItsRemountedTargetAreRecovered) {
  const Together& t = together();
  ASSERT_EQ(t.d.campaigns.size(), 2u);
  EXPECT_TRUE(t.d.campaigns[0].frames.parameters.empty());
  const Mechanism& frames = t.d.campaigns[1].frames;
  ASSERT_EQ(frames.kind, MechanismKind::kSessionFrames);
  ASSERT_EQ(frames.parameters.size(), 12u);
  const StationAndTool fitted = stationAndTool(frames);
  // The station against the truth, over the tips the first station measured (7 m apart).
  const Pose X_Tracker1Tracker0 = t.X_Tracker1Base * t.X_Tracker0Base.inverse();
  EXPECT_GT(X_Tracker1Tracker0.translation().norm(), 1.0);
  double worst_m = 0.0;
  for (const Measurement& row : t.merged.rows) {
    if (row.session != 0) continue;
    worst_m = std::max(worst_m, (fitted.X_Station * row.p_TipInTracker_m -
                                 X_Tracker1Tracker0 * row.p_TipInTracker_m).norm());
  }
  EXPECT_LT(worst_m, 0.02e-3);  // measured 5.0 µm
  // The remount, 10 mm and 0.63°, found to within the noise (measured 0.9 µm, 0.0003°).
  const Pose X_Error = remountedTool().inverse() * fitted.X_Tool;
  EXPECT_LT(X_Error.translation().norm(), 0.02e-3);
  EXPECT_LT(lie::logSO3(X_Error.linear()).norm(), 0.005 * kRadPerDeg);
  for (size_t i = 0; i < 12; ++i) {
    EXPECT_GT(frames.sigma[i], 0.0) << i;
    EXPECT_LT(frames.sigma[i], 3e-5) << i;  // measured 0.6–5.0 µm and µrad
  }
}

TEST(DiagnoseSessions, EachCampaignIsAtTheNoiseFloor) {
  const Diagnosis& d = together().d;
  ASSERT_EQ(d.campaigns.size(), 2u);
  for (const trainer::DiagnosedCampaign& c : d.campaigns) {
    SCOPED_TRACE(c.directory);
    EXPECT_EQ(c.fit_rows, 700);
    // Measured 0.116–0.117 mm without the effects, 0.016–0.017 mm with them (floor 0.016).
    EXPECT_GT(c.before_mean_m, 3.0 * d.floor_position_m);
    EXPECT_LT(c.after_mean_m, 1.3 * d.floor_position_m);
  }
  // Validation rows of both campaigns, each through its own frames.
  ASSERT_FALSE(d.gain.empty());
  for (const trainer::GainRow& g : d.gain) {
    SCOPED_TRACE("load " + std::to_string(g.load_kg) + " kg");
    EXPECT_EQ(g.rows, g.load_kg == 55.0 ? 100 : 160);
    EXPECT_LT(g.after.mean_position_m, 1.5 * d.floor_position_m);
    EXPECT_LT(g.after_gpr.mean_position_m, 1.5 * d.floor_position_m);
  }
}

TEST(DiagnoseSessions, TheModelIsTheFirstCampaignsWithoutTheOthersFrames) {
  const Together& t = together();
  const CalibratedModel& model = t.d.extended_model;
  for (const Mechanism& m : model.mechanisms) EXPECT_FALSE(isMeasurementOnly(m.kind));
  // The model file takes it, and predicts the first campaign's validation rows as measured.
  const std::vector<uint8_t> bytes = serializeModel(model);
  const CalibratedModel read = parseModel(bytes.data(), bytes.size(), "extended");
  const PhysicalModel physical = physicalModelOf(read);
  std::vector<Measurement> first;
  for (const Measurement& row : t.merged.rows) {
    if (row.session == 0 && row.set == RowSet::kValidation) first.push_back(row);
  }
  ASSERT_FALSE(first.empty());
  for (const trainer::AccuracySummary& s :
       trainer::summarize("extended", trainer::physicalPoseModel(physical), first)) {
    EXPECT_LT(s.mean_position_m, 1.5 * t.d.floor_position_m) << s.load_kg << " kg";
  }
}

// Joint 3's transmission error (harmonic 12) seen from two stations: the same in both, or its
// sine term 1.6 times larger in the second (a gear changed between the sessions).
Diagnosis profilesFromTwoStations(double second_sin_rad) {
  std::vector<Campaign> campaigns;
  for (const int station : {0, 1}) {
    const nlohmann::json effect = {{"name", "transmission_error"}, {"joint", 3},
                                   {"harmonic", 12},               {"sin_rad", station == 0 ? 1e-4 : second_sin_rad},
                                   {"cos_rad", 5e-5}};
    twin::TwinOptions options = trainer::test_support::paperOptions(5, {effect});
    options.station = station;
    campaigns.push_back(twin::simulateCampaign(options, nullptr));
    campaigns.back().directory = "station" + std::to_string(station);
  }
  const Campaign merged = mergeCampaigns(std::move(campaigns));
  return trainer::diagnose(merged, modelFromOutcome(merged, trainer::calibrateCampaign(merged)));
}

TEST(DiagnoseSessions, AProfileThatDiffersBetweenCampaignsIsNamedAndOneThatDoesNotIsNot) {
  const Diagnosis same = profilesFromTwoStations(1e-4);
  const Diagnosis changed = profilesFromTwoStations(1.6e-4);
  for (const Diagnosis* d : {&same, &changed}) {
    SCOPED_TRACE(d == &same ? "same profile" : "changed profile");
    const trainer::FoundEffect* profile = effectOf(*d, MechanismKind::kTransmissionError);
    ASSERT_NE(profile, nullptr);
    EXPECT_EQ(profile->mechanism.joint, 2);
    ASSERT_EQ(d->campaigns.size(), 2u);
    EXPECT_TRUE(d->campaigns[0].profile_differences.empty());
    ASSERT_EQ(d->campaigns[1].profile_differences.size(), 1u);
    EXPECT_EQ(d->campaigns[1].profile_differences[0].score.mechanism.joint, 2);
  }
  // Measured: the same gear z 0.0, RMS difference 0 µrad; the changed one removes 48 % of the
  // held-out error (z 17.9) with an RMS difference of 43 µrad (0.6e-4 rad of sine: 42 µrad RMS).
  const trainer::CampaignProfileDifference& none = same.campaigns[1].profile_differences[0];
  EXPECT_FALSE(none.score.significant);
  EXPECT_LT(none.score.relative_reduction, 0.01);
  EXPECT_LT(none.rms_rad, 10e-6);
  const trainer::CampaignProfileDifference& named = changed.campaigns[1].profile_differences[0];
  EXPECT_TRUE(named.score.significant);
  EXPECT_GT(named.score.relative_reduction, 0.2);
  EXPECT_NEAR(named.rms_rad, 0.6e-4 / std::sqrt(2.0), 15e-6);
  const std::string text = report::formatDiagnosis(changed, 0.0);
  EXPECT_NE(text.find("joint 3's profile: differs here"), std::string::npos) << text;
}

// A later campaign with too few fit rows to place its station is refused by name, with the
// first campaign's model given (calibrating them together would refuse it first).
TEST(DiagnoseSessions, ACampaignTooSmallForItsOwnStationIsRefusedByName) {
  std::vector<Campaign> campaigns;
  for (const int station : {0, 1}) {
    twin::TwinOptions options = trainer::test_support::paperOptions(3, {});
    options.protocol = "geometry";
    options.station = station;
    campaigns.push_back(twin::simulateCampaign(options, nullptr));
    campaigns.back().directory = "station" + std::to_string(station);
  }
  std::vector<Measurement> kept;
  for (const Measurement& row : campaigns[1].rows) {
    if (row.set == RowSet::kValidation || kept.size() < 3) kept.push_back(row);
  }
  campaigns[1].rows = kept;
  const CalibratedModel model =
      modelFromOutcome(campaigns[0], trainer::calibrateCampaign(campaigns[0]));
  const Campaign merged = mergeCampaigns(std::move(campaigns));
  try {
    trainer::diagnose(merged, model);
    FAIL() << "a campaign of 3 fit rows was diagnosed";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "station1");
    EXPECT_NE(std::string(e.what()).find("campaign 2 has 3 fit rows (outside set=validation); "
                                         "expected at least 4"),
              std::string::npos)
        << e.what();
  }
}

TEST(DiagnoseSessions, ACampaignsFramesAndZerosAreRefusedInAModelFile) {
  const trainer::FoundEffect* zero = effectOf(together().d, MechanismKind::kCampaignJointZero);
  ASSERT_NE(zero, nullptr);
  for (const Mechanism& m : {together().d.campaigns[1].frames, zero->mechanism}) {
    CalibratedModel model = together().d.extended_model;
    model.mechanisms = {m};
    const std::string problem = mechanismInModelProblem(model, 0);
    EXPECT_NE(problem.find(std::string(toString(m.kind)) + " describes a campaign's measurement"),
              std::string::npos)
        << problem;
    EXPECT_THROW(serializeModel(model), InputError);
  }
}

// A joint zero per campaign needs its joint and at least one later campaign.
TEST(DiagnoseSessions, AMalformedCampaignJointZeroIsNamed) {
  Mechanism m;
  m.kind = MechanismKind::kCampaignJointZero;
  m.joint = 2;
  m.order = 2;
  m.parameters = {1e-4, -2e-4};
  m.sigma = {1e-6, 1e-6};
  EXPECT_EQ(mechanismProblem(m, 6), "");
  EXPECT_EQ(mechanismParameterNames(m.kind, 6, 2),
            (std::vector<std::string>{"campaign2_rad", "campaign3_rad"}));
  Mechanism no_joint = m;
  no_joint.joint = -1;
  EXPECT_NE(mechanismProblem(no_joint, 6).find("campaign_joint_zero joint index -1; expected 0 to 5"),
            std::string::npos)
      << mechanismProblem(no_joint, 6);
  Mechanism no_campaign = m;
  no_campaign.order = 0;
  no_campaign.parameters.clear();
  no_campaign.sigma.clear();
  EXPECT_NE(mechanismProblem(no_campaign, 6).find("campaign_joint_zero order 0; expected"),
            std::string::npos)
      << mechanismProblem(no_campaign, 6);
  Mechanism short_of_one = m;
  short_of_one.parameters.pop_back();
  EXPECT_NE(mechanismProblem(short_of_one, 6).find("has 1 parameters and 2 sigmas; expected 2"),
            std::string::npos)
      << mechanismProblem(short_of_one, 6);
}

// A station and a tool through the parameters and back, at rotations up to near a half turn.
TEST(DiagnoseSessions, StationAndToolParametersRoundTrip) {
  for (const double angle : {0.0, 1e-9, 1.0, 3.1}) {
    Pose X_Station = Pose::Identity(), X_Tool = Pose::Identity();
    X_Station.linear() = lie::expSO3(angle * Vec3(0.6, -0.8, 0.0));
    X_Station.translation() = Vec3(-1.7, 3.6, 0.2);
    X_Tool.linear() = lie::expSO3(angle * Vec3(0.0, 0.0, 1.0));
    X_Tool.translation() = Vec3(0.005, -0.003, 0.008);
    Mechanism m;
    m.kind = MechanismKind::kSessionFrames;
    m.order = 1;
    m.parameters = stationAndToolParameters(X_Station, X_Tool);
    m.sigma.assign(m.parameters.size(), 0.0);
    EXPECT_EQ(mechanismProblem(m, 6), "");
    const StationAndTool back = stationAndTool(m);
    EXPECT_TRUE(back.X_Station.isApprox(X_Station, 1e-12)) << angle;
    EXPECT_TRUE(back.X_Tool.isApprox(X_Tool, 1e-12)) << angle;
  }
  Mechanism first;
  first.kind = MechanismKind::kSessionFrames;
  first.parameters.assign(12, 0.0);
  first.sigma.assign(12, 0.0);
  EXPECT_NE(mechanismProblem(first, 6).find("session_frames order 0; expected"), std::string::npos)
      << mechanismProblem(first, 6);
}

TEST(DiagnoseSessions, TheCliReportsEveryCampaign) {
  test::TempDir dir;
  const std::string bin = STEPCAL_BIN_DIR "/stepcal";
  const std::string a = (dir.path() / "a").string(), b = (dir.path() / "b").string();
  ASSERT_EQ(test::run(bin + " simulate --protocol geometry --seed 3 --out " + a).status, 0);
  ASSERT_EQ(test::run(bin + " simulate --protocol geometry --seed 3 --station 2 --out " + b).status, 0);
  const test::CommandResult json = test::run(bin + " diagnose " + a + " " + b + " --json 2>/dev/null");
  ASSERT_EQ(json.status, 0) << json.out;
  const nlohmann::json j = nlohmann::json::parse(json.out);
  ASSERT_EQ(j.at("campaigns").size(), 2u);
  EXPECT_EQ(j["campaigns"][0]["directory"], a);
  EXPECT_FALSE(j["campaigns"][0].contains("station"));
  const nlohmann::json& second = j["campaigns"][1];
  EXPECT_EQ(second["directory"], b);
  EXPECT_EQ(second["fit_rows"], 80);
  EXPECT_EQ(second["station"]["translation_mm"].size(), 3u);
  EXPECT_EQ(second["tool"]["rotation_sigma_deg"].size(), 3u);
  for (const nlohmann::json& c : j["campaigns"]) EXPECT_LT(c["after_mean_position_mm"].get<double>(), 0.03);
  const std::string html = (dir.path() / "report.html").string();
  const test::CommandResult text = test::run(bin + " diagnose " + a + " " + b + " --report " + html);
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_NE(text.out.find("Campaigns fitted together"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("2 " + b + ": 80 fit rows"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("registration_drift (the fit rows are several campaigns"),
            std::string::npos)
      << text.out;
  const std::string page = test::readText(html);
  EXPECT_NE(page.find("<a href=\"#campaigns\">campaigns</a>"), std::string::npos);
  EXPECT_NE(page.find("<h2 id=\"campaigns\">Campaigns fitted together</h2>"), std::string::npos);
  EXPECT_NE(page.find("<td>" + b + "</td><td>80</td>"), std::string::npos);
}

}  // namespace
}  // namespace stepcal
