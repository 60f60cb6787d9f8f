// The robot's own programs (tools/programs, `stepcal correct` on KRL, RAPID, URScript and Fanuc
// TP): real program files read and written back byte-identical; a replaced target changes its
// numbers and nothing else; garbage and truncated programs refused by line and column; and on
// the twin, a program of 240 targets per language (a tool 0.3 m out, a base frame, both wrist
// configurations) corrected by `stepcal correct` and then run as a controller would run it:
// each written pose through the nominal inverse from the joints before it, on the twin's truth;
// the same with the tool calibrated on the model (`stepcal tool`, then `--tool-file`).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/closed_form_ik.hpp"
#include "stepcal/common/robot_configuration.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/programs/configuration.hpp"
#include "stepcal/programs/program.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/command.hpp"
#include "support/files.hpp"

namespace stepcal {
namespace {

using programs::Language;

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";
const std::string kPrograms = std::string(STEPCAL_TEST_DATA_DIR) + "/programs/";

struct Fixture {
  const char* file;
  Language language;
  size_t targets, not_literals;
};
// The real files of tests/data/programs (SOURCES.md): each one's literal targets and the
// targets it computes at run time.
const std::vector<Fixture> kFixtures = {
    {"Program.src", Language::kKrl, 6, 1},        {"Program.mod", Language::kRapid, 6, 0},
    {"Prog1.script", Language::kUrScript, 6, 0},  {"UniveralRobots.script", Language::kUrScript, 12, 0},
    {"Program.LS", Language::kFanucTp, 6, 0},
    {"ROS_common.sys", Language::kRapid, 0, 0},   {"ROS_messages.sys", Language::kRapid, 0, 0},
    {"ROS_motion.mod", Language::kRapid, 0, 1},   {"ROS_motionServer.mod", Language::kRapid, 0, 0},
    {"ROS_socket.sys", Language::kRapid, 0, 0},   {"ROS_stateServer.mod", Language::kRapid, 0, 0},
    {"kuka_eki_hw_interface.src", Language::kKrl, 0, 0}, {"kuka_eki_hw_interface.dat", Language::kKrl, 0, 0},
    {"ros_rsi_KR_C2.src", Language::kKrl, 1, 1},  {"ros_rsi_KR_C4.src", Language::kKrl, 2, 0},
};

programs::Program read(Language language, const std::string& text, const std::string& path = "p") {
  return programs::readProgram(language, text, path);
}

TEST(Programs, RealFilesComeBackByteIdenticalWithTheirOwnTargets) {
  for (const Fixture& f : kFixtures) {
    const std::string path = kPrograms + f.file;
    const std::string text = test::readText(path);
    EXPECT_EQ(programs::languageOf(path, ""), f.language) << f.file;
    const programs::Program p = read(f.language, text, path);
    EXPECT_EQ(p.targets.size(), f.targets) << f.file;
    EXPECT_EQ(p.not_literals.size(), f.not_literals) << f.file;
    std::vector<programs::Replacement> same;
    for (size_t i = 0; i < p.targets.size(); ++i) same.push_back({i, p.targets[i].X_FrameTcp, p.targets[i].q_rad});
    EXPECT_EQ(programs::writeProgram(p, text, same), text) << f.file;
  }
}

/// The text with every target's number fields cut out: what a rewrite must keep.
std::string withoutTargets(const programs::Program& p, const std::string& text) {
  std::vector<std::pair<size_t, size_t>> spans;
  for (const programs::Target& t : p.targets) {
    for (const programs::NumberField& f : t.fields) spans.emplace_back(f.begin, f.end);
  }
  std::sort(spans.begin(), spans.end());
  std::string out;
  size_t at = 0;
  for (const auto& [b, e] : spans) {
    out += text.substr(at, b - at) + "#";
    at = e;
  }
  return out + text.substr(at);
}

// Every target moved 1.5 mm along x and turned 0.2° about z (joints by 0.2°): read back, each is
// where it was put (to the digits written), and the text between the numbers is the same bytes.
TEST(Programs, AReplacedTargetChangesItsNumbersAndNothingElse) {
  for (const Fixture& f : kFixtures) {
    const std::string text = test::readText(kPrograms + f.file);
    const programs::Program p = read(f.language, text);
    std::vector<programs::Replacement> moved;
    for (size_t i = 0; i < p.targets.size(); ++i) {
      programs::Replacement r{i, p.targets[i].X_FrameTcp, p.targets[i].q_rad};
      r.X_FrameTcp.translation().x() += 1.5e-3;
      r.X_FrameTcp.linear() = Eigen::AngleAxisd(0.2 * kRadPerDeg, Vec3::UnitZ()) * r.X_FrameTcp.linear();
      r.q_rad.array() += 0.2 * kRadPerDeg;
      moved.push_back(r);
    }
    const std::string out = programs::writeProgram(p, text, moved);
    const programs::Program back = read(f.language, out);
    ASSERT_EQ(back.targets.size(), p.targets.size()) << f.file;
    EXPECT_EQ(withoutTargets(back, out), withoutTargets(p, text)) << f.file;
    for (size_t i = 0; i < p.targets.size(); ++i) {
      const programs::Target& t = back.targets[i];
      if (t.kind == programs::TargetKind::kJoint) {
        EXPECT_LT((t.q_rad - moved[i].q_rad).cwiseAbs().maxCoeff(), 1e-6) << f.file << ":" << t.line;
      } else {
        EXPECT_LT((t.X_FrameTcp.translation() - moved[i].X_FrameTcp.translation()).norm(), 1e-6) << f.file << ":" << t.line;
        EXPECT_LT(lie::angleBetween(t.X_FrameTcp.linear(), moved[i].X_FrameTcp.linear()), 2e-6) << f.file << ":" << t.line;
      }
    }
  }
}

// A number written against its name (A4-0.5, found by mutating the real files) that loses its
// sign is written apart from the name, not merged into it (A40.5 would be another component).
TEST(Programs, ANumberThatLosesItsSignStaysApartFromItsName) {
  const std::string text = "DEF a()\nPTP {A1 1,A2 -90,A3 90,A4-0.5,A5 45,A6 0}\nEND\n";
  const programs::Program p = read(Language::kKrl, text);
  ASSERT_EQ(p.targets.size(), 1u);
  programs::Replacement r{0, Pose::Identity(), p.targets[0].q_rad};
  r.q_rad[3] = 0.5 * kRadPerDeg;
  const std::string out = programs::writeProgram(p, text, {r});
  EXPECT_EQ(out, "DEF a()\nPTP {A1 1.0000,A2 -90.0000,A3 90.0000,A4 0.5000,A5 45.0000,A6 0.0000}\nEND\n");
  EXPECT_EQ(read(Language::kKrl, out).targets.size(), 1u);
}

/// The refusal of `text`: its line and column, "line:column" ("" when it is read).
std::string refusal(Language language, const std::string& text) {
  try {
    read(language, text);
  } catch (const InputError& e) {
    return std::to_string(e.line()) + ":" + e.column();
  }
  return "";
}

/// Whether a KRL text's last statement (comments and blank lines aside) ends a routine.
bool endsAfterARoutine(const std::string& text) {
  std::string last;
  size_t at = 0;
  while (at < text.size()) {
    const size_t end = std::min(text.find('\n', at), text.size());
    std::string line = text.substr(at, end - at);
    line = line.substr(0, line.find(';'));
    line.erase(0, std::min(line.size(), line.find_first_not_of(" \t\r")));
    line.erase(line.find_last_not_of(" \t\r") + 1);
    if (!line.empty()) last = line;
    at = end + 1;
  }
  for (char& c : last) c = char(std::tolower(static_cast<unsigned char>(c)));
  return last == "end" || last == "endfct" || last == "enddat";
}

// Every real file cut short, at every line end and in the middle of every target, is refused
// with a line and a column, never read as a shorter program.
TEST(Programs, TruncatedProgramsAreRefusedByLineAndColumn) {
  for (const Fixture& f : kFixtures) {
    const std::string text = test::readText(kPrograms + f.file);
    const programs::Program p = read(f.language, text);
    std::vector<size_t> cuts;
    for (size_t i = 0; i + 8 < text.size(); ++i) {
      if (text[i] == '\n') cuts.push_back(i + 1);
    }
    for (const programs::Target& t : p.targets) cuts.push_back(t.fields[2].end);
    for (const size_t cut : cuts) {
      const std::string shorter = text.substr(0, cut);
      // A script cut after its last block's end is a whole script (without the call of it), a
      // KRL file cut between its routines a whole file of fewer routines: neither is a cut a
      // reader can tell.
      if (f.language == Language::kUrScript && cut > text.rfind("\nend")) continue;
      if (f.language == Language::kKrl && endsAfterARoutine(shorter)) continue;
      EXPECT_NE(refusal(f.language, shorter), "") << f.file << " cut at byte " << cut;
    }
  }
}

TEST(Programs, GarbageIsRefusedWithItsLineAndColumn) {
  EXPECT_EQ(refusal(Language::kKrl, "DEF a()\nLIN {X 1,Y 2,Z 3,A 0,B 0,C }\nEND\n"), "2:28");
  EXPECT_EQ(refusal(Language::kKrl, "DEF a()\nLIN {X 1,Y 2,Z 3,A 0,B 0,C 0\nEND\n"), "2:29");
  EXPECT_EQ(refusal(Language::kKrl, "DEF a()\nLIN {X 1,Y 2,Z 3,A 0,X 0,C 0}\nEND\n"), "2:24");
  EXPECT_EQ(refusal(Language::kKrl, "hello world\n"), "2:1");
  EXPECT_EQ(refusal(Language::kKrl, std::string("DEF a()\nEN\0D\n", 13)), "2:3");
  EXPECT_EQ(refusal(Language::kRapid, "MODULE m\nPROC main()\nMoveL [[1,2,3],[1,0,0,0],[0,0,0,0]],v1,z1,tool0;\nENDPROC\nENDMODULE\n"), "3:7");
  EXPECT_EQ(refusal(Language::kRapid, "MODULE m\nCONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]\nENDMODULE\n"), "3:1");
  EXPECT_EQ(refusal(Language::kRapid, "MODULE m\nPROC main()\nMoveL p, v100, z1;\nENDPROC\nENDMODULE\n"), "3:1");
  EXPECT_EQ(refusal(Language::kUrScript, "def a():\n  movel(p[0.1, 0.2, 0.3, 0, 0, 0], a=1\nend\n"), "2:3");
  EXPECT_EQ(refusal(Language::kUrScript, "def a():\n  movel(p[0.1, 0.2, 0.3, 0, 0, 0])\n"), "1:1");
  EXPECT_EQ(refusal(Language::kFanucTp, "/PROG a\n/POS\nP[1]{\n GP1:\n UF : 0, UT : 1,\n J1 = 1.0 deg, J2 = x deg\n};\n/END\n"), "6:21");
  EXPECT_EQ(refusal(Language::kFanucTp, "/PROG a\n/POS\nP[1]{\n GP1:\n UF : 0, UT : 1,\n X = 1.0 mm, Y = 2 mm\n};\n/END\n"), "4:2");
}

// What each language holds besides its literals: KRL's frames in order and S/T, RAPID's
// quaternion, work object and tool load, URScript's comments and composed poses, TP's second
// group and leading-dot numbers.
TEST(Programs, EachLanguageReadsItsFramesAndKeepsWhatItDoesNotCorrect) {
  const programs::Program krl = read(Language::kKrl,
      "DEF a()\n$BASE = BASE_DATA[2]\nlin {x 10, y 20, z 30, a 90, b 0, c 180, s 'B010', t 'B110010'}\n"
      "BAS(#TOOL, 3)\nLIN XP1:{X 10}\nLIN_REL {Z 5}\nPTP {A1 1, A2 -90, A3 90, A4 0, A5 45, A6 0, E1 0}\nend\n");
  ASSERT_EQ(krl.targets.size(), 2u);
  EXPECT_EQ(krl.frames[size_t(krl.targets[0].base)].name, "BASE_DATA[2]");
  EXPECT_EQ(krl.targets[0].configuration, "S 'B010' T 'B110010'");
  EXPECT_NEAR(krl.targets[0].X_FrameTcp.linear()(1, 0), 1.0, 1e-12);  // A 90 about z
  EXPECT_EQ(krl.frames[size_t(krl.targets[1].tool)].name, "TOOL_DATA[3]");
  EXPECT_EQ(krl.not_literals.size(), 2u);

  const programs::Program dat = read(Language::kKrl, test::readText(kPrograms + "twin/twin.dat"));
  ASSERT_EQ(dat.targets.size(), 1u);
  EXPECT_EQ(dat.targets[0].name, "XP1");
  EXPECT_EQ(dat.targets[0].configuration, "S 6 T 27");
  EXPECT_EQ(dat.targets[0].tool, -1);

  const programs::Program rapid = read(Language::kRapid,
      "MODULE m\n PERS tooldata t1:=[TRUE,[[0,0,300],[1,0,0,0]],[12.5,[0,0,100],[1,0,0,0],0,0,0]];\n"
      " TASK PERS wobjdata w1 := [FALSE,TRUE,\"\",[[1000,0,0],[1,0,0,0]],[[0,0,50],[1,0,0,0]]];\n"
      " CONST robtarget p10:=[[1,2,3],[0,1,0,0],[0,-1,2,1],[9E+09,9E9,9E9,9E9,9E9,9E9]];\n"
      " proc main()\n  movel p10, v100, z1, t1\\WObj:=w1;\n  MoveL Offs(p10,0,0,50), v100, fine, t1;\n"
      "  MoveAbsJ [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]]\\NoEOffs, v100, fine, tool0;\n endproc\nENDMODULE\n");
  ASSERT_EQ(rapid.targets.size(), 2u);
  EXPECT_EQ(rapid.targets[0].configuration, "[0,-1,2,1]");
  EXPECT_EQ(rapid.frames[size_t(rapid.targets[0].tool)].mass_kg, 12.5);
  EXPECT_NEAR(rapid.frames[size_t(rapid.targets[0].base)].X->translation().z(), 0.05, 1e-12);
  EXPECT_EQ(rapid.not_literals.size(), 1u);
  EXPECT_NEAR(rapid.targets[1].q_rad[4], 30.0 * kRadPerDeg, 1e-12);

  const programs::Program ur = read(Language::kUrScript,
      "def a():\n  # movel(p[1,2,3,0,0,0])\n  global home = p[0.1,0.2,0.3,0,3.14159,0]\n"
      "  movel(pose_trans(home, p[0,0,0.05,0,0,0]))\n  movej([0,-1.57,1.57,0,1.2,0], a=1.4)\nend\n");
  EXPECT_EQ(ur.targets.size(), 2u);
  EXPECT_EQ(ur.not_literals.size(), 1u);

  const programs::Program loaded = read(Language::kUrScript,
      "def a():\n  set_payload(2.5, [0, 0, 0.05])\n  set_tcp(p[0,0,0.3,0,0,0])\n  movel(p[0.1,0.2,0.3,0,3.14159,0])\n"
      "  set_payload(mass)\n  movej([0,-1.57,1.57,0,1.2,0])\nend\n");
  ASSERT_EQ(loaded.targets.size(), 2u);
  const programs::Frame& tool = loaded.frames[size_t(loaded.targets[0].tool)];
  EXPECT_NEAR(tool.X->translation().z(), 0.3, 1e-15);
  const programs::Load& payload = loaded.loads[size_t(loaded.targets[0].load)];
  EXPECT_EQ(payload.mass_kg, 2.5);
  EXPECT_EQ(payload.p_CoG_m.z(), 0.05);
  EXPECT_EQ(loaded.targets[1].load, loaded.targets[0].load);  // set_payload(mass) is reported
  EXPECT_EQ(loaded.not_literals.size(), 1u);

  const programs::Program tp = read(Language::kFanucTp,
      "/PROG a\n/MN\n 1:L P[1] 100mm/sec FINE ;\n 2:L P[2] 100mm/sec FINE Offset,PR[1] ;\n/POS\n"
      "P[1:\"pick\"]{\n   GP1:\n\tUF : 1, UT : 2,\t\tCONFIG : 'F U T, 0, 0, 0',\n\tX = .5 mm,\tY = -12.25 mm,"
      "\tZ = 300.000 mm,\n\tW = 180.000 deg,\tP = 0 deg,\tR = -.5 deg\n   GP2:\n\tUF : 1, UT : 2,\n\tJ1 = 12.000 mm\n};\n"
      "P[2]{\n   GP1:\n\tUF : 1, UT : 2,\n\tJ1 = 0 deg, J2 = 0 deg, J3 = 0 deg, J4 = 0 deg, J5 = -90 deg, J6 = 0 deg\n};\n/END\n");
  // RoboDK's tool: PR[9,1..6] = -30, 0, 40, 0, -60, 0 and UTOOL[9]=PR[9]; UF 2 only in a comment.
  const programs::Program robodk = read(Language::kFanucTp, test::readText(kPrograms + "Program.LS"));
  const programs::Frame& ut9 = robodk.frames[size_t(robodk.targets[0].tool)];
  ASSERT_EQ(ut9.name, "UT 9");
  ASSERT_TRUE(ut9.X.has_value());
  EXPECT_LT((ut9.X->translation() - Vec3(-0.03, 0.0, 0.04)).norm(), 1e-15);
  EXPECT_LT(lie::angleBetween(ut9.X->linear(), Eigen::AngleAxisd(-60.0 * kRadPerDeg, Vec3::UnitY()).toRotationMatrix()), 1e-12);
  EXPECT_FALSE(robodk.frames[size_t(robodk.targets[0].base)].X.has_value());

  ASSERT_EQ(tp.targets.size(), 1u);  // P[2] is moved by an offset at run time
  EXPECT_EQ(tp.targets[0].configuration, "F U T, 0, 0, 0");
  EXPECT_NEAR(tp.targets[0].X_FrameTcp.translation().x(), 0.5e-3, 1e-15);
  EXPECT_NEAR(tp.targets[0].X_FrameTcp.linear()(2, 2), -1.0, 1e-12);  // W 180 about x
  EXPECT_EQ(tp.not_literals.size(), 1u);
}


// ---- On the twin ----

/// A simulated cell (seed 1) calibrated, its model with no correction (the nominal chain: what
/// an offline programming tool knows), and the joints of another seed's poses.
struct TwinCell {
  std::string dir, model, identity, truth;
  std::vector<JointVector> joints;
};

const TwinCell& twinCell() {
  static const test::TempDir dir;
  static const TwinCell cell = [] {
    TwinCell c;
    c.dir = dir.path().string();
    c.model = c.dir + "/model.stepcal";
    c.identity = c.dir + "/identity.stepcal";
    c.truth = c.dir + "/cell/truth.json";
    const test::CommandResult r = test::run(
        kStepcal + " simulate --seed 1 --out " + c.dir + "/cell && " + kStepcal + " calibrate " + c.dir +
        "/cell --out " + c.model + " && " + kStepcal + " simulate --seed 5 --out " + c.dir + "/olp");
    EXPECT_EQ(r.status, 0) << r.out;
    const CalibratedModel model = readModelFile(c.model);
    CalibratedModel nominal;
    nominal.nominal_Base = model.nominal_Base;
    nominal.chain_Tracker = model.nominal_Base.rerooted(model.X_TrackerBase);
    nominal.X_TrackerBase = model.X_TrackerBase;
    nominal.sensor_frame = model.sensor_frame;
    nominal.gravity_Base = model.gravity_Base;
    writeModelFile(nominal, c.identity);
    for (const Measurement& row : readCampaign(c.dir + "/olp").rows) c.joints.push_back(row.q_rad);
    return c;
  }();
  return cell;
}

/// The program's tool (0.3 m out from the flange, tilted 10°) and base frame.
Pose twinTool() {
  Pose X = Pose::Identity();
  X.translation() = Vec3(0.02, 0.0, 0.3);
  X.linear() = Eigen::AngleAxisd(10.0 * kRadPerDeg, Vec3::UnitY()).toRotationMatrix();
  return X;
}
Pose twinBase() {
  Pose X = Pose::Identity();
  X.translation() = Vec3(0.9, -0.25, 0.4);
  X.linear() = Eigen::AngleAxisd(20.0 * kRadPerDeg, Vec3::UnitZ()).toRotationMatrix();
  return X;
}

/// A pair of targets: the joints q (a PTP/MoveAbsJ/movej), then the pose of q + δ nearby (a
/// LIN/MoveL/movel), in the base frame, with its configuration word.
struct TwinPair {
  JointVector q_joint, q_pose;
  Pose X_BaseTcp;  ///< the pose target (in the base frame; the user frame for all but UR)
  ArmBranch branch;
};

constexpr size_t kTwinPairs = 120;  // 240 targets

/// Every other pair in the other wrist configuration (q4 + π, −q5, q6 + π: the same pose).
std::vector<TwinPair> twinPairs(const runtime::RuntimeModel& model, bool in_user_frame) {
  runtime::Workspace ws = runtime::makeWorkspace(model);
  const ClosedFormInverse closed = ClosedFormInverse::recognise(model.file.nominal_Base);
  runtime::CallTerms terms;
  terms.tool_from = runtime::ToolFrom::kFlange;
  terms.X_Tool = twinTool();
  terms.frame = in_user_frame ? runtime::PoseFrame::kUser : runtime::PoseFrame::kBase;
  terms.X_BaseUser = twinBase();
  const std::vector<ChainJoint>& limits = model.file.nominal_Base.joints();
  std::vector<TwinPair> pairs;
  for (const JointVector& q : twinCell().joints) {
    if (pairs.size() == kTwinPairs) break;
    TwinPair pair;
    pair.q_joint = q;
    if (pairs.size() % 2 == 1) {
      pair.q_joint[3] += pair.q_joint[3] > 0.0 ? -kPi : kPi;
      pair.q_joint[4] = -pair.q_joint[4];
      pair.q_joint[5] += pair.q_joint[5] > 0.0 ? -kPi : kPi;
    }
    pair.q_pose = pair.q_joint;
    for (int j = 0; j < 6; ++j) pair.q_pose[j] += 0.02 * (j % 2 ? 1.0 : -1.0);
    bool within = std::abs(pair.q_pose[4]) > 0.05;  // away from the wrist singularity
    for (int j = 0; j < 6; ++j) {
      for (const JointVector* v : {&pair.q_joint, &pair.q_pose}) {
        within = within && (*v)[j] > limits[size_t(j)].lower_rad && (*v)[j] < limits[size_t(j)].upper_rad;
      }
    }
    if (!within) continue;
    pair.X_BaseTcp = runtime::nominalTcp(model, ws, pair.q_pose, terms);
    pair.branch = closed.branchOf(pair.q_pose);
    pairs.push_back(pair);
  }
  EXPECT_EQ(pairs.size(), kTwinPairs);
  return pairs;
}

std::string fixed(double v, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, v);
  return text;
}

/// Z, Y′, X″ angles of R in degrees (KRL A, B, C; Fanuc R, P, W).
Vec3 zyxDeg(const Mat3& R) { return R.eulerAngles(2, 1, 0) / kRadPerDeg; }

std::string krlFrame(const Pose& X) {
  const Vec3 abc = zyxDeg(X.linear());
  const Vec3 p = X.translation() * 1e3;
  return "X " + fixed(p.x(), 3) + ",Y " + fixed(p.y(), 3) + ",Z " + fixed(p.z(), 3) + ",A " + fixed(abc[0], 4) +
         ",B " + fixed(abc[1], 4) + ",C " + fixed(abc[2], 4);
}

std::string krlProgram(const std::vector<TwinPair>& pairs) {
  std::string out = "&ACCESS RVP\r\nDEF twin( )\r\n;FOLD frames\r\n$BASE = {FRAME: " + krlFrame(twinBase()) +
                    "}\r\n$TOOL = {FRAME: " + krlFrame(twinTool()) + "}\r\n;ENDFOLD\r\n";
  for (size_t i = 0; i < pairs.size(); ++i) {
    const TwinPair& p = pairs[i];
    out += "PTP {A1 " + fixed(p.q_joint[0] / kRadPerDeg, 4);
    for (int j = 1; j < 6; ++j) out += ",A" + std::to_string(j + 1) + " " + fixed(p.q_joint[j] / kRadPerDeg, 4);
    const KukaStatusTurn st = kukaStatusTurn(p.branch, p.q_pose);
    std::string t_bits;
    for (int b = 5; b >= 0; --b) t_bits += ((st.turn >> b) & 1) ? '1' : '0';
    out += "}\r\nlin {" + krlFrame(p.X_BaseTcp) + ", S " + std::to_string(st.status) + ", T " +
           (i % 3 ? std::to_string(st.turn) : "'B" + t_bits + "'") + "} C_DIS ; pair " + std::to_string(i) + "\r\n";
  }
  return out + "END\r\n";
}

std::string rapidPose(const Pose& X) {
  const Eigen::Quaterniond q(X.linear());
  const Vec3 p = X.translation() * 1e3;
  return "[[" + fixed(p.x(), 3) + "," + fixed(p.y(), 3) + "," + fixed(p.z(), 3) + "],[" + fixed(q.w(), 8) + "," +
         fixed(q.x(), 8) + "," + fixed(q.y(), 8) + "," + fixed(q.z(), 8) + "]]";
}

std::string rapidProgram(const std::vector<TwinPair>& pairs) {
  std::string out = "MODULE Twin\n  PERS tooldata tTwin:=[TRUE," + rapidPose(twinTool()) +
                    ",[0.001,[0,0,1],[1,0,0,0],0,0,0]];\n  TASK PERS wobjdata wTwin := [FALSE,TRUE,\"\"," +
                    rapidPose(twinBase()) + ",[[0,0,0],[1,0,0,0]]];\n  PROC main()\n";
  for (const TwinPair& p : pairs) {
    out += "    MoveAbsJ [[" + fixed(p.q_joint[0] / kRadPerDeg, 4);
    for (int j = 1; j < 6; ++j) out += "," + fixed(p.q_joint[j] / kRadPerDeg, 4);
    const AbbConfData c = abbConfData(p.branch, p.q_pose);
    std::string pose = rapidPose(p.X_BaseTcp);
    pose.pop_back();
    out += "],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v1000, fine, tTwin\\WObj:=wTwin;\n    MoveL " + pose + ",[" +
           std::to_string(c.cf1) + "," + std::to_string(c.cf4) + "," + std::to_string(c.cf6) + "," +
           std::to_string(c.cfx) + "],[9E9,9E9,9E9,9E9,9E9,9E9]], v1000, z10, tTwin \\WObj:=wTwin; ! pair\n";
  }
  return out + "  ENDPROC\nENDMODULE\n";
}

std::string urPose(const Pose& X) {
  const Eigen::AngleAxisd aa(X.linear());
  const Vec3 v = aa.axis() * aa.angle();
  const Vec3 p = X.translation();
  return "p[" + fixed(p.x(), 6) + ", " + fixed(p.y(), 6) + ", " + fixed(p.z(), 6) + ", " + fixed(v.x(), 6) + ", " +
         fixed(v.y(), 6) + ", " + fixed(v.z(), 6) + "]";
}

std::string urProgram(const std::vector<TwinPair>& pairs) {
  std::string out = "def twin():\n  # the tool\n  set_tcp(" + urPose(twinTool()) + ")\n";
  for (const TwinPair& p : pairs) {
    out += "  movej([" + fixed(p.q_joint[0], 6);
    for (int j = 1; j < 6; ++j) out += ", " + fixed(p.q_joint[j], 6);
    out += "], a=1.4, v=1.05)\n  movel(" + urPose(p.X_BaseTcp) + ", a=1.2, v=0.25)  # " + urPose(p.X_BaseTcp) + "\n";
  }
  return out + "end\ntwin()\n";
}

std::string tpProgram(const std::vector<TwinPair>& pairs) {
  std::string out = "/PROG  TWIN\n/ATTR\nDEFAULT_GROUP\t= 1,*,*,*,*;\n/MN\n";
  for (size_t i = 0; i < 2 * pairs.size(); ++i) {
    out += std::string(4 - std::to_string(i + 1).size(), ' ') + std::to_string(i + 1) + ":" + (i % 2 ? "L" : "J") +
           " P[" + std::to_string(i + 1) + "] " + (i % 2 ? "100mm/sec" : "100%") + " FINE ;\n";
  }
  out += "/POS\n";
  for (size_t i = 0; i < pairs.size(); ++i) {
    const TwinPair& p = pairs[i];
    out += "P[" + std::to_string(2 * i + 1) + "]{\n   GP1:\n\tUF : 1, UT : 1,\n";
    for (int j = 0; j < 6; ++j) {
      out += "\tJ" + std::to_string(j + 1) + "=" + fixed(p.q_joint[j] / kRadPerDeg, 3) + " deg" + (j < 5 ? "," : "") + (j == 2 || j == 5 ? "\n" : "");
    }
    const FanucConfig c = fanucConfig(p.branch, p.q_pose);
    const Vec3 rpw = zyxDeg(p.X_BaseTcp.linear());
    const Vec3 x = p.X_BaseTcp.translation() * 1e3;
    out += "};\nP[" + std::to_string(2 * i + 2) + "]{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : '" + (c.flip ? "F" : "N") +
           (c.up ? " U" : " D") + (c.front ? " T" : " B") + ", " + std::to_string(c.turn1) + ", " +
           std::to_string(c.turn4) + ", " + std::to_string(c.turn6) + "',\n\tX =" + fixed(x.x(), 3) + "  mm,\tY =" +
           fixed(x.y(), 3) + "  mm,\tZ =" + fixed(x.z(), 3) + "  mm,\n\tW =" + fixed(rpw[2], 3) + " deg,\tP =" +
           fixed(rpw[1], 3) + " deg,\tR =" + fixed(rpw[0], 3) + " deg\n};\n";
  }
  return out + "/END\n";
}

/// --program-frame NAME=x,y,z,qw,qx,qy,qz (mm).
std::string programFrame(const std::string& name, const Pose& X) {
  const Eigen::Quaterniond q(X.linear());
  const Vec3 p = X.translation() * 1e3;
  return " --program-frame '" + name + "=" + fixed(p.x(), 6) + "," + fixed(p.y(), 6) + "," + fixed(p.z(), 6) + "," +
         fixed(q.w(), 12) + "," + fixed(q.x(), 12) + "," + fixed(q.y(), 12) + "," + fixed(q.z(), 12) + "'";
}

struct TwinLanguage {
  Language language;
  const char* file;
  std::string (*program)(const std::vector<TwinPair>&);
  std::string options;
  bool user_frame;
};

/// Where the twin's true robot puts the program's TCP at joints q, tracker frame.
Pose trueTcp(const twin::TwinRobot& truth, const runtime::RuntimeModel& model, const JointVector& q) {
  ChainWorkspace ws;
  truth.deflectedFrames(q, 0.0, runtime::kUnknownTemperature_c, ws);
  return truth.X_TrackerBase() * ws.X_RootFrame[size_t(q.size())] * model.X_LastFlange_nominal * twinTool();
}

/// The joints a controller commands for a pose target of the program: its nominal chain's
/// closed form, in the branch and turns its configuration word names, nearest where it was.
JointVector controllerJoints(const runtime::RuntimeModel& model, const programs::Program& program,
                             const programs::Target& t, const Pose& X_BaseFrame, const JointVector& near) {
  const ClosedFormInverse closed = ClosedFormInverse::recognise(model.file.nominal_Base);
  const Pose X_FlangeTip = model.X_LastFlange_nominal.inverse() * model.file.nominal_Base.initialPose(6);
  const Pose X_BaseTip = X_BaseFrame * t.X_FrameTcp * twinTool().inverse() * X_FlangeTip;
  JointVector q(6);
  const std::optional<programs::ConfigurationWord> word = programs::readConfiguration(program.language, t, "p");
  const ControllerJoints joints;
  const ArmBranch branch = word ? programs::branchNamed(*word, joints) : closed.branchOf(near);
  EXPECT_EQ(closed.solve(X_BaseTip, branch, near, q), ClosedFormStatus::kOk) << t.line;
  if (word) programs::applyTurns(*word, model.file.nominal_Base, joints, q);
  return q;
}

/// Mean position error (mm) on the twin's truth of a program run as a controller runs it, over
/// its targets but those on the lines `left_out`.
double meanErrorOnTheTwin(const TwinCell& cell, const runtime::RuntimeModel& model, const std::string& text,
                          const TwinLanguage& l, const std::vector<TwinPair>& pairs,
                          const std::set<int>& left_out = {}) {
  std::ifstream truth_in(cell.truth);
  const twin::TwinRobot truth = twin::TwinRobot::fromTruthJson(nlohmann::json::parse(truth_in));
  runtime::Workspace ws = runtime::makeWorkspace(model);
  const programs::Program p = read(l.language, text);
  EXPECT_EQ(p.targets.size(), 2 * pairs.size());
  const Pose X_BaseFrame = l.user_frame ? twinBase() : Pose::Identity();
  double sum_m = 0.0;
  int count = 0;
  for (size_t i = 0; i < pairs.size(); ++i) {
    runtime::CallTerms terms;
    terms.frame = runtime::PoseFrame::kBase;
    terms.tool_from = runtime::ToolFrom::kFlange;
    terms.X_Tool = twinTool();
    const Pose X_desired_joints = model.file.X_TrackerBase * runtime::nominalTcp(model, ws, pairs[i].q_joint, terms);
    const Pose X_desired_pose = model.file.X_TrackerBase * X_BaseFrame * pairs[i].X_BaseTcp;
    const JointVector& q_joints = p.targets[2 * i].q_rad;
    const JointVector q_pose = controllerJoints(model, p, p.targets[2 * i + 1], X_BaseFrame, pairs[i].q_pose);
    if (!left_out.count(p.targets[2 * i].line)) {
      sum_m += (trueTcp(truth, model, q_joints).translation() - X_desired_joints.translation()).norm();
      ++count;
    }
    if (!left_out.count(p.targets[2 * i + 1].line)) {
      sum_m += (trueTcp(truth, model, q_pose).translation() - X_desired_pose.translation()).norm();
      ++count;
    }
  }
  return sum_m / double(count) * 1e3;
}

const std::vector<TwinLanguage>& twinLanguages() {
  static const std::vector<TwinLanguage> languages = {
      {Language::kKrl, "twin.src", krlProgram, "", true},
      {Language::kRapid, "twin.mod", rapidProgram, "", true},
      {Language::kUrScript, "twin.script", urProgram, "", false},
      {Language::kFanucTp, "twin.ls", tpProgram, programFrame("UF 1", twinBase()) + programFrame("UT 1", twinTool()), true},
  };
  return languages;
}

/// The JSON summary in a command's output (stdout and stderr merged).
nlohmann::json jsonIn(const std::string& out) {
  const size_t start = out.find('{');
  return nlohmann::json::parse(out.substr(start, out.rfind('}') + 1 - start));
}

class TwinProgram : public ::testing::TestWithParam<size_t> {};

// A program of 240 targets from the twin in each language: with the model of no correction it
// comes back byte-identical, every target unchanged; with the calibrated model, every target is
// corrected in its configuration, and the program run as a controller runs it (the written
// joints; each written pose through the nominal inverse in its written configuration) lands on
// the twin's truth at the model's own error at those joints, where as written it lands at the
// nominal chain's.
TEST_P(TwinProgram, IsCorrectedInItsConfigurationToTheModelsError) {
  const TwinCell& cell = twinCell();
  const TwinLanguage& l = twinLanguages()[GetParam()];
  const auto model = runtime::RuntimeModel::load(cell.model);
  const std::vector<TwinPair> pairs = twinPairs(*model, l.user_frame);
  const test::TempDir dir;
  const std::string program = (dir.path() / l.file).string(), out = (dir.path() / "out").string();
  const std::string text = l.program(pairs);
  {
    std::ofstream f(program, std::ios::binary);
    f << text;
  }
  const test::CommandResult same = test::run(kStepcal + " correct " + cell.identity + " " + program + " --out " + out +
                                             " --json" + l.options);
  ASSERT_EQ(same.status, 0) << same.out.substr(0, 2000);
  EXPECT_EQ(test::readText(out), text);
  const nlohmann::json unchanged = jsonIn(same.out);
  EXPECT_EQ(unchanged["outcomes"].value("unchanged", 0), int(2 * pairs.size())) << unchanged["outcomes"].dump();

  const test::CommandResult r = test::run(kStepcal + " correct " + cell.model + " " + program + " --out " + out +
                                          " --json --truth " + cell.truth + l.options);
  const nlohmann::json summary = jsonIn(r.out);
  // A target whose correction crosses a boundary of its configuration word (a joint across 0°,
  // a quadrant of ABB's cf1/cf4/cf6) is reported and kept as written: the exit status says so.
  int reported = 0;
  for (const auto& t : summary["targets"]) {
    if (t["outcome"] == "corrected") continue;
    EXPECT_EQ(t["outcome"], "changed configuration") << t.dump();
    std::printf("reported: %s\n", t.dump().c_str());
    ++reported;
  }
  EXPECT_EQ(r.status, reported == 0 ? 0 : 3);
  EXPECT_EQ(summary["not_corrected"], reported);
  EXPECT_LE(reported, 3);
  EXPECT_EQ(summary["outcomes"].value("corrected", 0), int(2 * pairs.size()) - reported) << summary["outcomes"].dump();
  const std::string corrected = test::readText(out);

  // The model's own error at the corrected joints, against the truth.
  std::ifstream truth_in(cell.truth);
  const twin::TwinRobot truth = twin::TwinRobot::fromTruthJson(nlohmann::json::parse(truth_in));
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  runtime::CallTerms terms;
  terms.frame = runtime::PoseFrame::kBase;
  terms.tool_from = runtime::ToolFrom::kFlange;
  terms.X_Tool = twinTool();
  terms.load_from = runtime::LoadFrom::kPayload;
  double model_sum_m = 0.0;
  for (const TwinPair& p : pairs) {
    for (const JointVector* q : {&p.q_joint, &p.q_pose}) {
      const Pose X_model = runtime::correctForward(*model, ws, *q, terms, runtime::kUnknownTemperature_c).X_FrameTcp;
      model_sum_m += ((model->file.X_TrackerBase * X_model).translation() - trueTcp(truth, *model, *q).translation()).norm();
    }
  }
  const double model_mm = model_sum_m / double(2 * pairs.size()) * 1e3;
  const double as_written_mm = meanErrorOnTheTwin(cell, *model, text, l, pairs);
  const double as_corrected_mm = meanErrorOnTheTwin(cell, *model, corrected, l, pairs);
  std::printf("%s, %zu targets on the twin: as written %.4f mm, as corrected %.4f mm; the model's own error at "
              "those joints %.4f mm; the driver's summary: commanded %.4f mm, corrected %.4f mm\n",
              programs::languageName(l.language).c_str(), 2 * pairs.size(), as_written_mm, as_corrected_mm, model_mm,
              summary["error_commanded"]["mean_position_mm"].get<double>(),
              summary["error_corrected"]["mean_position_mm"].get<double>());
  EXPECT_GT(as_written_mm, 1.0);
  EXPECT_LT(as_corrected_mm, as_written_mm / 5.0);
  EXPECT_NEAR(as_corrected_mm, model_mm, 0.01 + 0.2 * model_mm);
  EXPECT_NEAR(summary["error_commanded"]["mean_position_mm"].get<double>(), as_written_mm, 0.05 * as_written_mm);
}

// ---- With the tool calibrated on the twin ----

/// The program's tool calibrated with the model as a cell integrator would (docs/cell.md): an
/// SMR at the true TCP shot by the tracker (σ 0.015 mm per axis) in 8 poses of the other seed's
/// campaign, then `stepcal tool --out` (the tracker method: the TCP on the measured target).
struct TwinToolFile {
  std::string path;
  double sigma_mm = 0.0;  ///< the TCP's 1-σ as a length: √(trace of its covariance)
};

const TwinToolFile& twinToolFile() {
  static const TwinToolFile tool = [] {
    const TwinCell& cell = twinCell();
    const auto model = runtime::RuntimeModel::load(cell.model);
    const twin::TwinRobot truth = twin::TwinRobot::fromTruthJson(nlohmann::json::parse(test::readText(cell.truth)));
    std::mt19937 random(7);
    std::normal_distribution<double> normal(0.0, 0.015);
    std::string shots = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_n,fy_n,fz_n,mx_nm,my_nm,mz_nm,x_mm,y_mm,z_mm\n";
    for (size_t k = cell.joints.size() - 8; k < cell.joints.size(); ++k) {  // poses no program target uses
      const JointVector& q = cell.joints[k];
      for (int j = 0; j < 6; ++j) shots += fixed(q[j] / kRadPerDeg, 9) + ",";
      const Vec6 w = truth.sensorReading(q, 0.0);
      for (int i = 0; i < 6; ++i) shots += fixed(w[i], 9) + ",";
      const Vec3 p_mm = trueTcp(truth, *model, q).translation() * 1e3;
      shots += fixed(p_mm.x() + normal(random), 4) + "," + fixed(p_mm.y() + normal(random), 4) + "," +
               fixed(p_mm.z() + normal(random), 4) + "\n";
    }
    TwinToolFile t;
    t.path = cell.dir + "/tool.json";
    test::writeText(cell.dir + "/shots.csv", shots);
    const test::CommandResult r = test::run(kStepcal + " tool " + cell.model + " " + cell.dir + "/shots.csv --out " + t.path);
    EXPECT_EQ(r.status, 0) << r.out;
    std::printf("%s", r.out.c_str());
    const nlohmann::json j = nlohmann::json::parse(test::readText(t.path));
    for (int a = 0; a < 3; ++a) t.sigma_mm += j["tcp_covariance_in_target_mm2"][size_t(a)][size_t(a)].get<double>();
    t.sigma_mm = std::sqrt(t.sigma_mm);
    return t;
  }();
  return tool;
}

// The same programs corrected with the tool calibrated on the model (`--tool-file`): the TCP
// taken from the measured target, where no nominal transform enters, in place of the program's
// tool through the model's flange (docs/runtime.md, "The tool": its unidentifiable part nominal).
// Run as a controller runs it, with its own tool data as written, the program lands on the
// twin's truth at the model's own error at the measured target (its validation level) plus the
// TCP fit's, far below the flange route's.
TEST_P(TwinProgram, WithTheCalibratedToolIsCorrectedToTheModelsErrorAtTheTarget) {
  const TwinCell& cell = twinCell();
  const TwinToolFile& tool = twinToolFile();
  const TwinLanguage& l = twinLanguages()[GetParam()];
  const auto model = runtime::RuntimeModel::load(cell.model);
  const std::vector<TwinPair> pairs = twinPairs(*model, l.user_frame);
  const test::TempDir dir;
  const std::string program = (dir.path() / l.file).string(), out = (dir.path() / "out").string();
  const std::string text = l.program(pairs);
  test::writeText(program, text);
  const test::CommandResult r = test::run(kStepcal + " correct " + cell.model + " " + program + " --out " + out +
                                          " --json --truth " + cell.truth + " --tool-file " + tool.path + l.options);
  ASSERT_TRUE(r.status == 0 || r.status == 3) << r.out.substr(0, 2000);
  const nlohmann::json summary = jsonIn(r.out);
  EXPECT_LE(summary["not_corrected"].get<int>(), 3) << summary["outcomes"].dump();
  std::set<int> reported;  // a target whose correction would change its configuration: kept as written
  for (const auto& t : summary["targets"]) {
    if (t["outcome"] != "corrected") reported.insert(t["line"].get<int>());
  }
  ASSERT_EQ(summary["tool_files"].size(), 1u) << summary["tool_files"].dump();
  EXPECT_EQ(summary["tool_files"][0]["targets"], int(2 * pairs.size()));
  std::printf("tool files: %s\n", summary["tool_files"].dump().c_str());

  // The model's own error at the measured target, and at the TCP through its flange, at the
  // program's joints.
  const twin::TwinRobot truth = twin::TwinRobot::fromTruthJson(nlohmann::json::parse(test::readText(cell.truth)));
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  runtime::CallTerms flange;
  flange.frame = runtime::PoseFrame::kBase;
  flange.tool_from = runtime::ToolFrom::kFlange;
  flange.X_Tool = twinTool();
  flange.load_from = runtime::LoadFrom::kPayload;
  double target_sum_m = 0.0, flange_sum_m = 0.0;
  for (const TwinPair& p : pairs) {
    for (const JointVector* q : {&p.q_joint, &p.q_pose}) {
      const Pose X_target = runtime::correctForward(*model, ws, *q, truth.sensorReading(*q, 0.0),
                                                    runtime::kUnknownTemperature_c).X_TrackerTip;
      target_sum_m += (X_target.translation() - truth.X_TrackerTip(*q, 0.0).translation()).norm();
      const Pose X_flange = runtime::correctForward(*model, ws, *q, flange, runtime::kUnknownTemperature_c).X_FrameTcp;
      flange_sum_m += ((model->file.X_TrackerBase * X_flange).translation() - trueTcp(truth, *model, *q).translation()).norm();
    }
  }
  const double target_mm = target_sum_m / double(2 * pairs.size()) * 1e3;
  const double flange_mm = flange_sum_m / double(2 * pairs.size()) * 1e3;
  const double as_written_mm = meanErrorOnTheTwin(cell, *model, text, l, pairs);
  const double as_corrected_mm = meanErrorOnTheTwin(cell, *model, test::readText(out), l, pairs, reported);
  std::printf("%s, %zu targets, the tool of %s (1-sigma %.4f mm): as written %.4f mm, as corrected %.4f mm (the "
              "%zu corrected); the "
              "model's own error at the measured target %.4f mm, at the TCP through its flange %.4f mm; the "
              "driver's summary: commanded %.4f mm, corrected %.4f mm\n",
              programs::languageName(l.language).c_str(), 2 * pairs.size(), tool.path.c_str(), tool.sigma_mm,
              as_written_mm, as_corrected_mm, 2 * pairs.size() - reported.size(), target_mm, flange_mm,
              summary["error_commanded"]["mean_position_mm"].get<double>(),
              summary["error_corrected"]["mean_position_mm"].get<double>());
  EXPECT_GT(as_written_mm, 1.0);
  EXPECT_LE(as_corrected_mm, 2.0 * target_mm + tool.sigma_mm);
  EXPECT_LT(as_corrected_mm, flange_mm / 3.0);
  // The driver's figure is at the corrected joints; the program as run rounds them to its file's
  // resolution (TP's joints to 0.001 deg: up to ~0.02 mm at the IRB 4400's reach).
  EXPECT_NEAR(summary["error_corrected"]["mean_position_mm"].get<double>(), as_corrected_mm, 0.01);
}

// A tool file is refused, by file and field, when it was fitted with another model, and a tool
// name the program does not use is refused with the names it does; nothing is written.
TEST(Programs, CorrectRefusesAToolFileOfAnotherModelOrAToolTheProgramDoesNotUse) {
  const TwinCell& cell = twinCell();
  const TwinToolFile& tool = twinToolFile();
  const test::TempDir dir;
  const std::string program = (dir.path() / "twin.src").string(), out = (dir.path() / "out.src").string();
  test::writeText(program, test::readText(kPrograms + "twin/twin.src"));
  const test::CommandResult other = test::run(kStepcal + " correct " + cell.identity + " " + program + " --out " + out +
                                              " --tool-file " + tool.path);
  EXPECT_EQ(other.status, 2) << other.out;
  EXPECT_NE(other.out.find(tool.path), std::string::npos) << other.out;
  EXPECT_NE(other.out.find("model_id"), std::string::npos) << other.out;
  EXPECT_NE(other.out.find("is not that of " + cell.identity), std::string::npos) << other.out;
  const test::CommandResult unused = test::run(kStepcal + " correct " + cell.model + " " + program + " --out " + out +
                                               " --tool-file 'TOOL_DATA[7]=" + tool.path + "'");
  EXPECT_EQ(unused.status, 2) << unused.out;
  EXPECT_NE(unused.out.find("no target of the program uses the tool TOOL_DATA[7]; expected one of the tools it uses: "),
            std::string::npos) << unused.out;
  EXPECT_FALSE(std::filesystem::exists(out));

  // One file for every tool, but a program of two tools: each needs its own.
  const std::string two_tools = (dir.path() / "two.script").string(), out_script = (dir.path() / "out.script").string();
  std::string script = test::readText(kPrograms + "twin/twin.script");
  script.insert(script.find("  movej", script.find("movel")), "  set_tcp(p[0, 0, 0.2, 0, 0, 0])\n");
  test::writeText(two_tools, script);
  const test::CommandResult two = test::run(kStepcal + " correct " + cell.model + " " + two_tools + " --out " +
                                            out_script + " --tool-file " + tool.path);
  EXPECT_EQ(two.status, 2) << two.out;
  EXPECT_NE(two.out.find("stands for every tool, but the program uses two of different values: SET_TCP LINE 3 (line "
                         "4) and SET_TCP LINE 6; expected --tool-file NAME=TOOL.json for each tool calibrated"),
            std::string::npos) << two.out;
  const test::CommandResult named = test::run(kStepcal + " correct " + cell.model + " " + two_tools + " --out " +
                                              out_script + " --tool-file 'set_tcp line 3=" + tool.path + "'");
  EXPECT_EQ(named.status, 0) << named.out;
  EXPECT_NE(named.out.find("SET_TCP LINE 3: the calibrated TCP of " + tool.path + " (tracker, 8 points) for 2 targets"),
            std::string::npos) << named.out;
}

// The real files through `stepcal correct` with the model of no correction: each comes back
// byte-identical (their robots are not the twin's: what the IRB4400 cannot reach is reported).
TEST(Programs, RealFilesComeBackByteIdenticalThroughCorrectWithNoCorrection) {
  const TwinCell& cell = twinCell();
  const test::TempDir dir;
  for (const Fixture& f : kFixtures) {
    const std::string out = (dir.path() / f.file).string();
    const std::string frames = f.language == Language::kFanucTp ? " --program-frame 'UF 2=900,0,40,1,0,0,0' --program-frame 'UT 9=-30,0,40,1,0,0,0'" : "";
    const test::CommandResult r =
        test::run(kStepcal + " correct " + cell.identity + " " + kPrograms + f.file + " --out " + out + frames);
    EXPECT_TRUE(r.status == 0 || r.status == 3) << r.out;
    EXPECT_EQ(r.out.find(": corrected"), std::string::npos) << r.out;
    EXPECT_EQ(test::readText(out), test::readText(kPrograms + f.file)) << f.file;
  }
}

// A program `stepcal correct` does not fully understand is refused with its file, line and
// column (exit status 2), and nothing is written: never a half-corrected program.
TEST(Programs, CorrectRefusesAProgramItDoesNotUnderstandAndWritesNothing) {
  const TwinCell& cell = twinCell();
  const test::TempDir dir;
  const std::string program = (dir.path() / "cut.mod").string(), out = (dir.path() / "out.mod").string();
  const std::string text = test::readText(kPrograms + "twin/twin.mod");
  {
    std::ofstream f(program, std::ios::binary);
    f << text.substr(0, text.find("],[9E9", text.find("MoveL")));  // cut after the first MoveL's confdata
  }
  const test::CommandResult r = test::run(kStepcal + " correct " + cell.model + " " + program + " --out " + out);
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find(program + ":6: column '84': a list that the file ends in; expected ']'"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));
}

const char* const kTwinNames[] = {"Krl", "Rapid", "UrScript", "FanucTp"};
INSTANTIATE_TEST_SUITE_P(Programs, TwinProgram, ::testing::Values(size_t(0), size_t(1), size_t(2), size_t(3)),
                         [](const ::testing::TestParamInfo<size_t>& info) { return kTwinNames[info.param]; });

}  // namespace
}  // namespace stepcal
