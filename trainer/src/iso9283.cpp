#include "stepcal/trainer/iso9283.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "diagnose/fit_rows.hpp"
#include "diagnose/session_frames.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/trainer/accuracy.hpp"
#include "stepcal/trainer/iso9283_plan.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/trainer/registration.hpp"

namespace stepcal::trainer {
namespace {

constexpr const char* kCommanded = "commanded";

/// One row's deviation from where a method puts it, base_link axes.
struct Deviation {
  Vec3 position_m = Vec3::Zero();
  std::optional<Vec3> orientation_rad;  ///< (a, b, c); absent for a position-only row
  Vec3 p_Attained_m = Vec3::Zero();     ///< the attained position itself, base axes
  Mat3 R_Attained = Mat3::Identity();   ///< the attained orientation, base axes
};

/// The rows of one pose: the cycles of one commanded pose at one load.
struct PoseRows {
  std::vector<const Measurement*> rows;
  Pose X_BaseTip_commanded = Pose::Identity();
};

/// The nominal robot's tip at the row's joints, base_link, m: what the controller commands.
Pose commandedPose(const CalibratedModel& model, const Measurement& row, ChainWorkspace& ws) {
  forwardKinematics(model.nominal_Base, row.q_rad, ws);
  return tipPose(ws);
}

/// The rows certified: those of an ISO plan where there are any, else all; of options.set.
std::vector<const Measurement*> certifiedRows(const Campaign& campaign,
                                              const IsoCertifyOptions& options, bool& iso_plan) {
  iso_plan = std::any_of(campaign.rows.begin(), campaign.rows.end(), [](const Measurement& row) {
    return parseIsoPoseId(row.pose_id).has_value();
  });
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) {
    if (options.set && row.set != *options.set) continue;
    if (iso_plan && !parseIsoPoseId(row.pose_id)) continue;
    rows.push_back(&row);
  }
  return rows;
}

/// Rows grouped by load, then by commanded pose (within the options' tolerances), in row order.
std::map<double, std::vector<PoseRows>> posesByLoad(const CalibratedModel& model,
                                                    const std::vector<const Measurement*>& rows,
                                                    const IsoCertifyOptions& options) {
  std::map<double, std::vector<PoseRows>> by_load;
  ChainWorkspace ws;
  for (const Measurement* row : rows) {
    const Pose X = commandedPose(model, *row, ws);
    std::vector<PoseRows>& poses = by_load[row->load_kg];
    auto same = std::find_if(poses.begin(), poses.end(), [&](const PoseRows& pose) {
      return (pose.rows.front()->q_rad - row->q_rad).cwiseAbs().maxCoeff() <=
                 options.same_pose_joints_rad &&
             (pose.X_BaseTip_commanded.translation() - X.translation()).norm() <=
                 options.same_pose_position_m &&
             lie::angleBetween(pose.X_BaseTip_commanded.linear(), X.linear()) <=
                 options.same_pose_orientation_rad;
    });
    if (same == poses.end()) {
      poses.push_back({{}, X});
      same = poses.end() - 1;
    }
    same->rows.push_back(row);
  }
  return by_load;
}

Deviation deviationOf(const Pose& X_TrackerTip_predicted, const Measurement& row,
                      const Mat3& R_TrackerBase) {
  Deviation d;
  d.position_m =
      R_TrackerBase.transpose() * (row.p_TipInTracker_m - X_TrackerTip_predicted.translation());
  d.p_Attained_m = R_TrackerBase.transpose() * row.p_TipInTracker_m;
  d.R_Attained = R_TrackerBase.transpose() * row.X_TrackerTip().linear();
  if (row.has_orientation) {
    d.orientation_rad = R_TrackerBase.transpose() *
                        lie::logSO3(row.X_TrackerTip().linear() *
                                    X_TrackerTip_predicted.linear().transpose());
  }
  return d;
}

/// Mean and sample standard deviation (n − 1) of values; sd 0 for one value.
std::pair<double, double> meanAndSd(const std::vector<double>& values) {
  double mean = 0.0;
  for (const double v : values) mean += v;
  mean /= static_cast<double>(values.size());
  double squares = 0.0;
  for (const double v : values) squares += (v - mean) * (v - mean);
  const double sd =
      values.size() > 1 ? std::sqrt(squares / static_cast<double>(values.size() - 1)) : 0.0;
  return {mean, sd};
}

IsoFigure notMeasurable(const std::string& reason) { return {std::nullopt, reason}; }

/// AP and RP of one pose from the deviations of its pose-test cycles.
void poseAccuracyAndRepeatability(const std::vector<Deviation>& cycles, IsoPoseFigures& out) {
  Vec3 mean = Vec3::Zero();
  for (const Deviation& d : cycles) mean += d.position_m;
  mean /= static_cast<double>(cycles.size());
  out.mean_deviation_Base_m = mean;
  out.ap_position = {mean.norm(), ""};
  const bool oriented = std::all_of(cycles.begin(), cycles.end(),
                                    [](const Deviation& d) { return d.orientation_rad.has_value(); });
  if (oriented) {
    Vec3 angles = Vec3::Zero();
    for (const Deviation& d : cycles) angles += *d.orientation_rad;
    out.ap_orientation_rad = angles / static_cast<double>(cycles.size());
  }
  if (cycles.size() < 2) {
    out.rp_position = notMeasurable("measured once at this load: repeatability needs repeated "
                                    "cycles of one commanded pose (ISO 9283: 30)");
    return;
  }
  // Repeatability is the attained poses' own spread: the rows' joints as recorded may differ
  // between cycles of one command by more than the tip does (read back, as the UR10's are).
  Vec3 attained_mean = Vec3::Zero();
  for (const Deviation& d : cycles) attained_mean += d.p_Attained_m;
  attained_mean /= static_cast<double>(cycles.size());
  std::vector<double> distances;
  for (const Deviation& d : cycles) distances.push_back((d.p_Attained_m - attained_mean).norm());
  const auto [l_mean, l_sd] = meanAndSd(distances);
  out.rp_position = {l_mean + 3.0 * l_sd, ""};
  out.repeat_distances_m = distances;
  if (oriented) {
    Vec3 rp;
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<double> angle;  // about the first cycle's orientation (S does not see it)
      for (const Deviation& d : cycles) {
        angle.push_back(lie::logSO3(d.R_Attained * cycles.front().R_Attained.transpose())(axis));
      }
      rp(axis) = 3.0 * meanAndSd(angle).second;
    }
    out.rp_orientation_rad = rp;
  }
}

/// vAP of one pose from its cycles per approach direction.
void multiDirectional(const std::map<char, std::vector<Deviation>>& by_direction,
                      bool iso_plan, IsoPoseFigures& out) {
  std::vector<std::pair<Vec3, std::optional<Vec3>>> barycentres;
  for (const auto& [direction, cycles] : by_direction) {
    if (direction == 0) continue;
    Vec3 p = Vec3::Zero(), a = Vec3::Zero();
    bool oriented = true;
    for (const Deviation& d : cycles) {
      p += d.position_m;
      if (d.orientation_rad) a += *d.orientation_rad; else oriented = false;
    }
    const double n = static_cast<double>(cycles.size());
    barycentres.push_back({p / n, oriented ? std::optional<Vec3>(a / n) : std::nullopt});
  }
  if (barycentres.size() < 2) {
    out.vap_position = notMeasurable(
        iso_plan ? "this pose was not approached from two or more directions (the plan "
                   "approaches P1, P2 and P4 along +x, +y and +z)"
                 : "the rows name no approach direction (the pose_ids of stepcal plan --iso9283 "
                   "do)");
    return;
  }
  double largest = 0.0;
  Vec3 largest_angles = Vec3::Zero();
  bool oriented = true;
  for (size_t h = 0; h < barycentres.size(); ++h) {
    for (size_t k = h + 1; k < barycentres.size(); ++k) {
      largest = std::max(largest, (barycentres[h].first - barycentres[k].first).norm());
      if (barycentres[h].second && barycentres[k].second) {
        largest_angles =
            largest_angles.cwiseMax((*barycentres[h].second - *barycentres[k].second).cwiseAbs());
      } else {
        oriented = false;
      }
    }
  }
  out.vap_position = {largest, ""};
  if (oriented) out.vap_orientation_rad = largest_angles;
}

IsoPoseFigures poseFigures(const PoseRows& pose, const std::vector<Deviation>& deviations,
                           size_t pose_index, bool iso_plan) {
  IsoPoseFigures out;
  out.first_pose_id = pose.rows.front()->pose_id;
  const std::optional<IsoPoseId> id = parseIsoPoseId(out.first_pose_id);
  out.label = id ? "P" + std::to_string(id->pose) : "pose " + std::to_string(pose_index + 1);
  out.p_CommandedInBase_m = pose.X_BaseTip_commanded.translation();
  out.cycles = static_cast<int>(pose.rows.size());
  std::vector<Deviation> pose_test;
  std::map<char, std::vector<Deviation>> by_direction;
  for (size_t r = 0; r < pose.rows.size(); ++r) {
    const std::optional<IsoPoseId> row_id = parseIsoPoseId(pose.rows[r]->pose_id);
    const char direction = row_id ? row_id->approach : 0;
    by_direction[direction].push_back(deviations[r]);
    if (direction == 0) pose_test.push_back(deviations[r]);
    out.deviations_Base_m.push_back(deviations[r].position_m);
  }
  // A pose measured only in the multi-directional test: its accuracy from all of its rows.
  poseAccuracyAndRepeatability(pose_test.empty() ? by_direction.begin()->second : pose_test, out);
  multiDirectional(by_direction, iso_plan, out);
  return out;
}

/// AD and RD between P2 and P4 of the same cycles (pose-test rows of an ISO plan).
void distanceFigures(const std::vector<PoseRows>& poses,
                     const std::vector<std::vector<Deviation>>& deviations, bool iso_plan,
                     IsoMethodFigures& out) {
  if (!iso_plan) {
    out.ad_position = out.rd_position = notMeasurable(
        "the rows do not say which measurements of two poses belong to one cycle (the pose_ids "
        "of stepcal plan --iso9283 do: P2 and P4 of each cycle)");
    return;
  }
  std::map<int, Vec3> p2, p4;  // cycle → attained position (commanded + deviation), base axes
  Vec3 c2 = Vec3::Zero(), c4 = Vec3::Zero();
  for (size_t g = 0; g < poses.size(); ++g) {
    for (size_t r = 0; r < poses[g].rows.size(); ++r) {
      const IsoPoseId id = *parseIsoPoseId(poses[g].rows[r]->pose_id);
      if (id.approach != 0 || (id.pose != 2 && id.pose != 4)) continue;
      const Vec3& commanded = poses[g].X_BaseTip_commanded.translation();
      (id.pose == 2 ? c2 : c4) = commanded;
      (id.pose == 2 ? p2 : p4)[id.cycle] = commanded + deviations[g][r].position_m;
    }
  }
  std::vector<double> distances;
  for (const auto& [cycle, p] : p2) {
    if (p4.count(cycle)) distances.push_back((p - p4.at(cycle)).norm());
  }
  out.distance_cycles = static_cast<int>(distances.size());
  if (distances.empty()) {
    out.ad_position = out.rd_position =
        notMeasurable("no cycle holds both P2 and P4 at this load");
    return;
  }
  const auto [d_mean, d_sd] = meanAndSd(distances);
  out.ad_position = {d_mean - (c2 - c4).norm(), ""};
  out.rd_position = distances.size() < 2
                        ? notMeasurable("one cycle of P2 and P4: repeatability needs two or more")
                        : IsoFigure{3.0 * d_sd, ""};
}

/// The largest of the poses' figures, or why none is.
IsoFigure largest(const std::vector<IsoPoseFigures>& poses, IsoFigure IsoPoseFigures::*figure) {
  IsoFigure out;
  for (const IsoPoseFigures& pose : poses) {
    const IsoFigure& f = pose.*figure;
    if (f.value) out.value = std::max(out.value.value_or(0.0), *f.value);
  }
  if (!out.value) {
    out.not_measurable = poses.empty() ? "no pose" : (poses.front().*figure).not_measurable;
  }
  return out;
}

/// The median of values (not empty).
double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const size_t middle = values.size() / 2;
  return values.size() % 2 == 1 ? values[middle] : 0.5 * (values[middle - 1] + values[middle]);
}

/// The median of the poses' AP; RP pooled over the poses' cycles and the median of the poses'
/// RP (when any has cycles).
void pooledAndMedianFigures(IsoMethodFigures& out) {
  std::vector<double> ap, pooled, per_pose;
  for (const IsoPoseFigures& pose : out.poses) {
    ap.push_back(*pose.ap_position.value);
    pooled.insert(pooled.end(), pose.repeat_distances_m.begin(), pose.repeat_distances_m.end());
    if (pose.rp_position.value) per_pose.push_back(*pose.rp_position.value);
  }
  out.ap_position_median = {median(ap), ""};
  if (per_pose.empty()) {
    out.rp_position_pooled = out.rp_position_median = out.rp_position_max;
    return;
  }
  const auto [l_mean, l_sd] = meanAndSd(pooled);
  out.rp_position_pooled = {l_mean + 3.0 * l_sd, ""};
  out.rp_position_median = {median(per_pose), ""};
}

IsoMethodFigures methodFigures(const std::string& method, const PoseModel& predictor,
                               const Mat3& R_TrackerBase, const std::vector<PoseRows>& poses,
                               bool iso_plan) {
  IsoMethodFigures out;
  out.method = method;
  std::vector<std::vector<Deviation>> deviations(poses.size());
  for (size_t g = 0; g < poses.size(); ++g) {
    for (const Measurement* row : poses[g].rows) {
      deviations[g].push_back(deviationOf(predictor(*row), *row, R_TrackerBase));
    }
    out.poses.push_back(poseFigures(poses[g], deviations[g], g, iso_plan));
  }
  out.ap_position_max = largest(out.poses, &IsoPoseFigures::ap_position);
  out.rp_position_max = largest(out.poses, &IsoPoseFigures::rp_position);
  if (!out.rp_position_max.value) {
    out.rp_position_max.not_measurable =
        "no commanded pose was measured more than once at this load: repeatability needs "
        "repeated cycles of one pose (ISO 9283: 30)";
  }
  pooledAndMedianFigures(out);
  out.vap_position_max = largest(out.poses, &IsoPoseFigures::vap_position);
  distanceFigures(poses, deviations, iso_plan, out);
  return out;
}

/// The model's last layer, its frames fitted again on the rows when asked.
std::pair<std::string, PoseModel> correctedLayer(const CalibratedModel& model,
                                                 const std::vector<const Measurement*>& rows,
                                                 const Campaign& campaign, bool refit_frames) {
  const auto layers = modelLayers(model);
  if (!refit_frames) return layers.back();
  const diagnosis::FitRows fit = diagnosis::makeFitRows(rows, campaign.tracker, 1);
  PoseModel physical = physicalPoseModel(diagnosis::refitFrames(physicalModelOf(model), fit));
  if (!model.gpr) return {layers.back().first + " (frames refit)", physical};
  auto gpr = std::make_shared<const GprPredictor>(GprPredictor::fromParameters(*model.gpr));
  PoseModel with_gpr = [physical, gpr](const Measurement& row) {
    GprPredictor::Workspace workspace = gpr->makeWorkspace();
    Vec6 residual;
    gpr->predictInto(gprInput(row).data(), residual.data(), nullptr, workspace);
    return Pose(physical(row) * lie::expSE3(residual));
  };
  return {layers.back().first + " (frames refit)", with_gpr};
}

std::string robotName(const std::string& urdf_xml) {
  const size_t robot = urdf_xml.find("<robot");
  const size_t name = robot == std::string::npos ? robot : urdf_xml.find("name=\"", robot);
  if (name == std::string::npos) return "";
  const size_t end = urdf_xml.find('"', name + 6);
  return end == std::string::npos ? "" : urdf_xml.substr(name + 6, end - name - 6);
}

}  // namespace

IsoCertificate certifyIso9283(const CalibratedModel& model, const Campaign& campaign,
                              const IsoCertifyOptions& options) {
  requireCampaignOfModelRobot(model, campaign, "");
  diagnosis::requireJointCount(campaign, model.chain_Tracker.dof());
  IsoCertificate out;
  out.campaign_directory = campaign.directory;
  out.robot_name = robotName(campaign.urdf_xml);
  out.campaign_hash = campaignHash(campaign);
  out.frames_refit = options.refit_frames;
  out.tracker_position_sigma_m = campaign.tracker.position_sigma_m;
  const std::vector<const Measurement*> rows = certifiedRows(campaign, options, out.iso_plan_rows);
  if (rows.empty()) {
    throw InputError(std::string("no row to certify") +
                         (options.set ? std::string(" in set ") + toString(*options.set) : "") +
                         "; expected measured rows of the robot at commanded poses",
                     campaign.directory);
  }
  out.rows_used = static_cast<int>(rows.size());
  out.rows_left_out = static_cast<int>(campaign.rows.size() - rows.size());
  for (const Measurement* row : rows) {
    if (!row->temp_c) continue;
    out.temperature_min_c = std::min(out.temperature_min_c.value_or(*row->temp_c), *row->temp_c);
    out.temperature_max_c = std::max(out.temperature_max_c.value_or(*row->temp_c), *row->temp_c);
  }
  const Pose X_TrackerBase =
      options.refit_frames ? registerTracker(model.nominal_Base, rows) : model.X_TrackerBase;
  auto commanded = [&model, X_TrackerBase](const Measurement& row) {
    ChainWorkspace ws;
    return Pose(X_TrackerBase * commandedPose(model, row, ws));
  };
  const auto [corrected_name, corrected] =
      correctedLayer(model, rows, campaign, options.refit_frames);
  out.corrected_method = corrected_name;
  for (const auto& [load_kg, poses] : posesByLoad(model, rows, options)) {
    IsoLoadFigures load;
    load.load_kg = load_kg;
    for (const PoseRows& pose : poses) {
      load.rows += static_cast<int>(pose.rows.size());
      if (pose.rows.size() > 1) ++load.poses_with_cycles;
    }
    load.methods.push_back(
        methodFigures(kCommanded, commanded, X_TrackerBase.linear(), poses, out.iso_plan_rows));
    load.methods.push_back(
        methodFigures(corrected_name, corrected, X_TrackerBase.linear(), poses, out.iso_plan_rows));
    out.loads.push_back(std::move(load));
  }
  return out;
}

}  // namespace stepcal::trainer
