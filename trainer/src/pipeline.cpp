#include "stepcal/trainer/pipeline.hpp"

#include <cstdio>
#include <ctime>

#include "stepcal/common/error.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/trainer/registration.hpp"

namespace stepcal::trainer {
namespace {

PoseModel chainModel(const KinematicChain& chain_Tracker) {
  return [chain_Tracker](const Measurement& row) {
    ChainWorkspace ws;
    forwardKinematics(chain_Tracker, row.q_rad, ws);
    return tipPose(ws);
  };
}

void append(std::vector<AccuracySummary>& out, std::vector<AccuracySummary> more) {
  out.insert(out.end(), more.begin(), more.end());
}

}  // namespace

KinematicChain campaignChain(const Campaign& campaign, int* sensor_frame) {
  const std::string source =
      campaign.directory.empty() ? campaign.robot_file : campaign.directory + "/" + campaign.robot_file;
  std::vector<std::string> attached;
  if (!campaign.sensor_link.empty()) attached.push_back(campaign.sensor_link);
  KinematicChain chain =
      chainFromUrdf(campaign.urdf_xml, campaign.base_link, campaign.tip_link, attached, source);
  if (chain.dof() != campaign.joint_count) {
    throw InputError("the robot chain from '" + campaign.base_link + "' to '" + campaign.tip_link +
                         "' has " + std::to_string(chain.dof()) +
                         " revolute joints but measurements.csv has q1_deg..q" +
                         std::to_string(campaign.joint_count) + "_deg",
                     source);
  }
  if (sensor_frame) *sensor_frame = campaign.sensor_link.empty() ? -1 : 0;
  return chain;
}

CalibrationOutcome calibrateCampaign(const Campaign& campaign, const CalibrationOptions& options) {
  CalibrationOutcome out;
  out.nominal_Base = campaignChain(campaign, &out.sensor_frame);
  const std::vector<const Measurement*> fit = campaign.rowsIn(RowSet::kGeometry);
  if (fit.empty()) {
    throw InputError("no row has set=geometry; step 1 needs unloaded geometry rows to fit on",
                     campaign.directory + "/" + campaign.measurements_file);
  }
  out.X_TrackerBase_nominal = registerTracker(out.nominal_Base, fit);
  GeometricOptions frames_options = options.geometric;
  frames_options.scope = GeometricScope::kFramesOnly;
  out.frames = calibrateGeometry(out.nominal_Base, fit, campaign.tracker, frames_options);
  GeometricOptions poe_options = options.geometric;
  poe_options.scope = GeometricScope::kFullPoe;
  out.poe = calibrateGeometry(out.nominal_Base, fit, campaign.tracker, poe_options);

  append(out.accuracy, summarize(kMethodNominal,
                                 chainModel(out.nominal_Base.rerooted(out.X_TrackerBase_nominal)),
                                 campaign.rows));
  append(out.accuracy, summarize(kMethodFrames, chainModel(out.frames.chain_Tracker), campaign.rows));
  append(out.accuracy, summarize(kMethodPoe, chainModel(out.poe.chain_Tracker), campaign.rows));
  out.floor_position_m = noiseFloorMean(campaign.tracker.position_sigma_m);
  out.floor_orientation_rad = noiseFloorMean(campaign.tracker.orientation_sigma_rad);
  return out;
}

std::string campaignHash(const Campaign& campaign) {
  uint64_t h = 1469598103934665603ull;
  auto mix = [&h](const void* data, size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i) {
      h ^= bytes[i];
      h *= 1099511628211ull;
    }
  };
  mix(campaign.urdf_xml.data(), campaign.urdf_xml.size());
  for (const std::string* s : {&campaign.base_link, &campaign.tip_link, &campaign.sensor_link}) {
    mix(s->data(), s->size() + 1);  // the terminator separates the fields
  }
  for (const Measurement& m : campaign.rows) {
    mix(&m.seq, sizeof m.seq);
    mix(m.pose_id.data(), m.pose_id.size() + 1);
    mix(&m.set, sizeof m.set);
    mix(&m.load_kg, sizeof m.load_kg);
    mix(m.q_rad.data(), sizeof(double) * static_cast<size_t>(m.q_rad.size()));
    mix(m.wrench_Sensor.data(), sizeof(double) * 6);
    mix(m.p_TipInTracker_m.data(), sizeof(double) * 3);
    mix(m.q_TrackerTip.coeffs().data(), sizeof(double) * 4);
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

CalibratedModel modelFromOutcome(const Campaign& campaign, const CalibrationOutcome& outcome) {
  CalibratedModel model;
  model.chain_Tracker = outcome.poe.chain_Tracker;
  model.X_TrackerBase = outcome.poe.X_TrackerBase;
  model.sensor_frame = outcome.sensor_frame;
  model.gravity_Base = campaign.gravity_in_base.value_or(Vec3(0.0, 0.0, -9.80665));
  model.provenance.campaign_hash = campaignHash(campaign);
  model.provenance.campaign_path = campaign.directory;
  model.provenance.trainer_version = STEPCAL_VERSION;
  char when[32];
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &utc);
  model.provenance.created_utc = when;
  for (const AccuracySummary& s : outcome.accuracy) {
    if (s.set != RowSet::kValidation) continue;
    model.provenance.validation.push_back({s.method, s.load_kg, s.rows, s.mean_position_m,
                                           s.max_position_m, s.mean_orientation_rad});
  }
  return model;
}

}  // namespace stepcal::trainer
