// Hidden mechanisms for the diagnosis tests: drawn at random at realistic sizes, simulated into
// the paper's campaign by the twin, and looked up among what the diagnosis names.
#pragma once

#include <cmath>
#include <initializer_list>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/draws.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal::trainer::test_support {

// What a test hid: the twin's JSON, and what the diagnosis must report.
struct Hidden {
  nlohmann::json effect;
  MechanismKind kind = MechanismKind::kBacklash;
  int joint = -1;          // 0-based, −1 = none
  int source_joint = -1;   // joint_coupling
  int harmonic = 0;        // transmission_error: the harmonic hidden, and its coefficients
  double sin_rad = 0.0, cos_rad = 0.0;
  size_t primary = 0;      // index of the parameter checked to 20 %
  double truth = 0.0;      // its true value, SI
  bool load_dependent = false;
  std::vector<double> self_weight_truth;  // self_weight: (m, m·com) per link, as the model holds them
};

// A realistic mechanism of a kind (twin::drawMechanism: its sizes, and the joints where the
// protocol loads the torque-driven ones), with what the test checks of it.
// kind: 0 backlash, 1 transmission error, 2 nonlinear stiffness, 3 joint coupling, 4 thermal
// expansion, 5 sensor bias, 6 self weight.
inline Hidden drawOfKind(int kind, std::mt19937_64& rng) {
  const twin::DrawnMechanism drawn = twin::drawMechanism(kind, rng);
  Hidden h;
  h.effect = drawn.effect;
  h.kind = drawn.kind;
  h.joint = drawn.joint;
  h.source_joint = drawn.source_joint;
  const nlohmann::json& e = h.effect;
  switch (h.kind) {
    case MechanismKind::kBacklash:
      h.truth = e.at("lost_motion_rad");
      h.load_dependent = true;
      break;
    case MechanismKind::kTransmissionError:
      h.harmonic = e.at("harmonic");
      h.sin_rad = e.at("sin_rad");
      h.cos_rad = e.at("cos_rad");
      break;
    case MechanismKind::kNonlinearStiffness:
      h.truth = e.at("extra_compliance_rad_per_nm");
      h.load_dependent = true;
      break;
    case MechanismKind::kThermalExpansion: h.truth = e.at("expansion_per_k"); break;
    case MechanismKind::kSensorBias: {
      const std::vector<double> f = e.at("force_n");
      const Eigen::Vector3d force(f[0], f[1], f[2]);
      force.cwiseAbs().maxCoeff(&h.primary);
      h.truth = force(static_cast<Eigen::Index>(h.primary));
      h.load_dependent = false;
      break;
    }
    case MechanismKind::kSelfWeight:
      h.self_weight_truth.assign(24, 0.0);
      for (const nlohmann::json& link : e.at("links")) {
        const size_t k = static_cast<size_t>(4 * (link.at("link").get<int>() - 1));
        const double mass = link.at("mass_kg");
        const std::vector<double> com = link.at("com_m");
        h.self_weight_truth[k] = mass;
        for (size_t i = 0; i < 3; ++i) h.self_weight_truth[k + 1 + i] = mass * com[i];
      }
      break;
    default: h.truth = e.at("ratio"); break;  // joint coupling
  }
  return h;
}

inline constexpr int kHiddenKinds = 7;

/// One hidden mechanism of a kind drawn at random.
inline Hidden drawHidden(uint64_t seed) {
  std::mt19937_64 rng(seed * 7919 + 13);
  return drawOfKind(std::uniform_int_distribution<int>(0, kHiddenKinds - 1)(rng), rng);
}

inline twin::TwinOptions paperOptions(uint64_t seed, std::vector<nlohmann::json> effects) {
  twin::TwinOptions options;
  options.urdf_path = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";
  options.seed = seed;
  options.hidden_effects = std::move(effects);
  return options;
}

inline Diagnosis diagnoseSimulation(const twin::TwinOptions& options, Campaign* campaign_out = nullptr,
                                    nlohmann::json* truth_out = nullptr) {
  const Campaign campaign = twin::simulateCampaign(options, truth_out);
  const CalibratedModel model = modelFromOutcome(campaign, calibrateCampaign(campaign));
  if (campaign_out) *campaign_out = campaign;
  return diagnose(campaign, model);
}

// RMS over the rows of joint j's gravity torque from self_weight parameters, on the extended
// model's chain: the lumped masses are identifiable only through these torques. N·m.
inline double rmsGravityTorque(const CalibratedModel& model, const Campaign& campaign,
                        const std::vector<double>& parameters, int joint) {
  const PhysicalModel physical = physicalModelOf(model);
  ChainWorkspace ws;
  JointVector tau;
  double sum = 0.0;
  for (const Measurement& row : campaign.rows) {
    forwardKinematics(physical.chain_Tracker, row.q_rad, ws);
    selfWeightTorques(physical.chain_Tracker, ws, physical.gravity_Tracker, parameters, tau);
    sum += tau(joint) * tau(joint);
  }
  return std::sqrt(sum / static_cast<double>(campaign.rows.size()));
}

inline const FoundEffect* findEffect(const Diagnosis& d, const Hidden& h) {
  for (const FoundEffect& e : d.effects) {
    const Mechanism& m = e.mechanism;
    if (m.kind == h.kind && m.joint == h.joint && m.source_joint == h.source_joint) {
      return &e;
    }
  }
  return nullptr;
}

inline std::string effectsText(const Diagnosis& d) {
  std::string s;
  for (const FoundEffect& e : d.effects) s += describe(e.mechanism) + "; ";
  return s.empty() ? "(none)" : s;
}

/// A profile's values at the angles, fitted by harmonic k jointly with the harmonics the diagnosis
/// reports within reach of the geometry (share ≥ 50 %: the profile holds those only together with
/// its profile_geometry, and on a partial arc they are not orthogonal to k): k's (sin, cos) and
/// the RMS of what is left, rad.
struct HarmonicFit {
  Eigen::Vector2d at_k;
  double rest_rms_rad = 0.0;
};
inline HarmonicFit harmonicBesideGeometry(const FoundEffect& e, int k,
                                          const std::vector<double>& angles_rad) {
  std::vector<int> harmonics = {k};
  for (size_t i = 0; i < e.geometry_share.size(); ++i) {
    const int other = static_cast<int>(i) + 1;
    if (e.geometry_share[i] >= 0.5 && other != k) harmonics.push_back(other);
  }
  const Eigen::Index m = static_cast<Eigen::Index>(angles_rad.size());
  Eigen::MatrixXd X(m, 2 * static_cast<Eigen::Index>(harmonics.size()));
  Eigen::VectorXd y(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const double q = angles_rad[static_cast<size_t>(i)];
    for (size_t j = 0; j < harmonics.size(); ++j) {
      X(i, static_cast<Eigen::Index>(2 * j)) = std::sin(harmonics[j] * q);
      X(i, static_cast<Eigen::Index>(2 * j + 1)) = std::cos(harmonics[j] * q);
    }
    y(i) = transmissionOffset(e.mechanism, q);
  }
  const Eigen::VectorXd c = X.colPivHouseholderQr().solve(y);
  return {c.head<2>(), std::sqrt((y - X * c).squaredNorm() / static_cast<double>(m))};
}

/// The found effect e carries the hidden one's parameters: a self weight its gravity torques on
/// the shoulder and elbow (all the rows identify), a profile the hidden harmonic, a sensor bias
/// its force, anything else its primary parameter, each to 20 % (a sensor's moment bias within
/// 4σ). Prints how far off each is.
inline void expectParametersFound(const FoundEffect& found, const Hidden& h, const Diagnosis& d,
                                  const Campaign& campaign) {
  const FoundEffect* e = &found;
  if (h.kind == MechanismKind::kSensorBias) {
    // As vectors: a small component of a random direction is at the noise of its estimate.
    const std::vector<double>& p = e->mechanism.parameters;
    const std::vector<double>& s = e->mechanism.sigma;
    const std::vector<double> f = h.effect.at("force_n"), m = h.effect.at("moment_nm");
    const Vec3 f_truth(f[0], f[1], f[2]), m_truth(m[0], m[1], m[2]);
    const Vec3 f_fit(p[0], p[1], p[2]), m_fit(p[3], p[4], p[5]);
    const double m_sigma = std::sqrt(s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
    // The force to 20 %; the moment (0.3–1.5 N·m moves the tip by less than the tracker's noise
    // through the joints' compliance) within 4σ of its estimate.
    EXPECT_LT((f_fit - f_truth).norm(), 0.2 * f_truth.norm()) << "force " << f_fit.transpose();
    EXPECT_LT((m_fit - m_truth).norm(), 4.0 * m_sigma) << "moment " << m_fit.transpose();
    std::printf("[ hidden sensor_bias ] force off by %.1f %%, moment off by %.1f %% (%.2f N·m, "
                "σ %.2f N·m)\n",
                100.0 * (f_fit - f_truth).norm() / f_truth.norm(),
                100.0 * (m_fit - m_truth).norm() / m_truth.norm(), (m_fit - m_truth).norm(), m_sigma);
  } else if (h.kind == MechanismKind::kSelfWeight) {
    for (int joint : {1, 2}) {  // the shoulder and elbow carry the arm
      const double truth = rmsGravityTorque(d.extended_model, campaign, h.self_weight_truth, joint);
      const double fitted =
          rmsGravityTorque(d.extended_model, campaign, e->mechanism.parameters, joint);
      EXPECT_NEAR(fitted, truth, 0.2 * truth) << "RMS gravity torque of joint " << joint + 1;
      std::printf("[ hidden self_weight ] joint %d's RMS gravity torque off by %.1f %%\n",
                  joint + 1, 100.0 * std::abs(fitted - truth) / truth);
    }
  } else if (h.kind == MechanismKind::kTransmissionError) {
    // Over the angles it was fitted on, the profile is the hidden harmonic, up to the harmonics
    // it holds only together with the geometry: that harmonic to 20 %, and what else it holds
    // (noise it fitted) below half the harmonic's RMS.
    std::vector<double> angles;
    for (const Measurement& row : campaign.rows) {
      if (row.set != RowSet::kValidation) angles.push_back(row.q_rad(h.joint));
    }
    const Eigen::Vector2d truth(h.sin_rad, h.cos_rad);
    const HarmonicFit fit = harmonicBesideGeometry(*e, h.harmonic, angles);
    EXPECT_LT((fit.at_k - truth).norm(), 0.2 * truth.norm())
        << "harmonic " << h.harmonic << ": (" << fit.at_k(0) << ", " << fit.at_k(1) << ")";
    std::printf("[ hidden harmonic ] off by %.1f %% of the amplitude, the rest %.1f %% of its RMS\n",
                100.0 * (fit.at_k - truth).norm() / truth.norm(),
                100.0 * fit.rest_rms_rad / (truth.norm() / std::sqrt(2.0)));
    EXPECT_LT(fit.rest_rms_rad, 0.5 * truth.norm() / std::sqrt(2.0));
    EXPECT_TRUE(e->harmonics_separable) << "a single harmonic held by cancelling amplitudes";
  } else {
    const double fitted = e->mechanism.parameters[h.primary];
    EXPECT_NEAR(fitted, h.truth, 0.2 * std::abs(h.truth));
    std::printf("[ hidden %s ] off by %.1f %%\n", toString(h.kind),
                100.0 * std::abs(fitted - h.truth) / std::abs(h.truth));
  }
}

}  // namespace stepcal::trainer::test_support
