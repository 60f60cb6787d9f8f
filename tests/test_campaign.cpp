// Campaign files (campaign-format.md): reading, writing, exact round trip, and refusal of
// broken input with file, line, column, the bad value and what was expected.
//
// Decided: a measurements.csv with a header but no rows is refused (a campaign without rows
// is never meaningful and usually a failed export); writeCampaign refuses it likewise.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/units.hpp"
#include "support/campaign_rows.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

// Line numbers below refer to these texts: yaml keys on lines 1…10, csv header on line 1.
const char* const kValidYaml =
    "format: stepcal-campaign/1\n"
    "robot: robot.urdf\n"
    "base_link: base_link\n"
    "tip_link: tmac\n"
    "sensor_link: ft_sensor\n"
    "measurements: measurements.csv\n"
    "tracker:\n"
    "  position_sigma_mm: 0.015\n"
    "  orientation_sigma_deg: 0.01\n"
    "gravity_in_base: [0, 0, -9.80665]\n";

const char* const kValidCsv =
    "seq,pose_id,set,load_kg,q1_deg,q2_deg,q3_deg,fx_n,fy_n,fz_n,mx_nm,my_nm,mz_nm,"
    "x_mm,y_mm,z_mm,qw,qx,qy,qz,temp_c,note\n"
    "1,p1,geometry,0,10,-20.5,90,,,,,,,1000.5,-200,300,1,0,0,0,21.5,first\n"
    "2,p1,stiffness,20,10,-20.5,90,1,2,-196.133,0.1,0.2,0.3,1000.25,-200.125,299.5,,,,,21.75,\n"
    "3,p2,validation,0,-45,0,180,0,0,0,0,0,0,500,600,700,0.5,0.5,-0.5,0.5,,third\n";

const char* const kUrdf = "<robot name=\"r\"><link name=\"base_link\"/></robot>\n";

using test::readText;
using test::sameBits;
using test::TempDir;
using test::writeText;

/// Writes a campaign folder from texts (the robot file is always robot.urdf).
void writeFolder(const fs::path& dir, const std::string& yaml, const std::string& csv) {
  writeText(dir / "campaign.yaml", yaml);
  writeText(dir / "robot.urdf", kUrdf);
  writeText(dir / "measurements.csv", csv);
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "test bug: '" << from << "' not in text";
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

std::vector<std::string> splitOn(const std::string& s, char separator) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(s);
  while (std::getline(in, part, separator)) parts.push_back(part);
  if (!s.empty() && s.back() == separator) parts.emplace_back();
  return parts;
}

/// The csv text with the field of `column` on 1-based `line` set to value (line 1 = header).
std::string withField(const std::string& csv, int line, const std::string& column,
                      const std::string& value) {
  std::vector<std::string> lines = splitOn(csv, '\n');
  const std::vector<std::string> header = splitOn(lines[0], ',');
  const auto it = std::find(header.begin(), header.end(), column);
  EXPECT_NE(it, header.end()) << "test bug: no column " << column;
  std::vector<std::string> fields = splitOn(lines[static_cast<size_t>(line - 1)], ',');
  fields[static_cast<size_t>(it - header.begin())] = value;
  std::string joined_line;
  for (size_t i = 0; i < fields.size(); ++i) joined_line += (i ? "," : "") + fields[i];
  lines[static_cast<size_t>(line - 1)] = joined_line;
  std::string out;
  for (size_t i = 0; i + 1 < lines.size(); ++i) out += lines[i] + "\n";
  return out + lines.back();
}

/// The csv text without one column.
std::string withoutColumn(const std::string& csv, const std::string& column) {
  std::vector<std::string> lines = splitOn(csv, '\n');
  const std::vector<std::string> header = splitOn(lines[0], ',');
  const size_t index =
      static_cast<size_t>(std::find(header.begin(), header.end(), column) - header.begin());
  std::string out;
  for (size_t l = 0; l < lines.size(); ++l) {
    if (lines[l].empty()) continue;
    std::vector<std::string> fields = splitOn(lines[l], ',');
    fields.erase(fields.begin() + static_cast<std::ptrdiff_t>(index));
    for (size_t i = 0; i < fields.size(); ++i) out += (i ? "," : "") + fields[i];
    out += "\n";
  }
  return out;
}

/// Reads a folder built from the texts and checks where and what it reports.
void expectRefused(const std::string& yaml, const std::string& csv, const std::string& file,
                   int line, const std::string& column,
                   const std::vector<std::string>& message_parts) {
  TempDir dir;
  writeFolder(dir.path(), yaml, csv);
  test::expectInputError([&] { readCampaign(dir.path().string()); }, file, line, column,
                         message_parts);
}

void expectCsvRefused(const std::string& csv, int line, const std::string& column,
                      const std::vector<std::string>& message_parts) {
  expectRefused(kValidYaml, csv, "measurements.csv", line, column, message_parts);
}

void expectYamlRefused(const std::string& yaml, int line,
                       const std::vector<std::string>& message_parts) {
  expectRefused(yaml, kValidCsv, "campaign.yaml", line, "", message_parts);
}


// ---------------------------------------------------------------------------------------------
// Reading valid files

TEST(Campaign, ReadsTheValidExampleInSiUnits) {
  TempDir dir;
  writeFolder(dir.path(), kValidYaml, kValidCsv);
  const Campaign c = readCampaign(dir.path().string());

  EXPECT_EQ(c.directory, dir.path().string());
  EXPECT_EQ(c.robot_file, "robot.urdf");
  EXPECT_EQ(c.urdf_xml, kUrdf);
  EXPECT_EQ(c.base_link, "base_link");
  EXPECT_EQ(c.tip_link, "tmac");
  EXPECT_EQ(c.sensor_link, "ft_sensor");
  EXPECT_EQ(c.measurements_file, "measurements.csv");
  EXPECT_TRUE(c.tracker.stated);
  EXPECT_DOUBLE_EQ(c.tracker.position_sigma_m, 15e-6);
  EXPECT_DOUBLE_EQ(c.tracker.orientation_sigma_rad, 0.01 * kRadPerDeg);
  ASSERT_TRUE(c.gravity_in_base.has_value());
  EXPECT_EQ(*c.gravity_in_base, Vec3(0, 0, -9.80665));
  EXPECT_EQ(c.joint_count, 3);
  EXPECT_EQ(c.extra_columns, std::vector<std::string>{"note"});
  ASSERT_EQ(c.rows.size(), 3u);

  const Measurement& a = c.rows[0];
  EXPECT_EQ(a.seq, 1);
  EXPECT_EQ(a.pose_id, "p1");
  EXPECT_EQ(a.set, RowSet::kGeometry);
  EXPECT_EQ(a.load_kg, 0.0);
  ASSERT_EQ(a.q_rad.size(), 3);
  EXPECT_DOUBLE_EQ(a.q_rad[0], 10 * kRadPerDeg);
  EXPECT_DOUBLE_EQ(a.q_rad[1], -20.5 * kRadPerDeg);
  EXPECT_EQ(a.q_rad[2], kPi / 2);  // correctly rounded: "90" is exactly the double nearest π/2
  EXPECT_FALSE(a.has_wrench);
  EXPECT_EQ(a.wrenchOrZero(), Vec6::Zero());
  EXPECT_EQ(a.p_TipInTracker_m, Vec3(1.0005, -0.2, 0.3));  // mm → m by moving the point: exact
  EXPECT_TRUE(a.has_orientation);
  EXPECT_EQ(a.q_TrackerTip.coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_EQ(a.temp_c, 21.5);
  EXPECT_EQ(a.extra, std::vector<std::string>{"first"});
  EXPECT_EQ(a.source_line, 2);

  const Measurement& b = c.rows[1];
  EXPECT_EQ(b.set, RowSet::kStiffness);
  EXPECT_EQ(b.load_kg, 20.0);
  EXPECT_TRUE(b.has_wrench);
  Vec6 wrench;
  wrench << 1, 2, -196.133, 0.1, 0.2, 0.3;
  EXPECT_EQ(b.wrench_Sensor, wrench);
  EXPECT_FALSE(b.has_orientation);
  EXPECT_TRUE(b.X_TrackerTip().linear().isIdentity(0.0));
  EXPECT_EQ(b.X_TrackerTip().translation(), Vec3(1.00025, -0.200125, 0.2995));
  EXPECT_EQ(b.extra, std::vector<std::string>{""});

  const Measurement& d = c.rows[2];
  EXPECT_EQ(d.set, RowSet::kValidation);
  EXPECT_TRUE(d.has_wrench);  // zeros given on an unloaded row: a reading of zero
  EXPECT_EQ(d.wrench_Sensor, Vec6::Zero());
  EXPECT_FALSE(d.temp_c.has_value());
  // qw, qx, qy, qz = 0.5, 0.5, −0.5, 0.5: columns of R are the tip axes in tracker axes.
  const Mat3 R = d.X_TrackerTip().linear();
  const Mat3 expected = Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5).toRotationMatrix();
  EXPECT_TRUE(R.isApprox(expected, 1e-15));
  EXPECT_EQ(d.X_TrackerTip().translation(), Vec3(0.5, 0.6, 0.7));

  EXPECT_EQ(c.rowsIn(RowSet::kGeometry).size(), 1u);
  EXPECT_EQ(c.rowsIn(RowSet::kStiffness).front(), &c.rows[1]);
  EXPECT_TRUE(c.rowsIn(RowSet::kResidual).empty());
  EXPECT_EQ(c.rowsIn(RowSet::kValidation).front(), &c.rows[2]);
}

TEST(Campaign, AcceptsYamlPathJsonCrlfNoFinalNewlineAndAnyColumnOrder) {
  TempDir dir;
  std::string crlf;
  for (const char ch : std::string(kValidCsv))
    crlf += ch == '\n' ? std::string("\r\n") : std::string(1, ch);
  crlf.resize(crlf.size() - 2);  // and no final newline
  const char* json =
      "{\"format\": \"stepcal-campaign/1\", \"robot\": \"robot.urdf\", \"base_link\": "
      "\"base_link\", \"tip_link\": \"tmac\", \"measurements\": \"m.csv\"}";
  writeText(dir.path() / "c.json", json);
  writeText(dir.path() / "robot.urdf", kUrdf);
  // Columns reversed.
  std::string reversed;
  for (const std::string& line : splitOn(kValidCsv, '\n')) {
    if (line.empty()) continue;
    const std::vector<std::string> f = splitOn(line, ',');
    for (size_t i = f.size(); i-- > 0;) reversed += f[i] + (i ? "," : "\n");
  }
  writeText(dir.path() / "m.csv", crlf);
  const Campaign a = readCampaign((dir.path() / "c.json").string());
  writeText(dir.path() / "m.csv", reversed);
  const Campaign b = readCampaign((dir.path() / "c.json").string());

  EXPECT_FALSE(a.tracker.stated);
  EXPECT_FALSE(a.gravity_in_base.has_value());
  EXPECT_TRUE(a.sensor_link.empty());
  ASSERT_EQ(a.rows.size(), 3u);
  ASSERT_EQ(b.rows.size(), 3u);
  EXPECT_EQ(a.rows[2].extra, std::vector<std::string>{"third"});  // no CR left on the last field
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(a.rows[i].q_rad, b.rows[i].q_rad);
    EXPECT_EQ(a.rows[i].p_TipInTracker_m, b.rows[i].p_TipInTracker_m);
    EXPECT_EQ(a.rows[i].wrench_Sensor, b.rows[i].wrench_Sensor);
    EXPECT_EQ(a.rows[i].extra, b.rows[i].extra);
  }
}

TEST(Campaign, MinimalCsvWithoutOptionalColumns) {
  TempDir dir;
  writeFolder(dir.path(), kValidYaml,
              "seq,pose_id,set,load_kg,q1_deg,x_mm,y_mm,z_mm\n7,a,residual,0,1e1,-0,1.5e-3,2E2\n");
  const Campaign c = readCampaign((dir.path() / "campaign.yaml").string());
  ASSERT_EQ(c.rows.size(), 1u);
  const Measurement& m = c.rows[0];
  EXPECT_EQ(c.joint_count, 1);
  EXPECT_TRUE(c.extra_columns.empty());
  EXPECT_EQ(m.set, RowSet::kResidual);
  EXPECT_DOUBLE_EQ(m.q_rad[0], 10 * kRadPerDeg);
  EXPECT_TRUE(std::signbit(m.p_TipInTracker_m.x()));
  EXPECT_EQ(m.p_TipInTracker_m.y(), 1.5e-6);
  EXPECT_EQ(m.p_TipInTracker_m.z(), 0.2);
  EXPECT_FALSE(m.has_wrench);
  EXPECT_FALSE(m.has_orientation);
  EXPECT_FALSE(m.temp_c.has_value());
}

TEST(Campaign, SetNames) {
  EXPECT_STREQ(toString(RowSet::kGeometry), "geometry");
  EXPECT_STREQ(toString(RowSet::kStiffness), "stiffness");
  EXPECT_STREQ(toString(RowSet::kResidual), "residual");
  EXPECT_STREQ(toString(RowSet::kValidation), "validation");
}

// ---------------------------------------------------------------------------------------------
// Round trip

/// Values with many digits and extreme magnitudes, to stress the mm and deg conversions.
double awkward(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::uniform_int_distribution<int> pick(0, 19);
  switch (pick(rng)) {
    case 0:
      return 0.0;
    case 1:
      return -0.0;
    case 2:
      return std::ldexp(uniform(rng), -1000);  // near the bottom of the double range
    case 3:
      return uniform(rng) * 1e12;
    case 4:
      return std::nextafter(scale, 0.0);
    default:
      return uniform(rng) * scale;
  }
}

Campaign randomCampaign(std::mt19937_64& rng, int rows) {
  Campaign c;
  c.urdf_xml = "<robot name=\"x\">\r\n  <!-- kept verbatim -->\n</robot>";
  c.base_link = "base_link";
  c.tip_link = "tool0";
  c.sensor_link = "ft_sensor";
  c.tracker.stated = true;
  c.tracker.position_sigma_m = 0.1 + 1e-17;
  c.tracker.orientation_sigma_rad = 1e-3 / 3.0;
  c.gravity_in_base = Vec3(0.1 / 3.0, -1e-300, -9.80665);
  c.joint_count = 6;
  c.extra_columns = {"note", "std_x_mm", "q_tag"};
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int i = 0; i < rows; ++i) {
    Measurement m;
    m.seq = 1000 - 3 * i;
    m.pose_id = "p" + std::to_string(i / 4) + "_x";
    m.set = static_cast<RowSet>(i % 4);
    m.has_wrench = i % 3 != 0;
    m.load_kg = m.has_wrench ? 40.0 / 3.0 : 0.0;
    m.q_rad.resize(6);
    for (int j = 0; j < 6; ++j) m.q_rad[j] = awkward(rng, 2.0 * kPi);
    for (int a = 0; a < 6; ++a) m.wrench_Sensor[a] = m.has_wrench ? awkward(rng, 300.0) : 0.0;
    for (int a = 0; a < 3; ++a) m.p_TipInTracker_m[a] = awkward(rng, 5.0);
    m.has_orientation = i % 5 != 1;
    if (m.has_orientation) {
      m.q_TrackerTip =
          Eigen::Quaterniond(uniform(rng), uniform(rng), uniform(rng), uniform(rng)).normalized();
    }
    if (i % 7 != 2) m.temp_c = 20.0 + uniform(rng);
    m.extra = {i % 2 ? "text with spaces and \"quotes\"" : "", std::to_string(uniform(rng)),
               "t" + std::to_string(i)};
    c.rows.push_back(m);
  }
  return c;
}

void expectSameCampaign(const Campaign& a, const Campaign& b) {
  EXPECT_EQ(a.urdf_xml, b.urdf_xml);
  EXPECT_EQ(a.base_link, b.base_link);
  EXPECT_EQ(a.tip_link, b.tip_link);
  EXPECT_EQ(a.sensor_link, b.sensor_link);
  EXPECT_EQ(a.tracker.stated, b.tracker.stated);
  EXPECT_TRUE(sameBits(a.tracker.position_sigma_m, b.tracker.position_sigma_m));
  EXPECT_TRUE(sameBits(a.tracker.orientation_sigma_rad, b.tracker.orientation_sigma_rad));
  ASSERT_EQ(a.gravity_in_base.has_value(), b.gravity_in_base.has_value());
  if (a.gravity_in_base) {
    EXPECT_EQ(*a.gravity_in_base, *b.gravity_in_base);
  }
  EXPECT_EQ(a.joint_count, b.joint_count);
  EXPECT_EQ(a.extra_columns, b.extra_columns);
  test::expectSameRows(a, b, test::DoubleMatch::kSameBits);
}

TEST(Campaign, RoundTripIsBitExact) {
  std::mt19937_64 rng(20240607);
  const Campaign original = randomCampaign(rng, 2000);
  TempDir dir;
  const fs::path folder = dir.path() / "nested" / "campaign";
  writeCampaign(original, folder.string());
  const Campaign once = readCampaign(folder.string());
  expectSameCampaign(original, once);
  EXPECT_EQ(once.robot_file, "robot.urdf");
  EXPECT_EQ(once.measurements_file, "measurements.csv");
  // Written again, the files are identical: the written form is a fixed point.
  const fs::path again = dir.path() / "again";
  writeCampaign(once, again.string());
  for (const char* name : {"campaign.yaml", "robot.urdf", "measurements.csv"}) {
    EXPECT_EQ(readText(folder / name), readText(again / name)) << name;
  }
}

TEST(Campaign, WritesReadableNumbersAndOmitsUnusedColumns) {
  Campaign c;
  c.urdf_xml = kUrdf;
  c.base_link = "base_link";
  c.tip_link = "tmac";
  c.joint_count = 2;
  Measurement m;
  m.seq = 0;
  m.pose_id = "r0000";
  m.q_rad.resize(2);
  m.q_rad << kPi / 2, -0.1 * kRadPerDeg;
  m.p_TipInTracker_m = Vec3(1.2345, -0.0005, 12.0);
  c.rows.push_back(m);
  TempDir dir;
  writeCampaign(c, dir.path().string());
  EXPECT_EQ(readText(dir.path() / "measurements.csv"),
            "seq,pose_id,set,load_kg,q1_deg,q2_deg,x_mm,y_mm,z_mm\n"
            "0,r0000,geometry,0,90,-0.1,1234.5,-0.5,12000\n");
  const std::string yaml_text = readText(dir.path() / "campaign.yaml");
  EXPECT_EQ(yaml_text.find("tracker"), std::string::npos);
  EXPECT_EQ(yaml_text.find("sensor_link"), std::string::npos);
  EXPECT_EQ(yaml_text.find("gravity_in_base"), std::string::npos);
  expectSameCampaign(c, readCampaign(dir.path().string()));
}

/// writeCampaign refuses what the format cannot hold, naming the row and column.
void expectWriteRefused(const Campaign& c, int line, const std::string& column,
                        const char* message_part) {
  TempDir dir;
  test::expectInputError([&] { writeCampaign(c, (dir.path() / "out").string()); },
                         "measurements.csv", line, column, {message_part});
  EXPECT_FALSE(fs::exists(dir.path() / "out")) << "nothing is written on a refusal";
}

TEST(Campaign, WriteRefusesWhatTheFormatCannotHold) {
  std::mt19937_64 rng(1);
  const Campaign valid = randomCampaign(rng, 3);

  Campaign comma = valid;
  comma.rows[1].pose_id = "a,b";
  expectWriteRefused(comma, 3, "pose_id", "'a,b'");

  Campaign quote = valid;
  quote.rows[2].pose_id = "say \"x\"";
  expectWriteRefused(quote, 4, "pose_id", "quotes");

  Campaign extra = valid;
  extra.rows[0].extra[1] = "1,5";
  expectWriteRefused(extra, 2, "std_x_mm", "'1,5'");

  Campaign loaded = valid;
  loaded.rows[0].load_kg = 20.0;
  loaded.rows[0].has_wrench = false;
  expectWriteRefused(loaded, 2, "load_kg", "wrench");

  Campaign seq = valid;
  seq.rows[2].seq = seq.rows[0].seq;
  expectWriteRefused(seq, 4, "seq", "unique");

  Campaign clash = valid;
  clash.extra_columns[0] = "q7_deg";  // would read back as a joint column
  expectWriteRefused(clash, 1, "q7_deg", "not a format column");

  Campaign empty = valid;
  empty.rows.clear();
  expectWriteRefused(empty, 0, "", "no rows");
}

// ---------------------------------------------------------------------------------------------
// Broken campaign.yaml

/// kValidYaml with `from` replaced by `to`, refused on `line` with every one of `parts`.
struct YamlEdit {
  const char* name;
  const char* from;
  const char* to;
  int line;
  std::vector<std::string> parts;
};
void PrintTo(const YamlEdit& edit, std::ostream* out) { *out << edit.name; }

const YamlEdit kYamlEdits[] = {
    {"WrongFormatString", "stepcal-campaign/1", "stepcal-campaign/2", 1,
     {"'stepcal-campaign/2'", "expected 'stepcal-campaign/1'"}},
    {"MissingYamlKey", "tip_link: tmac\n", "", 0, {"'tip_link'", "missing", "expected the keys"}},
    {"UnknownYamlKey", "tip_link:", "tip_lnk:", 4,
     {"unknown key 'tip_lnk'", "did you mean 'tip_link'"}},
    {"UnknownTrackerKey", "position_sigma_mm", "position_sigma_m", 8,
     {"unknown key 'position_sigma_m'", "did you mean 'position_sigma_mm'"}},
    {"NonPositiveTrackerSigma", "0.015", "-0.015", 8,
     {"'-0.015'", "expected a number > 0 (millimetres)"}},
    {"GravityWithTwoNumbers", "[0, 0, -9.80665]", "[0, -9.80665]", 10,
     {"gravity_in_base", "expected a list of 3 numbers", "a list"}},
    {"GravityNotANumber", "[0, 0, -9.80665]", "[0, 0, .nan]", 10,
     {"'.nan'", "expected a number (m/s^2)"}},
    {"EmptyLinkName", "base_link: base_link", "base_link:", 3,
     {"'base_link'", "expected a link name", "got nothing"}},
    {"YamlSyntaxError", "[0, 0, -9.80665]", "[0, 0, -9.80665", 11, {"not valid YAML"}},
    {"RobotFileMissing", "robot: robot.urdf", "robot: robt.urdf", 2,
     {"robt.urdf", "does not exist", "relative to the folder of campaign.yaml"}},
    {"MeasurementsFileMissing", "measurements: measurements.csv", "measurements: m.csv", 6,
     {"m.csv", "does not exist"}},
};

class BrokenYaml : public ::testing::TestWithParam<YamlEdit> {};

TEST_P(BrokenYaml, IsRefusedOnItsLine) {
  const YamlEdit& edit = GetParam();
  expectYamlRefused(replaced(kValidYaml, edit.from, edit.to), edit.line, edit.parts);
}

INSTANTIATE_TEST_SUITE_P(CampaignRefuses, BrokenYaml, ::testing::ValuesIn(kYamlEdits),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(CampaignRefuses, DuplicateYamlKey) {
  expectYamlRefused(std::string(kValidYaml) + "robot: other.urdf\n", 11,
                    {"'robot'", "twice", "line 2"});
}

TEST(CampaignRefuses, NoCampaignAtPath) {
  TempDir dir;
  const test::Refusal r = test::refusalOf([&] { readCampaign(dir.path().string()); });
  EXPECT_EQ(r.file, "campaign.yaml");
  EXPECT_EQ(r.line, 0);
  EXPECT_NE(r.what.find("expected a campaign folder containing campaign.yaml"), std::string::npos)
      << r.what;
}

// ---------------------------------------------------------------------------------------------
// Broken measurements.csv: one field or one column

/// kValidCsv with the field of `column` on `line` (1 = header) set to `value`; refused on that
/// line at `reported_column` with every one of `parts`.
struct CsvFieldEdit {
  const char* name;
  int line;
  const char* column;
  const char* value;
  const char* reported_column;
  std::vector<std::string> parts;
};
void PrintTo(const CsvFieldEdit& edit, std::ostream* out) { *out << edit.name; }

const CsvFieldEdit kCsvFieldEdits[] = {
    // Header
    {"MisspelledRequiredColumn", 1, "x_mm", "x_m", "x_mm",
     {"required column 'x_mm' is missing", "did you mean 'x_m'"}},
    {"DuplicateColumn", 1, "note", "temp_c", "temp_c", {"'temp_c' appears twice"}},
    {"GapInJointColumns", 1, "q3_deg", "q4_deg", "q3_deg",
     {"'q3_deg' is missing but 'q4_deg' exists", "without gaps"}},
    {"BadJointColumnName", 1, "q3_deg", "q03_deg", "q03_deg", {"'q03_deg'", "no leading zeros"}},
    {"EmptyColumnName", 1, "note", "note,", "", {"column 23 has an empty name"}},
    // Rows
    {"NonNumericValue", 3, "q2_deg", "abc", "q2_deg", {"expected a number (degrees), got 'abc'"}},
    {"TrailingCharacters", 2, "y_mm", "1.5x", "y_mm",
     {"expected a number (millimetres), got '1.5x'"}},
    {"TwoSignsInTheExponent", 2, "y_mm", "1e+-5", "y_mm", {"got '1e+-5'"}},
    {"EmptyRequiredValue", 4, "q1_deg", "", "q1_deg", {"got ''", "the field is empty"}},
    {"SpacesAroundValue", 4, "load_kg", " 0", "load_kg", {"got ' 0'", "no spaces"}},
    // "12,5" splits into two fields: the row is one field too long.
    {"DecimalComma", 3, "q3_deg", "12,5", "",
     {"row has 23 fields; expected 22", "decimal point must be '.'"}},
    {"NotANumber", 2, "x_mm", "nan", "x_mm", {"got 'nan'", "must be finite"}},
    {"Infinity", 3, "fx_n", "inf", "fx_n",
     {"expected a number (newtons), got 'inf'", "must be finite"}},
    {"OutOfRange", 2, "temp_c", "1e999", "temp_c", {"got '1e999'", "out of range"}},
    {"BadSetName", 2, "set", "Geometry", "set",
     {"expected geometry, stiffness, residual or validation, got 'Geometry'"}},
    {"NegativeLoad", 4, "load_kg", "-1", "load_kg", {"expected a mass >= 0 (kilograms), got '-1'"}},
    {"HalfAWrenchOnARow", 3, "fz_n", "", "fz_n",
     {"got '' but fx_n is '1'", "all six wrench values or none"}},
    {"NonUnitQuaternion", 4, "qw", "0.6", "qw",
     {"(0.6, 0.5, -0.5, 0.5)", "has norm", "expected a unit quaternion"}},
    {"HalfAQuaternionOnARow", 2, "qy", "", "qy",
     {"got '' but qw is '1'", "all four quaternion values"}},
    {"DuplicateSeq", 4, "seq", "1", "seq", {"seq '1' already appears on line 2", "unique"}},
    {"NonIntegerSeq", 3, "seq", "2.0", "seq", {"expected an integer, got '2.0'"}},
    {"EmptyPoseId", 3, "pose_id", "", "pose_id", {"expected a pose id", "got ''"}},
};

class BrokenCsvField : public ::testing::TestWithParam<CsvFieldEdit> {};

TEST_P(BrokenCsvField, IsRefusedOnItsLineAndColumn) {
  const CsvFieldEdit& edit = GetParam();
  expectCsvRefused(withField(kValidCsv, edit.line, edit.column, edit.value), edit.line,
                   edit.reported_column, edit.parts);
}

INSTANTIATE_TEST_SUITE_P(CampaignRefuses, BrokenCsvField, ::testing::ValuesIn(kCsvFieldEdits),
                         [](const auto& info) { return std::string(info.param.name); });

/// kValidCsv without `column`; refused on the header line at that column with every `parts`.
struct CsvColumnRemoval {
  const char* name;
  const char* column;
  std::vector<std::string> parts;
};
void PrintTo(const CsvColumnRemoval& removal, std::ostream* out) { *out << removal.name; }

const CsvColumnRemoval kCsvColumnRemovals[] = {
    {"MissingRequiredColumn", "set", {"required column 'set'"}},
    {"HalfAWrenchInTheHeader", "my_nm", {"'my_nm' is missing", "all together or none"}},
    {"HalfAQuaternionInTheHeader", "qw", {"'qw' is missing"}},
};

class MissingCsvColumn : public ::testing::TestWithParam<CsvColumnRemoval> {};

TEST_P(MissingCsvColumn, IsRefusedOnTheHeader) {
  const CsvColumnRemoval& removal = GetParam();
  expectCsvRefused(withoutColumn(kValidCsv, removal.column), 1, removal.column, removal.parts);
}

INSTANTIATE_TEST_SUITE_P(CampaignRefuses, MissingCsvColumn,
                         ::testing::ValuesIn(kCsvColumnRemovals),
                         [](const auto& info) { return std::string(info.param.name); });

// ---------------------------------------------------------------------------------------------
// Broken measurements.csv: header

TEST(CampaignRefuses, EmptyFile) {
  expectCsvRefused("", 1, "", {"the file is empty", "expected a header line"});
}

TEST(CampaignRefuses, HeaderOnly) {
  expectCsvRefused(splitOn(kValidCsv, '\n')[0] + "\n", 1, "",
                   {"no rows", "expected at least one measurement"});
}

TEST(CampaignRefuses, NoJointColumns) {
  std::string csv = kValidCsv;
  for (const char* q : {"q1_deg", "q2_deg", "q3_deg"}) csv = withoutColumn(csv, q);
  expectCsvRefused(csv, 1, "q1_deg", {"'q1_deg' is missing", "q1_deg … qN_deg"});
}

TEST(CampaignRefuses, TooManyJoints) {
  std::string header = "seq,pose_id,set,load_kg";
  std::string row = "1,a,geometry,0";
  for (int k = 1; k <= kMaxJoints + 1; ++k) {
    header += ",q" + std::to_string(k) + "_deg";
    row += ",0";
  }
  const std::string last = "q" + std::to_string(kMaxJoints + 1) + "_deg";
  expectCsvRefused(header + ",x_mm,y_mm,z_mm\n" + row + ",1,2,3\n", 1, last,
                   {"too many joint columns", "at most 8"});
}

TEST(CampaignRefuses, SemicolonSeparated) {
  std::string csv = kValidCsv;
  std::replace(csv.begin(), csv.end(), ',', ';');
  expectCsvRefused(csv, 1, "seq", {"'seq' is missing", "separated by ',', not ';'"});
}

// A UTF-8 byte-order mark (spreadsheets' "CSV UTF-8") is skipped by every reader (csv.hpp).
TEST(Campaign, SkipsAByteOrderMark) {
  TempDir plain, marked;
  writeFolder(plain.path(), kValidYaml, kValidCsv);
  const std::string bom = "\xEF\xBB\xBF";
  writeFolder(marked.path(), bom + kValidYaml, bom + kValidCsv);
  const Campaign a = readCampaign(plain.path().string());
  const Campaign b = readCampaign(marked.path().string());
  ASSERT_EQ(b.rows.size(), a.rows.size());
  EXPECT_EQ(b.rows[0].seq, a.rows[0].seq);  // the first column is seq, not "\xEF\xBB\xBFseq"
  EXPECT_EQ(b.extra_columns, a.extra_columns);
}

TEST(PoseList, SkipsAByteOrderMark) {
  TempDir dir;
  const std::string text = "pose_id,load_kg,q1_deg,q2_deg\np1,0,10,20\np1,20,10,20\n";
  writeText(dir.path() / "plain.csv", text);
  writeText(dir.path() / "marked.csv", "\xEF\xBB\xBF" + text);
  const auto plain = readPoseList((dir.path() / "plain.csv").string(), 2);
  const auto marked = readPoseList((dir.path() / "marked.csv").string(), 2);
  ASSERT_EQ(marked.size(), plain.size());
  EXPECT_EQ(marked[1].pose_id, "p1");
  EXPECT_EQ(marked[1].q_rad, plain[1].q_rad);
}

TEST(PoseList, RefusesAFolderByName) {
  TempDir dir;
  test::expectInputError([&] { readPoseList(dir.path().string(), 6); }, "", 0, "",
                         {"pose list", "is a folder; expected a readable file"});
  const test::Refusal r = test::refusalOf([&] { readPoseList(dir.path().string(), 6); });
  EXPECT_EQ(r.what.find("campaign.yaml"), std::string::npos) << r.what;
}

// ---------------------------------------------------------------------------------------------
// A file where the campaign folder is expected: named as such in one short line

/// The error of reading `file` as a campaign: one line, short, saying a folder is expected.
void expectFileRefusedAsCampaign(const fs::path& file) {
  const test::Refusal r = test::refusalOf([&] { readCampaign(file.string()); });
  EXPECT_EQ(r.file, file.filename().string());
  EXPECT_NE(r.what.find("is a file; expected a campaign folder holding campaign.yaml"),
            std::string::npos)
      << r.what;
  EXPECT_EQ(r.what.find('\n'), std::string::npos) << r.what;
  EXPECT_LT(r.what.size(), 300u) << r.what;
}

TEST(CampaignRefuses, AMeasurementsFileGivenForTheFolder) {
  TempDir dir;
  std::string big = splitOn(kValidCsv, '\n')[0] + "\n";
  const std::string row = splitOn(kValidCsv, '\n')[1] + "\n";
  while (big.size() < 438 * 1024) big += row;  // the size of the file
  writeText(dir.path() / "measurements.csv", big);
  expectFileRefusedAsCampaign(dir.path() / "measurements.csv");
}

TEST(CampaignRefuses, ARobotDescriptionGivenForTheFolder) {
  TempDir dir;
  writeText(dir.path() / "robot.urdf", kUrdf);
  expectFileRefusedAsCampaign(dir.path() / "robot.urdf");
}

TEST(CampaignRefuses, ATableInCampaignYamlIsQuotedShort) {
  // A campaign.yaml holding a whole table: the value is quoted as its first characters.
  std::string big = kValidCsv;
  while (big.size() < 100 * 1024) big += splitOn(kValidCsv, '\n')[1] + "\n";
  TempDir dir;
  writeFolder(dir.path(), big, kValidCsv);
  const test::Refusal r = test::refusalOf([&] { readCampaign(dir.path().string()); });
  EXPECT_EQ(r.file, "campaign.yaml");
  EXPECT_NE(r.what.find("bytes)"), std::string::npos) << r.what;
  EXPECT_LT(r.what.size(), 400u) << r.what.substr(0, 400);
}

TEST(CampaignRefuses, WritingOverAFile) {
  TempDir dir;
  writeText(dir.path() / "taken", "x");
  std::mt19937_64 rng(1);
  test::expectInputError([&] { writeCampaign(randomCampaign(rng, 3), (dir.path() / "taken").string()); },
                         "taken", 0, "", {"is a file; expected the campaign folder to write"});
}

// ---------------------------------------------------------------------------------------------
// Broken measurements.csv: rows

TEST(CampaignRefuses, ShortRow) {
  expectCsvRefused(withoutColumn(kValidCsv, "note") + "4,p9,geometry,0\n", 5, "",
                   {"row has 4 fields; expected 21"});
}

TEST(CampaignRefuses, WrenchMissingOnALoadedRow) {
  std::string csv = kValidCsv;
  for (const char* f : {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"}) {
    csv = withField(csv, 3, f, "");
  }
  expectCsvRefused(csv, 3, "fx_n", {"load_kg '20'", "expected the F/T reading"});
}

TEST(CampaignRefuses, LoadedRowWithoutWrenchColumns) {
  std::string csv = kValidCsv;
  for (const char* f : {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"}) {
    csv = withoutColumn(csv, f);
  }
  expectCsvRefused(csv, 3, "load_kg", {"'20'", "no wrench columns"});
}

TEST(CampaignRefuses, EmptyLineInTheMiddle) {
  expectCsvRefused(replaced(kValidCsv, "\n3,", "\n\n3,"), 4, "", {"empty line"});
}

TEST(CampaignRefuses, TwoNewlinesAtTheEnd) {
  expectCsvRefused(std::string(kValidCsv) + "\n", 5, "", {"empty line"});
}

}  // namespace
}  // namespace stepcal
