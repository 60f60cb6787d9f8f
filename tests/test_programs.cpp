// The robot's own programs (tools/programs, `stepcal correct` on KRL, RAPID, URScript and Fanuc
// TP): real program files read and written back byte-identical; a replaced target changes its
// numbers and nothing else; garbage and truncated programs refused by line and column; and on
// the twin, a program of 240 targets per language (a tool 0.3 m out, a base frame, both wrist
// configurations) corrected by `stepcal correct` and then run as a controller would run it:
// each written pose through the nominal inverse from the joints before it, on the twin's truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
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

/// The refusal of `text`: its line and column, "line:column" ("" when it is read).
std::string refusal(Language language, const std::string& text) {
  try {
    read(language, text);
  } catch (const InputError& e) {
    return std::to_string(e.line()) + ":" + e.column();
  }
  return "";
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
      // A script cut after its last block's end is a whole script (without the call of it).
      if (f.language == Language::kUrScript && cut > text.rfind("\nend")) continue;
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

  const programs::Program tp = read(Language::kFanucTp,
      "/PROG a\n/MN\n 1:L P[1] 100mm/sec FINE ;\n 2:L P[2] 100mm/sec FINE Offset,PR[1] ;\n/POS\n"
      "P[1:\"pick\"]{\n   GP1:\n\tUF : 1, UT : 2,\t\tCONFIG : 'F U T, 0, 0, 0',\n\tX = .5 mm,\tY = -12.25 mm,"
      "\tZ = 300.000 mm,\n\tW = 180.000 deg,\tP = 0 deg,\tR = -.5 deg\n   GP2:\n\tUF : 1, UT : 2,\n\tJ1 = 12.000 mm\n};\n"
      "P[2]{\n   GP1:\n\tUF : 1, UT : 2,\n\tJ1 = 0 deg, J2 = 0 deg, J3 = 0 deg, J4 = 0 deg, J5 = -90 deg, J6 = 0 deg\n};\n/END\n");
  ASSERT_EQ(tp.targets.size(), 1u);  // P[2] is moved by an offset at run time
  EXPECT_EQ(tp.targets[0].configuration, "F U T, 0, 0, 0");
  EXPECT_NEAR(tp.targets[0].X_FrameTcp.translation().x(), 0.5e-3, 1e-15);
  EXPECT_NEAR(tp.targets[0].X_FrameTcp.linear()(2, 2), -1.0, 1e-12);  // W 180 about x
  EXPECT_EQ(tp.not_literals.size(), 1u);
}

}  // namespace
}  // namespace stepcal
