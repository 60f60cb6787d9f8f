// The general importer (`stepcal import mapped`): the IPA series through a mapping file give the
// campaign `stepcal import ipa` gives; a tracker export with point names and time stamps beside
// a KUKA-style joint log (decimal comma, header lines, rows while moving) joined by time stamp,
// and a tracker export of quaternions in metres joined by point name, against the values
// written; and every bad row or key refused with its file, line and what was expected.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
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

/// Rows while moving, one second before each point (other angles), and the point's own angles
/// 0.02 s after the tracker's time.
std::string kukaJointLog() {
  std::string s = "KRC4 axis log\nRobot: KR 210 R2700\nUnit: deg\nTime;A1;A2;A3;A4;A5;A6\n";
  for (const Point& p : kPoints) {
    s += clock(p.t_s - 1.0, true);
    for (double v : p.q_deg) s += ";" + fixed(v + 7.0, 3, true);
    s += "\n" + clock(p.t_s + 0.02, true);
    for (double v : p.q_deg) s += ";" + fixed(v, 3, true);
    s += "\n";
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
