// End to end through the `stepcal` command: simulate → calibrate --json, a campaign written
// by this test (not the twin) through the file format, and bad input → exit status 2.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/twin/draws.hpp"
#include "support/command.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

using test::CommandResult;
using test::run;

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("stepcal_test_cli_" + name);
  fs::remove_all(dir);
  return dir;
}

nlohmann::json calibrateJson(const fs::path& campaign, const fs::path& model) {
  const CommandResult r = run(kStepcal + " calibrate " + campaign.string() + " --out " + model.string() +
                    " --json 2>/dev/null");
  EXPECT_EQ(r.status, 0) << r.out;
  return nlohmann::json::parse(r.out.substr(r.out.find('{')));
}

const nlohmann::json& validationRow(const nlohmann::json& report, const std::string& method,
                                    double load_kg) {
  for (const auto& row : report["validation"]) {
    if (row["method"] == method && row["load_kg"] == load_kg) return row;
  }
  static const nlohmann::json none;
  ADD_FAILURE() << "no validation row for " << method << " at " << load_kg << " kg";
  return none;
}

TEST(Cli, SimulatedPaperCampaignReachesTheNoiseFloor) {
  const fs::path dir = scratch("paper");
  ASSERT_EQ(run(kStepcal + " simulate --protocol paper --seed 3 --out " + dir.string()).status, 0);
  const nlohmann::json report = calibrateJson(dir, dir / "model.stepcal");
  const double floor_mm = report["noise_floor"]["mean_position_mm"];
  const double floor_deg = report["noise_floor"]["mean_orientation_deg"];
  EXPECT_NEAR(floor_mm, 0.016, 0.001);
  const auto& nominal = validationRow(report, "nominal", 0.0);
  const auto& poe = validationRow(report, "poe", 0.0);
  EXPECT_GT(nominal["mean_position_mm"].get<double>(), 2.0);
  EXPECT_LE(poe["mean_position_mm"].get<double>(), 1.25 * floor_mm);
  EXPECT_LE(poe["mean_orientation_deg"].get<double>(), 1.25 * floor_deg);
  EXPECT_LE(report["geometry"]["iterations"].get<int>(), 5);
  EXPECT_EQ(report["geometry"]["rank"].get<int>(), 30);
  EXPECT_EQ(report["geometry"]["unobservable"].size(), 12u);

  // Step 2: every joint the loads excite within 3 % of the truth; the vertical joint 1 (a
  // vertical payload puts no torque on it) reported as not identified rather than a number.
  const nlohmann::json truth = nlohmann::json::parse(readTextFile((dir / "truth.json").string()));
  std::vector<double> true_stiffness;
  for (const auto& effect : truth["effects"]) {
    if (effect["name"] == "joint_compliance") true_stiffness = effect["stiffness_nm_per_rad"].get<std::vector<double>>();
  }
  ASSERT_EQ(true_stiffness.size(), 6u);
  const auto& stiffness = report["stiffness_nm_per_rad"];
  ASSERT_EQ(stiffness.size(), 6u);
  EXPECT_FALSE(stiffness[0]["identified"].get<bool>());
  EXPECT_TRUE(stiffness[0]["stiffness_nm_per_rad"].is_null());
  // Joints 2–5 carry hundreds of N·m and are pinned down to better than 1 %; joint 6 sees only
  // the payload's small lateral offset (~14 N·m), so the data fix it to several % only.
  int well_excited = 0;
  for (size_t j = 1; j < 6; ++j) {
    ASSERT_TRUE(stiffness[j]["identified"].get<bool>()) << "joint " << j + 1;
    const double k = stiffness[j]["stiffness_nm_per_rad"], sigma = stiffness[j]["sigma_nm_per_rad"];
    if (sigma <= 0.01 * k) {
      ++well_excited;
      EXPECT_NEAR(k / true_stiffness[j], 1.0, 0.03) << "joint " << j + 1;
    } else {
      EXPECT_LT(std::abs(k - true_stiffness[j]), 3 * sigma) << "joint " << j + 1;
    }
  }
  EXPECT_GE(well_excited, 4);
  EXPECT_GE(report["stiffness_validation"].size(), 3u);

  // Steps 2 and 3 at the noise floor at every load, the 55 kg extrapolation block included;
  // POE + GPR far worse and growing with load, as the paper found.
  double previous_gpr_only = 0.0;
  for (double load : {20.0, 30.0, 40.0, 55.0}) {
    for (const char* method : {"poe+stiffness", "poe+stiffness+gpr"}) {
      EXPECT_LE(validationRow(report, method, load)["mean_position_mm"].get<double>(), 1.25 * floor_mm)
          << method << " at " << load << " kg";
    }
    const double gpr_only = validationRow(report, "poe+gpr", load)["mean_position_mm"];
    EXPECT_GT(gpr_only, 3 * floor_mm) << load << " kg";
    EXPECT_GT(gpr_only, previous_gpr_only) << load << " kg";
    previous_gpr_only = gpr_only;
  }

  // The model file was written, holds every step and reads back.
  const CalibratedModel model = readModelFile((dir / "model.stepcal").string());
  EXPECT_EQ(model.chain_Tracker.dof(), 6);
  EXPECT_EQ(model.nominal_Base.dof(), 6);
  EXPECT_GE(model.nominal_Base.findFrame("ft_sensor"), 0);
  EXPECT_EQ(model.compliance_rad_per_nm.size(), 6);
  ASSERT_TRUE(model.gpr.has_value());
  EXPECT_EQ(model.gpr->inputs_normalised.rows(), 300);
  EXPECT_EQ(model.gpr->inputs_normalised.cols(), 12);
  EXPECT_FALSE(model.provenance.validation.empty());
  // Every layer evaluated from the model file alone reproduces the trainer's figures.
  const CommandResult validate =
      run(kStepcal + " validate " + (dir / "model.stepcal").string() + " " + dir.string() + " --json");
  ASSERT_EQ(validate.status, 0) << validate.out;
  int compared = 0;
  for (const auto& row : nlohmann::json::parse(validate.out)) {
    if (row["set"] != "validation") continue;
    const auto& trained = validationRow(report, row["method"], row["load_kg"]);
    EXPECT_NEAR(row["mean_position_mm"].get<double>(), trained["mean_position_mm"].get<double>(), 1e-9)
        << row["method"] << " at " << row["load_kg"];
    ++compared;
  }
  EXPECT_EQ(compared, 3 * 5);  // poe, poe+stiffness, poe+stiffness+gpr at five loads
  const CommandResult inspect = run(kStepcal + " inspect " + (dir / "model.stepcal").string());
  EXPECT_EQ(inspect.status, 0);
  EXPECT_NE(inspect.out.find("GPR: 300 training points, 12 inputs, 6 outputs"), std::string::npos)
      << inspect.out;
  EXPECT_NE(inspect.out.find("nominal chain: 6 revolute joints, rooted at the robot base, tool"),
            std::string::npos)
      << inspect.out;
}

TEST(Cli, CampaignNotWrittenByTheTwinCalibratesToo) {
  // A UR10 with its own geometric errors, written through the campaign format by this test.
  const std::string urdf_path = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";
  const KinematicChain nominal = chainFromUrdfFile(urdf_path, "base_link", "tool0");
  std::mt19937_64 rng(42);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  Eigen::VectorXd delta(42);
  for (int i = 0; i < 42; ++i) delta(i) = (i % 6 < 3 ? 2e-4 : 4e-4) * g(rng);
  const Pose X_TrackerBase = lie::expSE3((Vec6() << -2.0, 3.0, 0.7, 0.0, 0.01, -1.9).finished());
  const KinematicChain truth = nominal.corrected(delta).rerooted(X_TrackerBase);
  const double sigma_p = 20e-6, sigma_r = 0.01 * kRadPerDeg;
  Campaign c;
  c.urdf_xml = readTextFile(urdf_path);
  c.base_link = "base_link";
  c.tip_link = "tool0";
  c.tracker = {sigma_p, sigma_r, true};
  c.joint_count = 6;
  ChainWorkspace ws;
  for (int i = 0; i < 200; ++i) {
    Measurement m;
    m.seq = i;
    m.pose_id = "p" + std::to_string(i);
    m.set = i < 100 ? RowSet::kGeometry : RowSet::kValidation;
    m.q_rad.resize(6);
    for (int j = 0; j < 6; ++j) m.q_rad(j) = u(rng);
    forwardKinematics(truth, m.q_rad, ws);
    m.p_TipInTracker_m = tipPose(ws).translation() + sigma_p * Vec3(g(rng), g(rng), g(rng));
    m.has_orientation = i % 4 != 0;  // a quarter of the rows are position-only
    m.q_TrackerTip = Eigen::Quaterniond(lie::expSO3(sigma_r * Vec3(g(rng), g(rng), g(rng))) *
                                        tipPose(ws).linear());
    c.rows.push_back(m);
  }
  const fs::path dir = scratch("foreign");
  writeCampaign(c, dir.string());
  const nlohmann::json report = calibrateJson(dir, dir / "model.stepcal");
  const auto& poe = validationRow(report, "poe", 0.0);
  EXPECT_LE(poe["mean_position_mm"].get<double>(), 1.25 * 2 * std::sqrt(2 / kPi) * 0.020);
  EXPECT_EQ(report["geometry"]["rank"].get<int>(), 30);
}

// No subcommand, or one without its required arguments, is a usage error: exit status 2 (not
// CLI11's own numbers), with the usage; every --help ends with the exit status table.
TEST(Cli, UsageErrorsExitTwoAndHelpListsTheExitStatuses) {
  const CommandResult bare = run(kStepcal);
  EXPECT_EQ(bare.status, 2) << bare.out;
  EXPECT_NE(bare.out.find("Subcommands:"), std::string::npos) << bare.out;
  const CommandResult missing = run(kStepcal + " correct");
  EXPECT_EQ(missing.status, 2) << missing.out;
  EXPECT_NE(missing.out.find("model is required"), std::string::npos) << missing.out;
  EXPECT_EQ(run(kStepcal + " frobnicate").status, 2);
  for (const char* command : {" --help", " correct --help", " import --help", " import ipa --help"}) {
    const CommandResult help = run(kStepcal + command);
    EXPECT_EQ(help.status, 0) << command;
    EXPECT_NE(help.out.find("Exit status: 0 everything done"), std::string::npos) << command;
    EXPECT_NE(help.out.find("3 done in part"), std::string::npos) << command;
  }
  for (const std::string binary : {"/stepcal-client", "/stepcal-runtime"}) {
    const CommandResult help = run(std::string(STEPCAL_BIN_DIR) + binary + " --help");
    EXPECT_EQ(help.status, 0) << binary;
    EXPECT_NE(help.out.find("4 service unavailable"), std::string::npos) << binary << help.out;
  }
  EXPECT_EQ(run(std::string(STEPCAL_BIN_DIR) + "/stepcal-client --no-such-option").status, 2);
}

TEST(Cli, BadInputEndsWithAClearErrorAndStatusTwo) {
  const fs::path dir = scratch("bad");
  ASSERT_EQ(run(kStepcal + " simulate --protocol geometry --seed 1 --out " + dir.string()).status, 0);
  // Corrupt one joint angle on line 5.
  const fs::path csv = dir / "measurements.csv";
  std::string text = readTextFile(csv.string());
  size_t line_start = 0;
  for (int line = 1; line < 5; ++line) line_start = text.find('\n', line_start) + 1;
  const size_t field = text.find(',', text.find(',', text.find(',', text.find(',', line_start) + 1) + 1) + 1);
  text.replace(field + 1, 0, "x");
  FILE* f = fopen(csv.string().c_str(), "w");
  fwrite(text.data(), 1, text.size(), f);
  fclose(f);
  const CommandResult r = run(kStepcal + " calibrate " + dir.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("measurements.csv:5"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("q1_deg"), std::string::npos) << r.out;

  const CommandResult missing = run(kStepcal + " calibrate /nonexistent/campaign");
  EXPECT_EQ(missing.status, 2);
  EXPECT_NE(missing.out.find("/nonexistent/campaign"), std::string::npos) << missing.out;
  const CommandResult not_a_model = run(kStepcal + " inspect " + (dir / "campaign.yaml").string());
  EXPECT_EQ(not_a_model.status, 2);
  EXPECT_NE(not_a_model.out.find("not a stepcal model file"), std::string::npos) << not_a_model.out;
  const CommandResult robot = run(kStepcal + " simulate --robot ur5 --out " + dir.string());
  EXPECT_EQ(robot.status, 2);
  EXPECT_NE(robot.out.find("--robot 'ur5'"), std::string::npos) << robot.out;
  const CommandResult not_json = run(kStepcal + " simulate --effect '{joint:2}' --out " + dir.string());
  EXPECT_EQ(not_json.status, 2);
  EXPECT_NE(not_json.out.find("--effect '{joint:2}': not a JSON object"), std::string::npos) << not_json.out;
  const CommandResult bad_joint = run(kStepcal + " simulate --effect " +
                                      "'{\"name\": \"backlash\", \"joint\": 9, \"lost_motion_rad\": 1e-4}' --out " +
                                      dir.string());
  EXPECT_EQ(bad_joint.status, 2);
  EXPECT_NE(bad_joint.out.find("backlash.joint = 9"), std::string::npos) << bad_joint.out;
  const CommandResult bad_bias =
      run(kStepcal + " simulate --effect " +
          "'{\"name\": \"sensor_bias\", \"force_n\": [900, 0, 0], \"moment_nm\": [0, 0, 0]}' --out " +
          dir.string());
  EXPECT_EQ(bad_bias.status, 2);
  EXPECT_NE(bad_bias.out.find("sensor_bias.force_n = [900, 0, 0] N; expected finite values with norm < 500 N"),
            std::string::npos)
      << bad_bias.out;
  const CommandResult cog = run(kStepcal + " simulate --payload-cog 0,0.1 --out " + dir.string());
  EXPECT_EQ(cog.status, 2);
  EXPECT_NE(cog.out.find("--payload-cog has 2 values; expected x,y,z"), std::string::npos) << cog.out;
  const CommandResult stiffness = run(kStepcal + " simulate --stiffness 1e5,1e5 --out " + dir.string());
  EXPECT_EQ(stiffness.status, 2);
  EXPECT_NE(stiffness.out.find("stiffness_nm_per_rad has 2 values; expected one per revolute joint, 6"),
            std::string::npos) << stiffness.out;
  const CommandResult tip = run(kStepcal + " simulate --robot ur10 --tip-link tmac --out " + dir.string());
  EXPECT_EQ(tip.status, 2);
  EXPECT_NE(tip.out.find("ur10.urdf: tip_link 'tmac' is not a link"), std::string::npos) << tip.out;
  // Candidates from this campaign, corrupted above, and from one of another robot.
  const CommandResult not_read = run(kStepcal + " plan --poses 5 --candidates-from " + dir.string() +
                                     " --out " + (dir / "p.csv").string());
  EXPECT_EQ(not_read.status, 2);
  EXPECT_NE(not_read.out.find("measurements.csv:5"), std::string::npos) << not_read.out;
  const fs::path irb = scratch("bad_irb");
  ASSERT_EQ(run(kStepcal + " simulate --protocol geometry --out " + irb.string()).status, 0);
  const CommandResult other = run(kStepcal + " plan --robot ur10 --poses 5 --candidates-from " +
                                  irb.string() + " --out " + (dir / "p.csv").string());
  EXPECT_EQ(other.status, 2);
  EXPECT_NE(other.out.find("the campaign's joints (joint_1, joint_2, joint_3, joint_4, joint_5, "
                           "joint_6) are not the planned robot's (shoulder_pan_joint"),
            std::string::npos) << other.out;
  const CommandResult unknown = run(kStepcal + " simulate --effect '{\"name\": \"gear_wobble\"}' --out " +
                                    dir.string());
  EXPECT_EQ(unknown.status, 2);
  EXPECT_NE(unknown.out.find("unknown effect 'gear_wobble'; expected one of"), std::string::npos) << unknown.out;
}

// --gpr-points caps the GPR's training set of calibrate and of diagnose's extended model (the
// geometry campaign has 80 residual rows); fewer than two is refused before any work.
// A self weight hidden in the geometry campaign leaves the geometric model a residual the GPR
// learns (on a clean one it meets only the tracker's noise and is not taken); the diagnosis names
// it, so the extended model's GPR is judged on the training rows it was given.
TEST(Cli, GprPointsCapsTheTrainingSet) {
  const fs::path dir = scratch("gpr_points");
  const std::string self_weight =
      R"('{"name":"self_weight","links":[{"link":2,"mass_kg":40,"com_m":[0.3,0,0.1]},)"
      R"({"link":3,"mass_kg":30,"com_m":[0.2,0,0.05]}]}')";
  ASSERT_EQ(run(kStepcal + " simulate --protocol geometry --seed 1 --out " + dir.string() +
                " --effect " + self_weight)
                .status,
            0);
  const auto gprLine = [](const fs::path& model) {
    const CommandResult inspect = run(kStepcal + " inspect " + model.string());
    EXPECT_EQ(inspect.status, 0) << inspect.out;
    const size_t at = inspect.out.find("GPR: ");
    return at == std::string::npos ? std::string()
                                   : inspect.out.substr(at, inspect.out.find_first_of(",\n", at) - at);
  };
  ASSERT_EQ(run(kStepcal + " calibrate " + dir.string() + " --out " + (dir / "all.stepcal").string()).status, 0);
  EXPECT_EQ(gprLine(dir / "all.stepcal"), "GPR: 80 training points");
  const CommandResult capped = run(kStepcal + " calibrate " + dir.string() + " --gpr-points 30 --out " +
                                   (dir / "capped.stepcal").string());
  ASSERT_EQ(capped.status, 0) << capped.out;
  EXPECT_EQ(gprLine(dir / "capped.stepcal"), "GPR: 30 training points");
  const CommandResult extended = run(kStepcal + " diagnose " + dir.string() + " --gpr-points 30 --json --out " +
                                     (dir / "extended.stepcal").string());
  ASSERT_EQ(extended.status, 0) << extended.out;
  const nlohmann::json gpr =
      nlohmann::json::parse(extended.out.substr(extended.out.find('{'))).at("extended_gpr");
  EXPECT_EQ(gpr.at("training_rows"), 30) << gpr.dump();
  EXPECT_EQ(gprLine(dir / "extended.stepcal"),
            gpr.at("taken").get<bool>() ? "GPR: 30 training points" : "GPR: none (no step 3)");
  for (const char* command : {" calibrate ", " diagnose "}) {
    const CommandResult refused = run(kStepcal + command + dir.string() + " --gpr-points 1 --out " +
                                      (dir / "refused.stepcal").string());
    EXPECT_EQ(refused.status, 2) << command;
    EXPECT_NE(refused.out.find("--gpr-points 1: expected at least 2 training points (default 400)"),
              std::string::npos)
        << refused.out;
    EXPECT_FALSE(fs::exists(dir / "refused.stepcal"));
  }
}

// README, "From plan to URDF": plan → simulate --poses → calibrate → export urdf, as written there
// (fewer poses), and a bad pose list ends with its file, line, column and value.
TEST(Cli, FromPlanToUrdf) {
  const fs::path dir = scratch("plan");
  fs::create_directories(dir);
  const std::string poses = (dir / "poses.csv").string();
  const CommandResult plan = run(kStepcal + " plan --robot " + STEPCAL_ROBOTS_DIR +
                                 "/irb4400.urdf --poses 20 --loads 0,20,40 --tracker 4,0,1.2 --out " +
                                 poses);
  ASSERT_EQ(plan.status, 0) << plan.out;
  EXPECT_NE(plan.out.find("20 poses (D-optimal) x 3 loads = 60 rows"), std::string::npos) << plan.out;
  const fs::path campaign = dir / "planned";
  ASSERT_EQ(run(kStepcal + " simulate --robot irb4400 --poses " + poses + " --seed 1 --out " +
                campaign.string()).status, 0);
  const Campaign read = readCampaign(campaign.string());
  EXPECT_EQ(read.rowsIn(RowSet::kGeometry).size(), 20u);
  EXPECT_EQ(read.rowsIn(RowSet::kStiffness).size(), 40u);
  const nlohmann::json report = calibrateJson(campaign, dir / "planned.stepcal");
  // Compliance identified from the planned pairs: the loaded validation rows near the floor.
  EXPECT_LT(validationRow(report, "poe+stiffness", 40.0)["mean_position_mm"].get<double>(), 0.03);
  const CommandResult urdf = run(kStepcal + " export urdf " + (dir / "planned.stepcal").string() +
                                 " --out " + (dir / "robot_calibrated.urdf").string());
  EXPECT_EQ(urdf.status, 0) << urdf.out;
  EXPECT_TRUE(fs::exists(dir / "robot_calibrated.urdf"));

  std::string text = readTextFile(poses);
  text.replace(text.find('\n', text.find('\n') + 1) + 1, 0, "plan-999,0,1,2,3,4,x,6\n");
  FILE* f = fopen(poses.c_str(), "w");
  fwrite(text.data(), 1, text.size(), f);
  fclose(f);
  const CommandResult bad = run(kStepcal + " simulate --poses " + poses + " --out " +
                                (dir / "bad").string());
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.out.find("poses.csv:3: column 'q5_deg': expected a joint angle (deg), got 'x'"),
            std::string::npos) << bad.out;
}

/// The diagnosis's JSON of a campaign (and its extended model written to model_out).
nlohmann::json diagnoseJson(const fs::path& campaign, const fs::path& model_out) {
  const CommandResult r = run(kStepcal + " diagnose " + campaign.string() + " --out " +
                              model_out.string() + " --json 2>/dev/null");
  EXPECT_EQ(r.status, 0) << r.out;
  return nlohmann::json::parse(r.out.substr(r.out.find('{')));
}

// README, "Any robot": the walk on the UR10's description, run from the checkout as written
// there: plan (no F/T sensor: unloaded), simulate the plan, calibrate, export the calibrated URDF,
// diagnose. The twin's UR10 deflects under its own weight, which only the diagnosis models: it
// names self weight and its extended model is at the noise floor on the validation rows. Then
// a payload of known mass on the flange (--sensor-link tool0), planned and measured.
TEST(Cli, TheWalkWorksOnTheUr10) {
  const fs::path dir = scratch("ur10");
  fs::create_directories(dir);
  const std::string checkout = "cd " + fs::path(STEPCAL_ROBOTS_DIR).parent_path().string() + " && ";
  const std::string poses = (dir / "poses.csv").string();
  const CommandResult plan =
      run(checkout + kStepcal + " plan --robot robots/ur10.urdf --poses 40 --out " + poses);
  ASSERT_EQ(plan.status, 0) << plan.out;
  EXPECT_NE(plan.out.find("base_link -> tool0, no F/T sensor (unloaded rows only)"),
            std::string::npos) << plan.out;
  EXPECT_NE(plan.out.find("40 poses (D-optimal) x 1 loads = 40 rows"), std::string::npos) << plan.out;
  const fs::path campaign = dir / "planned";
  const CommandResult simulate = run(checkout + kStepcal + " simulate --robot robots/ur10.urdf --poses " +
                                     poses + " --seed 1 --out " + campaign.string());
  ASSERT_EQ(simulate.status, 0) << simulate.out;
  const Campaign read = readCampaign(campaign.string());
  EXPECT_EQ(read.tip_link, "tool0");
  EXPECT_EQ(read.sensor_link, "");
  EXPECT_EQ(read.rowsIn(RowSet::kGeometry).size(), 40u);
  EXPECT_EQ(read.rowsIn(RowSet::kValidation).size(), 50u);
  const nlohmann::json report = calibrateJson(campaign, dir / "planned.stepcal");
  const double floor_mm = report["noise_floor"]["mean_position_mm"];
  const double poe_mm = validationRow(report, "poe", 0.0)["mean_position_mm"];
  const CommandResult urdf = run(kStepcal + " export urdf " + (dir / "planned.stepcal").string() +
                                 " --out " + (dir / "robot_calibrated.urdf").string());
  EXPECT_EQ(urdf.status, 0) << urdf.out;
  EXPECT_TRUE(fs::exists(dir / "robot_calibrated.urdf"));
  const nlohmann::json diagnosis = diagnoseJson(campaign, dir / "extended.stepcal");
  for (const std::string& command :
       {" inspect " + (dir / "extended.stepcal").string(),
        " validate " + (dir / "extended.stepcal").string() + " " + campaign.string(),
        " validate " + (dir / "planned.stepcal").string() + " " + campaign.string() + " --refit-frames"}) {
    const CommandResult r = run(kStepcal + command);
    EXPECT_EQ(r.status, 0) << command << "\n" << r.out;
  }
  EXPECT_EQ(diagnosis["verdict"], "found");
  ASSERT_GE(diagnosis["effects"].size(), 1u);
  EXPECT_EQ(diagnosis["effects"][0]["name"], "self_weight");
  const double extended_mm = diagnosis["gain"][0]["after_mean_position_mm"];
  std::printf("UR10 twin, 40 planned poses: poe %.4f mm, extended %.4f mm on the validation rows "
              "(floor %.4f)\n", poe_mm, extended_mm, floor_mm);
  EXPECT_GT(poe_mm, 3 * floor_mm);  // its own weight, which a geometric model cannot take
  EXPECT_LT(extended_mm, 1.3 * floor_mm);

  // A payload of known mass and centre of gravity on the flange, at 5 and 10 kg.
  const std::string loaded_poses = (dir / "loaded.csv").string();
  const std::string payload = " --sensor-link tool0 --payload-cog 0,0.02,0.08";
  const CommandResult loaded_plan = run(kStepcal + " plan --robot ur10 --poses 30 --loads 0,5,10" +
                                        payload + " --out " + loaded_poses);
  ASSERT_EQ(loaded_plan.status, 0) << loaded_plan.out;
  EXPECT_NE(loaded_plan.out.find("30 poses (D-optimal) x 3 loads = 90 rows"), std::string::npos);
  const fs::path loaded = dir / "loaded";
  ASSERT_EQ(run(kStepcal + " simulate --robot ur10" + payload + " --poses " + loaded_poses +
                " --out " + loaded.string()).status, 0);
  const Campaign loaded_read = readCampaign(loaded.string());
  EXPECT_EQ(loaded_read.sensor_link, "tool0");
  EXPECT_EQ(loaded_read.rowsIn(RowSet::kStiffness).size(), 60u);
  // The validation rows are the paper protocol's, at 0–55 kg (the IRB4400's payloads): at the
  // fitted loads' range and twice the largest (0 and 20 kg) the extended model is at the floor;
  // beyond, the wrists' compliance, identified from 5–10 kg, extrapolates 3–5.5 times (measured
  // 1.2–1.4 times the floor at 30–55 kg).
  const nlohmann::json loaded_diagnosis = diagnoseJson(loaded, dir / "loaded.stepcal");
  for (const auto& g : loaded_diagnosis["gain"]) {
    std::printf("UR10 twin, payload on the flange: %g kg, extended %.4f mm\n",
                g["load_kg"].get<double>(), g["after_mean_position_mm"].get<double>());
    if (g["load_kg"].get<double>() <= 20.0) {
      EXPECT_LT(g["after_mean_position_mm"].get<double>(), 1.3 * floor_mm) << g.dump();
    }
  }
  // Payloads without a link to hang from are refused.
  const CommandResult refused =
      run(kStepcal + " plan --robot ur10 --poses 30 --loads 0,5 --out " + loaded_poses);
  EXPECT_EQ(refused.status, 2);
  EXPECT_NE(refused.out.find("has no F/T sensor link ('ft_sensor'); expected --loads 0, or "
                             "--sensor-link LINK"),
            std::string::npos) << refused.out;
}

// No path of the build's checkout is compiled into the command: its help names robots, not
// files, and the robots are found at run time, beside the executable or in $STEPCAL_ROBOTS_DIR.
TEST(Cli, ShippedRobotsAreFoundAtRunTime) {
  for (const char* command : {" plan --help", " simulate --help", " import ipa --help"}) {
    const CommandResult help = run(kStepcal + command);
    EXPECT_EQ(help.status, 0) << command;
    EXPECT_EQ(help.out.find(STEPCAL_ROBOTS_DIR), std::string::npos) << command << ":\n" << help.out;
    EXPECT_EQ(help.out.find(".urdf="), std::string::npos) << command << ":\n" << help.out;
  }
  const fs::path dir = scratch("robots_env");
  fs::create_directories(dir / "robots");
  fs::copy_file(std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf", dir / "robots" / "my_arm.urdf");
  const CommandResult r = run("STEPCAL_ROBOTS_DIR=" + (dir / "robots").string() + " " + kStepcal +
                              " simulate --robot my_arm --out " + (dir / "camp").string());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(readCampaign((dir / "camp").string()).tip_link, "tool0");
  const CommandResult unknown = run(kStepcal + " plan --robot my_arm --poses 5 --out " +
                                    (dir / "p.csv").string());
  EXPECT_EQ(unknown.status, 2);
  EXPECT_NE(unknown.out.find("--robot 'my_arm': no shipped robot of that name"), std::string::npos)
      << unknown.out;
}

// stepcal simulate --model: the twin of a calibrated robot on its campaign's rows, with the
// campaign's stated noise; a geometric model fitted on it finds what the model says.
TEST(Cli, SimulateTheRobotAModelDescribes) {
  const fs::path dir = scratch("from_model");
  ASSERT_EQ(run(kStepcal + " simulate --protocol geometry --seed 2 --out " + (dir / "camp").string() +
                " --effect '{\"name\": \"transmission_error\", \"joint\": 2, \"harmonic\": 3, "
                "\"sin_rad\": 2e-4, \"cos_rad\": 0}'").status, 0);
  diagnoseJson(dir / "camp", dir / "extended.stepcal");
  const CommandResult twin = run(kStepcal + " simulate --model " + (dir / "extended.stepcal").string() +
                                 " --seed 3 --out " + (dir / "twin").string());
  ASSERT_EQ(twin.status, 0) << twin.out;
  const Campaign real = readCampaign((dir / "camp").string());
  const Campaign simulated = readCampaign((dir / "twin").string());
  ASSERT_EQ(simulated.rows.size(), real.rows.size());
  EXPECT_EQ(simulated.tracker.position_sigma_m, real.tracker.position_sigma_m);
  for (size_t i = 0; i < real.rows.size(); ++i) EXPECT_EQ(simulated.rows[i].q_rad, real.rows[i].q_rad);
  const nlohmann::json truth = nlohmann::json::parse(readTextFile((dir / "twin" / "truth.json").string()));
  EXPECT_EQ(truth["format"], "stepcal-model-twin/1");
  EXPECT_EQ(truth["mechanisms"][0].get<std::string>().rfind("transmission_error (joint 2, ", 0), 0u)
      << truth.dump();
  // Both geometric models leave the harmonic: about as much on the twin as on the campaign.
  const double real_mm =
      validationRow(calibrateJson(dir / "camp", dir / "camp.stepcal"), "poe", 0.0)["mean_position_mm"];
  const double twin_mm =
      validationRow(calibrateJson(dir / "twin", dir / "twin.stepcal"), "poe", 0.0)["mean_position_mm"];
  std::printf("poe on the validation rows: campaign %.4f mm, its model's twin %.4f mm\n", real_mm,
              twin_mm);
  EXPECT_NEAR(twin_mm / real_mm, 1.0, 0.15);
  // A drawn robot's options do not go with --model.
  const CommandResult both = run(kStepcal + " simulate --model " + (dir / "extended.stepcal").string() +
                                 " --robot ur10 --out " + (dir / "x").string());
  EXPECT_NE(both.status, 0);
  EXPECT_NE(both.out.find("--robot"), std::string::npos) << both.out;
  const CommandResult garbage = run(kStepcal + " simulate --model " + (dir / "camp" / "campaign.yaml").string() +
                                    " --out " + (dir / "y").string());
  EXPECT_EQ(garbage.status, 2);
  EXPECT_NE(garbage.out.find("campaign.yaml"), std::string::npos) << garbage.out;
  // A malformed --off-axis-compliance: refused as bad input with the value, what was expected
  // and a hint, before anything is simulated.
  const std::vector<std::pair<std::string, std::string>> bad_tilts = {
      {"2-1.7e-7", "expected JOINT:C"},
      {"2:", "expected JOINT:C"},
      {"x:1e-7", "expected JOINT:C"},
      {"2:1e-7mm", "expected JOINT:C"},
      {"0:1e-7", "joint 0; expected a joint 1 … 6"},
      {"7:1e-7", "joint 7; expected a joint 1 … 6"},
      {"2:-1e-7", "compliance -1e-07 rad/(N·m); expected a finite value in [0, 1e-05)"},
      {"2:nan", "compliance nan rad/(N·m); expected a finite value"},
      {"2:abc", "expected JOINT:C"},
      {"2:0.5", "compliance 0.5 rad/(N·m)"}};
  for (const auto& [spec, said] : bad_tilts) {
    const CommandResult tilt = run(kStepcal + " simulate --model " +
                                   (dir / "extended.stepcal").string() +
                                   " --off-axis-compliance '" + spec + "' --out " +
                                   (dir / "tilted").string());
    EXPECT_EQ(tilt.status, 2) << spec << ": " << tilt.out;
    EXPECT_NE(tilt.out.find("--off-axis-compliance '" + spec + "'"), std::string::npos) << tilt.out;
    EXPECT_NE(tilt.out.find(said), std::string::npos) << tilt.out;
    EXPECT_NE(tilt.out.find("hint: 1:1.7e-7"), std::string::npos) << tilt.out;
    EXPECT_FALSE(fs::exists(dir / "tilted")) << spec;
  }
}

// Issue 42: a model knows its robot. The IRB4400's model given the real UR10's campaign (Series C)
// is refused by name by validate, diagnose --model, simulate --model and stepcal-client --campaign
// --check-model, a program of 7 joints by correct; so is a campaign whose joints are named alike
// in another geometry; its own campaign still validates.
TEST(Cli, AModelRefusesAnotherRobotsCampaignByName) {
  const fs::path dir = scratch("another_robot");
  ASSERT_EQ(run(kStepcal + " simulate --protocol geometry --seed 1 --out " + (dir / "irb").string()).status, 0);
  const std::string model = (dir / "irb.stepcal").string();
  calibrateJson(dir / "irb", model);
  const std::string ur10 = (dir / "ur10").string();
  const std::string csv =
      std::string(STEPCAL_TEST_DATA_DIR) + "/ipa-robot-accuracy/Series_C/measurements_random_poses.csv";
  ASSERT_EQ(run(kStepcal + " import ipa " + csv + " --out " + ur10).status, 0);
  const auto expectRefusedByName = [&](const std::string& command) {
    const CommandResult r = run(kStepcal + command);
    EXPECT_EQ(r.status, 2) << command << "\n" << r.out;
    for (const char* part : {"irb.stepcal", "the model's joints (joint_1, joint_2, joint_3, joint_4, joint_5, joint_6)",
                             "are not the campaign's (shoulder_pan_joint, shoulder_lift_joint",
                             "calibrated for"}) {
      EXPECT_NE(r.out.find(part), std::string::npos) << command << ": no '" << part << "' in\n" << r.out;
    }
  };
  expectRefusedByName(" validate " + model + " " + ur10);
  expectRefusedByName(" simulate --model " + model + " --campaign " + ur10 + " --out " + (dir / "twin").string());
  // A request names no robot: the client refuses to send the campaign's rows to the models it
  // checks the daemon's replies with.
  expectRefusedByName("-client --campaign " + ur10 + " --set geometry --check-model " + model);
  const CommandResult diagnose = run(kStepcal + " diagnose " + ur10 + " --model " + model);
  EXPECT_EQ(diagnose.status, 2) << diagnose.out;
  EXPECT_NE(diagnose.out.find("are not the campaign's (shoulder_pan_joint"), std::string::npos) << diagnose.out;

  // A program names no robot, only its joint count: one of 7 joints is refused naming the model's.
  const fs::path program = dir / "seven.csv";
  std::ofstream(program) << "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,q7_deg\n0,0,0,0,0,0,0\n";
  const CommandResult correct =
      run(kStepcal + " correct " + model + " " + program.string() + " --out " + (dir / "out.csv").string());
  EXPECT_EQ(correct.status, 2) << correct.out;
  for (const char* part : {"seven.csv", "q7_deg", "a robot with 7 joints", "a robot with 6 (joint_1, joint_2"}) {
    EXPECT_NE(correct.out.find(part), std::string::npos) << "no '" << part << "' in\n" << correct.out;
  }
  // Joints named alike in another geometry: joint_2 moved by 50 mm in the campaign's description.
  const fs::path moved = dir / "moved";
  fs::copy(dir / "irb", moved);
  std::string urdf = readTextFile((moved / "robot.urdf").string());
  const std::string origin = "<origin xyz=\"0.200 0 0.680\"";
  ASSERT_NE(urdf.find(origin), std::string::npos);
  urdf.replace(urdf.find(origin), origin.size(), "<origin xyz=\"0.250 0 0.680\"");
  std::ofstream((moved / "robot.urdf").string()) << urdf;
  const CommandResult geometry = run(kStepcal + " validate " + model + " " + moved.string());
  EXPECT_EQ(geometry.status, 2) << geometry.out;
  EXPECT_NE(geometry.out.find("differ in geometry: joint_2's nominal frame lies 50.0 mm"), std::string::npos)
      << geometry.out;
  // The robot the model was calibrated for still validates, also described by its calibrated URDF.
  const CommandResult same = run(kStepcal + " validate " + model + " " + (dir / "irb").string());
  EXPECT_EQ(same.status, 0) << same.out;
  const fs::path calibrated = dir / "calibrated";
  fs::copy(dir / "irb", calibrated);
  ASSERT_EQ(run(kStepcal + " export urdf " + model + " --campaign " + (dir / "irb").string() +
                " --out " + (calibrated / "robot.urdf").string()).status, 0);
  const CommandResult described = run(kStepcal + " validate " + model + " " + calibrated.string());
  EXPECT_EQ(described.status, 0) << described.out;
}

TEST(Cli, SimulateWritesHiddenEffectsIntoTheTruth) {
  const fs::path dir = scratch("hidden");
  const CommandResult r = run(kStepcal + " simulate --protocol geometry --seed 2 --out " + dir.string() +
                              " --effect '{\"name\": \"joint_coupling\", \"joints\": [4, 6], \"ratio\": 0.002}'");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json truth = nlohmann::json::parse(readTextFile((dir / "truth.json").string()));
  ASSERT_EQ(truth.at("effects").size(), 2u);
  EXPECT_EQ(truth.at("effects").at(1).at("name"), "joint_coupling");
  EXPECT_EQ(truth.at("effects").at(1).at("joints"), nlohmann::json({4, 6}));
  EXPECT_EQ(truth.at("effects").at(1).at("ratio"), 0.002);
}

// stepcal simulate --station: the same robot measured from another tracker placement.
TEST(Cli, SimulateAtAnotherStationMovesTheTrackerNotTheRobot) {
  const fs::path home = scratch("station_0");
  const fs::path moved = scratch("station_1");
  const std::string common = " simulate --protocol geometry --seed 4 --out ";
  ASSERT_EQ(run(kStepcal + common + home.string()).status, 0);
  const CommandResult r = run(kStepcal + common + moved.string() + " --station 1");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json a = nlohmann::json::parse(readTextFile((home / "truth.json").string()));
  const nlohmann::json b = nlohmann::json::parse(readTextFile((moved / "truth.json").string()));
  EXPECT_EQ(a.at("options").at("station"), 0);
  EXPECT_EQ(b.at("options").at("station"), 1);
  EXPECT_NE(a.at("X_TrackerBase_m"), b.at("X_TrackerBase_m"));
  EXPECT_EQ(a.at("initial_poses_m"), b.at("initial_poses_m"));
  EXPECT_EQ(a.at("effects"), b.at("effects"));
  EXPECT_NE(readCampaign(home.string()).rows[0].q_rad, readCampaign(moved.string()).rows[0].q_rad);

  const CommandResult negative = run(kStepcal + common + scratch("station_bad").string() +
                                     " --station -1");
  EXPECT_EQ(negative.status, 2);
  EXPECT_NE(negative.out.find("TwinOptions.station = -1; expected a tracker station >= 0"),
            std::string::npos)
      << negative.out;
}

TEST(Cli, SimulateWithASensorBiasOffsetsEveryReading) {
  const fs::path clean = scratch("clean");
  const fs::path biased = scratch("biased");
  const std::string common = " simulate --protocol geometry --seed 5 --out ";
  ASSERT_EQ(run(kStepcal + common + clean.string()).status, 0);
  const CommandResult r = run(kStepcal + common + biased.string() +
                              " --effect '{\"name\": \"sensor_bias\", \"force_n\": [1.5, -2, 0.8], "
                              "\"moment_nm\": [0.12, -0.05, 0.03]}'");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json truth = nlohmann::json::parse(readTextFile((biased / "truth.json").string()));
  ASSERT_EQ(truth.at("effects").size(), 2u);
  EXPECT_EQ(truth.at("effects").at(1),
            nlohmann::json::parse(R"({"name": "sensor_bias", "force_n": [1.5, -2.0, 0.8],
                                      "moment_nm": [0.12, -0.05, 0.03]})"));
  // Through the campaign files (shortest round-trip numbers): the same rows, every reading
  // offset by the bias, unloaded rows included.
  const Campaign a = readCampaign(biased.string());
  const Campaign b = readCampaign(clean.string());
  ASSERT_EQ(a.rows.size(), 130u);
  ASSERT_EQ(b.rows.size(), a.rows.size());
  Vec6 bias;
  bias << 1.5, -2.0, 0.8, 0.12, -0.05, 0.03;
  for (size_t i = 0; i < a.rows.size(); ++i) {
    EXPECT_EQ(a.rows[i].load_kg, 0.0);
    EXPECT_EQ(a.rows[i].p_TipInTracker_m, b.rows[i].p_TipInTracker_m);
    EXPECT_EQ(a.rows[i].temp_c, b.rows[i].temp_c);
    EXPECT_LT((a.rows[i].wrench_Sensor - b.rows[i].wrench_Sensor - bias).cwiseAbs().maxCoeff(), 1e-14)
        << "row " << i + 1;
  }
}

// What the diagnosis answers on the real UR10 Series C stays what it was when
// tests/data/diagnosis/ur10-series-c.json was written (its timing left out, numbers to 9 digits):
// first before the screening matrix stopped being held whole (issue 32), written again when the
// drift candidates joined the catalogue (a registration drift in time order found after the six
// profiles; every other answer within the tolerances below), when the verdict gained its
// unexplained part (its `unexplained` object added, every other answer as it was), when a
// time-order family had to be told apart from what moves with its driver (issue 43:
// drift.time_order_correlations and drift.confound_tests added, the drift text, and 11
// registration-drift candidates of rounds 4–8 no longer significant: confounded with the
// temperature; the effects and every number the same), when off_axis_compliance joined the
// catalogue (its one untestable entry added: no loaded row) and when a candidate came to be fitted
// within its physics' bounds (impossible_unbounded added), and when the verdict came to report
// the pairs of families the rows may not tell apart (family_pairs: the cubic registration drift
// of round 8 against joint 4's zero drift, ρ 0.75, told apart), the geometry pin (geometry_pin:
// not tested, every fit row unloaded) and the arm's own weight as six candidate variables of the
// unexplained part (variables_tested 86 → 92 and its text; nothing significant), and when a
// global cause had to explain its gain beside a joint's torque modulated by its angle
// (modulated_stand_in.cpp: a joint_zero_drift of joint 4 of round 7, never chosen, no longer
// significant beside joint 6's weight times harmonics 1–16 of its angle: 0.99 % of the round's
// error, under the 1 % minimum), and when tool_mount_compliance joined the catalogue (its one
// untestable entry added: no loaded row); every other answer the same. Strings, counts and flags must be
// equal; numbers
// within 1e-4 relative, a signed-rank z and its p-value within 1e-2 (one rank's step moves z by
// 6e-4 relative, and p by 2e-4), held-out gains and reductions also within 1e-5 absolute (mm, or a
// fraction of the held-out error), a self weight's masses and first moments also within 1e-6 kg or
// kg m (those the data leave to their prior sit at round-off, 1e-12, whose digits follow the order
// of a sum). Measured when it was made: at most 8e-6 relative outside those,
// 9e-7 absolute on a reduction (the global refit's Gauss-Newton stops within 1e-6 of its cost).
// After a change meant to change the answers, write the file again: `stepcal import ipa
// tests/data/ipa-robot-accuracy/Series_C/measurements_random_poses.csv --out DIR`, then
// `stepcal diagnose DIR --json`, without timing_s.
void expectSameAnswers(const nlohmann::json& stored, const nlohmann::json& now,
                       const std::string& path, int& differences) {
  if (differences > 20) return;
  const auto differ = [&](const std::string& what) {
    ++differences;
    ADD_FAILURE() << path << ": " << what;
  };
  if (stored.is_number_float() || (stored.is_number() && now.is_number_float())) {
    if (!now.is_number()) return differ("a number before, now " + now.dump());
    const std::string key = path.substr(path.find_last_of('.') + 1);
    const bool rank_statistic =
        key == "z_statistic" || key == "p_value" || key == "z" || key == "learner_z";
    const bool gain = key == "cv_gain_mm" || key == "relative_reduction" ||
                      key == "learner_gain_mm" || key == "learner_relative_reduction";
    const bool lumped_mass = key.size() > 3 && (key.compare(key.size() - 3, 3, "_kg") == 0 ||
                                                key.compare(key.size() - 4, 4, "_kgm") == 0);
    const double a = stored.get<double>(), b = now.get<double>();
    const double tolerance = (rank_statistic ? 1e-2 : 1e-4) * std::max(std::abs(a), std::abs(b)) +
                             (gain ? 1e-5 : lumped_mass ? 1e-6 : 1e-300);
    if (!(std::abs(a - b) <= tolerance)) differ(stored.dump() + " before, now " + now.dump());
    return;
  }
  if (stored.type() != now.type()) return differ(stored.dump() + " before, now " + now.dump());
  if (stored.is_object()) {
    for (const auto& [key, value] : stored.items()) {
      if (!now.contains(key)) {
        differ("'" + key + "' is gone");
        continue;
      }
      expectSameAnswers(value, now[key], path + "." + key, differences);
    }
    for (const auto& [key, value] : now.items()) {
      if (key != "timing_s" && !stored.contains(key)) differ("'" + key + "' is new");
    }
  } else if (stored.is_array()) {
    if (stored.size() != now.size()) {
      return differ(std::to_string(stored.size()) + " entries before, now " + std::to_string(now.size()));
    }
    for (size_t i = 0; i < stored.size(); ++i) {
      expectSameAnswers(stored[i], now[i], path + "[" + std::to_string(i) + "]", differences);
    }
  } else if (stored != now) {
    differ(stored.dump() + " before, now " + now.dump());
  }
}

// `stepcal diagnose DIR --json` against the JSON stored in tests/data/diagnosis/ (expectSameAnswers).
void expectTheStoredDiagnosis(const fs::path& dir, const std::string& stored_file) {
  const CommandResult diagnose = run(kStepcal + " diagnose " + dir.string() + " --json 2>/dev/null");
  ASSERT_EQ(diagnose.status, 0) << diagnose.out;
  const nlohmann::json now = nlohmann::json::parse(diagnose.out.substr(diagnose.out.find('{')));
  const nlohmann::json stored = nlohmann::json::parse(
      readTextFile(std::string(STEPCAL_TEST_DATA_DIR) + "/diagnosis/" + stored_file));
  int differences = 0;
  expectSameAnswers(stored, now, "", differences);
  EXPECT_EQ(differences, 0);
}

TEST(Cli, TheDiagnosisOfUr10SeriesCIsTheStoredOne) {
  const fs::path dir = scratch("ur10_series_c");
  const std::string csv =
      std::string(STEPCAL_TEST_DATA_DIR) + "/ipa-robot-accuracy/Series_C/measurements_random_poses.csv";
  const CommandResult import = run(kStepcal + " import ipa " + csv + " --out " + dir.string());
  ASSERT_EQ(import.status, 0) << import.out;
  expectTheStoredDiagnosis(dir, "ur10-series-c.json");
}

// The same for a simulated campaign, the stress run's seed 3 (a coupling of joint 4 into 6 and a
// nonlinear stiffness on joints 2 and 3: couplings, torque-driven families, profiles, the sensor
// bias and the self weight screened, three causes found and refitted): what `stepcal diagnose`
// wrote before its screening matrix was made chunk by chunk wherever its rows are needed instead
// of stored (issue 32), tests/data/diagnosis/twin-stress-seed-3.json, the same tolerances; written
// again when the drift candidates joined the catalogue (their scores added, every other answer
// the same), when the verdict gained its unexplained part (its `unexplained` object added), when
// a time-order family had to be told apart from what moves with its driver (issue 43: the drift's
// new fields and text, and its 7 candidates of rounds 1–3 no longer significant: a frame per load
// block explains what they did; the effects the same), when the extended model's GPR came to
// learn the residual per payload force (issue 43: not taken on this campaign, z 0.76, so its
// extended+gpr figures are the extended model's), when off_axis_compliance joined the catalogue
// (20 candidates added, none significant, and its untestable entry for the wrist's middle joint)
// and when a candidate came to be fitted within its physics' bounds (impossible_unbounded added),
// and when the verdict came to report the pairs of families the rows may not tell apart
// (family_pairs) and the geometry pin (geometry_pin: not pinned, F 0.7), and when a global cause
// had to explain its gain beside a joint's torque modulated by its angle (modulated_stand_in.cpp:
// a coupling 2 → 3 of round 2 and a self weight of round 3, neither in the data, no longer
// significant, with their modulated_stand_in; the nonlinear stiffness of joint 3 chosen at the
// neighbouring τ₀ of its grid, τ₀ 155.39 → 155.42 N·m after the refit), and when
// tool_mount_compliance joined the catalogue (4 candidates added, one a round, none significant);
// every other answer the same. Made again after a change meant to change the answers:
// `stepcal-diagnose-stress --seeds 3`, then `stepcal diagnose OUT/seed-3 --json` without timing_s.
TEST(Cli, TheDiagnosisOfATwinMixIsTheStoredOne) {
  const fs::path dir = scratch("twin_stress_seed_3");
  std::string simulate = kStepcal + " simulate --seed 3 --out " + dir.string();
  for (const twin::DrawnMechanism& drawn : twin::drawMechanismMix(3)) {
    simulate += " --effect '" + drawn.effect.dump() + "'";
  }
  const CommandResult simulated = run(simulate + " 2>&1");
  ASSERT_EQ(simulated.status, 0) << simulated.out;
  expectTheStoredDiagnosis(dir, "twin-stress-seed-3.json");
}

}  // namespace
}  // namespace stepcal
