// `stepcal correct` (tools/cli/correct.cpp): a 500-target offline program (the nominal joint
// targets of another seed's poses, with their payloads) run on the twin as commanded and as
// corrected: the corrected targets land at the model's own error against the truth; pose targets
// in a user frame, with a tool from the flange, come back to their joints; bad program files are
// refused with the file, line and column.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/csv.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/command.hpp"
#include "support/files.hpp"

namespace stepcal {
namespace {

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";

/// A simulated cell (seed 1, the paper protocol), calibrated, and an offline program's poses (the
/// rows of seed 5), made once for the binary with the stepcal command.
struct Cell {
  std::string dir, model, truth, olp;
};
const Cell& cell() {
  static const test::TempDir dir;
  static const Cell c = [] {
    Cell out;
    out.dir = dir.path().string();
    out.model = out.dir + "/model.stepcal";
    out.truth = out.dir + "/cell/truth.json";
    out.olp = out.dir + "/olp";
    const test::CommandResult r = test::run(
        kStepcal + " simulate --seed 1 --out " + out.dir + "/cell && " + kStepcal + " calibrate " +
        out.dir + "/cell --out " + out.model + " && " + kStepcal + " simulate --seed 5 --out " +
        out.olp);
    EXPECT_EQ(r.status, 0) << r.out;
    return out;
  }();
  return c;
}

/// The rows of a corrected program: column name → text, per line.
std::vector<std::map<std::string, std::string>> readCsv(const std::string& path) {
  const std::string text = test::readText(path);
  const std::vector<std::string_view> lines = splitLines(text);
  std::vector<std::map<std::string, std::string>> rows;
  if (lines.empty()) return rows;
  const std::vector<std::string_view> names = splitFields(lines[0]);
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string_view> fields = splitFields(lines[i]);
    EXPECT_EQ(fields.size(), names.size()) << path << ":" << i + 1;
    std::map<std::string, std::string> row;
    for (size_t k = 0; k < names.size() && k < fields.size(); ++k) {
      row[std::string(names[k])] = std::string(fields[k]);
    }
    rows.push_back(row);
  }
  return rows;
}

double number(const std::string& text) {
  const std::optional<double> v = parseFinite(text);
  EXPECT_TRUE(v) << inQuotes(text);
  return v.value_or(NAN);
}

// 500 nominal joint targets with their payloads, as an offline programming tool writes them:
// on the twin, as commanded they miss by the nominal model's millimetres; as corrected they land
// where the model's own error against the truth says (docs/runtime.md, "Correcting an offline
// program": 4.8 mm → 0.006 mm).
TEST(Correct, AProgramOf500TargetsLandsAtTheModelsError) {
  const Cell& c = cell();
  const Campaign olp = readCampaign(c.olp);
  const test::TempDir dir;
  const std::string program = (dir.path() / "program.csv").string();
  {
    std::ofstream out(program);
    out << "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,payload_kg,cog_x_mm,cog_y_mm,cog_z_mm,"
           "cog_frame\n";
    // The twin's payload: its centre of gravity (30, −20, 150) mm in the sensor frame, which
    // sits 45 mm along the flange's z.
    for (size_t i = 0; i < 500; ++i) {
      const Measurement& row = olp.rows[i];
      out << row.pose_id;
      for (int j = 0; j < 6; ++j) out << "," << formatShortest(row.q_rad[j] / kRadPerDeg);
      out << "," << formatShortest(row.load_kg) << ",30,-20,195,flange\n";
    }
  }
  const std::string corrected = (dir.path() / "corrected.csv").string();
  const test::CommandResult r = test::run(kStepcal + " correct " + c.model + " " + program +
                                          " --out " + corrected + " --truth " + c.truth + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json summary = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_EQ(summary["lines"], 500);
  EXPECT_EQ(summary["statuses"]["OK"], 500) << summary.dump();
  EXPECT_EQ(summary["in_coverage"], 500);

  // The model's own error against the truth, at its validation poses (the validation figure
  // without the tracker's noise).
  const auto model = runtime::RuntimeModel::load(c.model);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  std::ifstream truth_in(c.truth);
  const twin::TwinRobot truth = twin::TwinRobot::fromTruthJson(nlohmann::json::parse(truth_in));
  double model_sum_m = 0.0;
  int model_rows = 0;
  for (const Measurement* row : readCampaign(c.dir + "/cell").rowsIn(RowSet::kValidation)) {
    const Pose X = runtime::correctForward(*model, ws, row->q_rad, row->wrenchOrZero(),
                                           runtime::kUnknownTemperature_c).X_TrackerTip;
    model_sum_m += (X.translation() - truth.X_TrackerTip(row->q_rad, row->load_kg).translation()).norm();
    ++model_rows;
  }
  const double model_mm = model_sum_m / model_rows * 1e3;
  const double commanded_mm = summary["error_commanded"]["mean_position_mm"].get<double>();
  const double corrected_mm = summary["error_corrected"]["mean_position_mm"].get<double>();
  double measured_validation_mm = 0.0;  // the stored figure, against the tracker's measurements
  for (const auto& v : summary["model_validation"]) {
    if (v["method"] == "poe+stiffness+gpr" && v["load_kg"] == 30.0) {
      measured_validation_mm = v["mean_position_mm"].get<double>();
    }
  }
  std::printf("500 targets on the twin: as commanded %.4f mm, as corrected %.4f mm (max %.4f); the "
              "model against the truth at its validation poses %.4f mm, against the measurements "
              "%.4f mm (30 kg)\n",
              commanded_mm, corrected_mm,
              summary["error_corrected"]["max_position_mm"].get<double>(), model_mm,
              measured_validation_mm);
  EXPECT_GT(commanded_mm, 1.0);
  EXPECT_LT(corrected_mm, 2.0 * model_mm);
  EXPECT_GT(corrected_mm, 0.5 * model_mm);
  EXPECT_LT(corrected_mm, measured_validation_mm);

  // Per line: the same figures, and joint targets the twin takes to the nominal pose.
  const auto rows = readCsv(corrected);
  ASSERT_EQ(rows.size(), 500u);
  double sum_after = 0.0;
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].at("line"), std::to_string(i + 2));
    EXPECT_EQ(rows[i].at("id"), olp.rows[i].pose_id);
    EXPECT_EQ(rows[i].at("target"), "joints");
    EXPECT_EQ(rows[i].at("status"), "OK");
    EXPECT_EQ(rows[i].at("in_coverage"), "yes");
    EXPECT_LT(number(rows[i].at("residual_mm")), 1e-3);
    sum_after += number(rows[i].at("error_corrected_mm"));
    JointVector q(6);
    for (int j = 0; j < 6; ++j) q[j] = number(rows[i].at("q" + std::to_string(j + 1) + "_deg")) * kRadPerDeg;
    runtime::CallTerms terms;
    const Pose X_desired = runtime::nominalTcp(*model, ws, olp.rows[i].q_rad, terms);
    EXPECT_LT((truth.X_TrackerTip(q, olp.rows[i].load_kg).translation() - X_desired.translation()).norm(),
              0.05e-3);
  }
  EXPECT_NEAR(sum_after / 500, corrected_mm, 1e-5);
}

// Pose targets in a user frame with a tool from the flange and a payload: the model's own poses
// at known joints, asked for from a seed 2° off (the first line) and from the line before (the
// others), come back to those joints; the pre-distorted pose is in the user frame.
TEST(Correct, PoseTargetsInAUserFrameComeBackToTheirJoints) {
  const Cell& c = cell();
  const auto model = runtime::RuntimeModel::load(c.model);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  const Campaign olp = readCampaign(c.olp);
  runtime::CallTerms terms;
  terms.frame = runtime::PoseFrame::kUser;
  terms.X_BaseUser.translation() = Vec3(1.5, -0.2, 0.3);
  terms.X_BaseUser.linear() = Eigen::AngleAxisd(0.5, Vec3::UnitZ()).toRotationMatrix();
  terms.tool_from = runtime::ToolFrom::kFlange;
  terms.X_Tool.translation() = Vec3(0.0, 0.0, 0.35);
  terms.load_from = runtime::LoadFrom::kPayload;
  terms.payload.mass_kg = 25.0;
  terms.payload.frame = runtime::CogFrame::kTool;
  terms.payload.p_CoG_m = Vec3(0.0, 0.0, -0.1);
  const test::TempDir dir;
  const std::string program = (dir.path() / "program.csv").string();
  std::vector<JointVector> joints;
  {
    std::ofstream out(program);
    out << "x_mm,y_mm,z_mm,qw,qx,qy,qz,seed_q1_deg,seed_q2_deg,seed_q3_deg,seed_q4_deg,"
           "seed_q5_deg,seed_q6_deg,tool_from,tool_x_mm,tool_y_mm,tool_z_mm,tool_qw,tool_qx,"
           "tool_qy,tool_qz,payload_kg,cog_x_mm,cog_y_mm,cog_z_mm,cog_frame,temp_c\n";
    // Consecutive poses of one block: each close to the one before, as along a path.
    for (size_t i = 0; i < 20; ++i) {
      JointVector q = olp.rows[0].q_rad;
      for (int j = 0; j < 6; ++j) q[j] += 0.01 * double(i) * (j % 2 ? 1 : -1);
      joints.push_back(q);
      const Pose X = runtime::correctForward(*model, ws, q, terms, 22.0).X_FrameTcp;
      const Eigen::Quaterniond r(X.linear());
      out << formatShortest(X.translation().x() * 1e3) << "," << formatShortest(X.translation().y() * 1e3)
          << "," << formatShortest(X.translation().z() * 1e3) << "," << formatShortest(r.w()) << ","
          << formatShortest(r.x()) << "," << formatShortest(r.y()) << "," << formatShortest(r.z());
      for (int j = 0; j < 6; ++j) {
        out << "," << (i == 0 ? formatShortest(q[j] / kRadPerDeg + 2.0 * (j % 2 ? 1 : -1)) : "");
      }
      out << ",flange,0,0,350,1,0,0,0,25,0,0,-100,tool,22\n";
    }
  }
  const std::string corrected = (dir.path() / "corrected.csv").string();
  const test::CommandResult r =
      test::run(kStepcal + " correct " + c.model + " " + program + " --out " + corrected +
                " --frame user --user-frame 1500 -200 300 " + formatShortest(std::cos(0.25)) +
                " 0 0 " + formatShortest(std::sin(0.25)));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("20 lines: 20 OK"), std::string::npos) << r.out;
  const auto rows = readCsv(corrected);
  ASSERT_EQ(rows.size(), 20u);
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].at("target"), "pose");
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(number(rows[i].at("q" + std::to_string(j + 1) + "_deg")) * kRadPerDeg, joints[i][j], 2e-5)
          << "line " << i + 2;
    }
    JointVector q(6);
    for (int j = 0; j < 6; ++j) q[j] = number(rows[i].at("q" + std::to_string(j + 1) + "_deg")) * kRadPerDeg;
    const Pose X_nominal = runtime::nominalTcp(*model, ws, q, terms);
    EXPECT_NEAR(number(rows[i].at("x_mm")), X_nominal.translation().x() * 1e3, 1e-5);
    EXPECT_NEAR(number(rows[i].at("z_mm")), X_nominal.translation().z() * 1e3, 1e-5);
  }
}

// A program of which some targets cannot be corrected (poses 10 m out of reach) is still written,
// each line with its status, but the exit status says it was done in part (3) and stderr how
// many lines were not corrected: a script cannot take it for a corrected program.
TEST(Correct, APartlyCorrectedProgramExitsDoneInPart) {
  const Cell& c = cell();
  const Campaign olp = readCampaign(c.olp);
  const test::TempDir dir;
  const std::string program = (dir.path() / "program.csv").string();
  {
    std::ofstream out(program);
    out << "id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n";
    const auto model = runtime::RuntimeModel::load(c.model);
    runtime::Workspace ws = runtime::makeWorkspace(*model);
    for (size_t i = 0; i < 4; ++i) {
      const Pose X = runtime::correctForward(*model, ws, olp.rows[0].q_rad, runtime::CallTerms{},
                                             runtime::kUnknownTemperature_c)
                         .X_FrameTcp;
      const Eigen::Quaterniond q(X.linear());
      const double far_mm = i % 2 ? 10000.0 : 0.0;  // every other target out of reach
      out << "t" << i << "," << formatShortest(X.translation().x() * 1e3 + far_mm) << ","
          << formatShortest(X.translation().y() * 1e3) << ","
          << formatShortest(X.translation().z() * 1e3) << "," << formatShortest(q.w()) << ","
          << formatShortest(q.x()) << "," << formatShortest(q.y()) << "," << formatShortest(q.z())
          << "\n";
    }
  }
  std::string seed;
  for (int j = 0; j < 6; ++j) seed += " " + formatShortest(olp.rows[0].q_rad[j] / kRadPerDeg);
  const std::string corrected = (dir.path() / "corrected.csv").string();
  const test::CommandResult r = test::run(kStepcal + " correct " + c.model + " " + program +
                                          " --out " + corrected + " --seed" + seed);
  EXPECT_EQ(r.status, 3) << r.out;
  EXPECT_NE(r.out.find("stepcal correct: 2 of 4 lines not corrected"), std::string::npos) << r.out;
  const auto rows = readCsv(corrected);
  ASSERT_EQ(rows.size(), 4u);
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].at("status") == "OK", i % 2 == 0) << "line " << i + 2 << ": " << rows[i].at("status");
  }
  const test::CommandResult json = test::run(kStepcal + " correct " + c.model + " " + program +
                                             " --out " + corrected + " --seed" + seed + " --json");
  EXPECT_EQ(json.status, 3) << json.out;
  const size_t begin = json.out.find('{'), end = json.out.rfind('}');
  EXPECT_EQ(nlohmann::json::parse(json.out.substr(begin, end + 1 - begin))["not_corrected"], 2)
      << json.out;
}

// Every error in a program names the file, its line and its column.
TEST(Correct, BadProgramsAreRefusedWithTheirLineAndColumn) {
  const Cell& c = cell();
  const test::TempDir dir;
  const std::string path = (dir.path() / "program.csv").string();
  const std::string header = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,payload_kg";
  const std::string good = "a,10,-20,30,0,40,0,20";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", ":1: the header line is empty"},
      {header + ",speed\n" + good + ",3\n", ":1: column 'speed': unknown column"},
      {header + ",q1_deg\n" + good + ",1\n", ":1: column 'q1_deg': appears twice (column 9)"},
      {"id,q1_deg,q2_deg,q4_deg\n", ":1: column 'q3_deg': missing while other joint target columns"},
      {"id,q1_deg,q2_deg\n",
       ":1: column 'q2_deg': joint targets q1_deg … q2_deg are of a robot with 2 joints; the model was "
       "calibrated for a robot with 6 (joint_1, joint_2, joint_3, joint_4, joint_5, joint_6), "
       "expected q1_deg … q6_deg"},
      {header + ",q7_deg\n" + good + ",0\n", ":1: column 'q7_deg': joint targets q1_deg … q7_deg"},
      {"id,x_mm,y_mm\n", ":1: column 'z_mm': missing while other pose columns"},
      {"id,payload_kg\na,3\n", ":1: no target columns"},
      {header + "\n" + good + "\n" + "b,10,-20,30,0,40\n", ":3: 6 fields; expected 8"},
      {header + "\n" + good + "\nb,10,-20,x30,0,40,0,20\n",
       ":3: column 'q3_deg': 'x30' is not a number (column 4)"},
      {header + "\n" + good + "\nb,10,-20,30,,40,0,20\n",
       ":3: column 'q4_deg': empty (column 5) while other joint target columns are filled"},
      {header + "\nb,10,-20,30,0,40,0,-5\n", ":2: column 'payload_kg': negative (column 8)"},
      {header + "\nb,10,-20,30,0,40,0,nan\n", ":2: column 'payload_kg': 'nan' is not a number"},
      {header + "\n" + good + "\n\n" + good + "\n", ":3: empty line"},
      {header + "\n", ":1: no targets after the header"},
      {"x_mm,y_mm,z_mm,qw,qx,qy,qz\n1000,0,1500,1,0,0,0\n", ":2: column 'x_mm': a pose target needs a seed"},
      {"x_mm,y_mm,z_mm,qw,qx,qy,qz,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n"
       "1000,0,1500,1,0,0,0,10,-20,30,0,40,0\n",
       ":2: both a pose and a joint target"},
      {"x_mm,y_mm,z_mm,qw,qx,qy,qz,seed_q1_deg,seed_q2_deg,seed_q3_deg,seed_q4_deg,seed_q5_deg,"
       "seed_q6_deg\n1000,0,1500,1,0.1,0,0,0,0,0,0,0,0\n",
       ":2: column 'qw': the quaternion qw … qz has norm"},
      {header + ",tool_from\n" + good + ",target\n", ":1: column 'tool_from': without the tool columns"},
      {header + ",tool_from,tool_x_mm,tool_y_mm,tool_z_mm,tool_qw,tool_qx,tool_qy,tool_qz\n" + good +
           ",wrist,0,0,100,1,0,0,0\n",
       ":2: column 'tool_from': 'wrist' (column 9); expected target or flange"},
      {header + ",temp_c\n" + good + ",200\n", ":2: column 'temp_c': 200 °C (column 9)"},
      {header + ",cog_frame\n" + good + ",tool\n", ":1: column 'cog_frame': without cog_x_mm"},
      {"id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\na,1,2,3,4,5,6" + std::string(1, '\0') + "\n",
       ":2: holds a NUL byte"},
  };
  for (const auto& [text, expected] : cases) {
    test::writeText(path, text);
    const test::CommandResult r = test::run(kStepcal + " correct " + c.model + " " + path +
                                            " --out " + (dir.path() / "out.csv").string());
    EXPECT_EQ(r.status, 2) << expected << ": " << r.out;
    EXPECT_NE(r.out.find(path + expected), std::string::npos) << "expected " << expected << ": " << r.out;
    EXPECT_FALSE(std::filesystem::exists(dir.path() / "out.csv")) << "nothing written: " << r.out;
  }
  // Options: a frame without its transform, a seed of the wrong size, a missing model.
  test::writeText(path, header + "\n" + good + "\n");
  for (const auto& [args, expected] : std::vector<std::pair<std::string, std::string>>{
           {"--frame user", "--user-frame x y z qw qx qy qz goes with --frame user"},
           {"--frame shop", "--frame 'shop': expected tracker, base or user"},
           {"--seed 1 2 3", "--seed has 3 angles; the model has 6 joints"},
           {"--frame user --user-frame 0 0 0 2 0 0 0", "--user-frame: the quaternion has norm 2"}}) {
    const test::CommandResult r = test::run(kStepcal + " correct " + c.model + " " + path +
                                            " --out " + (dir.path() / "out.csv").string() + " " + args);
    EXPECT_EQ(r.status, 2) << args << ": " << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << args << ": " << r.out;
  }
}

// A folder given for the program or the model is named as such, in one line.
TEST(Correct, AFolderGivenForAFileIsNamedAsSuch) {
  const Cell& c = cell();
  const test::TempDir dir;
  const std::string program = (dir.path() / "program.csv").string();
  test::writeText(program, "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\na,10,-20,30,0,40,0\n");
  const std::string folder = dir.path().string();
  for (const auto& [args, expected] : std::vector<std::pair<std::string, std::string>>{
           {c.model + " " + folder, folder + ": is a folder; expected a file"},
           {folder + " " + program, folder + ": is a folder; expected a stepcal model file"}}) {
    const test::CommandResult r =
        test::run(kStepcal + " correct " + args + " --out " + (dir.path() / "out.csv").string());
    EXPECT_NE(r.status, 0) << args << ": " << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << args << ": " << r.out;
  }
}

// A program's end of file (csv.hpp's rule): the last newline is optional, CRLF reads as LF, a
// UTF-8 byte-order mark is skipped, and, unlike a campaign's measurements.csv, one blank line at
// the end is skipped; a second is refused.
TEST(Correct, AProgramsLineEndsDoNotChangeItsTargets) {
  const Cell& c = cell();
  const test::TempDir dir;
  const std::string path = (dir.path() / "program.csv").string();
  const std::string out = (dir.path() / "out.csv").string();
  const std::string header = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg";
  const std::string a = "a,10,-20,30,0,40,0", b = "b,-5,15,20,10,-30,45";
  auto correct = [&](const std::string& text) {
    test::writeText(path, text);
    const test::CommandResult r =
        test::run(kStepcal + " correct " + c.model + " " + path + " --out " + out);
    return r.status == 0 ? test::readText(out) : "status " + std::to_string(r.status) + ": " + r.out;
  };
  const std::string expected = correct(header + "\n" + a + "\n" + b + "\n");
  ASSERT_EQ(expected.rfind("status ", 0), std::string::npos) << expected;
  for (const std::string& text : {header + "\n" + a + "\n" + b,
                                  header + "\r\n" + a + "\r\n" + b + "\r\n",
                                  header + "\n" + a + "\n" + b + "\n\n",
                                  "\xEF\xBB\xBF" + header + "\n" + a + "\n" + b + "\n"}) {
    EXPECT_EQ(correct(text), expected) << text;
  }
  const std::string refused = correct(header + "\n" + a + "\n" + b + "\n\n\n");
  EXPECT_NE(refused.find(path + ":4: empty line"), std::string::npos) << refused;
}

}  // namespace
}  // namespace stepcal
