// The mapping file of the general importer (mapped.hpp): what it says, read strictly.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal::importers {

/// How a table file is written.
struct TableFormat {
  std::string path;  ///< resolved against the mapping file's folder
  char separator = ',';
  bool decimal_comma = false;  ///< ',' is the decimal mark; a '.' in a number is refused
  int skip_lines = 0;          ///< lines before the header line
};

/// A time column: seconds (or milliseconds) as a number, or a clock time
/// [YYYY-MM-DD[ T]]hh:mm:ss[.fff].
struct TimeColumn {
  std::string column;
  double seconds_per_unit = 1.0;  ///< for numeric stamps
};

enum class OrientationKind { kNone, kQuaternion, kEuler };

/// The measured orientation's columns and convention.
struct OrientationMapping {
  OrientationKind kind = OrientationKind::kNone;
  std::vector<std::string> columns;  ///< 4 (quaternion) or 3 (Euler angles), in `order`'s order
  bool scalar_first = true;          ///< quaternion: w x y z (true) or x y z w
  /// Euler: the axes, upper case = intrinsic (R = R_a1(θ1)·R_a2(θ2)·R_a3(θ3), e.g. KUKA's ZYX
  /// for A, B, C), lower case = extrinsic (fixed axes: R = R_a3(θ3)·R_a2(θ2)·R_a1(θ1)).
  std::string euler_axes;
  bool degrees = true;
};

/// Where the F/T sensor's six columns are and in which units.
struct WrenchMapping {
  enum class Table { kNone, kTracker, kJoints } table = Table::kNone;
  std::vector<std::string> columns;                  ///< fx, fy, fz, mx, my, mz in sensor_link axes
  std::string force_unit = "N", moment_unit = "Nm";  ///< as the mapping names them
  int force_shift_to_newtons = 0;         ///< decimal shift from the file's unit: N 0, kN +3
  int moment_shift_to_newton_metres = 0;  ///< Nm 0, Nmm -3, kNm +3
};

/// The whole mapping file.
struct ImportMapping {
  std::string file;  ///< the mapping file, for messages
  // Robot
  std::string urdf_path;
  std::string base_link, tip_link, flange_link;
  std::string sensor_link;  ///< the F/T sensor's frame; required with a wrench
  std::optional<Vec3> gravity_in_base;
  struct AddedLink {
    std::string parent;
    std::string transform_path;  ///< 4×4 matrix file, resolved
    double metres_per_unit = 1.0;
    bool invert = false;               ///< the file holds X_ChildParent
    Vec3 then_rpy_rad = Vec3::Zero();  ///< turned by this afterwards (URDF rpy)
  };
  std::optional<AddedLink> added_tip;
  // Tracker export
  TableFormat tracker;
  std::vector<std::string> position_columns;
  int length_shift_to_metres = -3;  ///< decimal shift from the file's unit: mm -3, m 0
  OrientationMapping orientation;
  std::string temperature_column;                         ///< empty: none
  std::vector<std::pair<std::string, std::string>> kept;  ///< campaign column ← tracker column
  TrackerNoise noise;
  std::optional<TimeColumn> tracker_time;
  std::string tracker_point;  ///< point name column; empty: none
  // Joint log
  TableFormat joints;
  std::vector<std::string> joint_columns;
  bool joints_in_degrees = false;
  /// q_urdf = sign·q_log + offset per joint, in chain order; empty: sign +1 and offset 0.
  std::vector<int> joint_sign;
  std::vector<double> joint_offset_rad;
  std::optional<TimeColumn> joints_time;
  std::string joints_point;
  std::string load_column;  ///< load_kg column of the joint log; empty: every row unloaded
  WrenchMapping wrench;     ///< from the tracker export or the joint log
  // Join
  enum class Join { kRow, kTimestamp, kPointName } join = Join::kRow;
  double tolerance_s = 0.0;
  int validation_from_row = -1;
};

/// Reads a mapping file; throws InputError with the file, line and key.
ImportMapping readImportMapping(const std::string& path);

}  // namespace stepcal::importers
