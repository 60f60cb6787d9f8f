// The general importer (`stepcal import mapped`): the IPA series through a mapping file give the
// campaign `stepcal import ipa` gives; a tracker export with point names and time stamps beside
// a KUKA-style joint log (decimal comma, header lines, rows while moving) joined by time stamp,
// and a tracker export of quaternions in metres joined by point name, against the values
// written; a log that counts axes otherwise than the URDF (sign and offset) against the plain
// one; an F/T sensor's wrench from either file in its units; and every bad row or key refused
// with its file, line and what was expected.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/importers/ipa.hpp"
#include "stepcal/importers/mapped.hpp"
#include "support/command.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;
using test::expectInputError;
using test::readText;
using test::TempDir;
using test::writeText;

const fs::path kData = fs::path(STEPCAL_TEST_DATA_DIR);
const std::string kUr10Urdf = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";

/// The URDF text without the line of the comment each importer adds before the tip link.
std::string withoutAddedComment(std::string urdf) {
  const size_t at = urdf.find("  <!-- Added by");
  if (at == std::string::npos) return urdf;
  return urdf.erase(at, urdf.find('\n', at) + 1 - at);
}

// Series D (632 rows) is the smallest series with the std columns.
TEST(MappedImport, IpaSeriesDThroughAMappingIsTheIpaImport) {
  const Campaign ipa = importers::importIpaSeries(
      (kData / "ipa-robot-accuracy/Series_D/measurements_iso_cubes.csv").string(), 500, kUr10Urdf);
  const Campaign mapped = importers::importMapped((kData / "import/ipa_series_d.yaml").string());
  const TempDir dir;
  writeCampaign(ipa, (dir.path() / "ipa").string());
  writeCampaign(mapped, (dir.path() / "mapped").string());
  ASSERT_EQ(mapped.rows.size(), 632u);
  for (const char* file : {"campaign.yaml", "measurements.csv"}) {
    EXPECT_EQ(readText(dir.path() / "mapped" / file), readText(dir.path() / "ipa" / file)) << file;
  }
  const std::string urdf = readText(dir.path() / "mapped/robot.urdf");
  EXPECT_NE(urdf.find("<!-- Added by stepcal import mapped"), std::string::npos);
  EXPECT_EQ(withoutAddedComment(urdf),
            withoutAddedComment(readText(dir.path() / "ipa/robot.urdf")));
}

// ---------------------------------------------------------------------------------------------
// A cell's own layout: tracker export with point names and times, KUKA-style joint log

/// One measured point: what the files say, in their units.
struct Point {
  std::string name;
  double t_s;  ///< seconds after 10:15:00
  std::array<double, 6> q_deg;
  std::array<double, 3> p_mm;
  std::array<double, 3> abc_deg;  ///< KUKA A, B, C: R = Rz(A)·Ry(B)·Rx(C)
};

const std::vector<Point> kPoints = {
    {"P01",
     2.125,
     {10.5, -80.25, 95.125, -15.5, 90.75, 3.25},
     {1234.5678, -512.25, 801.0625},
     {12.5, -30.25, 170.75}},
    {"P02",
     9.5,
     {-20.125, -95.5, 110.25, -30.0, 85.5, -45.125},
     {1500.0625, 200.5, 650.25},
     {-95.5, 10.125, -175.25}},
    {"P03",
     17.875,
     {45.0, -60.75, 70.5, -10.25, 100.125, 60.5},
     {980.125, 905.75, 1020.5},
     {60.25, 45.5, 5.75}},
    {"P04",
     26.25,
     {0.0, -110.25, 125.5, -45.75, 75.25, 0.125},
     {1710.875, -20.125, 420.375},
     {0.0, -5.25, 179.5}},
};

Mat3 kukaAbc(const std::array<double, 3>& abc_deg) {
  const auto rot = [](double deg, int axis) {
    const double a = deg * kPi / 180.0, c = std::cos(a), s = std::sin(a);
    Mat3 R = Mat3::Identity();
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    R(i, i) = c, R(i, j) = -s, R(j, i) = s, R(j, j) = c;
    return R;
  };
  return rot(abc_deg[0], 2) * rot(abc_deg[1], 1) * rot(abc_deg[2], 0);
}

std::string fixed(double v, int decimals, bool decimal_comma = false) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (decimal_comma) std::replace(s.begin(), s.end(), '.', ',');
  return s;
}

std::string clock(double t_s, bool decimal_comma) {
  return std::string(decimal_comma ? "04.03.2026 " : "2026-03-04 ") +
         "10:15:" + (t_s < 10 ? "0" : "") + fixed(t_s, 3, decimal_comma);
}

std::string trackerExport() {
  std::string s =
      "# AT960 export, job 'cell check'\n# frame: tracker\n"
      "Point,Time,X [mm],Y [mm],Z [mm],A [deg],B [deg],C [deg],T [C]\n";
  for (const Point& p : kPoints) {
    s += p.name + "," + clock(p.t_s, false);
    for (double v : p.p_mm) s += "," + fixed(v, 4);
    for (double v : p.abc_deg) s += "," + fixed(v, 4);
    s += ",21.5\n";
  }
  return s;
}

/// How a controller counts its axes against the URDF: q_log = sign·(q_urdf − offset), the
/// inverse of the mapping's q_urdf = sign·q_log + offset.
struct AxisCount {
  std::array<int, 6> sign{1, 1, 1, 1, 1, 1};
  std::array<double, 6> offset_deg{};
};

std::string loggedAngles(const std::array<double, 6>& q_deg, double add_deg, const AxisCount& a) {
  std::string s;
  for (size_t j = 0; j < 6; ++j) {
    s += ";" + fixed(a.sign[j] * (q_deg[j] + add_deg - a.offset_deg[j]), 3, true);
  }
  return s;
}

/// Rows while moving, one second before each point (other angles), and the point's own angles
/// 0.02 s after the tracker's time; each row followed by `extra(point, moving)` when given.
std::string kukaJointLog(const AxisCount& count = {}, const std::string& extra_header = "",
                         const std::function<std::string(size_t, bool)>& extra = nullptr) {
  std::string s =
      "KRC4 axis log\nRobot: KR 210 R2700\nUnit: deg\nTime;A1;A2;A3;A4;A5;A6" + extra_header + "\n";
  for (size_t i = 0; i < kPoints.size(); ++i) {
    const Point& p = kPoints[i];
    s += clock(p.t_s - 1.0, true) + loggedAngles(p.q_deg, 7.0, count) +
         (extra ? extra(i, true) : "");
    s += "\n" + clock(p.t_s + 0.02, true) + loggedAngles(p.q_deg, 0.0, count) +
         (extra ? extra(i, false) : "") + "\n";
  }
  return s;
}

const char* const kKukaMapping = R"(format: stepcal-import-mapping/1
robot:
  urdf: ROBOT
  base_link: base_link
  tip_link: tool0
tracker:
  file: tracker.csv
  skip_lines: 2
  point_name: Point
  time: Time
  position: ["X [mm]", "Y [mm]", "Z [mm]"]
  length_unit: mm
  orientation:
    euler: ZYX
    columns: ["A [deg]", "B [deg]", "C [deg]"]
    unit: deg
  temperature_c: T [C]
  position_sigma_mm: 0.02
  orientation_sigma_deg: 0.005
joints:
  file: joints.log
  separator: ";"
  decimal: comma
  skip_lines: 3
  time: Time
  columns: [A1, A2, A3, A4, A5, A6]
  unit: deg
join:
  by: timestamp
  tolerance_s: 0.1
validation_from_row: 3
)";

std::string withRobot(std::string mapping) {
  mapping.replace(mapping.find("ROBOT"), 5, kUr10Urdf);
  return mapping;
}

/// Writes the cell's files into dir, each text edited by the test, and returns the mapping's path.
std::string writeCell(const fs::path& dir, const std::string& mapping = withRobot(kKukaMapping),
                      const std::string& tracker = trackerExport(),
                      const std::string& joints = kukaJointLog()) {
  writeText(dir / "tracker.csv", tracker);
  writeText(dir / "joints.log", joints);
  writeText(dir / "mapping.yaml", mapping);
  return (dir / "mapping.yaml").string();
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

void expectThePoints(const Campaign& c) {
  ASSERT_EQ(c.rows.size(), kPoints.size());
  for (size_t i = 0; i < kPoints.size(); ++i) {
    const Point& p = kPoints[i];
    const Measurement& m = c.rows[i];
    EXPECT_EQ(m.pose_id, p.name);
    EXPECT_EQ(m.set, i >= 3 ? RowSet::kValidation : RowSet::kGeometry);
    for (int j = 0; j < 6; ++j)
      EXPECT_NEAR(m.q_rad[j], p.q_deg[static_cast<size_t>(j)] * kRadPerDeg, 1e-12);
    for (int a = 0; a < 3; ++a)
      EXPECT_NEAR(m.p_TipInTracker_m[a], p.p_mm[static_cast<size_t>(a)] * 1e-3, 1e-12);
    ASSERT_TRUE(m.has_orientation);
    EXPECT_LT((m.q_TrackerTip.toRotationMatrix() - kukaAbc(p.abc_deg)).cwiseAbs().maxCoeff(),
              1e-12);
  }
}

TEST(MappedImport, TrackerPointsAndAKukaJointLogJoinedByTime) {
  const TempDir dir;
  const Campaign c = importers::importMapped(writeCell(dir.path()));
  expectThePoints(c);
  EXPECT_EQ(c.tip_link, "tool0");
  EXPECT_NEAR(c.tracker.position_sigma_m, 20e-6, 1e-15);
  ASSERT_TRUE(c.rows[0].temp_c.has_value());
  EXPECT_EQ(*c.rows[0].temp_c, 21.5);
  // Written and read back as a campaign.
  writeCampaign(c, (dir.path() / "campaign").string());
  expectThePoints(readCampaign((dir.path() / "campaign").string()));
}

TEST(MappedImport, QuaternionsInMetresJoinedByPointName) {
  std::string tracker = "name\tx_m\ty_m\tz_m\tqx\tqy\tqz\tqw\n";
  std::string joints = "point,a1,a2,a3,a4,a5,a6\n";
  for (auto it = kPoints.rbegin(); it != kPoints.rend(); ++it) {  // the log in another order
    joints += it->name;
    for (double v : it->q_deg) joints += "," + fixed(v * kRadPerDeg, 17);
    joints += "\n";
  }
  for (const Point& p : kPoints) {
    const Eigen::Quaterniond q(kukaAbc(p.abc_deg));
    tracker += p.name;
    for (double v : p.p_mm) tracker += "\t" + fixed(v * 1e-3, 7);
    for (double v : {q.x(), q.y(), q.z(), q.w()}) tracker += "\t" + fixed(v, 17);
    tracker += "\n";
  }
  const std::string mapping = withRobot(R"(format: stepcal-import-mapping/1
robot: {urdf: ROBOT, base_link: base_link, tip_link: tool0}
tracker:
  file: tracker.csv
  separator: tab
  point_name: name
  position: [x_m, y_m, z_m]
  length_unit: m
  orientation: {quaternion: xyzw, columns: [qx, qy, qz, qw]}
joints: {file: joints.log, point_name: point, columns: [a1, a2, a3, a4, a5, a6], unit: rad}
join: {by: point_name}
validation_from_row: 3
)");
  const TempDir dir;
  expectThePoints(importers::importMapped(writeCell(dir.path(), mapping, tracker, joints)));
}

// ---------------------------------------------------------------------------------------------
// A controller that counts axes otherwise than the URDF: q_urdf = sign·q_log + offset

const AxisCount kFlippedAndOffset = {{1, -1, 1, 1, 1, -1}, {0.0, 90.0, -90.0, 0.0, 0.0, 180.0}};

std::string withAxisCount(const std::string& mapping) {
  return replaced(mapping, "  unit: deg\njoin:",
                  "  unit: deg\n  sign: [1, -1, 1, 1, 1, -1]\n"
                  "  offset_deg: [0, 90, -90, 0, 0, 180]\njoin:");
}

TEST(MappedImport, AFlippedAndOffsetAxisGivesThePlainCampaign) {
  const TempDir plain_dir, counted_dir;
  const Campaign plain = importers::importMapped(writeCell(plain_dir.path()));
  const Campaign counted =
      importers::importMapped(writeCell(counted_dir.path(), withAxisCount(withRobot(kKukaMapping)),
                                        trackerExport(), kukaJointLog(kFlippedAndOffset)));
  expectThePoints(counted);
  ASSERT_EQ(counted.rows.size(), plain.rows.size());
  for (size_t i = 0; i < plain.rows.size(); ++i) {
    EXPECT_LT((counted.rows[i].q_rad - plain.rows[i].q_rad).cwiseAbs().maxCoeff(), 1e-12) << i;
    EXPECT_EQ(counted.rows[i].p_TipInTracker_m, plain.rows[i].p_TipInTracker_m) << i;
  }
  // The log as written is not the URDF's: read without sign and offset, A2 is far off.
  const Campaign uncounted =
      importers::importMapped(writeCell(counted_dir.path(), withRobot(kKukaMapping),
                                        trackerExport(), kukaJointLog(kFlippedAndOffset)));
  EXPECT_GT(std::abs(uncounted.rows[0].q_rad[1] - plain.rows[0].q_rad[1]), 1.0);
}

TEST(MappedImport, RefusesABadSignOrOffsetByKeyAndValue) {
  const TempDir dir;
  const std::string mapping = withAxisCount(withRobot(kKukaMapping));
  const std::string log = kukaJointLog(kFlippedAndOffset);
  const auto import = [&](const std::string& edited) {
    importers::importMapped(writeCell(dir.path(), edited, trackerExport(), log));
  };
  expectInputError(
      [&] { import(replaced(mapping, "[1, -1, 1, 1, 1, -1]", "[1, -1, 2, 1, 1, -1]")); },
      "mapping.yaml", 28, "", {"key 'sign', item 3 (A3): expected 1 or -1, got '2'"});
  expectInputError(
      [&] { import(replaced(mapping, "[1, -1, 1, 1, 1, -1]", "[1, -1, 1, 1, 1]")); },
      "mapping.yaml", 28, "",
      {"key 'sign': expected a list of 6 signs, each 1 or -1 (one per name in joints.columns), "
       "got a list of 5"});
  expectInputError(
      [&] { import(replaced(mapping, "[0, 90, -90,", "[0, .inf, -90,")); }, "mapping.yaml", 29, "",
      {"key 'offset_deg', item 2: expected a list of 6 finite offsets in degrees", "got '.inf'"});
  expectInputError([&] { import(replaced(mapping, "[0, 90, -90,", "[0, [90], -90,")); },
                   "mapping.yaml", 29, "", {"item 2", "got a list"});
}

// ---------------------------------------------------------------------------------------------
// Wrenches: an F/T sensor's columns in the joint log (kN, N·mm) or in the tracker export (N, N·m)

/// Each point's payload and the wrench it exerts, N and N·m (sensor axes); P01 unloaded.
const std::array<double, 4> kLoadKg = {0.0, 20.0, 30.0, 40.0};
const std::array<std::array<double, 6>, 4> kWrench = {
    {{0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
     {12.375, -40.5, -196.133, 3.125, -7.5, 0.25},
     {-20.25, 61.5, -294.2, -4.75, 11.0, -0.5},
     {0.125, -2.5, -392.266, 0.0625, 0.375, 1.5}}};

/// The log's load and F/T columns: kN and N·mm with a decimal comma; P01's cells as given; none
/// on the rows while moving (never joined, never read).
std::string wrenchCells(size_t point, bool moving, const std::string& unloaded_cells = ";;;;;") {
  std::string s = ";" + fixed(kLoadKg[point], 1, true);
  if (moving) return s + ";;;;;;";
  if (kLoadKg[point] == 0.0) return s + ";" + unloaded_cells;
  for (size_t a = 0; a < 6; ++a) {
    s += ";" + (a < 3 ? fixed(kWrench[point][a] * 1e-3, 7, true)
                      : fixed(kWrench[point][a] * 1e3, 2, true));
  }
  return s;
}

std::string withLoggedWrench(const std::string& mapping) {
  return replaced(
      replaced(mapping, "  tip_link: tool0\n", "  tip_link: tool0\n  sensor_link: tool0\n"),
      "  unit: deg\njoin:",
      "  unit: deg\n  load_kg: Load\n"
      "  wrench: {columns: [Fx, Fy, Fz, Mx, My, Mz], force_unit: kN, moment_unit: Nmm}\n"
      "join:");
}

const char* const kWrenchHeader = ";Load;Fx;Fy;Fz;Mx;My;Mz";

void expectTheWrenches(const Campaign& c) {
  ASSERT_EQ(c.rows.size(), kLoadKg.size());
  EXPECT_EQ(c.sensor_link, "tool0");
  for (size_t i = 0; i < kLoadKg.size(); ++i) {
    EXPECT_EQ(c.rows[i].load_kg, kLoadKg[i]);
    EXPECT_EQ(c.rows[i].has_wrench, kLoadKg[i] > 0.0) << i;
    // The unit's change moves the decimal point: the double nearest the value in N or N·m.
    for (int a = 0; a < 6; ++a)
      EXPECT_EQ(c.rows[i].wrench_Sensor[a], kWrench[i][static_cast<size_t>(a)]);
  }
}

TEST(MappedImport, AWrenchInKilonewtonsAndNewtonMillimetresFromTheJointLog) {
  const TempDir dir;
  const Campaign c = importers::importMapped(
      writeCell(dir.path(), withLoggedWrench(withRobot(kKukaMapping)), trackerExport(),
                kukaJointLog({}, kWrenchHeader,
                             [](size_t i, bool moving) { return wrenchCells(i, moving); })));
  expectThePoints(c);
  expectTheWrenches(c);
  writeCampaign(c, (dir.path() / "campaign").string());
  expectTheWrenches(readCampaign((dir.path() / "campaign").string()));
}

TEST(MappedImport, AWrenchInNewtonsFromTheTrackerExport) {
  std::string tracker = "name,x_m,y_m,z_m,fx,fy,fz,mx,my,mz\n";
  std::string joints = "point,load,a1,a2,a3,a4,a5,a6\n";
  for (size_t i = 0; i < kPoints.size(); ++i) {
    const Point& p = kPoints[i];
    tracker += p.name;
    for (double v : p.p_mm) tracker += "," + fixed(v * 1e-3, 7);
    for (double v : kWrench[i]) tracker += "," + (kLoadKg[i] > 0 ? fixed(v, 4) : std::string());
    tracker += "\n";
    joints += p.name + "," + fixed(kLoadKg[i], 1);
    for (double v : p.q_deg) joints += "," + fixed(v, 3);
    joints += "\n";
  }
  const std::string mapping = withRobot(R"(format: stepcal-import-mapping/1
robot: {urdf: ROBOT, base_link: base_link, tip_link: tool0, sensor_link: tool0}
tracker:
  file: tracker.csv
  point_name: name
  position: [x_m, y_m, z_m]
  length_unit: m
  wrench: {columns: [fx, fy, fz, mx, my, mz]}
joints: {file: joints.log, point_name: point, columns: [a1, a2, a3, a4, a5, a6], load_kg: load}
join: {by: point_name}
)");
  const TempDir dir;
  expectTheWrenches(importers::importMapped(writeCell(dir.path(), mapping, tracker, joints)));
}

TEST(MappedImport, RefusesABadOrMissingWrenchCellByFileAndLine) {
  const TempDir dir;
  const std::string mapping = withLoggedWrench(withRobot(kKukaMapping));
  const auto log = [](const std::string& unloaded_cells) {
    return kukaJointLog({}, kWrenchHeader, [&](size_t i, bool moving) {
      return wrenchCells(i, moving, unloaded_cells);
    });
  };
  const auto import = [&](const std::string& edited_mapping, const std::string& joint_log) {
    importers::importMapped(writeCell(dir.path(), edited_mapping, trackerExport(), joint_log));
  };
  // Line 8: P02's own row. A cell that is no number, then one of the six left empty.
  const std::string good = log(";;;;;");
  expectInputError(
      [&] { import(mapping, replaced(good, "-0,1961330", "-0,19x")); }, "joints.log", 8, "Fz",
      {"expected a number with a decimal comma (kN, all six wrench values or none)", "'-0,19x'"});
  expectInputError([&] { import(mapping, replaced(good, ";-0,1961330;", ";;")); }, "joints.log", 8,
                   "Fz", {"(kN, all six wrench values or none), got ''"});
  // Line 6, P01 unloaded: some cells only. Line 8, loaded: none.
  expectInputError([&] { import(mapping, log("0;0;0;;0;0")); }, "joints.log", 6, "Mx",
                   {"(Nmm, all six wrench values or none), got ''"});
  expectInputError(
      [&] { import(mapping, replaced(good, wrenchCells(1, false).substr(5), ";;;;;;")); },
      "joints.log", 8, "Fx",
      {"no F/T reading on a row with payload 20 kg; expected the six wrench values"});
  // The mapping: a load without a wrench, a wrench without a sensor link, a unit it lacks.
  const std::string wrench_key =
      "  wrench: {columns: [Fx, Fy, Fz, Mx, My, Mz], force_unit: kN, moment_unit: Nmm}\n";
  expectInputError([&] { import(replaced(mapping, wrench_key, ""), good); }, "joints.log", 8,
                   "Load", {"payload '20,0' kg but the mapping names no wrench"});
  expectInputError([&] { import(replaced(mapping, "  sensor_link: tool0\n", ""), good); },
                   "mapping.yaml", 0, "", {"robot.sensor_link is missing"});
  expectInputError([&] { import(replaced(mapping, "moment_unit: Nmm", "moment_unit: lbf"), good); },
                   "mapping.yaml", 30, "",
                   {"key 'moment_unit': expected one of Nm, Nmm, kNm, got 'lbf'"});
  expectInputError(
      [&] {
        import(replaced(mapping, "  temperature_c: T [C]\n",
                        "  temperature_c: T [C]\n  wrench: {columns: [a, b, c, d, e, f]}\n"),
               good);
      },
      "mapping.yaml", 31, "", {"a wrench is mapped in tracker and in joints"});
}

// ---------------------------------------------------------------------------------------------
// Refusals: the file, the line, the column and what was expected

TEST(MappedImport, RefusesABadRowByFileAndLine) {
  const TempDir dir;
  const std::string log = kukaJointLog();
  // Line 8 of the log: P02's own angles, A3 written with a decimal point.
  expectInputError(
      [&] {
        importers::importMapped(writeCell(dir.path(), withRobot(kKukaMapping), trackerExport(),
                                          replaced(log, "110,250", "110.250")));
      },
      "joints.log", 8, "A3", {"expected a number with a decimal comma (degrees)", "'110.250'"});
  expectInputError(
      [&] {
        importers::importMapped(
            writeCell(dir.path(), withRobot(kKukaMapping),
                      replaced(trackerExport(), "10:15:17.875", "10:15:18.875")));
      },
      "tracker.csv", 6, "Time",
      {"no joint log row within tolerance_s 0.1 s", "joints.log line 10, 0.980 s away"});
  expectInputError(
      [&] {
        importers::importMapped(writeCell(dir.path(), withRobot(kKukaMapping),
                                          replaced(trackerExport(), ",21.5\nP02", "\nP02")));
      },
      "tracker.csv", 4, "", {"row has 8 fields; expected 9 as in the header (line 3)"});
  expectInputError(
      [&] {
        importers::importMapped(
            writeCell(dir.path(), withRobot(kKukaMapping),
                      replaced(trackerExport(), "2026-03-04 10:15:02.125", "10h15")));
      },
      "tracker.csv", 4, "Time",
      {"expected a number with a decimal point (a time stamp", "'10h15'"});
  expectInputError(
      [&] {
        importers::importMapped(
            writeCell(dir.path(), replaced(withRobot(kKukaMapping), "[A1,", "[Axis1,")));
      },
      "joints.log", 4, "Axis1",
      {"column 'Axis1' (joint angle, named by the mapping) is missing", "'A1'"});
  // A finite number of degrees whose radians are not (a campaign could not hold it).
  expectInputError(
      [&] {
        importers::importMapped(writeCell(dir.path(), withRobot(kKukaMapping), trackerExport(),
                                          replaced(log, "110,250", "1e308")));
      },
      "joints.log", 8, "A3", {"expected a joint angle whose value in degrees", "'1e308'"});
  // A number of millimetres whose metres underflow the doubles.
  expectInputError(
      [&] {
        importers::importMapped(writeCell(dir.path(), withRobot(kKukaMapping),
                                          replaced(trackerExport(), "1234.5678", "1e-322")));
      },
      "tracker.csv", 4, "X [mm]",
      {"expected a number (millimetres) within the range of doubles once converted", "'1e-322'"});
}

TEST(MappedImport, RefusesABadMappingByLine) {
  const TempDir dir;
  const std::string mapping = withRobot(kKukaMapping);
  expectInputError(
      [&] {
        importers::importMapped(
            writeCell(dir.path(), replaced(mapping, "  skip_lines: 2", "  skip_line: 2")));
      },
      "mapping.yaml", 8, "", {"mapping.tracker: unknown key 'skip_line'"});
  expectInputError(
      [&] {
        importers::importMapped(
            writeCell(dir.path(), replaced(mapping, "euler: ZYX", "euler: ZZY")));
      },
      "mapping.yaml", 14, "", {"expected three axes", "'ZZY'"});
  expectInputError(
      [&] { importers::importMapped(writeCell(dir.path(), replaced(mapping, "A5, A6]", "A5]"))); },
      "mapping.yaml", 0, "", {"has 6 joints", "joints.columns, which lists 5"});
  expectInputError(
      [&] {
        importers::importMapped(
            writeCell(dir.path(), replaced(mapping, "  tolerance_s: 0.1\n", "")));
      },
      "mapping.yaml", 28, "", {"mapping.join: required key 'tolerance_s' is missing"});
  // A kept column named as one of the campaign's own.
  expectInputError(
      [&] {
        importers::importMapped(writeCell(
            dir.path(), replaced(mapping, "  temperature_c: T [C]\n",
                                 "  temperature_c: T [C]\n  keep: {x_mm: \"X [mm]\"}\n")));
      },
      "mapping.yaml", 18, "", {"key 'keep': campaign column 'x_mm': expected a new bare name"});
}

TEST(MappedImport, TheCommandWritesNothingOnABadRow) {
  const TempDir dir;
  const std::string mapping = writeCell(dir.path(), withRobot(kKukaMapping), trackerExport(),
                                        replaced(kukaJointLog(), "110,250", "110.250"));
  const std::string stepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";
  const test::CommandResult bad =
      test::run(stepcal + " import mapped " + mapping + " --out " + (dir.path() / "out").string());
  EXPECT_EQ(bad.status, 2) << bad.out;
  EXPECT_NE(bad.out.find("joints.log:8: column 'A3'"), std::string::npos) << bad.out;
  EXPECT_FALSE(fs::exists(dir.path() / "out"));
  writeCell(dir.path());
  const test::CommandResult good =
      test::run(stepcal + " import mapped " + mapping + " --out " + (dir.path() / "out").string());
  ASSERT_EQ(good.status, 0) << good.out;
  expectThePoints(readCampaign((dir.path() / "out").string()));
}

}  // namespace
}  // namespace stepcal
