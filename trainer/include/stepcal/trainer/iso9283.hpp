// The pose characteristics of ISO 9283 from a campaign and a model file (`stepcal certify`):
// as commanded (the nominal robot the controller knows, uncorrected) and as corrected (the
// model's last layer: where the robot goes when its joints are corrected, attained − predicted).
//
// A pose is the rows of one load whose commanded poses (the nominal tip at their joints) agree
// to 0.2 mm and 0.5° and whose joints agree to 0.01 rad: its cycles (one pose reached in another
// joint configuration, as Series B of the real UR10 does, is another pose). Each row's deviation
// is the attained pose against the commanded (or predicted) one, in base_link's axes: e = p_attained − p_commanded, (a, b, c) the rotation
// vector of R_attained·R_commandedᵀ (small angles about x, y, z). Per pose, with x̄ the
// barycentre of the n cycles' deviations:
//   AP_P = ‖ē‖, AP_a/b/c = ā, b̄, c̄                       (pose accuracy)
//   RP_l = l̄ + 3 S_l, l_j = ‖x_j − x̄‖ of the attained positions x_j themselves,
//   S_l = √(Σ(l_j − l̄)²/(n−1)); RP_a/b/c = 3 S_a/b/c of the attained orientations
//                                                          (pose repeatability, n ≥ 2; with
//                                                          n = 2, l₁ = l₂ and RP_l = l̄; the
//                                                          same for every method)
//   vAP_P = max over approach directions h, k of ‖ē_h − ē_k‖; vAP_a/b/c likewise
//                                                          (multi-directional, ≥ 2 directions)
//   AD_P = D̄ − D_c, RD_P = 3 S_D with D_j = ‖p_P2,j − p_P4,j‖ attained in cycle j and D_c
//   commanded                                              (distance, cycles of P2 and P4)
// The multi-directional and distance characteristics need the pose_ids of `stepcal plan
// --iso9283` (iso9283_plan.hpp): the approach direction and the cycle are named there only.
// A characteristic the rows cannot give is reported with the reason, never a number.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"

namespace stepcal::trainer {

/// A value, or why the rows cannot give it.
struct IsoFigure {
  std::optional<double> value;  ///< SI: m or rad
  std::string not_measurable;   ///< the reason when value is empty
};

/// One pose's characteristics for one method.
struct IsoPoseFigures {
  std::string label;        ///< "P1" … "P5", or "pose k" (its first row's pose_id beside)
  std::string first_pose_id;
  Vec3 p_CommandedInBase_m = Vec3::Zero();
  int cycles = 0;           ///< rows of the pose (every approach direction)
  Vec3 mean_deviation_Base_m = Vec3::Zero();  ///< ē, base axes, m
  IsoFigure ap_position;                     ///< AP_P, m
  std::optional<Vec3> ap_orientation_rad;    ///< (AP_a, AP_b, AP_c), rad; absent without orientation
  IsoFigure rp_position;                     ///< RP_l, m
  std::optional<Vec3> rp_orientation_rad;    ///< 3 S_a/b/c, rad
  IsoFigure vap_position;                    ///< vAP_P, m
  std::optional<Vec3> vap_orientation_rad;   ///< vAP_a/b/c, rad
  std::vector<Vec3> deviations_Base_m;       ///< every cycle's e, for the charts
  std::vector<double> repeat_distances_m;    ///< l_j of the pose-test cycles (n ≥ 2), m
};

/// Every characteristic of one method at one load.
struct IsoMethodFigures {
  std::string method;  ///< "commanded" or the model layer's name
  std::vector<IsoPoseFigures> poses;
  IsoFigure ap_position_max;  ///< largest AP_P over the poses, m
  IsoFigure ap_position_median;  ///< median of the poses' AP_P, m
  IsoFigure rp_position_max;  ///< largest RP_l over the poses with cycles, m
  /// l̄ + 3 S_l of every pose's cycles about their own barycentre, pooled over the poses with
  /// cycles (ANSI/RIA R15.05-1 pools; ISO 9283 states RP per pose), m.
  IsoFigure rp_position_pooled;
  IsoFigure rp_position_median;  ///< median of the poses' RP_l, m
  IsoFigure vap_position_max;
  IsoFigure ad_position;      ///< AD_P, m
  IsoFigure rd_position;      ///< RD_P, m
  int distance_cycles = 0;    ///< cycles with both P2 and P4
};

struct IsoLoadFigures {
  double load_kg = 0.0;
  int rows = 0;
  int poses_with_cycles = 0;  ///< poses measured at least twice
  std::vector<IsoMethodFigures> methods;  ///< commanded, then corrected
};

struct IsoCertificate {
  std::string campaign_directory;
  std::string robot_name;      ///< the URDF's <robot name>
  std::string model_path;
  /// The model file's own CRC-32 (of all but its last 4 bytes), hex; set by the caller.
  std::string model_crc32;
  std::string campaign_hash;   ///< campaignHash
  std::string corrected_method;
  bool iso_plan_rows = false;  ///< the rows are a `stepcal plan --iso9283` campaign's
  int rows_used = 0, rows_left_out = 0;
  bool frames_refit = false;
  std::optional<double> temperature_min_c, temperature_max_c;
  double tracker_position_sigma_m = 0.0;
  std::vector<IsoLoadFigures> loads;
};

struct IsoCertifyOptions {
  /// Fit the tracker (and, for the corrected model, the tool) frame again on the campaign's rows
  /// (validate --refit-frames): a campaign measured with the tracker moved. The fit takes up part
  /// of the pose accuracy it is then judged on.
  bool refit_frames = false;
  std::optional<RowSet> set;  ///< only the rows of this set; none: every row
  double same_pose_position_m = 0.2e-3;  ///< commanded poses this close are one pose's cycles
  double same_pose_orientation_rad = 0.5 * 3.14159265358979323846 / 180.0;
  double same_pose_joints_rad = 0.01;  ///< and joints this close (one joint configuration)
};

/// The characteristics of the campaign's rows (those of an ISO plan where it has any, else all
/// of options.set) for the nominal robot and the model's last layer. Throws InputError when the
/// campaign is not of the model's robot or has no row to certify.
IsoCertificate certifyIso9283(const CalibratedModel& model, const Campaign& campaign,
                              const IsoCertifyOptions& options = {});

}  // namespace stepcal::trainer
