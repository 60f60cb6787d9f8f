// Reading and writing measurement campaigns (campaign-format.md, stepcal-campaign/1).
//
// Millimetres and degrees are converted at this boundary only. Conversions are chosen so that
// readCampaign(writeCampaign(c)) reproduces every double bit-exactly:
//   - mm ↔ m moves the decimal point of the decimal text instead of multiplying, so a metre
//     value is rounded once (from its exact decimal) and its shortest form comes back exactly;
//   - deg → rad multiplies in extended precision, and the writer picks the shortest decimal
//     that reads back to the same radian double (a plain double conversion cannot do this:
//     in some binades there are fewer degree doubles than radian doubles).
#include "stepcal/common/campaign.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <string_view>

#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

constexpr const char* kFormat = "stepcal-campaign/1";

constexpr std::array<const char*, 6> kWrenchColumns = {"fx_n",  "fy_n",  "fz_n",
                                                       "mx_nm", "my_nm", "mz_nm"};
constexpr std::array<const char*, 4> kQuaternionColumns = {"qw", "qx", "qy", "qz"};
constexpr std::array<const char*, 9> kYamlKeys = {"format",      "robot",          "base_link",
                                                  "tip_link",    "sensor_link",    "flange_link",
                                                  "measurements", "tracker",       "gravity_in_base"};
constexpr std::array<const char*, 2> kTrackerKeys = {"position_sigma_mm", "orientation_sigma_deg"};

// ---------------------------------------------------------------------------------------------
// Numbers

/// Millimetre text as metres, by moving the decimal point three places (one rounding).
std::optional<double> parseMillimetresAsMetres(std::string_view s) {
  return parseFiniteShifted(s, -3);
}

/// Degree text as radians, multiplied in extended precision.
std::optional<double> parseDegreesAsRadians(std::string_view s) {
  long double deg = 0.0L;
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, deg);
  if (ec != std::errc() || ptr != end || !std::isfinite(deg)) return std::nullopt;
  const double rad = static_cast<double>(deg * kRadPerDegExtended);
  if (!std::isfinite(rad)) return std::nullopt;
  return rad;
}

/// Metres as millimetre text: the shortest metre text with the decimal point moved right by 3.
std::string formatMetresAsMillimetres(double m) {
  if (m == 0.0) return std::signbit(m) ? "-0" : "0";
  std::array<char, 64> buf{};
  const auto r =
      std::to_chars(buf.data(), buf.data() + buf.size(), m, std::chars_format::scientific);
  const std::string_view s(buf.data(), static_cast<size_t>(r.ptr - buf.data()));
  const size_t e = s.find('e');
  std::string out = m < 0.0 ? "-" : "";
  std::string digits;
  for (size_t i = m < 0.0 ? 1 : 0; i < e; ++i) {
    if (s[i] != '.') digits += s[i];
  }
  std::string_view exp_text = s.substr(e + 1);
  if (exp_text.front() == '+') exp_text.remove_prefix(1);
  int exponent = 0;
  std::from_chars(exp_text.data(), exp_text.data() + exp_text.size(), exponent);
  exponent += 3;
  // value = d0.d1d2… × 10^exponent: the decimal point goes after digit (exponent + 1).
  const int point = exponent + 1;
  const int n = static_cast<int>(digits.size());
  if (point > 21 || point < -5) {
    out += digits.substr(0, 1);
    if (n > 1) out += "." + digits.substr(1);
    return out + "e" + std::to_string(exponent);
  }
  if (point <= 0) return out + "0." + std::string(static_cast<size_t>(-point), '0') + digits;
  if (point >= n) return out + digits + std::string(static_cast<size_t>(point - n), '0');
  return out + digits.substr(0, static_cast<size_t>(point)) + "." +
         digits.substr(static_cast<size_t>(point));
}

/// Radians as degree text that parseDegreesAsRadians maps back to exactly rad: the shortest
/// form of the degree double when that works (almost always), else the fewest digits of the
/// extended-precision degree value that do.
std::string formatRadiansAsDegrees(double rad) {
  const long double deg = static_cast<long double>(rad) / kRadPerDegExtended;
  std::string text = formatShortest(static_cast<double>(deg));
  if (parseDegreesAsRadians(text) == rad) return text;
  // Longer forms of the extended-precision value; the longest reads back to deg itself,
  // whose product with kRadPerDegExtended rounds to rad.
  for (int digits = std::numeric_limits<double>::max_digits10;
       digits <= std::numeric_limits<long double>::max_digits10; ++digits) {
    std::array<char, 96> buf{};
    const auto r =
        std::to_chars(buf.data(), buf.data() + buf.size(), deg, std::chars_format::general, digits);
    text.assign(buf.data(), r.ptr);
    if (parseDegreesAsRadians(text) == rad) return text;
  }
  return text;  // only where long double is no wider than double: within 1 ulp
}

/// Extra words for a number that failed to parse, when its look suggests why.
std::string numberHint(std::string_view s) {
  if (s.empty()) return " (the field is empty)";
  if (s.front() == ' ' || s.back() == ' ' || s.front() == '\t' || s.back() == '\t') {
    return " (no spaces around values)";
  }
  if (s.front() == '+') return " (write it without a leading '+')";
  if (s.find(';') != std::string_view::npos) return " (columns are separated by ',', not ';')";
  if (parseFinite(s) == std::nullopt) {
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ptr == s.data() + s.size() && ec == std::errc()) return " (must be finite)";
    if (ec == std::errc::result_out_of_range) return " (out of range)";
  }
  return "";
}

// ---------------------------------------------------------------------------------------------
// Names

/// Edit distance, for "did you mean" hints.
size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// " (did you mean 'x'?)" for the closest candidate within two edits, else "".
template <typename Names>
std::string didYouMean(std::string_view name, const Names& candidates) {
  std::string best;
  size_t best_distance = 3;
  for (const auto& candidate : candidates) {
    const size_t d = editDistance(name, candidate);
    if (d < best_distance) {
      best_distance = d;
      best = candidate;
    }
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

template <typename Names>
std::string joined(const Names& names) {
  std::string out;
  for (const auto& name : names) out += (out.empty() ? "" : ", ") + std::string(name);
  return out;
}

/// What a measurements.csv column name means to the reader.
enum class ColumnKind { kFixed, kJoint, kBadJoint, kExtra };

/// kJoint sets *joint to K for a column named qK_deg (K ≥ 1, no leading zero).
ColumnKind classifyColumn(std::string_view name, int* joint) {
  static const std::array<const char*, 18> kFixedNames = {
      "seq",   "pose_id", "set",  "load_kg", "fx_n", "fy_n", "fz_n", "mx_nm", "my_nm",
      "mz_nm", "x_mm",    "y_mm", "z_mm",    "qw",   "qx",   "qy",   "qz",    "temp_c"};
  if (std::find(kFixedNames.begin(), kFixedNames.end(), name) != kFixedNames.end()) {
    return ColumnKind::kFixed;
  }
  if (name.size() < 6 || name.front() != 'q' || name.substr(name.size() - 4) != "_deg") {
    return ColumnKind::kExtra;
  }
  const std::string_view digits = name.substr(1, name.size() - 5);
  if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return ColumnKind::kExtra;
  }
  int k = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), k);
  if (ec != std::errc() || ptr != digits.data() + digits.size() || k < 1 || digits.front() == '0') {
    return ColumnKind::kBadJoint;
  }
  *joint = k;
  return ColumnKind::kJoint;
}

std::string jointColumn(int k) { return "q" + std::to_string(k) + "_deg"; }

std::optional<RowSet> parseSet(std::string_view s) {
  if (s == "geometry") return RowSet::kGeometry;
  if (s == "stiffness") return RowSet::kStiffness;
  if (s == "residual") return RowSet::kResidual;
  if (s == "validation") return RowSet::kValidation;
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Files

/// Whole file as text; throws naming the place that refers to it (file, line) when it cannot,
/// or the file itself when nothing refers to it.
std::string readReferredFile(const fs::path& path, const std::string& what,
                             const std::string& referrer, int referrer_line) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    const char* found = fs::is_directory(path, ec) ? " is a folder"
                        : fs::exists(path, ec)     ? " is not a regular file"
                                                   : " does not exist";
    const char* relative_to = referrer.empty()
                                  ? ""
                                  : " (a relative path is relative to the folder of campaign.yaml)";
    throw InputError(what + " " + inQuotes(path.string()) + found + "; expected a readable file" +
                         relative_to,
                     referrer, referrer_line);
  }
  std::ifstream in(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.is_open() || in.bad()) {
    throw InputError(what + " " + inQuotes(path.string()) + " cannot be read", referrer,
                     referrer_line);
  }
  return text;
}

void writeFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  if (!out) throw InputError("cannot write the file", path.string());
}

// ---------------------------------------------------------------------------------------------
// campaign.yaml

int lineOf(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : 0;
}

/// One key of a YAML mapping; errors about its value are reported on the key's line (a
/// missing value has no position of its own).
struct YamlEntry {
  std::string key;
  YAML::Node value;
  int line = 0;
};

class YamlReader {
 public:
  explicit YamlReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(int line, const std::string& message) const {
    throw InputError(message, file_, line);
  }

  /// Checks the keys of a mapping: all known, none twice.
  template <typename Keys>
  std::map<std::string, YamlEntry> keysOf(const YAML::Node& map, const Keys& known,
                                          const std::string& where) const {
    std::map<std::string, YamlEntry> out;
    for (const auto& entry : map) {
      const int line = lineOf(entry.first);
      if (!entry.first.IsScalar()) fail(line, where + ": expected text keys");
      const std::string key = entry.first.Scalar();
      if (std::find(known.begin(), known.end(), key) == known.end()) {
        fail(line, where + ": unknown key " + inQuotes(key) + "; expected one of " + joined(known) +
                       didYouMean(key, known));
      }
      if (const auto it = out.find(key); it != out.end()) {
        fail(line, where + ": key " + inQuotes(key) + " appears twice (first on line " +
                       std::to_string(it->second.line) + ")");
      }
      out[key] = {key, entry.second, line};
    }
    return out;
  }

  /// A non-empty text value.
  std::string text(const YamlEntry& e, const std::string& expected) const {
    if (!e.value.IsScalar() || e.value.Scalar().empty()) {
      fail(e.line, "key " + inQuotes(e.key) + ": expected " + expected + ", got " + shape(e.value));
    }
    return e.value.Scalar();
  }

  /// A finite number > 0, through the given unit conversion.
  template <typename Convert>
  double positive(const YamlEntry& e, const std::string& unit, Convert convert) const {
    const std::optional<double> v = e.value.IsScalar() ? convert(e.value.Scalar()) : std::nullopt;
    if (!v || !(*v > 0.0)) {
      fail(e.line, "key " + inQuotes(e.key) + ": expected a number > 0 (" + unit + "), got " +
                       shape(e.value));
    }
    return *v;
  }

  static std::string shape(const YAML::Node& value) {
    if (value.IsSequence()) return "a list";
    if (value.IsMap()) return "a mapping";
    if (value.IsNull()) return "nothing";
    return inQuotes(value.Scalar());
  }

 private:
  std::string file_;
};

// ---------------------------------------------------------------------------------------------
// measurements.csv

/// Column positions of one measurements.csv header.
struct CsvLayout {
  int field_count = 0;
  int seq = -1, pose_id = -1, set = -1, load = -1, temp = -1;
  std::array<int, 3> position{-1, -1, -1};
  std::vector<int> joints;  // q1_deg … qN_deg
  std::array<int, 6> wrench{-1, -1, -1, -1, -1, -1};
  std::array<int, 4> quaternion{-1, -1, -1, -1};
  std::vector<int> extra;
  std::vector<std::string> names;
};

class CsvReader {
 public:
  explicit CsvReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(int line, const std::string& column, const std::string& message) const {
    throw InputError(message, file_, line, column);
  }

  CsvLayout parseHeader(std::string_view header) const {
    CsvLayout layout;
    const std::vector<std::string_view> names = splitFields(header);
    layout.field_count = static_cast<int>(names.size());
    std::map<int, int> joint_positions;  // K → position of qK_deg
    std::map<std::string, int> fixed;
    for (int i = 0; i < layout.field_count; ++i) {
      const std::string name(names[static_cast<size_t>(i)]);
      layout.names.push_back(name);
      if (name.empty()) {
        fail(1, "",
             "column " + std::to_string(i + 1) +
                 " has an empty name; expected a column "
                 "name (a trailing ',' makes an empty column)");
      }
      if (name.find_first_of(" \t\"") != std::string::npos) {
        fail(1, name,
             "column name " + inQuotes(name) +
                 " contains spaces or quotes; expected "
                 "a bare name such as x_mm (the format has no quoting)");
      }
      if (std::count(layout.names.begin(), layout.names.end(), name) > 1) {
        fail(1, name,
             "column " + inQuotes(name) +
                 " appears twice in the header; expected "
                 "each column once");
      }
      int k = 0;
      switch (classifyColumn(name, &k)) {
        case ColumnKind::kFixed:
          fixed[name] = i;
          break;
        case ColumnKind::kJoint:
          joint_positions[k] = i;
          break;
        case ColumnKind::kBadJoint:
          fail(1, name,
               "bad joint column name " + inQuotes(name) +
                   "; expected q1_deg … qN_deg "
                   "(numbered from 1, no leading zeros)");
        case ColumnKind::kExtra:
          layout.extra.push_back(i);
          break;
      }
    }
    auto require = [&](const char* name) {
      const auto it = fixed.find(name);
      if (it == fixed.end()) {
        std::string hint = didYouMean(name, layout.names);
        if (hint.empty() && layout.field_count == 1 && header.find(';') != std::string::npos) {
          hint = " (columns are separated by ',', not ';')";
        }
        fail(1, name,
             "required column " + inQuotes(name) + " is missing; the header has " +
                 joined(layout.names) + hint);
      }
      return it->second;
    };
    layout.seq = require("seq");
    layout.pose_id = require("pose_id");
    layout.set = require("set");
    layout.load = require("load_kg");
    if (joint_positions.empty()) {
      fail(1, "q1_deg",
           "required column 'q1_deg' is missing; expected the joint columns "
           "q1_deg … qN_deg");
    }
    for (const auto& [k, position] : joint_positions) {
      const int expected = static_cast<int>(layout.joints.size()) + 1;
      if (k != expected) {
        fail(1, jointColumn(expected),
             "joint column " + inQuotes(jointColumn(expected)) + " is missing but " +
                 inQuotes(jointColumn(k)) + " exists; expected q1_deg … qN_deg without gaps");
      }
      if (k > kMaxJoints) {
        fail(1, jointColumn(k),
             "too many joint columns: at most " + std::to_string(kMaxJoints) + " (q1_deg … q" +
                 std::to_string(kMaxJoints) + "_deg) are supported");
      }
      layout.joints.push_back(position);
    }
    for (int a = 0; a < 3; ++a) {
      layout.position[static_cast<size_t>(a)] = require(std::array{"x_mm", "y_mm", "z_mm"}[a]);
    }
    optionalGroup(fixed, kWrenchColumns, layout.wrench.data(),
                  "the wrench columns fx_n, fy_n, "
                  "fz_n, mx_nm, my_nm, mz_nm");
    optionalGroup(fixed, kQuaternionColumns, layout.quaternion.data(),
                  "the quaternion columns qw, qx, qy, qz");
    if (const auto it = fixed.find("temp_c"); it != fixed.end()) layout.temp = it->second;
    return layout;
  }

  /// One data row's fields, with the header layout and the line its messages name.
  struct Row {
    const CsvLayout& layout;
    std::vector<std::string_view> fields;
    int line = 0;

    std::string_view field(int i) const { return fields[static_cast<size_t>(i)]; }
    const std::string& name(int i) const { return layout.names[static_cast<size_t>(i)]; }
  };

  /// Parses one data row; seq_lines maps every seq seen so far to its line.
  Measurement parseRow(const CsvLayout& layout, std::string_view text, int line,
                       std::map<int64_t, int>& seq_lines) const {
    const Row row{layout, splitRow(layout, text, line), line};
    Measurement m;
    m.source_line = line;
    m.seq = parseSeq(row, seq_lines);
    parsePoseSetAndLoad(row, m);
    m.q_rad.resize(static_cast<Eigen::Index>(layout.joints.size()));
    for (size_t j = 0; j < layout.joints.size(); ++j) {
      m.q_rad[static_cast<Eigen::Index>(j)] =
          number(row, layout.joints[j], "degrees", parseDegreesAsRadians);
    }
    for (int a = 0; a < 3; ++a) {
      m.p_TipInTracker_m[a] = number(row, layout.position[static_cast<size_t>(a)], "millimetres",
                                     parseMillimetresAsMetres);
    }
    parseWrench(row, m);
    parseOrientation(row, m);
    if (layout.temp >= 0 && !row.field(layout.temp).empty()) {
      m.temp_c = number(row, layout.temp, "degrees Celsius", parseFinite);
    }
    for (const int i : layout.extra) m.extra.emplace_back(row.field(i));
    return m;
  }

 private:
  /// A data row's fields; fails on an empty line or a field count unlike the header's.
  std::vector<std::string_view> splitRow(const CsvLayout& layout, std::string_view text,
                                         int line) const {
    if (text.empty()) {
      fail(line, "",
           "empty line; expected a measurement row (empty lines are only allowed "
           "as the file's final newline)");
    }
    std::vector<std::string_view> fields = splitFields(text);
    const int n = static_cast<int>(fields.size());
    if (n != layout.field_count) {
      std::string hint;
      if (n > layout.field_count) {
        hint = " (the decimal point must be '.': a decimal comma splits a number in two)";
      } else if (n == 1 && text.find(';') != std::string_view::npos) {
        hint = " (columns are separated by ',', not ';')";
      }
      fail(line, "",
           "row has " + std::to_string(n) + " fields; expected " +
               std::to_string(layout.field_count) + " as in the header" + hint);
    }
    return fields;
  }

  /// Field i through a text-to-number conversion; fails naming the unit when it does not parse.
  template <typename Convert>
  double number(const Row& row, int i, const char* unit, Convert convert) const {
    const std::optional<double> v = convert(row.field(i));
    if (!v) {
      fail(row.line, row.name(i),
           "expected a number (" + std::string(unit) + "), got " + inQuotes(row.field(i)) +
               numberHint(row.field(i)));
    }
    return *v;
  }

  /// The row's seq: an integer no earlier row has.
  int64_t parseSeq(const Row& row, std::map<int64_t, int>& seq_lines) const {
    const std::string_view s = row.field(row.layout.seq);
    int64_t seq = 0;
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), seq);
    if (ec != std::errc() || ptr != s.data() + s.size()) {
      fail(row.line, "seq", "expected an integer, got " + inQuotes(s) + numberHint(s));
    }
    const auto [it, inserted] = seq_lines.emplace(seq, row.line);
    if (!inserted) {
      fail(row.line, "seq",
           "seq " + inQuotes(s) + " already appears on line " + std::to_string(it->second) +
               "; expected unique values");
    }
    return seq;
  }

  /// pose_id, set and load_kg.
  void parsePoseSetAndLoad(const Row& row, Measurement& m) const {
    const CsvLayout& layout = row.layout;
    m.pose_id = std::string(row.field(layout.pose_id));
    if (m.pose_id.empty() || m.pose_id.find('"') != std::string::npos) {
      fail(row.line, "pose_id",
           "expected a pose id (non-empty text without quotes), got " + inQuotes(m.pose_id));
    }
    const std::optional<RowSet> set = parseSet(row.field(layout.set));
    if (!set) {
      fail(row.line, "set",
           "expected geometry, stiffness, residual or validation, got " +
               inQuotes(row.field(layout.set)));
    }
    m.set = *set;
    m.load_kg = number(row, layout.load, "kilograms", parseFinite);
    if (m.load_kg < 0.0) {
      fail(row.line, "load_kg",
           "expected a mass >= 0 (kilograms), got " + inQuotes(row.field(layout.load)));
    }
  }

  /// The F/T reading: all six values or none, and none only on an unloaded row.
  void parseWrench(const Row& row, Measurement& m) const {
    const CsvLayout& layout = row.layout;
    if (layout.wrench[0] >= 0) {
      if (allEmpty(row, layout.wrench)) {
        if (m.load_kg > 0.0) {
          fail(row.line, "fx_n",
               "empty on a row with load_kg " + inQuotes(row.field(layout.load)) +
                   "; expected the F/T reading fx_n … mz_nm (a wrench may only "
                   "be missing where load_kg is 0)");
        }
      } else {
        requireComplete(row, layout.wrench, "all six wrench values");
        for (int a = 0; a < 6; ++a) {
          m.wrench_Sensor[a] = number(row, layout.wrench[static_cast<size_t>(a)],
                                      a < 3 ? "newtons" : "newton metres", parseFinite);
        }
        m.has_wrench = true;
      }
    } else if (m.load_kg > 0.0) {
      fail(row.line, "load_kg",
           "load_kg is " + inQuotes(row.field(layout.load)) +
               " but the file has no "
               "wrench columns; expected fx_n … mz_nm on loaded rows");
    }
  }

  /// The measured orientation, when the row has its quaternion: unit norm within the tolerance.
  void parseOrientation(const Row& row, Measurement& m) const {
    const CsvLayout& layout = row.layout;
    if (layout.quaternion[0] < 0 || allEmpty(row, layout.quaternion)) return;
    requireComplete(row, layout.quaternion, "all four quaternion values");
    Eigen::Vector4d wxyz;
    for (int a = 0; a < 4; ++a) {
      wxyz[a] = number(row, layout.quaternion[static_cast<size_t>(a)], "quaternion component",
                       parseFinite);
    }
    const double norm = wxyz.norm();
    if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
      fail(row.line, "qw",
           "quaternion (qw, qx, qy, qz) = (" + std::string(row.field(layout.quaternion[0])) +
               ", " + std::string(row.field(layout.quaternion[1])) + ", " +
               std::string(row.field(layout.quaternion[2])) + ", " +
               std::string(row.field(layout.quaternion[3])) + ") has norm " +
               formatShortest(norm) +
               "; expected a unit quaternion (norm within "
               "1e-6 of 1)");
    }
    // Already unit to round-off: kept as is, so a written quaternion reads back bit-exactly.
    if (std::abs(norm - 1.0) > 8.0 * std::numeric_limits<double>::epsilon()) wxyz /= norm;
    m.q_TrackerTip = Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
    m.has_orientation = true;
  }

  template <size_t N>
  static bool allEmpty(const Row& row, const std::array<int, N>& at) {
    return std::all_of(at.begin(), at.end(), [&](int i) { return row.field(i).empty(); });
  }

  /// Some fields of a group are set: every one must be.
  template <size_t N>
  void requireComplete(const Row& row, const std::array<int, N>& at,
                       const std::string& what) const {
    const auto set = std::find_if(at.begin(), at.end(), [&](int i) { return !row.field(i).empty(); });
    for (const int i : at) {
      if (row.field(i).empty()) {
        fail(row.line, row.name(i),
             "got '' but " + row.name(*set) + " is " + inQuotes(row.field(*set)) + "; expected " +
                 what + " or none on a row");
      }
    }
  }

  /// A group of optional columns: all present (positions into at) or none.
  template <size_t N>
  void optionalGroup(const std::map<std::string, int>& fixed,
                     const std::array<const char*, N>& names, int* at,
                     const std::string& what) const {
    size_t present = 0;
    for (size_t a = 0; a < N; ++a) {
      const auto it = fixed.find(names[a]);
      at[a] = it == fixed.end() ? -1 : it->second;
      present += it == fixed.end() ? 0 : 1;
    }
    if (present == 0 || present == N) return;
    for (size_t a = 0; a < N; ++a) {
      if (at[a] < 0) {
        fail(1, names[a],
             "column " + inQuotes(names[a]) + " is missing; expected " + what +
                 " all together or none");
      }
    }
  }

  std::string file_;
};

// ---------------------------------------------------------------------------------------------
// Writing

/// Text that a field can hold: no separator, quote or line break.
bool isBareField(const std::string& s, bool allow_quotes) {
  return s.find_first_of(allow_quotes ? ",\r\n" : ",\"\r\n") == std::string::npos;
}

void requireFinite(double v, const std::string& file, int line, const std::string& column) {
  if (!std::isfinite(v)) {
    throw InputError("cannot write " + formatShortest(v) + "; expected a finite number", file, line,
                     column);
  }
}

std::string csvText(const Campaign& c, const std::string& file) {
  const bool any_wrench =
      std::any_of(c.rows.begin(), c.rows.end(), [](const auto& m) { return m.has_wrench; });
  const bool any_orientation =
      std::any_of(c.rows.begin(), c.rows.end(), [](const auto& m) { return m.has_orientation; });
  const bool any_temp =
      std::any_of(c.rows.begin(), c.rows.end(), [](const auto& m) { return m.temp_c.has_value(); });
  if (c.rows.empty()) throw InputError("the campaign has no rows; expected at least one", file);
  if (c.joint_count < 1 || c.joint_count > kMaxJoints) {
    throw InputError("joint_count is " + std::to_string(c.joint_count) + "; expected 1 … " +
                         std::to_string(kMaxJoints),
                     file);
  }

  std::string header = "seq,pose_id,set,load_kg";
  for (int k = 1; k <= c.joint_count; ++k) header += "," + jointColumn(k);
  if (any_wrench) {
    for (const char* name : kWrenchColumns) header += std::string(",") + name;
  }
  header += ",x_mm,y_mm,z_mm";
  if (any_orientation) {
    for (const char* name : kQuaternionColumns) header += std::string(",") + name;
  }
  if (any_temp) header += ",temp_c";
  std::vector<std::string> seen;
  for (const std::string& name : c.extra_columns) {
    int k = 0;
    if (name.empty() || !isBareField(name, false) ||
        name.find_first_of(" \t") != std::string::npos ||
        classifyColumn(name, &k) != ColumnKind::kExtra ||
        std::find(seen.begin(), seen.end(), name) != seen.end()) {
      throw InputError("extra column name " + inQuotes(name) +
                           " cannot be written; expected a "
                           "unique bare name that is not a format column",
                       file, 1, name);
    }
    seen.push_back(name);
    header += "," + name;
  }

  std::string out = header + "\n";
  std::map<int64_t, int> seq_lines;
  int line = 1;
  for (const Measurement& m : c.rows) {
    ++line;
    if (!seq_lines.emplace(m.seq, line).second) {
      throw InputError("seq " + std::to_string(m.seq) + " repeats; expected unique values", file,
                       line, "seq");
    }
    if (m.pose_id.empty() || !isBareField(m.pose_id, false)) {
      throw InputError("pose_id " + inQuotes(m.pose_id) +
                           " cannot be written; expected non-empty "
                           "text without ',', quotes or line breaks (the format has no quoting)",
                       file, line, "pose_id");
    }
    requireFinite(m.load_kg, file, line, "load_kg");
    if (m.load_kg < 0.0 || (m.load_kg > 0.0 && !m.has_wrench)) {
      throw InputError("load_kg " + formatShortest(m.load_kg) +
                           " cannot be written; expected "
                           ">= 0, and a wrench where it is > 0",
                       file, line, "load_kg");
    }
    if (m.q_rad.size() != c.joint_count) {
      throw InputError("row has " + std::to_string(m.q_rad.size()) + " joint values; expected " +
                           std::to_string(c.joint_count) + " (joint_count)",
                       file, line, "q1_deg");
    }
    if (m.extra.size() != c.extra_columns.size()) {
      throw InputError("row has " + std::to_string(m.extra.size()) + " extra values; expected " +
                           std::to_string(c.extra_columns.size()) + " (one per extra column)",
                       file, line);
    }
    out += std::to_string(m.seq) + "," + m.pose_id + "," + toString(m.set) + "," +
           formatShortest(m.load_kg);
    for (int k = 0; k < c.joint_count; ++k) {
      requireFinite(m.q_rad[k], file, line, jointColumn(k + 1));
      out += "," + formatRadiansAsDegrees(m.q_rad[k]);
    }
    if (any_wrench) {
      for (int a = 0; a < 6; ++a) {
        requireFinite(m.wrench_Sensor[a], file, line, kWrenchColumns[static_cast<size_t>(a)]);
        out += "," + (m.has_wrench ? formatShortest(m.wrench_Sensor[a]) : std::string());
      }
    }
    for (int a = 0; a < 3; ++a) {
      requireFinite(m.p_TipInTracker_m[a], file, line, std::array{"x_mm", "y_mm", "z_mm"}[a]);
      out += "," + formatMetresAsMillimetres(m.p_TipInTracker_m[a]);
    }
    if (any_orientation) {
      const Eigen::Vector4d wxyz(m.q_TrackerTip.w(), m.q_TrackerTip.x(), m.q_TrackerTip.y(),
                                 m.q_TrackerTip.z());
      if (m.has_orientation && !(std::abs(wxyz.norm() - 1.0) <= kQuaternionNormTolerance)) {
        throw InputError(
            "quaternion has norm " + formatShortest(wxyz.norm()) + "; expected a unit quaternion",
            file, line, "qw");
      }
      for (int a = 0; a < 4; ++a) {
        out += "," + (m.has_orientation ? formatShortest(wxyz[a]) : std::string());
      }
    }
    if (any_temp) {
      if (m.temp_c) requireFinite(*m.temp_c, file, line, "temp_c");
      out += "," + (m.temp_c ? formatShortest(*m.temp_c) : std::string());
    }
    for (size_t i = 0; i < m.extra.size(); ++i) {
      if (!isBareField(m.extra[i], true)) {
        throw InputError("value " + inQuotes(m.extra[i]) +
                             " cannot be written; expected text "
                             "without ',' or line breaks (the format has no quoting)",
                         file, line, c.extra_columns[i]);
      }
      out += "," + m.extra[i];
    }
    out += "\n";
  }
  return out;
}

std::string yamlText(const Campaign& c, const std::string& file) {
  for (const auto& [key, value] :
       {std::pair{"base_link", &c.base_link}, std::pair{"tip_link", &c.tip_link}}) {
    if (value->empty())
      throw InputError(std::string(key) + " is empty; expected a link name", file);
  }
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "robot" << YAML::Value << "robot.urdf";
  out << YAML::Key << "base_link" << YAML::Value << c.base_link;
  out << YAML::Key << "tip_link" << YAML::Value << c.tip_link;
  if (!c.sensor_link.empty()) out << YAML::Key << "sensor_link" << YAML::Value << c.sensor_link;
  if (!c.flange_link.empty()) out << YAML::Key << "flange_link" << YAML::Value << c.flange_link;
  out << YAML::Key << "measurements" << YAML::Value << "measurements.csv";
  if (c.tracker.stated) {
    out << YAML::Key << "tracker" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "position_sigma_mm" << YAML::Value
        << formatMetresAsMillimetres(c.tracker.position_sigma_m);
    out << YAML::Key << "orientation_sigma_deg" << YAML::Value
        << formatRadiansAsDegrees(c.tracker.orientation_sigma_rad);
    out << YAML::EndMap;
  }
  if (c.gravity_in_base) {
    out << YAML::Key << "gravity_in_base" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (int a = 0; a < 3; ++a) out << formatShortest((*c.gravity_in_base)[a]);
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
  if (!out.good()) throw InputError("cannot write campaign.yaml: " + out.GetLastError(), file);
  return std::string(out.c_str()) + "\n";
}

// ---------------------------------------------------------------------------------------------
// Reading, step by step

/// What a campaign path is, for a file given in its place.
constexpr const char* kCampaignFolderText =
    "a campaign folder holding campaign.yaml, robot.urdf and measurements.csv (or the path of "
    "its campaign.yaml)";

/// Whether a file given as the campaign may be its campaign.yaml: YAML or JSON by its name,
/// not a table, a robot description or a model given where a folder is expected.
bool isCampaignFileName(const fs::path& path) {
  const std::string extension = path.extension().string();
  return extension == ".yaml" || extension == ".yml" || extension == ".json";
}

YAML::Node parseYaml(const std::string& text, const std::string& file) {
  try {
    return YAML::Load(std::string(withoutByteOrderMark(text)));
  } catch (const YAML::Exception& e) {
    throw InputError("not valid YAML: " + e.msg, file, e.mark.line >= 0 ? e.mark.line + 1 : 0);
  }
}

/// Where campaign.yaml names the robot description and the measurements (for their errors).
struct ReferredFileLines {
  int robot = 0;
  int measurements = 0;
};

/// The keys format, robot, base_link, tip_link, measurements (required), sensor_link and
/// flange_link (optional).
ReferredFileLines readNamesAndLinks(const YamlReader& yaml,
                                    const std::map<std::string, YamlEntry>& keys, Campaign& c) {
  auto required = [&](const char* key) -> const YamlEntry& {
    const auto it = keys.find(key);
    if (it == keys.end()) {
      yaml.fail(0, "required key " + inQuotes(key) +
                       " is missing; expected the keys format, "
                       "robot, base_link, tip_link and measurements");
    }
    return it->second;
  };
  const YamlEntry& format = required("format");
  if (!format.value.IsScalar() || format.value.Scalar() != kFormat) {
    yaml.fail(format.line, "key 'format': expected " + inQuotes(kFormat) + ", got " +
                               YamlReader::shape(format.value) +
                               " (this reader knows version 1 only)");
  }
  const YamlEntry& robot = required("robot");
  c.robot_file = yaml.text(robot, "the robot description's file name");
  c.base_link = yaml.text(required("base_link"), "a link name");
  c.tip_link = yaml.text(required("tip_link"), "a link name");
  const YamlEntry& measurements = required("measurements");
  c.measurements_file = yaml.text(measurements, "the measurements file's name");
  if (const auto it = keys.find("sensor_link"); it != keys.end()) {
    c.sensor_link = yaml.text(it->second, "a link name (omit the key if there is no F/T sensor)");
  }
  if (const auto it = keys.find("flange_link"); it != keys.end()) {
    c.flange_link = yaml.text(it->second, "a link name (the robot's mounting flange; omit the "
                                          "key if it is not in the robot description)");
  }
  return {robot.line, measurements.line};
}

/// The key tracker: the instrument's stated noise, both values.
void readTracker(const YamlReader& yaml, const YamlEntry& tracker, Campaign& c) {
  if (!tracker.value.IsMap()) {
    yaml.fail(tracker.line,
              "key 'tracker': expected a mapping with position_sigma_mm and "
              "orientation_sigma_deg, got " +
                  YamlReader::shape(tracker.value));
  }
  const auto tracker_keys = yaml.keysOf(tracker.value, kTrackerKeys, "tracker");
  for (const char* key : kTrackerKeys) {
    if (tracker_keys.count(key) == 0) {
      yaml.fail(tracker.line, "tracker: key " + inQuotes(key) +
                                  " is missing; expected both "
                                  "position_sigma_mm and orientation_sigma_deg");
    }
  }
  c.tracker.position_sigma_m = yaml.positive(tracker_keys.at("position_sigma_mm"), "millimetres",
                                             parseMillimetresAsMetres);
  c.tracker.orientation_sigma_rad =
      yaml.positive(tracker_keys.at("orientation_sigma_deg"), "degrees", parseDegreesAsRadians);
  c.tracker.stated = true;
}

/// The key gravity_in_base: 3 numbers, m/s², base axes.
Vec3 readGravity(const YamlReader& yaml, const YamlEntry& entry) {
  const YAML::Node& g = entry.value;
  if (!g.IsSequence() || g.size() != 3) {
    yaml.fail(entry.line,
              "key 'gravity_in_base': expected a list of 3 numbers (m/s^2, "
              "base_link axes), got " +
                  YamlReader::shape(g));
  }
  Vec3 gravity = Vec3::Zero();
  for (size_t a = 0; a < 3; ++a) {
    const std::optional<double> v = g[a].IsScalar() ? parseFinite(g[a].Scalar()) : std::nullopt;
    if (!v) {
      yaml.fail(lineOf(g[a]), "key 'gravity_in_base': expected a number (m/s^2), got " +
                                  YamlReader::shape(g[a]));
    }
    gravity[static_cast<Eigen::Index>(a)] = *v;
  }
  return gravity;
}

/// measurements.csv (named on yaml_line of yaml_file): its header, then every row.
void readMeasurements(const fs::path& csv_path, const std::string& yaml_file, int yaml_line,
                      Campaign& c) {
  const std::string csv_text = readReferredFile(csv_path, "measurements file", yaml_file, yaml_line);
  const CsvReader csv(csv_path.string());
  const std::vector<std::string_view> lines = splitLines(csv_text);
  if (lines.empty()) {
    csv.fail(1, "", "the file is empty; expected a header line and at least one row");
  }
  if (lines[0].empty()) csv.fail(1, "", "the header line is empty; expected the column names");
  const CsvLayout layout = csv.parseHeader(lines[0]);
  if (lines.size() == 1) {
    csv.fail(1, "",
             "the file has a header but no rows; expected at least one measurement "
             "(an empty campaign is usually a failed export)");
  }
  c.joint_count = static_cast<int>(layout.joints.size());
  for (const int i : layout.extra) c.extra_columns.push_back(layout.names[static_cast<size_t>(i)]);
  std::map<int64_t, int> seq_lines;
  c.rows.reserve(lines.size() - 1);
  for (size_t i = 1; i < lines.size(); ++i) {
    c.rows.push_back(csv.parseRow(layout, lines[i], static_cast<int>(i) + 1, seq_lines));
  }
}

}  // namespace

const char* toString(RowSet set) noexcept {
  switch (set) {
    case RowSet::kGeometry:
      return "geometry";
    case RowSet::kStiffness:
      return "stiffness";
    case RowSet::kResidual:
      return "residual";
    case RowSet::kValidation:
      return "validation";
  }
  return "?";
}

Pose Measurement::X_TrackerTip() const {
  Pose X = Pose::Identity();
  X.translation() = p_TipInTracker_m;
  if (has_orientation) X.linear() = q_TrackerTip.toRotationMatrix();
  return X;
}

std::vector<const Measurement*> Campaign::rowsIn(RowSet set) const {
  std::vector<const Measurement*> out;
  for (const Measurement& m : rows) {
    if (m.set == set) out.push_back(&m);
  }
  return out;
}

Campaign readCampaign(const std::string& path) {
  std::error_code ec;
  const fs::path yaml_path =
      fs::is_directory(path, ec) ? fs::path(path) / "campaign.yaml" : fs::path(path);
  const std::string yaml_file = yaml_path.string();
  if (fs::is_regular_file(yaml_path, ec) && !isCampaignFileName(yaml_path)) {
    throw InputError(std::string("is a file; expected ") + kCampaignFolderText, yaml_file);
  }
  if (!fs::is_regular_file(yaml_path, ec)) {
    throw InputError(
        "no campaign here; expected a campaign folder containing campaign.yaml, "
        "or the path of its campaign.yaml",
        yaml_file);
  }
  const YAML::Node root =
      parseYaml(readReferredFile(yaml_path, "campaign file", yaml_file, 0), yaml_file);
  const YamlReader yaml(yaml_file);
  if (!root.IsMap()) {
    yaml.fail(1, "expected a YAML mapping with the keys " + joined(kYamlKeys) + ", got " +
                     (root.IsNull() ? std::string("an empty file") : YamlReader::shape(root)));
  }
  const auto keys = yaml.keysOf(root, kYamlKeys, "campaign");

  Campaign c;
  c.directory = yaml_path.parent_path().empty() ? "." : yaml_path.parent_path().string();
  const ReferredFileLines lines = readNamesAndLinks(yaml, keys, c);
  if (const auto it = keys.find("tracker"); it != keys.end()) readTracker(yaml, it->second, c);
  if (const auto it = keys.find("gravity_in_base"); it != keys.end()) {
    c.gravity_in_base = readGravity(yaml, it->second);
  }

  c.urdf_xml = readReferredFile(yaml_path.parent_path() / c.robot_file, "robot description",
                                yaml_file, lines.robot);
  readMeasurements(yaml_path.parent_path() / c.measurements_file, yaml_file, lines.measurements,
                   c);
  return c;
}

void writeCampaign(const Campaign& campaign, const std::string& directory) {
  const fs::path dir(directory);
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw InputError("is a file; expected the campaign folder to write (created if missing)",
                     directory);
  }
  const std::string yaml = yamlText(campaign, (dir / "campaign.yaml").string());
  const std::string csv = csvText(campaign, (dir / "measurements.csv").string());
  fs::create_directories(dir, ec);
  if (ec) {
    throw InputError("cannot create the campaign folder: " + ec.message(), directory);
  }
  writeFile(dir / "robot.urdf", campaign.urdf_xml);
  writeFile(dir / "measurements.csv", csv);
  writeFile(dir / "campaign.yaml", yaml);
}


// ---------------------------------------------------------------------------------------------
// poses.csv

std::vector<PlannedMeasurement> readPoseList(const std::string& path, int joint_count) {
  const std::string text = readReferredFile(path, "pose list", "", 0);
  auto fail = [&](int line, const std::string& column, const std::string& message) {
    throw InputError(message, path, line, column);
  };
  const std::vector<std::string_view> lines = splitLines(text);
  if (lines.empty() || lines[0].empty()) {
    fail(1, "", "the header line is empty; expected pose_id,load_kg,q1_deg,…,q" +
                    std::to_string(joint_count) + "_deg");
  }
  std::vector<std::string> expected = {"pose_id", "load_kg"};
  for (int k = 1; k <= joint_count; ++k) expected.push_back(jointColumn(k));
  const std::vector<std::string_view> names = splitFields(lines[0]);
  std::map<std::string, int> position;  // column name → field index
  for (size_t i = 0; i < names.size(); ++i) {
    const std::string name(names[i]);
    if (std::find(expected.begin(), expected.end(), name) == expected.end()) {
      fail(1, name,
           "unknown column " + inQuotes(name) + "; expected only " + joined(expected) +
               " (hint: a pose list holds the commanded poses, the robot has " +
               std::to_string(joint_count) + " joints)");
    }
    if (!position.emplace(name, static_cast<int>(i)).second) {
      fail(1, name, "column " + inQuotes(name) + " appears twice; expected each column once");
    }
  }
  for (const std::string& name : expected) {
    if (position.count(name) == 0) {
      fail(1, name, "required column " + inQuotes(name) + " is missing; expected " +
                        joined(expected));
    }
  }
  if (lines.size() == 1) fail(1, "", "the file has a header but no rows; expected one row per measurement");

  std::vector<PlannedMeasurement> rows;
  std::map<std::string, size_t> unloaded_of;  // pose_id → index of its unloaded row
  std::map<std::pair<std::string, double>, int> line_of;  // (pose_id, load) → line
  for (size_t i = 1; i < lines.size(); ++i) {
    const int line = static_cast<int>(i) + 1;
    const std::vector<std::string_view> fields = splitFields(lines[i]);
    if (fields.size() != names.size()) {
      fail(line, "", "row has " + std::to_string(fields.size()) + " fields; expected " +
                         std::to_string(names.size()) + " as in the header (hint: the decimal "
                         "point is '.', columns are separated by ',')");
    }
    auto field = [&](const std::string& name) { return fields[static_cast<size_t>(position[name])]; };
    PlannedMeasurement row;
    row.source_line = line;
    row.pose_id = std::string(field("pose_id"));
    if (row.pose_id.empty() || row.pose_id.find('"') != std::string::npos) {
      fail(line, "pose_id", "expected a pose id (non-empty text without quotes), got " +
                                inQuotes(row.pose_id));
    }
    const std::optional<double> load = parseFinite(field("load_kg"));
    if (!load || *load < 0.0) {
      fail(line, "load_kg", "expected a payload mass >= 0 (kg), got " + inQuotes(field("load_kg")) +
                                numberHint(field("load_kg")));
    }
    row.load_kg = *load;
    row.q_rad.resize(joint_count);
    for (int k = 1; k <= joint_count; ++k) {
      const std::string name = jointColumn(k);
      const std::optional<double> q = parseDegreesAsRadians(field(name));
      if (!q) {
        fail(line, name, "expected a joint angle (deg), got " + inQuotes(field(name)) +
                             numberHint(field(name)));
      }
      row.q_rad(k - 1) = *q;
    }
    const auto [it, inserted] = line_of.emplace(std::make_pair(row.pose_id, row.load_kg), line);
    if (!inserted) {
      fail(line, "load_kg", "pose_id " + inQuotes(row.pose_id) + " at " +
                                formatShortest(row.load_kg) + " kg already appears on line " +
                                std::to_string(it->second) + "; expected each load once per pose");
    }
    if (row.load_kg == 0.0) unloaded_of[row.pose_id] = rows.size();
    rows.push_back(std::move(row));
  }
  for (const PlannedMeasurement& row : rows) {
    const auto unloaded = unloaded_of.find(row.pose_id);
    if (unloaded == unloaded_of.end()) {
      fail(row.source_line, "pose_id",
           "pose_id " + inQuotes(row.pose_id) + " has no unloaded row; expected one at load_kg 0 "
           "(step 2 measures a load's deflection against it)");
    }
    const PlannedMeasurement& reference = rows[unloaded->second];
    for (int k = 0; k < joint_count; ++k) {
      if (row.q_rad(k) != reference.q_rad(k)) {
        fail(row.source_line, jointColumn(k + 1),
             "value " + inQuotes(formatRadiansAsDegrees(row.q_rad(k))) + " differs from the unloaded row's " +
                 inQuotes(formatRadiansAsDegrees(reference.q_rad(k))) + " (line " +
                 std::to_string(reference.source_line) +
                 "); expected the same commanded angles for every load of a pose_id");
      }
    }
  }
  return rows;
}

void writePoseList(const std::vector<PlannedMeasurement>& rows, const std::string& path) {
  std::string text = "pose_id,load_kg";
  const int joint_count = rows.empty() ? 0 : static_cast<int>(rows.front().q_rad.size());
  for (int k = 1; k <= joint_count; ++k) text += "," + jointColumn(k);
  text += "\n";
  for (const PlannedMeasurement& row : rows) {
    STEPCAL_INVARIANT(row.q_rad.size() == joint_count, "pose list rows of different joint counts");
    text += row.pose_id + "," + formatShortest(row.load_kg);
    for (int k = 0; k < joint_count; ++k) text += "," + formatRadiansAsDegrees(row.q_rad(k));
    text += "\n";
  }
  writeFile(path, text);
}

Campaign mergeCampaigns(std::vector<Campaign> campaigns) {
  if (campaigns.empty()) throw InputError("no campaign to merge; expected at least one folder");
  if (campaigns.size() == 1) return std::move(campaigns[0]);
  Campaign merged = campaigns[0];
  merged.rows.clear();
  const Campaign& first = campaigns[0];
  for (size_t k = 0; k < campaigns.size(); ++k) {
    const Campaign& c = campaigns[k];
    const auto differs = [&](const std::string& field, const std::string& mine,
                             const std::string& theirs) {
      throw InputError("campaign " + std::to_string(k + 1) + " has " + field + " " + mine +
                           ", campaign 1 (" + first.directory + ") " + theirs +
                           "; expected one robot measured in every campaign",
                       c.directory + "/campaign.yaml", 0, field);
    };
    if (c.urdf_xml != first.urdf_xml) {
      differs("robot", "'" + c.robot_file + "'", "'" + first.robot_file + "' with other contents");
    }
    if (c.base_link != first.base_link) differs("base_link", c.base_link, first.base_link);
    if (c.tip_link != first.tip_link) differs("tip_link", c.tip_link, first.tip_link);
    if (c.sensor_link != first.sensor_link) {
      differs("sensor_link", "'" + c.sensor_link + "'", "'" + first.sensor_link + "'");
    }
    if (c.flange_link != first.flange_link) {
      differs("flange_link", "'" + c.flange_link + "'", "'" + first.flange_link + "'");
    }
    if (c.joint_count != first.joint_count) {
      differs("joints", std::to_string(c.joint_count), std::to_string(first.joint_count));
    }
    if (c.gravity_in_base.has_value() != first.gravity_in_base.has_value() ||
        (c.gravity_in_base && (*c.gravity_in_base - *first.gravity_in_base).norm() > 1e-9)) {
      differs("gravity", c.gravity_in_base ? "stated" : "not stated",
              first.gravity_in_base ? "another or stated" : "not stated");
    }
    CampaignSession session{c.directory, c.tracker, merged.rows.size(), c.rows.size()};
    merged.tracker.position_sigma_m =
        std::max(merged.tracker.position_sigma_m, c.tracker.position_sigma_m);
    merged.tracker.orientation_sigma_rad =
        std::max(merged.tracker.orientation_sigma_rad, c.tracker.orientation_sigma_rad);
    merged.tracker.stated = merged.tracker.stated || c.tracker.stated;
    const bool same_columns = c.extra_columns == first.extra_columns;
    if (!same_columns) merged.extra_columns.clear();
    for (Measurement row : c.rows) {
      row.session = static_cast<int>(k);
      merged.rows.push_back(std::move(row));
    }
    merged.sessions.push_back(std::move(session));
  }
  if (merged.extra_columns.empty()) {
    for (Measurement& row : merged.rows) row.extra.clear();
  }
  return merged;
}

}  // namespace stepcal
