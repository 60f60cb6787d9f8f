// Step 2 on data this test makes itself: a chain with known compliance, payload wrenches,
// exact deflected FK. The identification must recover C_θ, say which joints it cannot see,
// and refuse unusable pairs with a clear message.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/trainer/gpr.hpp"
#include "stepcal/trainer/stiffness.hpp"

namespace stepcal::trainer {
namespace {

const JointVector kTrueStiffness =
    (JointVector(6) << 501130, 633590, 508209, 124391, 75782, 74226).finished();

struct LoadedCampaign {
  KinematicChain chain_Tracker;
  int sensor = 0;
  std::vector<Measurement> rows;
};

// Poses measured unloaded and at 20/40 kg; the payload hangs 0.15 m out with a lateral offset.
LoadedCampaign makeCampaign(uint64_t seed, double sigma_p, double sigma_r, bool orientation = true) {
  LoadedCampaign s;
  s.chain_Tracker = chainFromUrdfFile(std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf",
                                      "base_link", "tmac", {"ft_sensor"})
                        .rerooted(lie::expSE3((Vec6() << 4, 1, 0.5, 0, 0, 2.5).finished()));
  const Vec3 g_Tracker = s.chain_Tracker.initialPose(0).linear() * Vec3(0, 0, -9.80665);
  const Vec3 p_CoGInSensor(0.04, -0.03, 0.15);
  const JointVector compliance = kTrueStiffness.cwiseInverse();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  ChainWorkspace ws;
  JointVector q_link;
  int seq = 0;
  for (int pose = 0; pose < 60; ++pose) {
    JointVector q(6);
    q << 0.8 * u(rng), 0.5 * u(rng) + 0.2, 0.4 * u(rng), 2 * u(rng), 0.5 + 0.8 * std::abs(u(rng)), 2 * u(rng);
    for (double load : {0.0, 20.0, 40.0}) {
      // The wrench at the true deflected pose, found by iterating the sensor's orientation.
      Vec6 wrench = Vec6::Zero();
      for (int it = 0; it < 4; ++it) {
        deflectedJointAngles(s.chain_Tracker, s.sensor, q, wrench, compliance, ws, q_link);
        const Pose X_TrackerSensor = framePose(s.chain_Tracker, ws, s.sensor);
        const Vec3 f_Sensor = X_TrackerSensor.linear().transpose() * (load * g_Tracker);
        wrench.head<3>() = f_Sensor;
        wrench.tail<3>() = p_CoGInSensor.cross(f_Sensor);
      }
      deflectedJointAngles(s.chain_Tracker, s.sensor, q, wrench, compliance, ws, q_link);
      Measurement m;
      m.seq = seq++;
      m.source_line = m.seq + 2;
      m.pose_id = "p" + std::to_string(pose);
      m.set = RowSet::kStiffness;
      m.load_kg = load;
      m.q_rad = q;
      m.has_wrench = true;
      m.wrench_Sensor = wrench;
      m.p_TipInTracker_m = tipPose(ws).translation() + sigma_p * Vec3(g(rng), g(rng), g(rng));
      m.has_orientation = orientation;
      m.q_TrackerTip = Eigen::Quaterniond(lie::expSO3(sigma_r * Vec3(g(rng), g(rng), g(rng))) *
                                          tipPose(ws).linear());
      s.rows.push_back(m);
    }
  }
  return s;
}

std::vector<const Measurement*> pointers(const std::vector<Measurement>& rows) {
  std::vector<const Measurement*> out;
  for (const Measurement& r : rows) out.push_back(&r);
  return out;
}

TrackerNoise noise(double sigma_p, double sigma_r) { return {sigma_p, sigma_r, true}; }

TEST(Stiffness, NoiselessPairsRecoverTheComplianceAndSkipTheVerticalJoint) {
  const LoadedCampaign s = makeCampaign(1, 0, 0);
  const auto pairs = deflectionPairs(pointers(s.rows));
  ASSERT_EQ(pairs.size(), 120u);
  const StiffnessResult r = identifyCompliance(s.chain_Tracker, s.sensor, pairs, noise(1e-5, 1e-4));
  // A vertical payload puts no torque on the vertical joint 1.
  EXPECT_FALSE(r.joints[0].excited);
  EXPECT_EQ(r.compliance_rad_per_nm(0), 0.0);
  for (int j = 1; j < 6; ++j) {
    ASSERT_TRUE(r.joints[static_cast<size_t>(j)].excited) << j;
    // Linearised model vs exact deflected FK: agreement to second order in Δθ (~1e-3).
    EXPECT_NEAR(r.joints[static_cast<size_t>(j)].stiffness_nm_per_rad / kTrueStiffness(j), 1.0, 5e-3)
        << "joint " << j + 1;
  }
}

TEST(Stiffness, NoisyPairsStayWithinTheirUncertainty) {
  const LoadedCampaign s = makeCampaign(2, 10e-6, 0.005 * kRadPerDeg);
  const StiffnessResult r = identifyCompliance(s.chain_Tracker, s.sensor,
                                               deflectionPairs(pointers(s.rows)),
                                               noise(10e-6, 0.005 * kRadPerDeg));
  for (int j = 1; j < 6; ++j) {
    const JointCompliance& jc = r.joints[static_cast<size_t>(j)];
    if (!jc.excited) continue;
    EXPECT_LT(std::abs(jc.stiffness_nm_per_rad - kTrueStiffness(j)),
              4 * jc.stiffness_sigma_nm_per_rad + 5e-3 * kTrueStiffness(j))
        << "joint " << j + 1;
  }
  // The modelled deflection matches the measured one.
  const auto check = validateCompliance(s.chain_Tracker, s.sensor, r.compliance_rad_per_nm,
                                        deflectionPairs(pointers(s.rows)));
  ASSERT_EQ(check.size(), 2u);
  EXPECT_EQ(check[0].load_kg, 20.0);
  for (const auto& v : check) EXPECT_LT(v.mean_deviation_pct, 10.0);
}

TEST(Stiffness, PositionOnlyPairsWork) {
  const LoadedCampaign s = makeCampaign(3, 0, 0, false);
  const StiffnessResult r = identifyCompliance(s.chain_Tracker, s.sensor,
                                               deflectionPairs(pointers(s.rows)), noise(1e-5, 1e-4));
  EXPECT_NEAR(r.joints[1].stiffness_nm_per_rad / kTrueStiffness(1), 1.0, 5e-3);
}

TEST(Stiffness, RefusesUnusablePairs) {
  LoadedCampaign s = makeCampaign(4, 0, 0);
  // Two unloaded rows under one pose_id.
  std::vector<Measurement> twice = s.rows;
  twice[3].pose_id = twice[0].pose_id;
  try {
    deflectionPairs(pointers(twice));
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.column(), "pose_id");
    EXPECT_NE(std::string(e.what()).find("two unloaded rows"), std::string::npos) << e.what();
  }
  // Loaded row commanded elsewhere.
  std::vector<Measurement> moved = s.rows;
  moved[1].q_rad(2) += 0.01;
  EXPECT_THROW(deflectionPairs(pointers(moved)), InputError);
  // Loaded row without a wrench.
  std::vector<Measurement> blind = s.rows;
  blind[2].has_wrench = false;
  try {
    identifyCompliance(s.chain_Tracker, s.sensor, deflectionPairs(pointers(blind)), noise(1e-5, 1e-4));
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), blind[2].source_line);
  }
  EXPECT_THROW(identifyCompliance(s.chain_Tracker, -1, deflectionPairs(pointers(s.rows)),
                                  noise(1e-5, 1e-4)),
               InputError);
  EXPECT_THROW(identifyCompliance(s.chain_Tracker, s.sensor, {}, noise(1e-5, 1e-4)), InputError);
}

TEST(Compliance, WrenchTransformAndTorquesMatchVirtualWork) {
  // τ·δq = W·δx: the torques from the transformed wrench do the same work as the wrench does
  // on the sensor frame's displacement, checked by finite differences.
  const LoadedCampaign s = makeCampaign(5, 0, 0);
  const Vec6 wrench_Sensor = (Vec6() << 12, -30, 200, 4, -6, 1.5).finished();
  ChainWorkspace ws;
  const JointVector q = s.rows[0].q_rad;
  forwardKinematics(s.chain_Tracker, q, ws);
  Jacobian J;
  spatialJacobian(s.chain_Tracker, ws, J);
  const Pose X0 = framePose(s.chain_Tracker, ws, s.sensor);
  const JointVector tau = jointTorques(J, wrenchInRoot(X0, wrench_Sensor));
  for (int j = 0; j < 6; ++j) {
    JointVector qp = q;
    qp(j) += 1e-7;
    forwardKinematics(s.chain_Tracker, qp, ws);
    // Body twist of the sensor frame, paired with the wrench in sensor axes.
    const Vec6 body = lie::logSE3(X0.inverse() * framePose(s.chain_Tracker, ws, s.sensor)) / 1e-7;
    EXPECT_NEAR(tau(j), body.dot(wrench_Sensor), 1e-4 * (1 + std::abs(tau(j)))) << j;
  }
}

TEST(Gpr, WhiteNoiseResidualIsExplainedAsNoise) {
  // With nothing to learn, the fit must say so (small σ_f, σ_n ≈ the spread), not explain the
  // noise with vanishing length scales: the runtime's variance check relies on it.
  std::mt19937_64 rng(6);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd X(200, 8), Y(200, 3);
  for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] = g(rng);
  for (Eigen::Index i = 0; i < Y.size(); ++i) Y.data()[i] = 1e-5 * g(rng);
  const GaussianProcess gp = GaussianProcess::fit(X, Y);
  EXPECT_LT(gp.hyperparameters().signal_sigma, 0.2 * gp.hyperparameters().noise_sigma);
  EXPECT_NEAR(gp.hyperparameters().noise_sigma, 1.0, 0.2);
}

}  // namespace
}  // namespace stepcal::trainer
