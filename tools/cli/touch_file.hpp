// The touch file of `stepcal tool` and `stepcal frame` (docs/cell.md, "The touch file"): one
// touch or measured point per line, strict, every error naming the file, line and column.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/model_file.hpp"
#include "stepcal/common/types.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::cli {

/// One line of a touch file, in SI.
struct Touch {
  int line = 0;
  std::string id;
  std::optional<JointVector> q_rad;           ///< the controller's joint reading
  std::optional<Vec3> p_InTracker_m;          ///< the tracker's measurement (x_mm … z_mm)
  std::optional<Mat3> R_TrackerTcp;           ///< its orientation, from a campaign's qw … qz
  std::optional<Vec6> wrench_Sensor;          ///< fx_n … mz_nm when given
  std::string point;                          ///< three-point role: origin, x or xy
  std::optional<Vec3> p_NominalInFrame_m;     ///< a fiducial's nominal coordinates (nx_mm …)
};

/// Reads a touch file for a model of `joints` joints. Columns (a header of names, any order):
/// id; q1_deg … qN_deg; x_mm, y_mm, z_mm; fx_n … mz_nm; point; nx_mm, ny_mm, nz_mm. A group
/// present is filled on every line, except that a line may hold joints or a measured point or
/// both. Throws InputError naming the file, line and column.
std::vector<Touch> readTouchFile(const std::string& path, int joints);

/// Tracker shots at the TCP as a campaign (docs/campaign-format.md): every row's joints, wrench,
/// measured point and, where the row has one, measured orientation (its tip_link is then the
/// reflector or 6-D target at the TCP). Throws InputError when the
/// campaign is of another robot than the model's.
std::vector<Touch> readCampaignShots(const std::string& path, const CalibratedModel& model,
                                     const std::string& model_path);

/// The mean norm of a 3-D normal error of per-axis σ is 2 √(2/π) σ ≈ 1.596 σ.
inline constexpr double kMeanNormPerAxisSigma = 1.5957691216057308;

/// One point's per-axis σ from the model's own accuracy: its full layer's largest mean position
/// error on the validation rows at training (any load) over kMeanNormPerAxisSigma; 0 when the
/// model holds no validation figures.
double modelPointSigma(const CalibratedModel& model);

/// One orientation's per-axis σ from the model's own accuracy, as modelPointSigma (its full
/// layer's largest mean orientation error over kMeanNormPerAxisSigma), rad.
double modelOrientationSigma(const CalibratedModel& model);

/// The calibrated target's pose at each touch (the runtime's forward, the GPR and compliance
/// included): under the touch's wrench (fx_n …), else the payload's weight when given, else
/// the model's unloaded wrench. Throws InputError naming a line without joints.
std::vector<Pose> touchPoses(const runtime::RuntimeModel& model, const std::vector<Touch>& touches,
                             const std::optional<runtime::Payload>& payload,
                             const std::string& path);

}  // namespace stepcal::cli
