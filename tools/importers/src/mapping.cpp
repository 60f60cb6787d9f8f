// Reading the general importer's mapping file (mapping.hpp), strictly: an unknown key, a key
// given twice or a value of the wrong kind is refused with its line.
#include "mapping.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>

#include "stepcal/common/error.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::importers {
namespace {

namespace fs = std::filesystem;

constexpr const char* kFormat = "stepcal-import-mapping/1";

std::string listed(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

std::string shapeOf(const YAML::Node& value) {
  if (value.IsSequence()) return "a list";
  if (value.IsMap()) return "a mapping";
  if (value.IsNull()) return "nothing";
  return inQuotes(value.Scalar());
}

/// One mapping of the file, its keys checked; values read by key with the key's line in errors.
class Section {
 public:
  Section(const YAML::Node& node, std::string where, const std::vector<std::string>& known,
          const std::string& file, int line)
      : where_(std::move(where)), file_(file), line_(line) {
    if (!node.IsMap()) fail(line, "expected a mapping, got " + shapeOf(node));
    for (const auto& entry : node) {
      const int key_line = entry.first.Mark().line + 1;
      const std::string key = entry.first.IsScalar() ? entry.first.Scalar() : std::string();
      if (std::find(known.begin(), known.end(), key) == known.end()) {
        fail(key_line, "unknown key " + inQuotes(key) + "; expected one of " + listed(known));
      }
      if (!entries_.emplace(key, Entry{entry.second, key_line}).second) {
        fail(key_line, "key " + inQuotes(key) + " appears twice");
      }
    }
  }

  [[noreturn]] void fail(int line, const std::string& message) const {
    throw InputError(where_ + ": " + message, file_, line);
  }
  bool has(const std::string& key) const { return entries_.count(key) != 0; }
  int lineOf(const std::string& key) const { return entries_.at(key).line; }
  const YAML::Node& node(const std::string& key) const { return entries_.at(key).value; }

  std::string text(const std::string& key) const {
    if (!has(key)) fail(line_, "required key " + inQuotes(key) + " is missing");
    const Entry& e = entries_.at(key);
    if (!e.value.IsScalar() || e.value.Scalar().empty()) {
      fail(e.line, "key " + inQuotes(key) + ": expected text, got " + shapeOf(e.value));
    }
    return e.value.Scalar();
  }
  std::string textOr(const std::string& key, const std::string& fallback) const {
    return has(key) ? text(key) : fallback;
  }
  std::string oneOf(const std::string& key, const std::vector<std::string>& allowed,
                    const std::string& fallback) const {
    const std::string v = textOr(key, fallback);
    if (std::find(allowed.begin(), allowed.end(), v) == allowed.end()) {
      fail(lineOf(key), "key " + inQuotes(key) + ": expected one of " + listed(allowed) + ", got " +
                            inQuotes(v));
    }
    return v;
  }
  double number(const std::string& key, const std::string& expected) const {
    const std::optional<double> v = parseFinite(text(key));
    if (!v)
      fail(lineOf(key),
           "key " + inQuotes(key) + ": expected " + expected + ", got " + shapeOf(node(key)));
    return *v;
  }
  std::vector<std::string> texts(const std::string& key, size_t count) const {
    if (!has(key)) fail(line_, "required key " + inQuotes(key) + " is missing");
    const Entry& e = entries_.at(key);
    std::vector<std::string> out;
    if (e.value.IsSequence()) {
      for (const auto& item : e.value) {
        if (item.IsScalar() && !item.Scalar().empty()) out.push_back(item.Scalar());
      }
    }
    if (!e.value.IsSequence() || out.size() != e.value.size() || (count && out.size() != count) ||
        out.empty()) {
      fail(e.line, "key " + inQuotes(key) + ": expected a list of " +
                       (count ? std::to_string(count) + " " : std::string()) + "names, got " +
                       shapeOf(e.value));
    }
    return out;
  }
  /// A list of exactly `count` finite numbers, each described by `each` in messages.
  std::vector<double> numbers(const std::string& key, size_t count, const std::string& each) const {
    if (!has(key)) fail(line_, "required key " + inQuotes(key) + " is missing");
    const Entry& e = entries_.at(key);
    const std::string expected = "expected a list of " + std::to_string(count) + " " + each;
    if (!e.value.IsSequence() || e.value.size() != count) {
      fail(e.line, "key " + inQuotes(key) + ": " + expected + ", got " +
                       (e.value.IsSequence() ? "a list of " + std::to_string(e.value.size())
                                             : shapeOf(e.value)));
    }
    std::vector<double> out;
    for (size_t i = 0; i < count; ++i) {
      const YAML::Node item = e.value[i];
      const std::optional<double> v =
          item.IsScalar() ? parseFinite(item.Scalar()) : std::optional<double>();
      if (!v) {
        fail(item.Mark().line + 1, "key " + inQuotes(key) + ", item " + std::to_string(i + 1) +
                                       ": " + expected + ", got " + shapeOf(item));
      }
      out.push_back(*v);
    }
    return out;
  }
  /// A whole number >= 0 that fits an int (no float-to-int overflow on any value).
  int count(const std::string& key, const std::string& what) const {
    const double n = number(key, what + ", a whole number >= 0");
    if (!(n >= 0 && n <= 1e9 && n == std::floor(n))) {
      fail(lineOf(key), "key " + inQuotes(key) + ": expected " + what +
                            ", a whole number >= 0, got " + shapeOf(node(key)));
    }
    return static_cast<int>(n);
  }
  Vec3 vector3(const std::string& key, const std::string& unit) const {
    const std::vector<std::string> items = texts(key, 3);
    Vec3 v;
    for (int i = 0; i < 3; ++i) {
      const std::optional<double> x = parseFinite(items[static_cast<size_t>(i)]);
      if (!x)
        fail(lineOf(key), "key " + inQuotes(key) + ": expected 3 numbers (" + unit + "), got " +
                              inQuotes(items[static_cast<size_t>(i)]));
      v[i] = *x;
    }
    return v;
  }
  Section sub(const std::string& key, const std::vector<std::string>& known) const {
    if (!has(key)) fail(line_, "required key " + inQuotes(key) + " is missing");
    return Section(node(key), where_ + "." + key, known, file_, lineOf(key));
  }

 private:
  struct Entry {
    YAML::Node value;
    int line = 0;
  };
  std::string where_;
  std::string file_;
  int line_ = 0;  ///< where the section starts, for keys it lacks
  std::map<std::string, Entry> entries_;
};

/// Whether a name can be an extra column of a campaign (docs/campaign-format.md): bare, and not
/// one of the format's own columns.
bool isExtraColumnName(const std::string& name) {
  static const std::array<const char*, 18> kCampaignColumns = {
      "seq",   "pose_id", "set",  "load_kg", "fx_n", "fy_n", "fz_n", "mx_nm", "my_nm",
      "mz_nm", "x_mm",    "y_mm", "z_mm",    "qw",   "qx",   "qy",   "qz",    "temp_c"};
  if (name.empty() || name.find_first_of(" \t\",\r\n") != std::string::npos) return false;
  if (std::find(kCampaignColumns.begin(), kCampaignColumns.end(), name) != kCampaignColumns.end()) {
    return false;
  }
  const bool joint_like =
      name.size() >= 6 && name.front() == 'q' && name.compare(name.size() - 4, 4, "_deg") == 0 &&
      std::all_of(name.begin() + 1, name.end() - 4, [](char c) { return c >= '0' && c <= '9'; });
  return !joint_like;
}

std::string resolved(const fs::path& folder, const std::string& path) {
  return fs::path(path).is_absolute() ? path : (folder / path).lexically_normal().string();
}

TableFormat tableFormat(const Section& s, const fs::path& folder) {
  TableFormat t;
  t.path = resolved(folder, s.text("file"));
  const std::string separator = s.oneOf("separator", {",", ";", "tab", "space"}, ",");
  t.separator = separator == "tab" ? '\t' : separator == "space" ? ' ' : separator[0];
  t.decimal_comma = s.oneOf("decimal", {"point", "comma"}, "point") == "comma";
  if (t.decimal_comma && t.separator == ',') {
    s.fail(s.lineOf("decimal"), "a decimal comma needs another separator (';', tab or space)");
  }
  if (s.has("skip_lines")) t.skip_lines = s.count("skip_lines", "a count of lines");
  return t;
}

std::optional<TimeColumn> timeColumn(const Section& s) {
  if (!s.has("time")) return std::nullopt;
  TimeColumn t;
  t.column = s.text("time");
  t.seconds_per_unit = s.oneOf("time_unit", {"s", "ms"}, "s") == "ms" ? 1e-3 : 1.0;
  return t;
}

void readRobot(const Section& top, const fs::path& folder, ImportMapping& m) {
  const Section r = top.sub("robot", {"urdf", "base_link", "tip_link", "flange_link", "sensor_link",
                                      "gravity_in_base", "add_tip_link"});
  const std::string urdf = r.text("urdf");
  m.urdf_path = isRobotPath(urdf) ? resolved(folder, urdf) : robotDescriptionPath(urdf);
  m.base_link = r.text("base_link");
  m.tip_link = r.text("tip_link");
  m.flange_link = r.textOr("flange_link", "");
  m.sensor_link = r.textOr("sensor_link", "");
  if (r.has("gravity_in_base")) m.gravity_in_base = r.vector3("gravity_in_base", "m/s²");
  if (!r.has("add_tip_link")) return;
  const Section a =
      r.sub("add_tip_link", {"parent", "transform_file", "unit", "invert", "then_rpy_deg"});
  ImportMapping::AddedLink link;
  link.parent = a.text("parent");
  link.transform_path = resolved(folder, a.text("transform_file"));
  link.metres_per_unit = a.oneOf("unit", {"mm", "m"}, "m") == "mm" ? kMPerMm : 1.0;
  link.invert = a.oneOf("invert", {"true", "false"}, "false") == "true";
  if (a.has("then_rpy_deg")) {
    link.then_rpy_rad = a.vector3("then_rpy_deg", "degrees") * kPi / 180.0;
  }
  m.added_tip = link;
}

void readOrientation(const Section& t, OrientationMapping& o) {
  if (!t.has("orientation")) return;
  const Section s = t.sub("orientation", {"quaternion", "euler", "columns", "unit"});
  if (s.has("quaternion") == s.has("euler")) {
    s.fail(t.lineOf("orientation"), "expected either 'quaternion: wxyz|xyzw' or 'euler: AXES'");
  }
  if (s.has("quaternion")) {
    o.kind = OrientationKind::kQuaternion;
    o.scalar_first = s.oneOf("quaternion", {"wxyz", "xyzw"}, "wxyz") == "wxyz";
    o.columns = s.texts("columns", 4);
    return;
  }
  o.kind = OrientationKind::kEuler;
  o.euler_axes = s.text("euler");
  const std::string& a = o.euler_axes;
  const bool upper = std::all_of(a.begin(), a.end(), [](char c) { return c >= 'X' && c <= 'Z'; });
  const bool lower = std::all_of(a.begin(), a.end(), [](char c) { return c >= 'x' && c <= 'z'; });
  if (a.size() != 3 || !(upper || lower) || a[0] == a[1] || a[1] == a[2]) {
    s.fail(
        s.lineOf("euler"),
        "key 'euler': expected three axes, upper case for intrinsic (XYZ; ZYX: KUKA A, B, C; "
        "ZYZ) or lower case for extrinsic (xyz: roll, pitch, yaw), no axis twice in a row, got " +
            inQuotes(a));
  }
  o.columns = s.texts("columns", 3);
  o.degrees = s.oneOf("unit", {"deg", "rad"}, "deg") == "deg";
}

/// The F/T sensor's columns in a table's section (tracker or joints), in one of them only.
void readWrench(const Section& table, WrenchMapping::Table which, WrenchMapping& w) {
  if (!table.has("wrench")) return;
  if (w.table != WrenchMapping::Table::kNone) {
    table.fail(table.lineOf("wrench"),
               "a wrench is mapped in tracker and in joints; expected it in one of them");
  }
  const Section s = table.sub("wrench", {"columns", "force_unit", "moment_unit"});
  w.table = which;
  w.columns = s.texts("columns", 6);
  w.force_unit = s.oneOf("force_unit", {"N", "kN"}, "N");
  w.force_shift_to_newtons = w.force_unit == "kN" ? 3 : 0;
  w.moment_unit = s.oneOf("moment_unit", {"Nm", "Nmm", "kNm"}, "Nm");
  w.moment_shift_to_newton_metres = w.moment_unit == "Nmm" ? -3 : w.moment_unit == "kNm" ? 3 : 0;
}

void readTracker(const Section& top, const fs::path& folder, ImportMapping& m) {
  const Section t =
      top.sub("tracker", {"file", "separator", "decimal", "skip_lines", "position", "length_unit",
                          "orientation", "temperature_c", "keep", "position_sigma_mm",
                          "orientation_sigma_deg", "time", "time_unit", "point_name", "wrench"});
  m.tracker = tableFormat(t, folder);
  m.position_columns = t.texts("position", 3);
  m.length_shift_to_metres = t.oneOf("length_unit", {"mm", "m"}, "mm") == "mm" ? -3 : 0;
  readOrientation(t, m.orientation);
  m.temperature_column = t.textOr("temperature_c", "");
  if (t.has("keep")) {
    const YAML::Node& keep = t.node("keep");
    if (!keep.IsMap())
      t.fail(t.lineOf("keep"), "key 'keep': expected a mapping campaign_column: tracker_column");
    for (const auto& entry : keep) {
      const int line = entry.first.Mark().line + 1;
      if (!entry.second.IsScalar() || entry.second.Scalar().empty()) {
        t.fail(line, "key 'keep': expected a tracker column name");
      }
      const std::string name = entry.first.IsScalar() ? entry.first.Scalar() : std::string();
      if (!isExtraColumnName(name) || std::any_of(m.kept.begin(), m.kept.end(),
                                                  [&](const auto& k) { return k.first == name; })) {
        t.fail(line, "key 'keep': campaign column " + inQuotes(name) +
                         ": expected a new bare name (no spaces, quotes, commas or line breaks) "
                         "that is none of the campaign's own columns (seq, pose_id, set, load_kg, "
                         "qN_deg, fx_n … mz_nm, x_mm … z_mm, qw … qz, temp_c), each once");
      }
      m.kept.emplace_back(name, entry.second.Scalar());
    }
  }
  if (t.has("position_sigma_mm") != t.has("orientation_sigma_deg")) {
    t.fail(t.lineOf(t.has("position_sigma_mm") ? "position_sigma_mm" : "orientation_sigma_deg"),
           "expected position_sigma_mm and orientation_sigma_deg together");
  }
  if (t.has("position_sigma_mm")) {
    m.noise.position_sigma_m = t.number("position_sigma_mm", "a number (mm)") * kMPerMm;
    m.noise.orientation_sigma_rad =
        t.number("orientation_sigma_deg", "a number (deg)") * kRadPerDeg;
    if (!(m.noise.position_sigma_m > 0) || !(m.noise.orientation_sigma_rad > 0)) {
      t.fail(t.lineOf("position_sigma_mm"), "expected tracker sigmas > 0");
    }
    m.noise.stated = true;
  }
  m.tracker_time = timeColumn(t);
  m.tracker_point = t.textOr("point_name", "");
  readWrench(t, WrenchMapping::Table::kTracker, m.wrench);
}

/// q_urdf = sign·q_log + offset: the controller's count of each axis turned into the URDF's.
void readJointConvention(const Section& j, ImportMapping& m) {
  const size_t n = m.joint_columns.size();
  const std::string per_joint = " (one per name in joints.columns)";
  if (j.has("sign")) {
    const std::vector<double> sign = j.numbers("sign", n, "signs, each 1 or -1" + per_joint);
    for (size_t i = 0; i < n; ++i) {
      if (sign[i] != 1.0 && sign[i] != -1.0) {
        j.fail(j.node("sign")[i].Mark().line + 1,
               "key 'sign', item " + std::to_string(i + 1) + " (" + m.joint_columns[i] +
                   "): expected 1 or -1, got " + inQuotes(j.node("sign")[i].Scalar()));
      }
      m.joint_sign.push_back(sign[i] > 0 ? 1 : -1);
    }
  }
  if (j.has("offset_deg")) {
    for (double offset_deg : j.numbers("offset_deg", n, "finite offsets in degrees" + per_joint)) {
      m.joint_offset_rad.push_back(offset_deg * kRadPerDeg);
    }
  }
}

void readJoints(const Section& top, const fs::path& folder, ImportMapping& m) {
  const Section j =
      top.sub("joints", {"file", "separator", "decimal", "skip_lines", "columns", "unit", "sign",
                         "offset_deg", "time", "time_unit", "point_name", "load_kg", "wrench"});
  m.joints = tableFormat(j, folder);
  m.joint_columns = j.texts("columns", 0);
  m.joints_in_degrees = j.oneOf("unit", {"deg", "rad"}, "deg") == "deg";
  m.joints_time = timeColumn(j);
  m.joints_point = j.textOr("point_name", "");
  m.load_column = j.textOr("load_kg", "");
  readJointConvention(j, m);
  readWrench(j, WrenchMapping::Table::kJoints, m.wrench);
}

void readJoin(const Section& top, ImportMapping& m) {
  const Section j = top.sub("join", {"by", "tolerance_s"});
  const std::string by = j.oneOf("by", {"row", "timestamp", "point_name"}, "row");
  if (by == "timestamp") {
    m.join = ImportMapping::Join::kTimestamp;
    m.tolerance_s = j.number("tolerance_s", "a time in seconds > 0");
    if (!(m.tolerance_s > 0)) j.fail(j.lineOf("tolerance_s"), "expected tolerance_s > 0");
    if (!m.tracker_time || !m.joints_time) {
      j.fail(j.lineOf("by"), "joining by timestamp needs 'time' in both tracker and joints");
    }
  } else if (by == "point_name") {
    m.join = ImportMapping::Join::kPointName;
    if (m.tracker_point.empty() || m.joints_point.empty()) {
      j.fail(j.lineOf("by"), "joining by point name needs 'point_name' in both tracker and joints");
    }
  } else if (j.has("tolerance_s")) {
    j.fail(j.lineOf("tolerance_s"), "tolerance_s is for 'by: timestamp' only");
  }
}

}  // namespace

ImportMapping readImportMapping(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw InputError("mapping file not found; expected a readable YAML file", path);
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw InputError("not valid YAML: " + e.msg, path, e.mark.line >= 0 ? e.mark.line + 1 : 0);
  }
  const Section top(root, "mapping",
                    {"format", "robot", "tracker", "joints", "join", "validation_from_row"}, path,
                    1);
  if (top.text("format") != kFormat) {
    top.fail(top.lineOf("format"), "key 'format': expected " + std::string(kFormat) + ", got " +
                                       inQuotes(top.text("format")));
  }
  ImportMapping m;
  m.file = path;
  const fs::path folder = fs::path(path).parent_path();
  readRobot(top, folder, m);
  readTracker(top, folder, m);
  readJoints(top, folder, m);
  readJoin(top, m);
  if (top.has("validation_from_row")) {
    m.validation_from_row = top.count("validation_from_row", "a row index");
  }
  if (m.wrench.table != WrenchMapping::Table::kNone && m.sensor_link.empty()) {
    throw InputError(
        "a wrench is mapped but robot.sensor_link is missing; expected the link "
        "whose axes the F/T sensor reports in",
        path);
  }
  return m;
}

}  // namespace stepcal::importers
