// Step 1 on data this test makes itself (not the twin): the trainer must rely on the
// campaign contents alone. Noiseless data recover every identifiable parameter to round-off;
// noisy data reach the tracker-noise floor; the null space is named.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/trainer/accuracy.hpp"
#include "stepcal/trainer/geometric.hpp"
#include "stepcal/trainer/registration.hpp"

namespace stepcal::trainer {
namespace {

struct Truth {
  KinematicChain nominal_Base;
  KinematicChain true_Tracker;
};

Truth makeTruth(const std::string& urdf, const std::string& tip, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Truth t;
  t.nominal_Base = chainFromUrdfFile(std::string(STEPCAL_ROBOTS_DIR) + "/" + urdf, "base_link", tip);
  const int n = t.nominal_Base.dof();
  Eigen::VectorXd delta(6 * (n + 1));
  for (int k = 0; k <= n; ++k) {
    const double trans = k == n ? 3e-3 : 3e-4, rot = k == n ? 1.0 * kRadPerDeg : 5e-4;
    for (int c = 0; c < 3; ++c) delta(6 * k + c) = trans * g(rng);
    for (int c = 3; c < 6; ++c) delta(6 * k + c) = rot * g(rng);
  }
  Vec6 xi_TrackerBase;
  xi_TrackerBase << 3.5, -1.2, 0.4, 0.02, -0.03, 2.2;
  t.true_Tracker = t.nominal_Base.corrected(delta).rerooted(lie::expSE3(xi_TrackerBase));
  return t;
}

std::vector<Measurement> measure(const KinematicChain& truth, int count, uint64_t seed,
                                 double sigma_p, double sigma_r, bool orientation = true) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Measurement> rows;
  ChainWorkspace ws;
  for (int i = 0; i < count; ++i) {
    Measurement m;
    m.seq = i;
    m.pose_id = "p" + std::to_string(i);
    m.q_rad.resize(truth.dof());
    for (int j = 0; j < truth.dof(); ++j) m.q_rad(j) = 1.2 * u(rng);
    forwardKinematics(truth, m.q_rad, ws);
    m.p_TipInTracker_m = tipPose(ws).translation() + sigma_p * Vec3(g(rng), g(rng), g(rng));
    m.has_orientation = orientation;
    m.q_TrackerTip = Eigen::Quaterniond(
        lie::expSO3(sigma_r * Vec3(g(rng), g(rng), g(rng))) * tipPose(ws).linear());
    rows.push_back(m);
  }
  return rows;
}

std::vector<const Measurement*> pointers(const std::vector<Measurement>& rows) {
  std::vector<const Measurement*> out;
  for (const Measurement& r : rows) out.push_back(&r);
  return out;
}

TrackerNoise noise(double sigma_p, double sigma_r) {
  TrackerNoise n;
  n.position_sigma_m = sigma_p;
  n.orientation_sigma_rad = sigma_r;
  n.stated = true;
  return n;
}

TEST(Geometric, NoiselessDataRecoverIdentifiableParametersToRoundOff) {
  const Truth t = makeTruth("irb4400.urdf", "tmac", 1);
  const std::vector<Measurement> fit = measure(t.true_Tracker, 80, 2, 0, 0);
  const GeometricResult r = calibrateGeometry(t.nominal_Base, pointers(fit), noise(1e-5, 1e-4));
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.observability.parameter_count, 42);
  EXPECT_EQ(r.observability.rank, 30);  // 6(n+1) − 2n for six revolute joints, full 6-D data
  int structural = 0;
  for (const auto& u : r.observability.unobservable) structural += u.structural ? 1 : 0;
  EXPECT_EQ(structural, 12);
  EXPECT_EQ(r.observability.unobservable.size(), 12u);
  // Identifiable = every pose the model predicts: compare on poses never fitted.
  ChainWorkspace ws_true, ws_cal;
  for (const Measurement& m : measure(t.true_Tracker, 50, 3, 0, 0)) {
    forwardKinematics(t.true_Tracker, m.q_rad, ws_true);
    forwardKinematics(r.chain_Tracker, m.q_rad, ws_cal);
    EXPECT_LT((tipPose(ws_true).translation() - tipPose(ws_cal).translation()).norm(), 1e-11);
    EXPECT_LT(lie::angleBetween(tipPose(ws_true).linear(), tipPose(ws_cal).linear()), 1e-12);
  }
}

TEST(Geometric, NoisyDataReachTheNoiseFloor) {
  const double sigma_p = 10e-6, sigma_r = 0.005 * kRadPerDeg;
  const Truth t = makeTruth("irb4400.urdf", "tmac", 4);
  const std::vector<Measurement> fit = measure(t.true_Tracker, 80, 5, sigma_p, sigma_r);
  const std::vector<Measurement> val = measure(t.true_Tracker, 400, 6, sigma_p, sigma_r);
  const GeometricResult r = calibrateGeometry(t.nominal_Base, pointers(fit), noise(sigma_p, sigma_r));
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.iterations, 5);
  const auto summary = summarize("poe", [&](const Measurement& m) {
    ChainWorkspace ws;
    forwardKinematics(r.chain_Tracker, m.q_rad, ws);
    return tipPose(ws);
  }, val);
  ASSERT_EQ(summary.size(), 1u);
  const double floor_p = noiseFloorMean(sigma_p), floor_r = noiseFloorMean(sigma_r);
  std::printf("validation: %.4f mm (floor %.4f), %.5f deg (floor %.5f), %d iterations\n",
              summary[0].mean_position_m * 1e3, floor_p * 1e3,
              summary[0].mean_orientation_rad * kDegPerRad, floor_r * kDegPerRad, r.iterations);
  EXPECT_LE(summary[0].mean_position_m, 1.25 * floor_p);
  EXPECT_LE(summary[0].mean_orientation_rad, 1.25 * floor_r);
}

TEST(Geometric, PositionOnlyRowsWork) {
  const double sigma_p = 10e-6;
  const Truth t = makeTruth("irb4400.urdf", "tmac", 7);
  const std::vector<Measurement> fit = measure(t.true_Tracker, 100, 8, sigma_p, 0, false);
  const std::vector<Measurement> val = measure(t.true_Tracker, 300, 9, sigma_p, 0, false);
  const GeometricResult r = calibrateGeometry(t.nominal_Base, pointers(fit), noise(sigma_p, 1e-4));
  EXPECT_TRUE(r.converged);
  // Points alone cannot see the tool's orientation about the tip point, among others.
  EXPECT_LT(r.observability.rank, 30);
  bool non_structural = false;
  for (const auto& u : r.observability.unobservable) non_structural |= !u.structural;
  EXPECT_TRUE(non_structural);
  const auto summary = summarize("poe", [&](const Measurement& m) {
    ChainWorkspace ws;
    forwardKinematics(r.chain_Tracker, m.q_rad, ws);
    return tipPose(ws);
  }, val);
  EXPECT_LE(summary[0].mean_position_m, 1.25 * noiseFloorMean(sigma_p));
}

TEST(Geometric, OtherRobotAndFramesOnlyScope) {
  const Truth t = makeTruth("ur10.urdf", "tool0", 10);
  const std::vector<Measurement> fit = measure(t.true_Tracker, 60, 11, 0, 0);
  GeometricOptions frames_only;
  frames_only.scope = GeometricScope::kFramesOnly;
  const GeometricResult f = calibrateGeometry(t.nominal_Base, pointers(fit), noise(1e-5, 1e-4),
                                              frames_only);
  EXPECT_EQ(f.observability.parameter_count, 12);
  EXPECT_EQ(f.observability.rank, 12);
  const GeometricResult full = calibrateGeometry(t.nominal_Base, pointers(fit), noise(1e-5, 1e-4));
  EXPECT_EQ(full.observability.rank, 30);
  EXPECT_LT(full.history.back().rms_position_m, 1e-11);
  EXPECT_GT(f.history.back().rms_position_m, 1e-5);  // joint-frame errors remain
}

TEST(Geometric, RefusesUnusableRows) {
  const Truth t = makeTruth("irb4400.urdf", "tmac", 12);
  std::vector<Measurement> fit = measure(t.true_Tracker, 2, 13, 0, 0);
  EXPECT_THROW(calibrateGeometry(t.nominal_Base, pointers(fit), noise(1e-5, 1e-4)), InputError);
  fit = measure(t.true_Tracker, 10, 13, 0, 0);
  fit[4].q_rad.resize(5);
  fit[4].source_line = 6;
  try {
    calibrateGeometry(t.nominal_Base, pointers(fit), noise(1e-5, 1e-4));
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 6);
    EXPECT_NE(std::string(e.what()).find("5 joint angles"), std::string::npos) << e.what();
  }
}

TEST(Registration, KabschRecoversATransformAndRefusesCollinearPoints) {
  const Pose X = lie::expSE3((Vec6() << 1, 2, 3, 0.4, -0.5, 2.9).finished());
  std::vector<Vec3> a = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.2, 0.9}}, b;
  for (const Vec3& p : a) b.push_back(X * p);
  EXPECT_LT((fitRigidTransform(a, b).matrix() - X.matrix()).norm(), 1e-12);
  std::vector<Vec3> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  EXPECT_THROW(fitRigidTransform(line, line), InputError);
}

}  // namespace
}  // namespace stepcal::trainer
