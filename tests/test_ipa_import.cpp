// Importer of the IPA UR10 data set: the real Series C (tests/data keeps a copy), which way round
// Trafo_TM_F_init.txt is, and refusal of broken synthetic files.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/importers/ipa.hpp"
#include "stepcal/trainer/registration.hpp"
#include "support/campaign_rows.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

const std::string kUr10Urdf = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";
// A copy of Series C travels with the tests (tests/data/ipa-robot-accuracy/NOTICE.md).
const fs::path kSeriesC = fs::path(STEPCAL_TEST_DATA_DIR) / "ipa-robot-accuracy" / "Series_C";
const fs::path kSeriesCCsv = kSeriesC / "measurements_random_poses.csv";

Mat3 eulerXyz(double rx_deg, double ry_deg, double rz_deg) {
  return (Eigen::AngleAxisd(rx_deg * kRadPerDeg, Vec3::UnitX()) *
          Eigen::AngleAxisd(ry_deg * kRadPerDeg, Vec3::UnitY()) *
          Eigen::AngleAxisd(rz_deg * kRadPerDeg, Vec3::UnitZ()))
      .toRotationMatrix();
}

/// The imported Series C, once for all tests.
const Campaign& seriesC() {
  static const Campaign campaign =
      importers::importIpaSeries(kSeriesCCsv.string(), 2000, kUr10Urdf);
  return campaign;
}

using test::TempDir;
using test::writeText;

// ---------------------------------------------------------------------------------------------
// The real Series C

TEST(IpaImport, SeriesCRowsSetsAndUnits) {
  const Campaign& c = seriesC();
  ASSERT_EQ(c.rows.size(), 2773u);  // 2774 lines with the header
  EXPECT_EQ(c.rowsIn(RowSet::kGeometry).size(), 2000u);
  EXPECT_EQ(c.rowsIn(RowSet::kValidation).size(), 773u);
  EXPECT_EQ(c.rows[1999].set, RowSet::kGeometry);
  EXPECT_EQ(c.rows[2000].set, RowSet::kValidation);
  EXPECT_EQ(c.rows[2000].pose_id, "r2000");
  EXPECT_EQ(c.rows[2000].seq, 2000);
  EXPECT_EQ(c.base_link, "base_link");
  EXPECT_EQ(c.tip_link, "tmac");
  EXPECT_TRUE(c.sensor_link.empty());
  EXPECT_EQ(c.joint_count, 6);
  EXPECT_TRUE(c.tracker.stated);
  EXPECT_DOUBLE_EQ(c.tracker.position_sigma_m, 0.015e-3);
  EXPECT_DOUBLE_EQ(c.tracker.orientation_sigma_rad, 0.01 * kRadPerDeg);
  EXPECT_EQ(c.extra_columns, (std::vector<std::string>{"std_x_mm", "std_y_mm", "std_z_mm",
                                                       "std_rx_deg", "std_ry_deg", "std_rz_deg"}));

  // First data line, converted by hand:
  // …;-3,14159;-1,5708;0;-1,5708;0;0;21,68000031;383,97123;0,041565;-3240,7562;0,022023;
  // 201,72621;0,0055848;-90,179563;0,0024569;-20,112975;0,0065397;-90,157388;0,008348
  const Measurement& m = c.rows[0];
  EXPECT_EQ(m.seq, 0);
  EXPECT_EQ(m.pose_id, "r0000");
  EXPECT_EQ(m.set, RowSet::kGeometry);
  EXPECT_EQ(m.load_kg, 0.0);
  EXPECT_FALSE(m.has_wrench);
  EXPECT_EQ(m.source_line, 2);
  JointVector q(6);
  q << -3.14159, -1.5708, 0, -1.5708, 0, 0;
  EXPECT_EQ(m.q_rad, q);  // already radians: no conversion
  EXPECT_EQ(m.p_TipInTracker_m, Vec3(0.38397123, -3.2407562, 0.20172621));  // mm → m, exact
  ASSERT_TRUE(m.has_orientation);
  EXPECT_TRUE(
      m.X_TrackerTip().linear().isApprox(eulerXyz(-90.179563, -20.112975, -90.157388), 1e-14));
  EXPECT_EQ(m.temp_c, 21.68000031);
  EXPECT_EQ(m.extra, (std::vector<std::string>{"0.041565", "0.022023", "0.0055848", "0.0024569",
                                               "0.0065397", "0.008348"}));
}

TEST(IpaImport, SeriesCRobotDescriptionHasTheTmacLink) {
  const KinematicChain chain = chainFromUrdf(seriesC().urdf_xml, "base_link", "tmac");
  ASSERT_EQ(chain.dof(), 6);
  const KinematicChain flange = chainFromUrdfFile(kUr10Urdf, "base_link", "tool0");
  // The tip pose after joint 6 is tool0's offset times X_FlangeTmac.
  const Pose X_FlangeTmac = flange.initialPose(6).inverse() * chain.initialPose(6);
  EXPECT_NEAR(X_FlangeTmac.translation().x(), 0.0, 1e-4);
  EXPECT_NEAR(X_FlangeTmac.translation().y(), 0.0, 1e-4);
  EXPECT_NEAR(X_FlangeTmac.translation().z(), 0.109, 1e-4);  // 109 mm out of the flange
  EXPECT_GT(X_FlangeTmac.linear().col(2).dot(Vec3::UnitZ()), 0.9999);
}

TEST(IpaImport, SeriesCRoundTripsThroughCampaignFiles) {
  const Campaign& c = seriesC();
  TempDir dir;
  writeCampaign(c, (dir.path() / "series_c").string());
  const Campaign back = readCampaign((dir.path() / "series_c").string());
  EXPECT_EQ(back.urdf_xml, c.urdf_xml);
  EXPECT_EQ(back.tip_link, "tmac");
  EXPECT_EQ(back.extra_columns, c.extra_columns);
  EXPECT_TRUE(back.tracker.stated);
  EXPECT_EQ(back.tracker.position_sigma_m, c.tracker.position_sigma_m);
  EXPECT_EQ(back.tracker.orientation_sigma_rad, c.tracker.orientation_sigma_rad);
  test::expectSameRows(c, back);
  // The tracker's digits survive: the written file shows the source's millimetres.
  std::ifstream csv(dir.path() / "series_c" / "measurements.csv");
  std::string header, first;
  std::getline(csv, header);
  std::getline(csv, first);
  EXPECT_NE(first.find(",383.97123,-3240.7562,201.72621,"), std::string::npos) << first;
}

// ---------------------------------------------------------------------------------------------
// Which way round Trafo_TM_F_init.txt is

/// The 4×4 of a Trafo file, translation converted to metres.
Pose readTrafoMatrix(const fs::path& path) {
  std::ifstream in(path);
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    for (int k = 0; k < 4; ++k) in >> M(r, k);
  }
  Pose X = Pose::Identity();
  X.linear() = lie::projectToSO3(M.topLeftCorner<3, 3>());
  X.translation() = M.topRightCorner<3, 1>() * 1e-3;
  return X;
}

/// One data line of a series: its ';' fields with decimal commas made points.
std::vector<double> seriesNumbers(std::string line) {
  std::replace(line.begin(), line.end(), ',', '.');
  std::vector<double> values;
  std::istringstream fields(line);
  std::string field;
  while (std::getline(fields, field, ';')) values.push_back(std::stod(field));
  return values;
}

// The Goal columns are the commanded T-Mac TCP in ROS's base_link (our base_link turned by π
// about z). FK·X⁻¹ reproduces them to well under a millimetre with the nominal UR10, FK·X is
// off by twice the 109 mm offset: the file holds X_TcpFlange.
// The UR10 stood upright before a levelled tracker: registered to the nominal arm, the base's z
// axis is the tracker's vertical to a fraction of a degree, so the importer's gravity_in_base of
// −9.80665 m/s² along the base z holds (and the self weight's torques with it).
TEST(IpaImport, SeriesCBaseIsUprightSoGravityIsMinusZ) {
  const Campaign& c = seriesC();
  ASSERT_TRUE(c.gravity_in_base.has_value());
  EXPECT_EQ(*c.gravity_in_base, Vec3(0.0, 0.0, -9.80665));
  std::vector<const Measurement*> rows;
  for (const Measurement& m : c.rows) rows.push_back(&m);
  const KinematicChain chain = chainFromUrdf(c.urdf_xml, c.base_link, c.tip_link);
  const Pose X_TrackerBase = trainer::registerTracker(chain, rows);
  const double tilt_deg =
      std::acos(std::min(1.0, X_TrackerBase.linear().col(2).dot(Vec3::UnitZ()))) / kRadPerDeg;
  EXPECT_LT(tilt_deg, 0.5);
}

TEST(IpaImport, TrafoFileIsTheFlangeInTheTcpFrame) {
  const KinematicChain flange = chainFromUrdfFile(kUr10Urdf, "base_link", "tool0");
  const Pose X_File = readTrafoMatrix(kSeriesC / "Trafo_TM_F_init.txt");
  Pose X_RosBaseBase = Pose::Identity();
  X_RosBaseBase.linear() = lie::rotationFromRpy(0, 0, kPi);

  std::ifstream in(kSeriesCCsv);
  std::string line;
  std::getline(in, line);  // header: Timestamp;Goal x;…;Goal yaw;6 joints;…
  double max_mm[2] = {0, 0}, max_deg[2] = {0, 0};
  ChainWorkspace ws;
  int rows = 0;
  for (; std::getline(in, line); ++rows) {
    const std::vector<double> v = seriesNumbers(line);
    Pose goal = Pose::Identity();
    goal.translation() = Vec3(v[1], v[2], v[3]);
    goal.linear() = lie::rotationFromRpy(v[4], v[5], v[6]);
    JointVector q(6);
    for (int j = 0; j < 6; ++j) q[j] = v[static_cast<size_t>(7 + j)];
    ASSERT_TRUE(forwardKinematics(flange, q, ws));
    const Pose X_FlangeTcp[2] = {X_File.inverse(), X_File};
    for (int d = 0; d < 2; ++d) {
      const Pose commanded = X_RosBaseBase * tipPose(ws) * X_FlangeTcp[d];
      max_mm[d] = std::max(max_mm[d], (commanded.translation() - goal.translation()).norm() * 1e3);
      max_deg[d] =
          std::max(max_deg[d], lie::angleBetween(commanded.linear(), goal.linear()) / kRadPerDeg);
    }
  }
  std::cout << "Series C, " << rows << " rows, Goal vs FK·X_FlangeTcp:\n"
            << "  X_FlangeTcp = file⁻¹: max " << max_mm[0] << " mm, " << max_deg[0] << " deg\n"
            << "  X_FlangeTcp = file:   max " << max_mm[1] << " mm, " << max_deg[1] << " deg\n";
  EXPECT_LT(max_mm[0], 1.0);
  EXPECT_LT(max_deg[0], 0.1);
  EXPECT_GT(max_mm[1], 200.0);
  EXPECT_GT(max_deg[1], 170.0);
}

// The tracker's T-Mac axes are the TCP axes turned by π about z: R_measured·R_FK(tmac)ᵀ is one
// constant rotation (the tracker's) to a fraction of a degree; with the TCP axes it is not.
TEST(IpaImport, MeasuredOrientationMatchesTheTmacLink) {
  const Campaign& c = seriesC();
  const KinematicChain chain = chainFromUrdf(c.urdf_xml, "base_link", "tmac");
  const Mat3 R_TmacTcp = lie::rotationFromRpy(0, 0, kPi);  // the turn is its own inverse
  ChainWorkspace ws;
  Mat3 R_first[2];
  double spread_deg[2] = {0, 0};
  for (size_t i = 0; i < c.rows.size(); ++i) {
    ASSERT_TRUE(forwardKinematics(chain, c.rows[i].q_rad, ws));
    const Mat3 R_BaseTmac = tipPose(ws).linear();
    const Mat3 R_BaseFrame[2] = {R_BaseTmac, R_BaseTmac * R_TmacTcp};
    for (int f = 0; f < 2; ++f) {
      const Mat3 R_TrackerBase = c.rows[i].X_TrackerTip().linear() * R_BaseFrame[f].transpose();
      if (i == 0) R_first[f] = R_TrackerBase;
      spread_deg[f] = std::max(spread_deg[f], lie::angleBetween(R_first[f], R_TrackerBase) / kRadPerDeg);
    }
  }
  std::cout << "Series C, spread of R_TrackerBase: tmac axes " << spread_deg[0] << " deg, TCP axes "
            << spread_deg[1] << " deg\n";
  EXPECT_LT(spread_deg[0], 1.0);
  EXPECT_GT(spread_deg[1], 45.0);
}

// ---------------------------------------------------------------------------------------------
// Broken synthetic series

const char* const kHeader =
    "Timestamp;Goal x;Goal y;Goal z;Goal roll;Goal pitch;Goal yaw;shoulder_pan_joint;"
    "shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;"
    "measurement_temperature;measurement_x;measurement_std_x;measurement_y;measurement_std_y;"
    "measurement_z;measurement_std_z;measurement_rx;measurement_std_rx;measurement_ry;"
    "measurement_std_ry;measurement_rz;measurement_std_rz";
const std::vector<std::string> kRows = {
    "2,02011E+13;-0,000181978;-0,365141;1,4273;1,57005;1,56969;-0,000186977;-3,14159;-1,5708;0;"
    "-1,5708;0;0;21,68000031;383,97123;0,041565;-3240,7562;0,022023;201,72621;0,0055848;"
    "-90,179563;0,0024569;-20,112975;0,0065397;-90,157388;0,008348",
    "2,02011E+13;0,0103459;-0,480444;1,00632;3,10253;1,66683;1,57927;-4,08444;-2,6946;1,69873;"
    "-2,031;0,99275;-0,0673035;21,68000031;335,14778;0,0054521;-3134,3677;0,0062093;"
    "-221,16088;0,0076535;-84,20352;0,00099888;-22,726835;0,0026542;-88,245609;0,0014716",
    "2,02011E+13;-0,0051336;-0,413612;0,846258;3,60029;1,58947;1,66501;-3,65442;-2,82442;"
    "2,02635;-2,23002;0,148482;-0,104726;21,68000031;366,98838;0,0053833;-3193,923;0,0014461;"
    "-379,93994;0,0037511;-89,065785;0,0018116;0,79839706;0,0022225;-89,749441;0,0022997"};
// As in the data set: CRLF, "-0." and "1.", no final newline.
const char* const kTrafo =
    "-0.00079633 0.99999968 -0. -0.\r\n"
    "-0.99999937 -0.00079633 -0.00079633 0.08679961\r\n"
    "-0.00079633 -0.00000063 0.99999968 -108.99996544\r\n"
    "0. 0. 0. 1.";

/// Text of the header and rows with one field replaced (line 1 = header).
std::string seriesText(int line = 0, const std::string& column = "",
                       const std::string& value = "") {
  std::vector<std::string> lines = {kHeader};
  lines.insert(lines.end(), kRows.begin(), kRows.end());
  if (line > 0) {
    std::vector<std::string> names, fields;
    std::istringstream h(kHeader), f(lines[static_cast<size_t>(line - 1)]);
    for (std::string s; std::getline(h, s, ';');) names.push_back(s);
    for (std::string s; std::getline(f, s, ';');) fields.push_back(s);
    const size_t i =
        static_cast<size_t>(std::find(names.begin(), names.end(), column) - names.begin());
    EXPECT_LT(i, names.size()) << "test bug: no column " << column;
    fields[i] = value;
    std::string joined;
    for (size_t k = 0; k < fields.size(); ++k) joined += (k ? ";" : "") + fields[k];
    lines[static_cast<size_t>(line - 1)] = joined;
  }
  std::string out;
  for (const std::string& l : lines) out += l + "\r\n";
  return out;
}

/// Imports a synthetic series folder; expects a refusal at file/line/column naming parts.
void expectRefused(const std::string& series, const char* trafo, const std::string& file, int line,
                   const std::string& column, const std::vector<std::string>& message_parts,
                   int validation_from_row = -1, const std::string& urdf = kUr10Urdf) {
  TempDir dir;
  writeText(dir.path() / "series.csv", series);
  if (trafo) writeText(dir.path() / "Trafo_TM_F_init.txt", trafo);
  test::expectInputError(
      [&] {
        importers::importIpaSeries((dir.path() / "series.csv").string(), validation_from_row,
                                   urdf);
      },
      file, line, column, message_parts);
}

TEST(IpaImport, SyntheticSeriesImports) {
  TempDir dir;
  std::string text = seriesText();
  text.resize(text.size() - 2);  // like Series A: no final newline
  writeText(dir.path() / "series.csv", text);
  writeText(dir.path() / "Trafo_TM_F_init.txt", kTrafo);
  const Campaign c = importers::importIpaSeries((dir.path() / "series.csv").string(), 1, kUr10Urdf);
  ASSERT_EQ(c.rows.size(), 3u);
  EXPECT_EQ(c.rows[0].set, RowSet::kGeometry);
  EXPECT_EQ(c.rows[1].set, RowSet::kValidation);
  EXPECT_EQ(c.rows[2].set, RowSet::kValidation);
  EXPECT_EQ(c.rows[2].p_TipInTracker_m, Vec3(0.36698838, -3.193923, -0.37993994));
  EXPECT_EQ(c.rows[2].q_rad[5], -0.104726);
  EXPECT_EQ(c.rows[1].extra[3], "0.00099888");
}

// A UTF-8 byte-order mark (spreadsheets' "CSV UTF-8") is skipped, as by every reader (csv.hpp).
TEST(IpaImport, SkipsAByteOrderMark) {
  TempDir dir;
  writeText(dir.path() / "series.csv", "\xEF\xBB\xBF" + seriesText());
  writeText(dir.path() / "Trafo_TM_F_init.txt", std::string("\xEF\xBB\xBF") + kTrafo);
  const Campaign marked =
      importers::importIpaSeries((dir.path() / "series.csv").string(), 1, kUr10Urdf);
  writeText(dir.path() / "series.csv", seriesText());
  writeText(dir.path() / "Trafo_TM_F_init.txt", kTrafo);
  const Campaign plain =
      importers::importIpaSeries((dir.path() / "series.csv").string(), 1, kUr10Urdf);
  ASSERT_EQ(marked.rows.size(), 3u);
  EXPECT_EQ(marked.urdf_xml, plain.urdf_xml);  // the same T-Mac transform
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(marked.rows[i].q_rad, plain.rows[i].q_rad);
}

TEST(IpaImport, RefusesAFolderForTheSeries) {
  TempDir dir;
  fs::create_directory(dir.path() / "series.csv");
  test::expectInputError(
      [&] { importers::importIpaSeries((dir.path() / "series.csv").string(), -1, kUr10Urdf); },
      "series.csv", 0, "", {"is a folder; expected a readable file"});
}

TEST(IpaImport, RefusesDecimalPoint) {
  expectRefused(seriesText(3, "measurement_x", "335.14778"), kTrafo, "series.csv", 3,
                "measurement_x",
                {"expected a number with a decimal comma (millimetres), got '335.14778'",
                 "a '.' is not expected"});
}

TEST(IpaImport, RefusesThousandsSeparator) {
  expectRefused(seriesText(2, "measurement_y", "-3.240,7562"), kTrafo, "series.csv", 2,
                "measurement_y", {"got '-3.240,7562'"});
}

TEST(IpaImport, RefusesTwoDecimalCommas) {
  expectRefused(seriesText(4, "elbow_joint", "2,026,35"), kTrafo, "series.csv", 4, "elbow_joint",
                {"expected a number with a decimal comma (radians), got '2,026,35'"});
}

TEST(IpaImport, RefusesEmptyValue) {
  expectRefused(seriesText(2, "measurement_temperature", ""), kTrafo, "series.csv", 2,
                "measurement_temperature", {"(degrees Celsius), got ''"});
}

TEST(IpaImport, RefusesMissingColumn) {
  std::string header = kHeader;
  header = header.substr(0, header.find(";measurement_rz"));
  std::string text = header + "\r\n";
  for (const std::string& row : kRows)
    text += row.substr(0, row.rfind(';', row.rfind(';') - 1)) + "\r\n";
  expectRefused(text, kTrafo, "series.csv", 1, "measurement_rz",
                {"required column 'measurement_rz' is missing"});
}

TEST(IpaImport, RefusesDuplicateAndUnknownColumns) {
  expectRefused(seriesText(1, "measurement_std_ry", "Goal x"), kTrafo, "series.csv", 1, "Goal x",
                {"'Goal x' appears twice"});
  expectRefused(seriesText(1, "measurement_std_ry", "Goal_x"), kTrafo, "series.csv", 1, "Goal_x",
                {"unknown column 'Goal_x'"});
}

TEST(IpaImport, RefusesShortRow) {
  std::string text = seriesText();
  text += kRows[0].substr(0, kRows[0].rfind(';')) + "\r\n";
  expectRefused(text, kTrafo, "series.csv", 5, "", {"row has 25 fields; expected 26"});
}

TEST(IpaImport, RefusesEmptyLineInTheMiddle) {
  std::string text = seriesText();
  text.insert(text.find("\r\n") + 2, "\r\n");
  expectRefused(text, kTrafo, "series.csv", 2, "", {"row has 1 fields; expected 26"});
}

TEST(IpaImport, RefusesHeaderOnly) {
  expectRefused(std::string(kHeader) + "\r\n", kTrafo, "series.csv", 1, "", {"no rows"});
}

TEST(IpaImport, RefusesValidationRowPastTheEnd) {
  expectRefused(seriesText(), kTrafo, "series.csv", 0, "", {"validation_from_row is 3", "0 … 2"},
                3);
}

TEST(IpaImport, RefusesMissingTrafoFile) {
  expectRefused(seriesText(), nullptr, "Trafo_TM_F_init.txt", 0, "",
                {"not found", "expected a readable file"});
}

TEST(IpaImport, RefusesBadTrafoNumber) {
  expectRefused(seriesText(),
                "-0.00079633 0.99999968 -0. -0.\n"
                "-0.99999937 -0.00079633 -0,00079633 0.08679961\n"
                "-0.00079633 -0.00000063 0.99999968 -108.99996544\n"
                "0. 0. 0. 1.\n",
                "Trafo_TM_F_init.txt", 2, "3",
                {"expected a number with a decimal point, got '-0,00079633'"});
}

TEST(IpaImport, RefusesTrafoRowOfThree) {
  expectRefused(seriesText(),
                "-0.00079633 0.99999968 -0. -0.\n"
                "-0.99999937 -0.00079633 0.08679961\n"
                "-0.00079633 -0.00000063 0.99999968 -108.99996544\n"
                "0. 0. 0. 1.\n",
                "Trafo_TM_F_init.txt", 2, "", {"row has 3 numbers; expected 4"});
}

TEST(IpaImport, RefusesTrafoWithThreeRows) {
  expectRefused(seriesText(), "1. 0. 0. 0.\n0. 1. 0. 0.\n0. 0. 1. 0.\n", "Trafo_TM_F_init.txt", 0,
                "", {"has 3 lines; expected the 4 rows"});
}

TEST(IpaImport, RefusesTrafoThatIsNotRigid) {
  expectRefused(seriesText(), "1. 0. 0. 0.\n0. 1. 0. 0.\n0. 0. 2. 0.\n0. 0. 0. 1.",
                "Trafo_TM_F_init.txt", 0, "", {"expected a rigid transform", "off by 3"});
  expectRefused(seriesText(), "1. 0. 0. 0.\n0. 1. 0. 0.\n0. 0. -1. 0.\n0. 0. 0. 1.",
                "Trafo_TM_F_init.txt", 0, "", {"determinant +1"});
}

TEST(IpaImport, RefusesUrdfWithoutRobotElement) {
  TempDir dir;
  writeText(dir.path() / "broken.urdf", "<robot name=\"ur10\">");
  expectRefused(seriesText(), kTrafo, "broken.urdf", 0, "", {"ending with </robot>"}, -1,
                (dir.path() / "broken.urdf").string());
}

}  // namespace
}  // namespace stepcal
