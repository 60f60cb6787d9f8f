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

inline double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}
inline int pick(std::mt19937_64& rng, std::initializer_list<int> choices) {
  const auto i = std::uniform_int_distribution<size_t>(0, choices.size() - 1)(rng);
  return *(choices.begin() + static_cast<long>(i));
}

// A realistic mechanism at a size a laser tracker sees on the paper's campaign: lost motion of
// 0.6–1.4 arcmin, cyclic errors of 10–25 arcsec (20–50 on the wrist), couplings of 0.05–0.2 %, a joint up to twice as
// soft at small torque, thermal expansion of steel or aluminium, a mistared sensor, an upper arm
// and forearm out of balance. Joints where the protocol loads them (backlash, nonlinear
// stiffness).
// kind: 0 backlash, 1 transmission error, 2 nonlinear stiffness, 3 joint coupling, 4 thermal
// expansion, 5 sensor bias, 6 self weight.
inline Hidden drawOfKind(int kind, std::mt19937_64& rng) {
  Hidden h;
  switch (kind) {
    case 0: {
      const int joint = pick(rng, {2, 3, 5});
      const double b = uniform(rng, 1.7e-4, 4e-4);
      h.effect = {{"name", "backlash"}, {"joint", joint}, {"lost_motion_rad", b}};
      h.kind = MechanismKind::kBacklash;
      h.joint = joint - 1;
      h.truth = b;
      h.load_dependent = true;
      break;
    }
    case 1: {
      // A harmonic whose period fits at least twice into the joint's arc on the paper's campaign
      // (joints 1–3 sweep 90–120°, 4–6 over 200°): a slower one is not separable from the
      // joint's geometry there (TransmissionError.SlowHarmonicOnANarrowArc).
      // Wrist joints at twice the size: their lever to the T-Mac is a decimetre, so 10 arcsec
      // there move it by less than the tracker's noise (and wrist gears are the less accurate).
      const int joint = pick(rng, {1, 2, 3, 4, 5, 6});
      const int harmonic = std::uniform_int_distribution<int>(joint <= 3 ? 9 : 4, 16)(rng);
      const double size = joint <= 3 ? 1.0 : 2.0;
      const double amplitude = uniform(rng, 5e-5 * size, 1.2e-4 * size);
      const double phase = uniform(rng, -M_PI, M_PI);
      const double a = amplitude * std::cos(phase), b = amplitude * std::sin(phase);
      h.effect = {{"name", "transmission_error"}, {"joint", joint}, {"harmonic", harmonic},
                  {"sin_rad", a},                  {"cos_rad", b}};
      h.kind = MechanismKind::kTransmissionError;
      h.joint = joint - 1;
      h.harmonic = harmonic;
      h.sin_rad = a;
      h.cos_rad = b;
      break;
    }
    case 2: {
      const int joint = pick(rng, {2, 3});
      const double c = uniform(rng, 0.6e-6, 1.5e-6), t0 = uniform(rng, 120.0, 300.0);
      h.effect = {{"name", "nonlinear_stiffness"},
                  {"joint", joint},
                  {"extra_compliance_rad_per_nm", c},
                  {"saturation_torque_nm", t0}};
      h.kind = MechanismKind::kNonlinearStiffness;
      h.joint = joint - 1;
      h.truth = c;
      h.load_dependent = true;
      break;
    }
    case 4: {  // steel/aluminium arm, 8–24 ppm/K
      const double alpha = uniform(rng, 8e-6, 2.4e-5);
      h.effect = {{"name", "thermal_expansion"}, {"expansion_per_k", alpha}, {"reference_temp_c", 20.0}};
      h.kind = MechanismKind::kThermalExpansion;
      h.truth = alpha;
      break;
    }
    case 5: {  // a tare gone wrong: 15–40 N, 0.3–1.5 N·m
      Eigen::Vector3d f = Eigen::Vector3d::Zero(), m = f;
      for (int i = 0; i < 3; ++i) {
        f(i) = uniform(rng, -1.0, 1.0);
        m(i) = uniform(rng, -1.0, 1.0);
      }
      f *= uniform(rng, 15.0, 40.0) / f.norm();
      m *= uniform(rng, 0.3, 1.5) / m.norm();
      h.effect = {{"name", "sensor_bias"},
                  {"force_n", {f(0), f(1), f(2)}},
                  {"moment_nm", {m(0), m(1), m(2)}}};
      h.kind = MechanismKind::kSensorBias;
      f.cwiseAbs().maxCoeff(&h.primary);
      h.truth = f(static_cast<Eigen::Index>(h.primary));
      h.load_dependent = false;
      break;
    }
    case 6: {  // upper arm and forearm imbalance left by the counterbalance
      nlohmann::json links = nlohmann::json::array();
      h.self_weight_truth.assign(24, 0.0);
      for (int link : {2, 3}) {
        const double mass = uniform(rng, 30.0, 80.0);
        const Eigen::Vector3d com(uniform(rng, -0.1, 0.4), uniform(rng, -0.05, 0.05),
                                  uniform(rng, -0.1, 0.4));
        links.push_back({{"link", link}, {"mass_kg", mass}, {"com_m", {com(0), com(1), com(2)}}});
        const size_t k = static_cast<size_t>(4 * (link - 1));
        h.self_weight_truth[k] = mass;
        for (int i = 0; i < 3; ++i) h.self_weight_truth[k + 1 + static_cast<size_t>(i)] = mass * com(i);
      }
      h.effect = {{"name", "self_weight"}, {"links", links}};
      h.kind = MechanismKind::kSelfWeight;
      break;
    }
    default: {  // 3
      const int from = pick(rng, {4, 5, 6});
      int to = pick(rng, {4, 5, 6});
      if (to == from) to = from == 6 ? 5 : from + 1;
      const double ratio = uniform(rng, 5e-4, 2e-3);
      h.effect = {{"name", "joint_coupling"}, {"joints", {from, to}}, {"ratio", ratio}};
      h.kind = MechanismKind::kJointCoupling;
      h.joint = to - 1;
      h.source_joint = from - 1;
      h.truth = ratio;
      break;
    }
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
