// A measurement campaign (docs/campaign-format.md, format stepcal-campaign/1).
//
// In memory everything is SI: metres, radians, newtons, N·m. Millimetres and degrees exist
// only in the files. Reading is strict: any bad file, line, column or value throws InputError
// naming where and what was expected, and nothing partial is returned.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/types.hpp"

namespace stepcal {

/// Which calibration step may fit on a row; validation rows are never fitted.
enum class RowSet { kGeometry, kStiffness, kResidual, kValidation };

/// "geometry", "stiffness", "residual" or "validation".
const char* toString(RowSet set) noexcept;

/// One measured robot pose (one line of measurements.csv).
struct Measurement {
  int64_t seq = 0;                  ///< time order
  std::string pose_id;              ///< rows sharing it were commanded to the same joints
  RowSet set = RowSet::kGeometry;
  double load_kg = 0.0;             ///< nominal payload, informational
  JointVector q_rad;                ///< controller joint angles, URDF convention, rad
  bool has_wrench = false;          ///< false: no sensor reading (only allowed unloaded)
  Vec6 wrench_Sensor = Vec6::Zero();  ///< (f [N], m [N·m]) the payload exerts, sensor_link axes
  Vec3 p_TipInTracker_m = Vec3::Zero();  ///< measured tip_link origin in the tracker frame, m
  bool has_orientation = false;     ///< false: position-only (3D reflector) row
  Eigen::Quaterniond q_TrackerTip = Eigen::Quaterniond::Identity();  ///< unit, tip axes
  std::optional<double> temp_c;     ///< temperature, °C
  std::vector<std::string> extra;   ///< values of unknown columns, kept verbatim
  int source_line = 0;              ///< line in measurements.csv (1 = header), for messages
  int session = 0;                  ///< index in Campaign::sessions of the campaign it came from

  /// Measured pose X_TrackerTip (identity rotation when has_orientation is false).
  Pose X_TrackerTip() const;
  /// Wrench on the sensor; zero when has_wrench is false.
  Vec6 wrenchOrZero() const { return has_wrench ? wrench_Sensor : Vec6::Zero(); }
};

/// The instrument's stated 1-σ noise per axis, used to weight rows.
struct TrackerNoise {
  double position_sigma_m = 15e-6;      ///< per axis, m
  double orientation_sigma_rad = 1.7453292519943295e-4;  ///< per axis, rad (0.01°)
  bool stated = false;                  ///< false: the campaign gave no tracker block
};

/// One of several campaigns of one robot merged into one (mergeCampaigns): a session measured
/// from its own tracker station, perhaps with the target remounted.
struct CampaignSession {
  std::string directory;  ///< folder it was read from
  TrackerNoise tracker;   ///< its tracker's stated noise
  size_t first_row = 0, row_count = 0;  ///< its rows in Campaign::rows
};

/// A whole campaign: description, robot and rows.
struct Campaign {
  std::string directory;                ///< folder it was read from (empty if built in memory)
  std::string robot_file = "robot.urdf";   ///< as written in campaign.yaml
  std::string urdf_xml;                 ///< the robot description's text
  std::string base_link;
  std::string tip_link;
  std::string sensor_link;              ///< empty: no F/T sensor
  /// The robot's mounting flange, the frame of the controller's tool data (ROS-Industrial
  /// tool0); empty: not named. The model keeps it (runtime: tools given from the flange).
  std::string flange_link;
  std::string measurements_file = "measurements.csv";
  TrackerNoise tracker;
  std::optional<Vec3> gravity_in_base;  ///< m/s², base_link axes
  int joint_count = 0;                  ///< N of the q1_deg … qN_deg columns
  std::vector<std::string> extra_columns;  ///< unknown column names, in file order
  std::vector<Measurement> rows;        ///< in file order
  /// The campaigns merged into this one, in order; empty: one campaign, every row session 0.
  std::vector<CampaignSession> sessions;

  /// Number of sessions: 1 for a campaign read from one folder.
  int sessionCount() const { return sessions.empty() ? 1 : static_cast<int>(sessions.size()); }
  /// The tracker noise of a session's rows.
  const TrackerNoise& trackerOf(int session) const {
    return sessions.empty() ? tracker : sessions[static_cast<size_t>(session)].tracker;
  }
  /// The folder of a session's campaign.
  const std::string& directoryOf(int session) const {
    return sessions.empty() ? directory : sessions[static_cast<size_t>(session)].directory;
  }

  /// Rows of one set, in file order.
  std::vector<const Measurement*> rowsIn(RowSet set) const;
};

/// One row of a pose list (poses.csv, the plan of a campaign): a commanded pose to measure at
/// one payload. Joint angles rad, load kg.
struct PlannedMeasurement {
  std::string pose_id;  ///< rows sharing it are one pose measured at several loads
  double load_kg = 0.0;  ///< nominal payload; 0 = unloaded
  JointVector q_rad;     ///< commanded joint angles, URDF convention, rad
  int source_line = 0;   ///< line in the file (1 = header), 0 when planned in memory
};

/// Reads a pose list: header `pose_id,load_kg,q1_deg,…,qN_deg` (any order, nothing else), one
/// row per measurement, degrees in the file. Every pose_id has exactly one unloaded row (step 1
/// fits it, step 2 pairs the loaded rows with it) and its loaded rows repeat its angles.
/// joint_count is N. Throws InputError naming file, line, column, value and expectation.
std::vector<PlannedMeasurement> readPoseList(const std::string& path, int joint_count);

/// Writes a pose list that readPoseList reads back exactly. Throws InputError on I/O errors.
void writePoseList(const std::vector<PlannedMeasurement>& rows, const std::string& path);

/// Reads a campaign folder (or the path of its campaign.yaml). Throws InputError.
Campaign readCampaign(const std::string& path);

/// Several campaigns of one robot as one: rows in order, each with its session; the first
/// campaign's folder, robot and links; its tracker block the largest stated noise of them (the
/// rows keep their own, trackerOf). Unknown columns are kept only when every campaign has the same.
/// One campaign is returned as it is. Throws InputError naming the campaign and the field that
/// differs (robot description, base/tip/sensor/flange link, joint count, gravity).
Campaign mergeCampaigns(std::vector<Campaign> campaigns);

/// Writes campaign.yaml, the robot description and measurements.csv into a folder (created
/// if needed). Values round-trip exactly through readCampaign. Throws InputError on I/O errors.
void writeCampaign(const Campaign& campaign, const std::string& directory);

}  // namespace stepcal
