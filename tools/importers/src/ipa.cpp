// Importer of the IPA UR10 data set into a campaign (see ipa.hpp).
//
// The series files are ';'-separated with decimal commas and a header line: joint angles
// `shoulder_pan_joint … wrist_3_joint` in rad, the measured T-Mac pose `measurement_x/y/z`
// in mm and `measurement_rx/ry/rz` in degrees (intrinsic XYZ Euler: R = Rx(rx)·Ry(ry)·Rz(rz)),
// `measurement_temperature` in °C, optionally `measurement_std_*`, plus the commanded T-Mac
// pose (`Goal …`) and a `Timestamp` (Excel-mangled in some series), which are not imported.
//
// Where the T-Mac sits on the flange (checked on Series A–C with the nominal UR10):
//   - Trafo_TM_F_init.txt holds X_TcpFlange, the flange in the frame of the TCP the path
//     planner used: Goal = Rz(π)·FK_tool0(q)·X_TcpFlange⁻¹ (Rz(π): ROS base_link vs DH base)
//     to 0.4 mm and 0.04° on all of Series C, while the matrix taken as X_FlangeTcp misses by
//     218 mm and 180°. Its origin is 109 mm out along the flange's z axis.
//   - The tracker reports the T-Mac axes turned by π about z against that TCP frame: with
//     R_FlangeTmac = R_FlangeTcp·Rz(π), R_measured·(R_tool0·R_FlangeTmac)ᵀ is one constant
//     rotation (the tracker's) to 0.1° rms; without the turn it spreads over 90°.
// So tmac = TCP·Rz(π). (The measured point itself lies about 93 mm out, not 109: that offset
// is left to calibration, which fits the tip's initial pose.) tests/test_ipa_import.cpp
// demonstrates both findings.
#include "stepcal/importers/ipa.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <string_view>
#include <vector>

#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "shared.hpp"

namespace stepcal::importers {
namespace {

namespace fs = std::filesystem;

constexpr std::array<const char*, 6> kJointColumns = {"shoulder_pan_joint", "shoulder_lift_joint",
                                                      "elbow_joint",        "wrist_1_joint",
                                                      "wrist_2_joint",      "wrist_3_joint"};
constexpr std::array<const char*, 3> kPositionColumns = {"measurement_x", "measurement_y",
                                                         "measurement_z"};
constexpr std::array<const char*, 3> kAngleColumns = {"measurement_rx", "measurement_ry",
                                                      "measurement_rz"};
constexpr const char* kTemperatureColumn = "measurement_temperature";
constexpr std::array<const char*, 6> kStdColumns = {"measurement_std_x",  "measurement_std_y",
                                                    "measurement_std_z",  "measurement_std_rx",
                                                    "measurement_std_ry", "measurement_std_rz"};
/// Names of the std columns in the campaign (values kept in mm and deg, as in the source).
constexpr std::array<const char*, 6> kStdExtraColumns = {"std_x_mm",   "std_y_mm",   "std_z_mm",
                                                         "std_rx_deg", "std_ry_deg", "std_rz_deg"};
/// Columns that are known but not imported: the commanded pose and the time stamp.
constexpr std::array<const char*, 7> kIgnoredColumns = {
    "Timestamp", "Goal x", "Goal y", "Goal z", "Goal roll", "Goal pitch", "Goal yaw"};

constexpr const char* kTrafoFile = "Trafo_TM_F_init.txt";
/// Standard gravity, m/s².
constexpr double kStandardGravity = 9.80665;
/// Stated 1-σ noise of the Leica laser tracker with T-Mac (manufacturer's specification).
constexpr double kTrackerPositionSigma_m = 0.015e-3;
constexpr double kTrackerOrientationSigma_rad = 0.01 * kRadPerDeg;

template <typename Names>
bool contains(const Names& names, std::string_view name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

/// Refuses a robot description whose chain base_link → tmac is not the UR10's six joints.
void checkChain(const std::string& urdf_xml, const std::string& source) {
  const KinematicChain chain = chainFromUrdf(urdf_xml, "base_link", "tmac", {}, source);
  bool same = chain.dof() == static_cast<int>(kJointColumns.size());
  for (int j = 0; same && j < chain.dof(); ++j) {
    same = chain.joints()[static_cast<size_t>(j)].name == kJointColumns[static_cast<size_t>(j)];
  }
  if (!same) {
    std::string names;
    for (const ChainJoint& joint : chain.joints())
      names += (names.empty() ? "" : ", ") + joint.name;
    throw InputError("chain base_link → tmac has the joints " + names +
                         "; expected the UR10's shoulder_pan_joint … wrist_3_joint in order",
                     source);
  }
}

// ---------------------------------------------------------------------------------------------
// The series CSV

struct SeriesLayout {
  int field_count = 0;
  std::vector<std::string> names;
  std::array<int, 6> joints{};
  std::array<int, 3> position{};
  std::array<int, 3> angles{};
  int temperature = -1;
  std::array<int, 6> stds{-1, -1, -1, -1, -1, -1};
  bool has_std = false;
};

SeriesLayout parseHeader(std::string_view header, const std::string& file) {
  SeriesLayout layout;
  std::map<std::string, int> at;
  for (std::string_view name_view : splitFields(header, ';')) {
    const std::string name(name_view);
    const int i = static_cast<int>(layout.names.size());
    layout.names.push_back(name);
    if (!contains(kJointColumns, name) && !contains(kPositionColumns, name) &&
        !contains(kAngleColumns, name) && !contains(kStdColumns, name) &&
        !contains(kIgnoredColumns, name) && name != kTemperatureColumn) {
      throw InputError("unknown column " + inQuotes(name) +
                           "; expected the IPA data set's columns (Timestamp, Goal …, joints, "
                           "measurement_…), separated by ';'",
                       file, 1, name);
    }
    if (!at.emplace(name, i).second) {
      throw InputError("column " + inQuotes(name) + " appears twice; expected each once", file, 1,
                       name);
    }
  }
  layout.field_count = static_cast<int>(layout.names.size());
  auto require = [&](const char* name) {
    const auto it = at.find(name);
    if (it == at.end()) {
      throw InputError("required column " + inQuotes(name) + " is missing", file, 1, name);
    }
    return it->second;
  };
  for (size_t j = 0; j < 6; ++j) layout.joints[j] = require(kJointColumns[j]);
  for (size_t a = 0; a < 3; ++a) {
    layout.position[a] = require(kPositionColumns[a]);
    layout.angles[a] = require(kAngleColumns[a]);
  }
  layout.temperature = require(kTemperatureColumn);
  layout.has_std = std::any_of(kStdColumns.begin(), kStdColumns.end(),
                               [&](const char* name) { return at.count(name) != 0; });
  if (layout.has_std) {
    for (size_t a = 0; a < 6; ++a) layout.stds[a] = require(kStdColumns[a]);
  }
  return layout;
}

/// A field written with a decimal comma, as text with a decimal point; throws if it is not.
std::string decimalText(std::string_view field, const std::string& unit, const std::string& file,
                        int line, const std::string& column) {
  std::string s(field);
  std::replace(s.begin(), s.end(), ',', '.');
  if (field.find('.') != std::string_view::npos || !parseFinite(s)) {
    const std::string hint = field.find('.') != std::string_view::npos
                                 ? " (this data set writes decimal commas; a '.' is not expected)"
                                 : "";
    throw InputError(
        "expected a number with a decimal comma (" + unit + "), got " + inQuotes(field) + hint,
        file, line, column);
  }
  return s;
}

}  // namespace

Campaign importIpaSeries(const std::string& series_csv, int validation_from_row,
                         const std::string& ur10_urdf_path) {
  if (validation_from_row < -1) {
    throw InputError("validation_from_row is " + std::to_string(validation_from_row) +
                         "; expected -1 (no validation rows) or a row index >= 0",
                     series_csv);
  }
  const fs::path csv_path(series_csv);
  const std::string text = readExistingFile(series_csv, "IPA series file");
  const Pose X_TcpFlange =
      readRigidTransformFile((csv_path.parent_path() / kTrafoFile).string(),
                             "T-Mac transform " + inQuotes(kTrafoFile), kMPerMm);
  Pose Z_pi = Pose::Identity();
  Z_pi.linear() = lie::rotationFromRpy(0.0, 0.0, kPi);
  const Pose X_FlangeTmac = X_TcpFlange.inverse() * Z_pi;

  Campaign c;
  c.urdf_xml = withFixedLink(readExistingFile(ur10_urdf_path, "UR10 robot description"), "tool0",
                             "tmac", X_FlangeTmac,
                             "Added by the IPA importer: the Leica T-Mac frame the tracker "
                             "measures, from " + std::string(kTrafoFile) +
                                 " (inverted, turned by pi about z).",
                             ur10_urdf_path);
  checkChain(c.urdf_xml, ur10_urdf_path);
  c.base_link = "base_link";
  c.tip_link = "tmac";
  c.flange_link = "tool0";  // the UR10's flange (DH frame 6), the frame of its TCP settings
  c.tracker.position_sigma_m = kTrackerPositionSigma_m;
  c.tracker.orientation_sigma_rad = kTrackerOrientationSigma_rad;
  c.tracker.stated = true;
  // The UR10 stood upright: the registered base z axis is vertical in the (levelled) tracker's
  // frame to 0.12° on Series C (tests/test_ipa_import.cpp), so gravity is −z of the base.
  c.gravity_in_base = Vec3(0.0, 0.0, -kStandardGravity);
  c.joint_count = static_cast<int>(kJointColumns.size());

  const std::vector<std::string_view> lines = splitLines(text);
  if (lines.empty()) throw InputError("the file is empty; expected a header line", series_csv, 1);
  const SeriesLayout layout = parseHeader(lines[0], series_csv);
  if (lines.size() == 1) {
    throw InputError("the file has no rows after the header; expected measurements", series_csv, 1);
  }
  const int row_count = static_cast<int>(lines.size()) - 1;
  if (validation_from_row >= row_count) {
    throw InputError("validation_from_row is " + std::to_string(validation_from_row) +
                         " but the series has rows 0 … " + std::to_string(row_count - 1) +
                         "; expected -1 or a row index in that range",
                     series_csv);
  }
  if (layout.has_std) c.extra_columns.assign(kStdExtraColumns.begin(), kStdExtraColumns.end());

  c.rows.reserve(static_cast<size_t>(row_count));
  for (int row = 0; row < row_count; ++row) {
    const int line = row + 2;
    const std::vector<std::string_view> fields = splitFields(lines[static_cast<size_t>(row) + 1], ';');
    if (static_cast<int>(fields.size()) != layout.field_count) {
      throw InputError("row has " + std::to_string(fields.size()) + " fields; expected " +
                           std::to_string(layout.field_count) + " as in the header",
                       series_csv, line);
    }
    auto number = [&](int i, const std::string& unit) {
      return decimalText(fields[static_cast<size_t>(i)], unit, series_csv, line,
                         layout.names[static_cast<size_t>(i)]);
    };
    Measurement m;
    m.seq = row;
    std::array<char, 16> id{};
    std::snprintf(id.data(), id.size(), "r%04d", row);
    m.pose_id = id.data();
    m.set = validation_from_row >= 0 && row >= validation_from_row ? RowSet::kValidation
                                                                   : RowSet::kGeometry;
    m.source_line = line;
    m.q_rad.resize(6);
    for (size_t j = 0; j < 6; ++j) {
      m.q_rad[static_cast<Eigen::Index>(j)] = *parseFinite(number(layout.joints[j], "radians"));
    }
    for (size_t a = 0; a < 3; ++a) {
      const std::optional<double> p_m =
          parseFiniteShifted(number(layout.position[a], "millimetres"), -3);
      if (!p_m) {
        throw InputError("expected a length in metres' range, got " +
                             inQuotes(fields[static_cast<size_t>(layout.position[a])]) + " mm",
                         series_csv, line, layout.names[static_cast<size_t>(layout.position[a])]);
      }
      m.p_TipInTracker_m[static_cast<Eigen::Index>(a)] = *p_m;
    }
    Vec3 angles_rad;  // (deg·π)/180 rather than deg·kRadPerDeg: the imported rows stay bit-exact
    for (size_t a = 0; a < 3; ++a) {
      angles_rad[static_cast<Eigen::Index>(a)] =
          *parseFinite(number(layout.angles[a], "degrees")) * kPi / 180.0;
    }
    const Mat3 R_TrackerTmac = (Eigen::AngleAxisd(angles_rad.x(), Vec3::UnitX()) *
                                Eigen::AngleAxisd(angles_rad.y(), Vec3::UnitY()) *
                                Eigen::AngleAxisd(angles_rad.z(), Vec3::UnitZ()))
                                   .toRotationMatrix();
    m.q_TrackerTip = Eigen::Quaterniond(R_TrackerTmac).normalized();
    m.has_orientation = true;
    m.temp_c = *parseFinite(number(layout.temperature, "degrees Celsius"));
    if (layout.has_std) {
      for (size_t a = 0; a < 6; ++a)
        m.extra.push_back(number(layout.stds[a], a < 3 ? "mm" : "deg"));
    }
    c.rows.push_back(std::move(m));
  }
  return c;
}

}  // namespace stepcal::importers
