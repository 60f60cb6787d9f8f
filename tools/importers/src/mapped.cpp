// The general importer (mapped.hpp): the tracker export and the joint log as tables, their rows
// joined, each joined pair one campaign row.
#include "stepcal/importers/mapped.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string_view>
#include <vector>

#include "mapping.hpp"
#include "shared.hpp"
#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal::importers {
namespace {

std::string_view trimmed(std::string_view s) {
  const size_t first = s.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

/// A table file read whole: header names and rows of fields, each row with its file line.
class Table {
 public:
  Table(const TableFormat& format, const std::string& what)
      : format_(format), text_(std::make_shared<std::string>(readExistingFile(format.path, what))) {
    const std::vector<std::string_view> lines = splitLines(*text_);
    const int header_line = format.skip_lines + 1;
    if (static_cast<int>(lines.size()) < header_line) {
      throw InputError("has " + std::to_string(lines.size()) + " lines; expected " +
                           std::to_string(format.skip_lines) + " to skip and a header line",
                       format.path);
    }
    header_line_ = header_line;
    for (std::string_view name : fieldsOf(lines[static_cast<size_t>(header_line - 1)])) {
      names_.emplace_back(name);
    }
    for (size_t i = static_cast<size_t>(header_line); i < lines.size(); ++i) {
      if (trimmed(lines[i]).empty()) continue;  // blank lines are no rows
      std::vector<std::string_view> fields = fieldsOf(lines[i]);
      const int line = static_cast<int>(i) + 1;
      if (fields.size() != names_.size()) {
        fail(line, "",
             "row has " + std::to_string(fields.size()) + " fields; expected " +
                 std::to_string(names_.size()) + " as in the header (line " +
                 std::to_string(header_line) + ")");
      }
      rows_.push_back(std::move(fields));
      lines_.push_back(line);
    }
    if (rows_.empty()) fail(header_line, "", "no rows after the header; expected measurements");
  }

  [[noreturn]] void fail(int line, const std::string& column, const std::string& message) const {
    throw InputError(message, format_.path, line, column);
  }
  const std::string& path() const { return format_.path; }
  bool decimalComma() const { return format_.decimal_comma; }
  int rowCount() const { return static_cast<int>(rows_.size()); }
  int lineOf(int row) const { return lines_[static_cast<size_t>(row)]; }

  /// Position of a named column; refuses a name the header lacks.
  int column(const std::string& name, const std::string& meaning) const {
    const auto it = std::find(names_.begin(), names_.end(), name);
    if (it == names_.end()) {
      std::string all;
      for (const std::string& n : names_) all += (all.empty() ? "" : ", ") + inQuotes(n);
      fail(header_line_, name,
           "column " + inQuotes(name) + " (" + meaning +
               ", named by the mapping) is missing; the "
               "header has " +
               all);
    }
    return static_cast<int>(it - names_.begin());
  }
  std::string_view field(int row, int col) const {
    return rows_[static_cast<size_t>(row)][static_cast<size_t>(col)];
  }
  /// A number's text with a decimal point; refuses what is not a number in the table's writing.
  std::string numberText(int row, int col, const std::string& unit) const {
    const std::string_view f = field(row, col);
    std::string s(f);
    bool ok = true;
    if (format_.decimal_comma) {
      ok = f.find('.') == std::string_view::npos;
      std::replace(s.begin(), s.end(), ',', '.');
    }
    if (!ok || !parseFinite(s)) {
      const std::string mark = format_.decimal_comma ? "a decimal comma" : "a decimal point";
      fail(lineOf(row), names_[static_cast<size_t>(col)],
           "expected a number with " + mark + " (" + unit + "), got " + inQuotes(f));
    }
    return s;
  }
  double number(int row, int col, const std::string& unit) const {
    return *parseFinite(numberText(row, col, unit));
  }
  /// The number times 10^decimal_shift (a unit's change, rounded once from the decimal text);
  /// refuses one that the change takes out of the doubles' range.
  double shiftedNumber(int row, int col, const std::string& unit, int decimal_shift) const {
    const std::optional<double> v = parseFiniteShifted(numberText(row, col, unit), decimal_shift);
    if (!v) {
      fail(lineOf(row), nameOf(col),
           "expected a number (" + unit + ") within the range of doubles once converted, got " +
               inQuotes(field(row, col)));
    }
    return *v;
  }
  const std::string& nameOf(int col) const { return names_[static_cast<size_t>(col)]; }

 private:
  std::vector<std::string_view> fieldsOf(std::string_view line) const {
    std::vector<std::string_view> out;
    for (std::string_view f : splitFields(line, format_.separator)) {
      if (format_.separator == ' ' && f.empty()) continue;  // runs of spaces separate once
      out.push_back(trimmed(f));
    }
    return out;
  }

  TableFormat format_;
  std::shared_ptr<const std::string> text_;  ///< the fields are views into it
  int header_line_ = 1;
  std::vector<std::string> names_;
  std::vector<std::vector<std::string_view>> rows_;
  std::vector<int> lines_;
};

// ---------------------------------------------------------------------------------------------
// Time stamps

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
long daysFromCivil(int y, int m, int d) {
  y -= m <= 2;
  const int era = (y >= 0 ? y : y - 399) / 400;
  const int yoe = y - era * 400;
  const int doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return static_cast<long>(era) * 146097 + doe - 719468;
}

/// Seconds of a clock stamp [YYYY-MM-DD[ T]|DD.MM.YYYY ]hh:mm:ss[.fff]; nullopt if it is not one.
std::optional<double> clockSeconds(std::string_view s, bool decimal_comma) {
  int y = 1970, mo = 1, d = 1, h = 0, mi = 0, consumed = 0;
  double sec = 0.0;
  std::string text(s);
  if (decimal_comma) std::replace(text.begin(), text.end(), ',', '.');
  const char* c = text.c_str();
  if (std::sscanf(c, "%4d-%2d-%2d%*1[ T]%n", &y, &mo, &d, &consumed) == 3 && consumed > 0) {
    c += consumed;
  } else if (std::sscanf(c, "%2d.%2d.%4d %n", &d, &mo, &y, &consumed) == 3 && consumed > 0) {
    c += consumed;
  }
  consumed = 0;
  if (std::sscanf(c, "%2d:%2d:%n", &h, &mi, &consumed) != 2 || consumed == 0) return std::nullopt;
  const std::optional<double> seconds = parseFinite(c + consumed);
  if (!seconds || *seconds < 0 || *seconds >= 61 || h > 23 || mi > 59 || mo < 1 || mo > 12 ||
      d < 1 || d > 31) {
    return std::nullopt;
  }
  sec = *seconds;
  return static_cast<double>(daysFromCivil(y, mo, d)) * 86400.0 + h * 3600.0 + mi * 60.0 + sec;
}

std::vector<double> timesOf(const Table& t, const TimeColumn& time) {
  const int col = t.column(time.column, "time stamp");
  std::vector<double> out;
  for (int r = 0; r < t.rowCount(); ++r) {
    if (std::optional<double> clock = clockSeconds(t.field(r, col), t.decimalComma())) {
      out.push_back(*clock);
      continue;
    }
    out.push_back(t.number(r, col,
                           "a time stamp: seconds, or hh:mm:ss[.fff] after an optional "
                           "date YYYY-MM-DD or DD.MM.YYYY") *
                  time.seconds_per_unit);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Joining

/// For each tracker row, its joint log row.
std::vector<int> joinByTimestamp(const ImportMapping& m, const Table& tracker,
                                 const Table& joints) {
  const std::vector<double> t_tracker = timesOf(tracker, *m.tracker_time);
  const std::vector<double> t_joints = timesOf(joints, *m.joints_time);
  std::vector<int> order(t_joints.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return t_joints[static_cast<size_t>(a)] < t_joints[static_cast<size_t>(b)];
  });
  std::vector<int> out;
  for (int r = 0; r < tracker.rowCount(); ++r) {
    const double t = t_tracker[static_cast<size_t>(r)];
    const auto it = std::lower_bound(order.begin(), order.end(), t, [&](int j, double value) {
      return t_joints[static_cast<size_t>(j)] < value;
    });
    int best = -1;
    for (auto c : {it, it == order.begin() ? it : it - 1}) {
      if (c == order.end()) continue;
      if (best < 0 || std::abs(t_joints[static_cast<size_t>(*c)] - t) <
                          std::abs(t_joints[static_cast<size_t>(best)] - t)) {
        best = *c;
      }
    }
    const double gap = std::abs(t_joints[static_cast<size_t>(best)] - t);
    if (gap > m.tolerance_s) {
      std::array<char, 32> gap_text{};  // ms: stamps of a day and more leave no finer digits
      std::snprintf(gap_text.data(), gap_text.size(), "%.3f", gap);
      tracker.fail(tracker.lineOf(r), m.tracker_time->column,
                   "no joint log row within tolerance_s " + formatShortest(m.tolerance_s) +
                       " s; the nearest is " + joints.path() + " line " +
                       std::to_string(joints.lineOf(best)) + ", " + gap_text.data() +
                       " s away (expected the controller's reading at the tracker's time)");
    }
    out.push_back(best);
  }
  return out;
}

std::vector<int> joinByPointName(const ImportMapping& m, const Table& tracker,
                                 const Table& joints) {
  const int jcol = joints.column(m.joints_point, "point name");
  std::map<std::string, int, std::less<>> row_of;
  for (int r = 0; r < joints.rowCount(); ++r) {
    const std::string name(joints.field(r, jcol));
    const auto [it, added] = row_of.emplace(name, r);
    if (!added) {
      joints.fail(joints.lineOf(r), m.joints_point,
                  "point " + inQuotes(name) + " appears again (first on line " +
                      std::to_string(joints.lineOf(it->second)) + "); expected each point once");
    }
  }
  const int tcol = tracker.column(m.tracker_point, "point name");
  std::vector<int> out;
  for (int r = 0; r < tracker.rowCount(); ++r) {
    const auto it = row_of.find(tracker.field(r, tcol));
    if (it == row_of.end()) {
      tracker.fail(tracker.lineOf(r), m.tracker_point,
                   "point " + inQuotes(tracker.field(r, tcol)) + " is not in the joint log " +
                       joints.path() + "; expected a point name it has");
    }
    out.push_back(it->second);
  }
  return out;
}

std::vector<int> joinedRows(const ImportMapping& m, const Table& tracker, const Table& joints) {
  switch (m.join) {
    case ImportMapping::Join::kTimestamp:
      return joinByTimestamp(m, tracker, joints);
    case ImportMapping::Join::kPointName:
      return joinByPointName(m, tracker, joints);
    case ImportMapping::Join::kRow:
      break;
  }
  if (tracker.rowCount() != joints.rowCount()) {
    throw InputError("joined by row, the tracker export " + tracker.path() + " has " +
                         std::to_string(tracker.rowCount()) + " rows and the joint log " +
                         joints.path() + " " + std::to_string(joints.rowCount()) +
                         "; expected as many",
                     m.file);
  }
  std::vector<int> out(static_cast<size_t>(tracker.rowCount()));
  for (size_t i = 0; i < out.size(); ++i) out[i] = static_cast<int>(i);
  return out;
}

// ---------------------------------------------------------------------------------------------
// Rows

Vec3 axisOf(char name) { return Vec3::Unit(std::tolower(static_cast<unsigned char>(name)) - 'x'); }

/// The measured orientation of one row, by the mapping's convention.
Eigen::Quaterniond orientationOf(const OrientationMapping& o, const Table& t,
                                 const std::vector<int>& cols, int row) {
  std::vector<double> v;
  for (int c : cols)
    v.push_back(t.number(row, c,
                         o.kind == OrientationKind::kQuaternion ? "quaternion component"
                         : o.degrees                            ? "degrees"
                                                                : "radians"));
  if (o.kind == OrientationKind::kQuaternion) {
    const Eigen::Quaterniond q = o.scalar_first ? Eigen::Quaterniond(v[0], v[1], v[2], v[3])
                                                : Eigen::Quaterniond(v[3], v[0], v[1], v[2]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      t.fail(t.lineOf(row), t.nameOf(cols[0]),
             "quaternion has norm " + formatShortest(q.norm()) +
                 "; expected a unit quaternion "
                 "(within 1e-3) in the order the mapping states");
    }
    return q.normalized();
  }
  for (size_t i = 0; i < v.size(); ++i) {
    v[i] = o.degrees ? v[i] * kPi / 180.0 : v[i];  // (deg·π)/180: bit-exact as ipa.cpp
    if (!std::isfinite(v[i])) {
      t.fail(t.lineOf(row), t.nameOf(cols[i]),
             "expected an angle within the range of doubles in radians, got " +
                 inQuotes(t.field(row, cols[i])));
    }
  }
  const std::string& axes = o.euler_axes;
  const bool intrinsic = axes[0] <= 'Z';
  const Eigen::AngleAxisd first(v[0], axisOf(axes[0])), second(v[1], axisOf(axes[1])),
      third(v[2], axisOf(axes[2]));
  const Mat3 R = intrinsic ? (first * second * third).toRotationMatrix()
                           : (third * second * first).toRotationMatrix();
  return Eigen::Quaterniond(R).normalized();
}

std::string poseIdOf(const ImportMapping& m, const Table& tracker, int point_col, int row) {
  if (point_col < 0) {
    std::array<char, 16> id{};
    std::snprintf(id.data(), id.size(), "r%04d", row);
    return id.data();
  }
  const std::string_view name = tracker.field(row, point_col);
  if (name.empty() || name.find_first_of(",\"\r\n") != std::string_view::npos) {
    tracker.fail(tracker.lineOf(row), m.tracker_point,
                 "point name " + inQuotes(name) +
                     ": expected a non-empty name without ',', '\"' or a carriage return");
  }
  return std::string(name);
}

/// Column positions the rows read.
struct Columns {
  std::vector<int> position, orientation, kept, joints, wrench;
  int temperature = -1, point = -1, load = -1;
};

Columns columnsOf(const ImportMapping& m, const Table& tracker, const Table& joints) {
  Columns c;
  for (const std::string& n : m.position_columns)
    c.position.push_back(tracker.column(n, "position"));
  for (const std::string& n : m.orientation.columns)
    c.orientation.push_back(tracker.column(n, "orientation"));
  for (const auto& [name, column] : m.kept)
    c.kept.push_back(tracker.column(column, "kept as " + name));
  for (const std::string& n : m.joint_columns) c.joints.push_back(joints.column(n, "joint angle"));
  if (!m.temperature_column.empty())
    c.temperature = tracker.column(m.temperature_column, "temperature");
  if (!m.tracker_point.empty()) c.point = tracker.column(m.tracker_point, "point name");
  if (!m.load_column.empty()) c.load = joints.column(m.load_column, "payload, kg");
  if (m.wrench.table != WrenchMapping::Table::kNone) {
    const Table& t = m.wrench.table == WrenchMapping::Table::kTracker ? tracker : joints;
    for (const std::string& n : m.wrench.columns) c.wrench.push_back(t.column(n, "F/T reading"));
  }
  return c;
}

/// The controller's angle of one joint in the URDF's sign and zero: q_urdf = sign·q_log + offset.
double urdfJointAngle(const ImportMapping& m, size_t joint, double q_log_rad) {
  double q = q_log_rad;
  if (!m.joint_sign.empty() && m.joint_sign[joint] < 0) q = -q;
  if (!m.joint_offset_rad.empty() && m.joint_offset_rad[joint] != 0.0) {
    q += m.joint_offset_rad[joint];  // skipped at 0: -0.0 stays as written (byte-identical files)
  }
  return q;
}

/// The F/T reading of a row: all six cells or none, none only where the row is unloaded (the
/// campaign's rule, docs/campaign-format.md). row: the row of the table the wrench is in.
void readWrench(const ImportMapping& m, const Table& t, const Columns& c, int row, Measurement& r) {
  const bool all_empty = std::all_of(c.wrench.begin(), c.wrench.end(),
                                     [&](int col) { return t.field(row, col).empty(); });
  if (all_empty && r.load_kg == 0.0) return;
  if (all_empty) {
    t.fail(t.lineOf(row), m.wrench.columns[0],
           "no F/T reading on a row with payload " + formatShortest(r.load_kg) +
               " kg; expected the six wrench values (a wrench may only be missing unloaded)");
  }
  for (int a = 0; a < 6; ++a) {
    r.wrench_Sensor[a] = t.shiftedNumber(
        row, c.wrench[static_cast<size_t>(a)],
        (a < 3 ? m.wrench.force_unit : m.wrench.moment_unit) + ", all six wrench values or none",
        a < 3 ? m.wrench.force_shift_to_newtons : m.wrench.moment_shift_to_newton_metres);
  }
  r.has_wrench = true;
}

Measurement rowOf(const ImportMapping& m, const Table& tracker, const Table& joints,
                  const Columns& c, int row, int joint_row) {
  Measurement r;
  r.seq = row;
  r.pose_id = poseIdOf(m, tracker, c.point, row);
  r.set = m.validation_from_row >= 0 && row >= m.validation_from_row ? RowSet::kValidation
                                                                     : RowSet::kGeometry;
  r.source_line = tracker.lineOf(row);
  const std::string length_unit = m.length_shift_to_metres == -3 ? "millimetres" : "metres";
  for (int a = 0; a < 3; ++a) {
    const int col = c.position[static_cast<size_t>(a)];
    r.p_TipInTracker_m[a] = tracker.shiftedNumber(row, col, length_unit, m.length_shift_to_metres);
  }
  if (m.orientation.kind != OrientationKind::kNone) {
    r.q_TrackerTip = orientationOf(m.orientation, tracker, c.orientation, row);
    r.has_orientation = true;
  }
  if (c.temperature >= 0) r.temp_c = tracker.number(row, c.temperature, "degrees Celsius");
  for (int col : c.kept) r.extra.push_back(tracker.numberText(row, col, "a number to keep"));
  r.q_rad.resize(static_cast<Eigen::Index>(c.joints.size()));
  for (size_t j = 0; j < c.joints.size(); ++j) {
    const double q =
        joints.number(joint_row, c.joints[j], m.joints_in_degrees ? "degrees" : "radians");
    const double q_rad = urdfJointAngle(m, j, m.joints_in_degrees ? q * kPi / 180.0 : q);
    if (!std::isfinite(q_rad) || !std::isfinite(q_rad * kDegPerRad)) {  // campaigns hold degrees
      joints.fail(joints.lineOf(joint_row), m.joint_columns[j],
                  "expected a joint angle whose value in degrees (sign and offset applied) is "
                  "within the range of doubles, got " +
                      inQuotes(joints.field(joint_row, c.joints[j])));
    }
    r.q_rad[static_cast<Eigen::Index>(j)] = q_rad;
  }
  if (c.load >= 0) {
    r.load_kg = joints.number(joint_row, c.load, "kg");
    if (r.load_kg < 0) {
      joints.fail(joints.lineOf(joint_row), m.load_column,
                  "expected a payload >= 0 kg, got " + inQuotes(joints.field(joint_row, c.load)));
    }
    if (r.load_kg > 0 && c.wrench.empty()) {
      joints.fail(joints.lineOf(joint_row), m.load_column,
                  "payload " + inQuotes(joints.field(joint_row, c.load)) +
                      " kg but the mapping names no wrench; expected tracker.wrench or "
                      "joints.wrench (a loaded row needs the F/T reading)");
    }
  }
  if (!c.wrench.empty()) {
    const bool in_tracker = m.wrench.table == WrenchMapping::Table::kTracker;
    readWrench(m, in_tracker ? tracker : joints, c, in_tracker ? row : joint_row, r);
  }
  return r;
}

// ---------------------------------------------------------------------------------------------
// Robot

std::string robotDescription(const ImportMapping& m) {
  std::string urdf = readExistingFile(m.urdf_path, "robot description (robot.urdf of the mapping)");
  if (!m.added_tip) return urdf;
  const ImportMapping::AddedLink& a = *m.added_tip;
  Pose X = readRigidTransformFile(a.transform_path, "transform of robot.add_tip_link",
                                  a.metres_per_unit);
  if (a.invert) X = X.inverse();
  Pose turn = Pose::Identity();
  turn.linear() = lie::rotationFromRpy(a.then_rpy_rad.x(), a.then_rpy_rad.y(), a.then_rpy_rad.z());
  return withFixedLink(urdf, a.parent, m.tip_link, X * turn,
                       "Added by stepcal import mapped: the measured frame, from " +
                           a.transform_path + (a.invert ? " (inverted)" : ""),
                       m.urdf_path);
}

void checkJointCount(const ImportMapping& m, const Campaign& c) {
  const KinematicChain chain = chainFromUrdf(c.urdf_xml, c.base_link, c.tip_link, {}, m.urdf_path);
  if (chain.dof() != static_cast<int>(m.joint_columns.size())) {
    std::string names;
    for (const ChainJoint& joint : chain.joints())
      names += (names.empty() ? "" : ", ") + joint.name;
    throw InputError("the chain " + c.base_link + " → " + c.tip_link + " has " +
                         std::to_string(chain.dof()) + " joints (" + names +
                         "); expected as many names in joints.columns, which lists " +
                         std::to_string(m.joint_columns.size()),
                     m.file);
  }
}

}  // namespace

Campaign importMapped(const std::string& mapping_path) {
  const ImportMapping m = readImportMapping(mapping_path);
  Campaign c;
  c.urdf_xml = robotDescription(m);
  c.base_link = m.base_link;
  c.tip_link = m.tip_link;
  c.flange_link = m.flange_link;
  c.sensor_link = m.sensor_link;
  c.tracker = m.noise;
  c.gravity_in_base = m.gravity_in_base;
  c.joint_count = static_cast<int>(m.joint_columns.size());
  checkJointCount(m, c);
  for (const auto& kept : m.kept) c.extra_columns.push_back(kept.first);

  const Table tracker(m.tracker, "tracker export (tracker.file of the mapping)");
  const Table joints(m.joints, "joint log (joints.file of the mapping)");
  if (m.validation_from_row >= tracker.rowCount()) {
    throw InputError("validation_from_row is " + std::to_string(m.validation_from_row) +
                         " but the tracker export has rows 0 … " +
                         std::to_string(tracker.rowCount() - 1) +
                         "; expected a row index in that range",
                     m.file);
  }
  const Columns columns = columnsOf(m, tracker, joints);
  const std::vector<int> joint_rows = joinedRows(m, tracker, joints);
  for (int r = 0; r < tracker.rowCount(); ++r) {
    c.rows.push_back(rowOf(m, tracker, joints, columns, r, joint_rows[static_cast<size_t>(r)]));
  }
  return c;
}

}  // namespace stepcal::importers
