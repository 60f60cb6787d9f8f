// The load a robot program's targets are corrected under (`stepcal correct PROGRAM`,
// tools/cli/program_load.cpp): each language's own (KRL $LOAD and LOAD_DATA[n], RAPID tooldata,
// GripLoad and \TLoad, URScript set_payload, Fanuc PAYLOAD[n]) read where it is in force; the
// values the program names without (LOAD_DATA[n], PAYLOAD[n]) from --program-load, refused by line
// and column naming the option when not given; and on the demo's twin (`--truth`), a program whose
// load changes half-way corrected to the joints the CSV driver gives the same targets with that
// payload in its columns.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/programs/program.hpp"
#include "support/command.hpp"
#include "support/files.hpp"

namespace stepcal {
namespace {

using programs::Language;

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";

programs::Program read(Language language, const std::string& text) { return programs::readProgram(language, text, "p"); }

const programs::Load& loadOf(const programs::Program& p, size_t target) {
  return p.loads.at(size_t(p.targets.at(target).load));
}

TEST(ProgramLoads, KrlReadsLoadAndLoadDataAndBasSelectsTheToolsLoad) {
  const programs::Program krl = read(Language::kKrl,
      "DEF a()\n$LOAD = {M 30.0, CM {X 0, Y 5, Z 150, A 0, B 0, C 0}, J {X 0, Y 0, Z 0}}\n"
      "PTP {A1 0, A2 -90, A3 90, A4 0, A5 45, A6 0}\n$LOAD = load_data[2]\nPTP {A1 1, A2 -90, A3 90, A4 0, A5 45, A6 0}\n"
      "BAS(#TOOL, 3)\nPTP {A1 2, A2 -90, A3 90, A4 0, A5 45, A6 0}\nBAS(#TOOL, 0)\nPTP {A1 3, A2 -90, A3 90, A4 0, A5 45, A6 0}\n"
      "end\n");
  ASSERT_EQ(krl.targets.size(), 4u);
  EXPECT_EQ(loadOf(krl, 0).name, "$LOAD line 2");
  EXPECT_EQ(loadOf(krl, 0).mass_kg, 30.0);
  EXPECT_EQ(loadOf(krl, 0).p_CoG_m, Vec3(0.0, 0.005, 0.15));
  EXPECT_EQ(loadOf(krl, 1).name, "LOAD_DATA[2]");
  EXPECT_FALSE(loadOf(krl, 1).mass_kg.has_value());
  EXPECT_EQ(loadOf(krl, 2).name, "LOAD_DATA[3]");
  EXPECT_EQ(krl.targets[3].load, -1);  // the flange carries nothing

  // A load built component by component holds the controller's values: the command line's.
  const programs::Program parts = read(Language::kKrl,
      "DEF a()\n$LOAD.M=$DEF_L_M\n$LOAD.CM=$DEF_L_CM\nPTP {A1 0, A2 -90, A3 90, A4 0, A5 45, A6 0}\nend\n");
  ASSERT_EQ(parts.targets.size(), 1u);
  EXPECT_EQ(loadOf(parts, 0).name, "$LOAD line 3");
  EXPECT_FALSE(loadOf(parts, 0).mass_kg.has_value());

  // $config.dat's LOAD_DATA: M -1 is the robot type's default load, which no program holds.
  const programs::Program dat = read(Language::kKrl,
      "DEFDAT $CONFIG\nLOAD_DATA[1]={M 12.5,CM {X 0.0,Y 0.0,Z 80.0,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}\n"
      "LOAD_DATA[2]={M -1.0,CM {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}\nENDDAT\n");
  ASSERT_EQ(dat.loads.size(), 2u);
  EXPECT_EQ(dat.loads[0].mass_kg, 12.5);
  EXPECT_NEAR(dat.loads[0].p_CoG_m.z(), 0.08, 1e-15);
  EXPECT_FALSE(dat.loads[1].mass_kg.has_value());
  EXPECT_NE(dat.loads[1].without_values.find("M -1.0"), std::string::npos);
}

TEST(ProgramLoads, RapidReadsTLoadAndGripLoadAndUrAndTpTheirPayloads) {
  const programs::Program rapid = read(Language::kRapid,
      "MODULE m\n PERS loaddata part:=[18,[0,0,70],[1,0,0,0],0,0,0];\n proc main()\n"
      "  MoveAbsJ [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n  GripLoad part;\n"
      "  MoveAbsJ [[1,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n"
      "  MoveAbsJ [[2,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0\\TLoad:=total;\n"
      "  GripLoad load0;\n  MoveAbsJ [[3,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0\\TLoad:=load0;\n"
      " endproc\nENDMODULE\n");
  const programs::Program declared = read(Language::kRapid,
      "MODULE m\n CONST robtarget p10:=[[1,2,3],[0,1,0,0],[0,-1,2,1],[9E+09,9E9,9E9,9E9,9E9,9E9]];\n proc main()\n"
      "  MoveL p10, v100, fine, tool0;\n  GripLoad part;\n  MoveL p10, v100, fine, tool0;\n endproc\nENDMODULE\n");
  EXPECT_EQ(declared.targets.at(0).grip_load, -1);
  EXPECT_EQ(declared.targets[0].other_loads, "line 6 with another tool or load");
  ASSERT_EQ(rapid.targets.size(), 4u);
  EXPECT_EQ(rapid.targets[0].grip_load, -1);
  EXPECT_EQ(rapid.loads.at(size_t(rapid.targets[1].grip_load)).mass_kg, 18.0);
  EXPECT_EQ(loadOf(rapid, 2).name, "total");  // declared elsewhere: its values from the command line
  EXPECT_FALSE(loadOf(rapid, 2).mass_kg.has_value());
  EXPECT_EQ(rapid.targets[3].load, -1);
  EXPECT_EQ(rapid.targets[3].grip_load, -1);

  // set_payload(m) keeps the centre of gravity in force, as UR's does; set_payload_cog the mass.
  const programs::Program ur = read(Language::kUrScript,
      "def a():\n  set_payload(2.5, [0, 0, 0.05])\n  movej([0,-1.57,1.57,0,1.2,0])\n  set_payload(4)\n"
      "  movej([0,-1.57,1.57,0,1.3,0])\n  set_payload_cog([0.01, 0, 0.1])\n  movej([0,-1.57,1.57,0,1.4,0])\n"
      "  set_target_payload(7, [0, 0, 0.2], [0, 0, 0, 0, 0, 0])\n  movej([0,-1.57,1.57,0,1.5,0])\nend\n");
  ASSERT_EQ(ur.targets.size(), 4u);
  EXPECT_EQ(loadOf(ur, 0).mass_kg, 2.5);
  EXPECT_EQ(loadOf(ur, 1).mass_kg, 4.0);
  EXPECT_EQ(loadOf(ur, 1).p_CoG_m, Vec3(0, 0, 0.05));
  EXPECT_EQ(loadOf(ur, 2).mass_kg, 4.0);
  EXPECT_EQ(loadOf(ur, 2).p_CoG_m, Vec3(0.01, 0, 0.1));
  EXPECT_EQ(loadOf(ur, 3).mass_kg, 7.0);
  EXPECT_EQ(loadOf(ur, 3).p_CoG_m, Vec3(0, 0, 0.2));
  EXPECT_TRUE(ur.not_literals.empty());

  // A P[n] takes the payload of the first motion to it.
  const programs::Program tp = read(Language::kFanucTp,
      "/PROG a\n/MN\n 1:  PAYLOAD[2] ;\n 2:J P[1] 100% FINE ;\n 3:  PAYLOAD[1] ;\n 4:L P[2] 100mm/sec FINE ;\n"
      " 5:J P[1] 100% FINE ;\n 6:  PAYLOAD[3:gripper] ;\n 7:J P[3] 100% FINE ;\n/POS\nP[1]{\n   GP1:\n\tUF : 0, UT : 1,\n\tJ1 = 0 deg, J2 = 0 deg, J3 = 0 deg, J4 = 0 deg,"
      " J5 = -90 deg, J6 = 0 deg\n};\nP[2]{\n   GP1:\n\tUF : 0, UT : 1,\n\tJ1 = 1 deg, J2 = 0 deg, J3 = 0 deg, J4 = 0 deg,"
      " J5 = -90 deg, J6 = 0 deg\n};\nP[3]{\n   GP1:\n\tUF : 0, UT : 1,\n\tJ1 = 2 deg, J2 = 0 deg, J3 = 0 deg, J4 = 0 deg,"
      " J5 = -90 deg, J6 = 0 deg\n};\n/END\n");
  ASSERT_EQ(tp.targets.size(), 3u);
  EXPECT_EQ(loadOf(tp, 0).name, "PAYLOAD[2]");
  EXPECT_EQ(loadOf(tp, 1).name, "PAYLOAD[1]");
  EXPECT_EQ(tp.targets[0].other_loads, "line 7 under PAYLOAD[1]");  // P[1] again, corrected for the first
  EXPECT_EQ(tp.targets[1].other_loads, "");
  EXPECT_EQ(loadOf(tp, 2).name, "PAYLOAD[3]");
}

// ---- On the demo's twin, against the CSV driver ----

struct Demo {
  std::string model, truth;
  std::string identity;  ///< the model's nominal chain: no correction
};

const Demo& demo() {
  static const test::TempDir dir;
  static const Demo d = [] {
    const std::string out = (dir.path() / "demo").string();
    const test::CommandResult r = test::run(kStepcal + " demo --out " + out);
    EXPECT_EQ(r.status, 0) << r.out;
    const CalibratedModel model = readModelFile(out + "/model.stepcal");
    CalibratedModel nominal;
    nominal.nominal_Base = model.nominal_Base;
    nominal.chain_Tracker = model.nominal_Base.rerooted(model.X_TrackerBase);
    nominal.X_TrackerBase = model.X_TrackerBase;
    nominal.sensor_frame = model.sensor_frame;
    nominal.gravity_Base = model.gravity_Base;
    writeModelFile(nominal, out + "/identity.stepcal");
    return Demo{out + "/model.stepcal", out + "/truth.json", out + "/identity.stepcal"};
  }();
  return d;
}

/// Six joint targets of the IRB 4400, deg: the first three under one load, the last three under
/// another.
const double kJoints_deg[6][6] = {
    {-21.1364, -19.1875, 21.3237, -35.0800, -74.4335, 106.8615}, {-21.5225, -27.5135, 12.9838, -162.7255, -56.3271, 1.0954},
    {-0.7822, -12.5533, -24.5131, -49.8362, 23.1354, -91.6865},  {10.25, -5.5, 15.75, 20.5, 40.25, -30.5},
    {25.5, 5.25, -10.5, -60.75, 55.5, 45.25},                    {-35.75, -15.5, 30.25, 90.5, -35.25, 120.75}};

/// A load as the CSV's columns: kg, then the centre of gravity in the flange frame, mm.
struct CsvLoad {
  double mass_kg, x_mm, y_mm, z_mm;
};

struct LoadedProgram {
  const char* file;
  std::string text;
  std::string options;
  CsvLoad first, second;  ///< the loads the program names, as the CSV gives them
  std::string first_name, second_name;
  /// RAPID: the last targets' load in place of `second` (a \TLoad), from this target on; 6: none.
  int third_from = 6;
  CsvLoad third{0, 0, 0, 0};
  std::string third_name;

  const CsvLoad& load(int target) const { return target >= third_from ? third : target < 3 ? first : second; }
  const std::string& name(int target) const {
    return target >= third_from ? third_name : target < 3 ? first_name : second_name;
  }
};

std::string degrees(int target, const char* separator, const char* prefix = "") {
  std::string out;
  for (int j = 0; j < 6; ++j) {
    char number[32];
    std::snprintf(number, sizeof number, "%.4f", kJoints_deg[target][j]);
    out += (j ? separator : "") + std::string(prefix) + (prefix[0] ? std::to_string(j + 1) + " " : "") + number;
  }
  return out;
}

std::string radians(int target) {
  std::string out;
  for (int j = 0; j < 6; ++j) {
    char number[40];
    std::snprintf(number, sizeof number, "%.17g", kJoints_deg[target][j] * kRadPerDeg);
    out += (j ? ", " : "") + std::string(number);
  }
  return out;
}

// The tool: 300 mm along the flange's z.
std::vector<LoadedProgram> loadedPrograms() {
  std::vector<LoadedProgram> programs;
  std::string krl = "DEF loaded( )\n$TOOL = {FRAME: X 0,Y 0,Z 300,A 0,B 0,C 0}\n"
                    "$LOAD = {M 30.0, CM {X 0, Y 0, Z 150, A 0, B 0, C 0}, J {X 0, Y 0, Z 0}}\n";
  for (int i = 0; i < 6; ++i) {
    if (i == 3) krl += "$LOAD = LOAD_DATA[1]\n";
    krl += "PTP {" + degrees(i, ",", "A") + "}\n";
  }
  programs.push_back({"loaded.src", krl + "END\n", " --program-load 'LOAD_DATA[1]=60,10,0,200'", {30, 0, 0, 150},
                      {60, 10, 0, 200}, "$LOAD line 3", "LOAD_DATA[1]", 6, {0, 0, 0, 0}, ""});

  // The tool's own 12 kg at 120 mm, then with an 18 kg part 70 mm out in the tool frame: 30 kg at
  // (12 · 120 + 18 · 370) / 30 = 270 mm; the last target with a total load of its own (\TLoad).
  std::string rapid = "MODULE Loaded\n  PERS tooldata tSpindle:=[TRUE,[[0,0,300],[1,0,0,0]],[12,[0,0,120],[1,0,0,0],0,0,0]];\n"
                      "  PERS loaddata part:=[18,[0,0,70],[1,0,0,0],0,0,0];\n"
                      "  PERS loaddata total:=[50,[5,0,200],[1,0,0,0],0,0,0];\n  PROC main()\n";
  for (int i = 0; i < 6; ++i) {
    if (i == 3) rapid += "    GripLoad part;\n";
    rapid += "    MoveAbsJ [[" + degrees(i, ",") + "],[9E9,9E9,9E9,9E9,9E9,9E9]], v1000, fine, tSpindle" +
             (i == 5 ? "\\TLoad:=total" : "") + ";\n";
  }
  programs.push_back({"loaded.mod", rapid + "  ENDPROC\nENDMODULE\n", "", {12, 0, 0, 120}, {30, 0, 0, 270},
                      "tSpindle's load", "tSpindle's load + part", 5, {50, 5, 0, 200}, "total"});

  std::string ur = "def loaded():\n  set_tcp(p[0, 0, 0.3, 0, 0, 0])\n  set_payload(30, [0, 0, 0.15])\n";
  for (int i = 0; i < 6; ++i) {
    if (i == 3) ur += "  set_payload(60, [0.01, 0, 0.2])\n";
    ur += "  movej([" + radians(i) + "], a=1.4, v=1.05)\n";
  }
  programs.push_back({"loaded.script", ur + "end\n", "", {30, 0, 0, 150}, {60, 10, 0, 200}, "set_payload line 3",
                      "set_payload line 7", 6, {0, 0, 0, 0}, ""});

  std::string mn = "/PROG  LOADED\n/MN\n   1:  PAYLOAD[1] ;\n", pos = "/POS\n";
  for (int i = 0; i < 6; ++i) {
    if (i == 3) mn += "   5:  PAYLOAD[2] ;\n";
    mn += "   " + std::to_string(i + 2) + ":J P[" + std::to_string(i + 1) + "] 100% FINE ;\n";
    pos += "P[" + std::to_string(i + 1) + "]{\n   GP1:\n\tUF : 0, UT : 1,\n";
    for (int j = 0; j < 6; ++j) {
      char number[32];
      std::snprintf(number, sizeof number, "%.4f", kJoints_deg[i][j]);
      pos += "\tJ" + std::to_string(j + 1) + " = " + number + " deg" + (j < 5 ? "," : "\n");
    }
    pos += "};\n";
  }
  programs.push_back({"LOADED.LS", mn + pos + "/END\n",
                      " --program-frame 'UT 1=0,0,300,1,0,0,0' --program-load 'PAYLOAD[1]=30,0,0,150' --program-load "
                      "'PAYLOAD[2]=60,10,0,200'",
                      {30, 0, 0, 150}, {60, 10, 0, 200}, "PAYLOAD[1]", "PAYLOAD[2]", 6, {0, 0, 0, 0}, ""});
  return programs;
}

/// The same targets in stepcal's CSV: the joints, the tool from the flange, the payload.
std::string csvProgram(const LoadedProgram& p) {
  std::string out = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,tool_from,tool_x_mm,tool_y_mm,tool_z_mm,tool_qw,"
                    "tool_qx,tool_qy,tool_qz,payload_kg,cog_x_mm,cog_y_mm,cog_z_mm,cog_frame\n";
  for (int i = 0; i < 6; ++i) {
    const CsvLoad& l = p.load(i);
    char load[128];
    std::snprintf(load, sizeof load, "%.17g,%.17g,%.17g,%.17g", l.mass_kg, l.x_mm, l.y_mm, l.z_mm);
    out += "t" + std::to_string(i) + "," + degrees(i, ",") + ",flange,0,0,300,1,0,0,0," + load + ",flange\n";
  }
  return out;
}

nlohmann::json jsonIn(const std::string& out) {
  const size_t start = out.find('{');
  return nlohmann::json::parse(out.substr(start, out.rfind('}') + 1 - start));
}

/// The corrected CSV's joints, rad, a row per target.
std::vector<std::vector<double>> csvJoints(const std::string& text) {
  std::vector<std::vector<double>> rows;
  size_t at = text.find('\n') + 1;
  while (at < text.size()) {
    const size_t end = text.find('\n', at);
    std::vector<std::string> fields;
    size_t f = at;
    for (size_t c = at; c <= end; ++c) {
      if (c == end || text[c] == ',') {
        fields.push_back(text.substr(f, c - f));
        f = c + 1;
      }
    }
    std::vector<double> q;
    for (int j = 0; j < 6; ++j) q.push_back(std::stod(fields[size_t(4 + j)]) * kRadPerDeg);
    rows.push_back(q);
    at = end + 1;
  }
  return rows;
}

// docs/runtime.md's example is the KRL program of this generator.
TEST(ProgramLoads, TheDocumentedKrlProgramIsTheGenerators) {
  EXPECT_EQ(test::readText(std::string(STEPCAL_TEST_DATA_DIR) + "/programs/twin/loaded.src"), loadedPrograms()[0].text);
}

class LoadedProgramOnTheTwin : public ::testing::TestWithParam<size_t> {};

// Each language's program, its load changing after the third target, corrected with --truth:
// every target's joints are the CSV driver's for the same target and payload (to 1e-9 rad), the
// twin's errors as commanded and as corrected the CSV's, and each target names its load.
TEST_P(LoadedProgramOnTheTwin, IsCorrectedAsTheCsvWithThatPayload) {
  const Demo& d = demo();
  const LoadedProgram p = loadedPrograms()[GetParam()];
  const test::TempDir dir;
  const std::string program = (dir.path() / p.file).string(), csv = (dir.path() / "loaded.csv").string();
  test::writeText(program, p.text);
  test::writeText(csv, csvProgram(p));
  // With no correction, the loaded program comes back byte-identical.
  const test::CommandResult same = test::run(kStepcal + " correct " + d.identity + " " + program + " --out " +
                                             (dir.path() / "same").string() + " --json" + p.options);
  ASSERT_EQ(same.status, 0) << same.out;
  EXPECT_EQ(test::readText(dir.path() / "same"), p.text);
  EXPECT_EQ(jsonIn(same.out)["outcomes"].value("unchanged", 0), 6) << same.out;
  const test::CommandResult r = test::run(kStepcal + " correct " + d.model + " " + program + " --out " +
                                          (dir.path() / "out").string() + " --json --truth " + d.truth + p.options);
  ASSERT_EQ(r.status, 0) << r.out;
  const test::CommandResult c = test::run(kStepcal + " correct " + d.model + " " + csv + " --out " +
                                          (dir.path() / "out.csv").string() + " --frame base --json --truth " + d.truth);
  ASSERT_EQ(c.status, 0) << c.out;
  const nlohmann::json program_summary = jsonIn(r.out), csv_summary = jsonIn(c.out);
  const std::vector<std::vector<double>> q_csv = csvJoints(test::readText(dir.path() / "out.csv"));
  ASSERT_EQ(program_summary["targets"].size(), 6u);
  ASSERT_EQ(q_csv.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    const nlohmann::json& t = program_summary["targets"][i];
    const CsvLoad& l = p.load(int(i));
    EXPECT_EQ(t["load"]["name"], p.name(int(i))) << t.dump();
    EXPECT_NEAR(t["load"]["mass_kg"].get<double>(), l.mass_kg, 1e-12);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(t["load"]["cog_flange_mm"][size_t(a)].get<double>(), (&l.x_mm)[a], 1e-9) << t.dump();
    }
    for (size_t j = 0; j < 6; ++j) {
      EXPECT_NEAR(t["q_corrected_deg"][j].get<double>() * kRadPerDeg, q_csv[i][j], 1e-9) << "target " << i << " joint " << j;
    }
  }
  for (const char* e : {"error_commanded", "error_corrected"}) {
    EXPECT_NEAR(program_summary[e]["mean_position_mm"].get<double>(), csv_summary[e]["mean_position_mm"].get<double>(), 1e-9);
  }
  // The load is felt: the CSV's same targets unloaded are corrected to other joints.
  LoadedProgram unloaded = p;
  unloaded.first = unloaded.second = unloaded.third = CsvLoad{0, 0, 0, 0};
  test::writeText(csv, csvProgram(unloaded));
  ASSERT_EQ(test::run(kStepcal + " correct " + d.model + " " + csv + " --out " + (dir.path() / "out.csv").string() +
                      " --frame base").status, 0);
  const std::vector<std::vector<double>> q_unloaded = csvJoints(test::readText(dir.path() / "out.csv"));
  for (size_t i = 0; i < 6; ++i) {
    double moved_rad = 0.0;
    for (size_t j = 0; j < 6; ++j) moved_rad = std::max(moved_rad, std::abs(q_unloaded[i][j] - q_csv[i][j]));
    EXPECT_GT(moved_rad, 1e-5) << "target " << i;
  }
}

const char* const kLanguages[] = {"Krl", "Rapid", "UrScript", "FanucTp"};
INSTANTIATE_TEST_SUITE_P(ProgramLoads, LoadedProgramOnTheTwin, ::testing::Values(size_t(0), size_t(1), size_t(2), size_t(3)),
                         [](const ::testing::TestParamInfo<size_t>& info) { return kLanguages[info.param]; });

// A load the program names without values and the command line does not give is refused with
// the target's line and column, naming --program-load; nothing is written.
TEST(ProgramLoads, ALoadWithoutValuesIsRefusedNamingTheOption) {
  const Demo& d = demo();
  const test::TempDir dir;
  const LoadedProgram krl = loadedPrograms()[0], tp = loadedPrograms()[3];
  for (const LoadedProgram* p : {&krl, &tp}) {
    const std::string program = (dir.path() / p->file).string(), out = (dir.path() / "out").string();
    test::writeText(program, p->text);
    const std::string frames = p == &tp ? " --program-frame 'UT 1=0,0,300,1,0,0,0' --program-load 'PAYLOAD[1]=30,0,0,150'" : "";
    const test::CommandResult r = test::run(kStepcal + " correct " + d.model + " " + program + " --out " + out + frames);
    EXPECT_EQ(r.status, 2) << r.out;
    const std::string where = p == &krl ? program + ":8: column '5': a target is moved under LOAD_DATA[1], whose values "
                                                    "the program does not give; expected them with --program-load "
                                                    "'LOAD_DATA[1]=kg,x,y,z'"
                                        : program + ":28: column '4': a target is moved under PAYLOAD[2], whose values "
                                                    "the program does not give; expected them with --program-load "
                                                    "'PAYLOAD[2]=kg,x,y,z'";
    EXPECT_NE(r.out.find(where), std::string::npos) << r.out;
    EXPECT_FALSE(std::filesystem::exists(out));
  }
}

// Malformed option values (a count off, a word for a number, no name, a negative mass) are refused
// naming the option and its value; nothing is written.
TEST(ProgramLoads, MalformedLoadAndFrameOptionsAreRefused) {
  const Demo& d = demo();
  const test::TempDir dir;
  const LoadedProgram krl = loadedPrograms()[0];
  const std::string program = (dir.path() / krl.file).string(), out = (dir.path() / "out").string();
  test::writeText(program, krl.text);
  const std::pair<std::string, std::string> cases[] = {
      {"--program-load 'LOAD_DATA[1]=60,10,0'", "expected NAME=kg,x,y,z"},
      {"--program-load 'LOAD_DATA[1]=60,ten,0,200'", "expected NAME=kg,x,y,z"},
      {"--program-load '=60,10,0,200'", "expected NAME=kg,x,y,z"},
      {"--program-load 'LOAD_DATA[1]=-60,10,0,200'", "a negative mass; expected kg ≥ 0"},
      {"--program-frame 'TOOL=0,0,300,1,0,0'", "expected NAME=x,y,z,qw,qx,qy,qz"},
      {"--program-frame 'TOOL=0,0,300,2,0,0,0'", "expected a unit quaternion"}};
  for (const auto& [option, expected] : cases) {
    const test::CommandResult r = test::run(kStepcal + " correct " + d.model + " " + program + " --out " + out + " " + option);
    EXPECT_EQ(r.status, 2) << option << "\n" << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << option << "\n" << r.out;
    EXPECT_FALSE(std::filesystem::exists(out)) << option;
  }
}

// A .dat's points name no load (their .src holds the $LOAD): --program-load LOAD=… serves them,
// else they are unloaded, and their lines say which.
TEST(ProgramLoads, LoadServesTheTargetsWhoseProgramNamesNone) {
  const Demo& d = demo();
  const test::TempDir dir;
  const std::string dat = std::string(STEPCAL_TEST_DATA_DIR) + "/programs/twin/twin.dat";
  const std::string frames = " --program-frame 'TOOL=20,0,300,0.996194698,0,0.087155743,0' --program-frame "
                             "'BASE=900,-250,400,0.984807753,0,0,0.173648178' --json";
  for (const double mass_kg : {0.0, 25.0}) {
    const std::string load = mass_kg > 0.0 ? " --program-load 'LOAD=25,0,0,100'" : "";
    const test::CommandResult r =
        test::run(kStepcal + " correct " + d.model + " " + dat + " --out " + (dir.path() / "out.dat").string() + frames + load);
    ASSERT_EQ(r.status, 0) << r.out;
    const nlohmann::json target = jsonIn(r.out)["targets"][0];
    EXPECT_EQ(target["load"]["name"], mass_kg > 0.0 ? "LOAD" : "") << target.dump();
    EXPECT_EQ(target["load"]["mass_kg"].get<double>(), mass_kg);
  }
}

}  // namespace
}  // namespace stepcal
