// The twin's load effects outside the diagnosis's catalogue: bearing_tilt (a joint's compliance
// perpendicular to its axis) and angle_dependent_stiffness (a joint's compliance varying with
// its angle), against their closed forms and finite differences, their input checks, truth.json
// round trips, and their sizes on the paper protocol; and the campaign designs that confound a
// load effect with the time order or not (TwinOptions::load_order, temperature_ramp_c).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/twin/draws.hpp"
#include "stepcal/twin/effects.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/campaign_rows.hpp"

namespace stepcal::twin {
namespace {

const std::string kIrb = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";

TwinOptions noiselessPaper(uint64_t seed) {
  TwinOptions o;
  o.urdf_path = kIrb;
  o.seed = seed;
  o.tracker_position_sigma_m = 0.0;
  o.tracker_orientation_sigma_rad = 0.0;
  o.ft_force_sigma_n = 0.0;
  o.ft_moment_sigma_nm = 0.0;
  o.temperature_sigma_c = 0.0;
  return o;
}

nlohmann::json bearingTilt(int joint, double c) {
  return {{"name", "bearing_tilt"}, {"joint", joint}, {"compliance_rad_per_nm", c}};
}

nlohmann::json angleDependentStiffness(int joint, int harmonic, double amplitude, double phase) {
  return {{"name", "angle_dependent_stiffness"}, {"joint", joint}, {"harmonic", harmonic},
          {"amplitude", amplitude}, {"phase_rad", phase}};
}

// Mean tip displacement [m] per load of a robot with the effects against the same robot
// without, over the paper protocol's rows.
std::map<double, double> meanTipDeflectionByLoad(TwinOptions o,
                                                 const std::vector<nlohmann::json>& effects) {
  const TwinRobot plain(o);
  o.hidden_effects = effects;
  const TwinRobot with(o);
  const Campaign c = simulateCampaign(o, nullptr);
  std::map<double, std::pair<double, int>> sums;
  for (const Measurement& m : c.rows) {
    auto& [sum, count] = sums[m.load_kg];
    sum += (with.X_BaseTip(m.q_rad, m.load_kg).translation() -
            plain.X_BaseTip(m.q_rad, m.load_kg).translation())
               .norm();
    ++count;
  }
  std::map<double, double> mean;
  for (const auto& [load, s] : sums) mean[load] = s.first / s.second;
  return mean;
}

// Every 7th row of the paper protocol's campaign of o (noiseless): commanded angles and load.
std::vector<Measurement> someRows(const TwinOptions& o) {
  const Campaign c = simulateCampaign(o, nullptr);
  std::vector<Measurement> rows;
  for (size_t i = 0; i < c.rows.size(); i += 7) rows.push_back(c.rows[i]);
  return rows;
}

TEST(TwinLoadEffects, BearingTiltIsNothingUnloadedOrAtZeroCompliance) {
  TwinOptions o = noiselessPaper(4);
  const TwinRobot plain(o);
  o.hidden_effects = {bearingTilt(1, 0.0), bearingTilt(2, 2e-7)};
  const TwinRobot zero_or_unloaded(o);
  for (const Measurement& m : someRows(o)) {
    // c = 0 on joint 1: no tilt at any load; joint 2 unloaded (no self_weight): no moment.
    const TwinRobot::Deflection d = zero_or_unloaded.deflection(m.q_rad, m.load_kg);
    EXPECT_EQ(d.tilt_rad[0], Vec3::Zero());
    if (m.load_kg == 0.0) {
      EXPECT_EQ(d.tilt_rad[1], Vec3::Zero());
      EXPECT_EQ(zero_or_unloaded.X_BaseTip(m.q_rad, 0.0).matrix(),
                plain.X_BaseTip(m.q_rad, 0.0).matrix())
          << m.pose_id;
    } else {
      EXPECT_GT(d.tilt_rad[1].norm(), 0.0) << m.pose_id;
    }
  }
}

// The moment about joint j's frame origin, in its axes, of the payload at its CoG and the
// given point masses {link, kg, centre in the link's frame}, from the robot's deflected frames.
Vec3 momentAboutJoint(const TwinRobot& robot, const JointVector& q, double load_kg, int joint,
                      const std::vector<std::tuple<int, double, Vec3>>& masses) {
  ChainWorkspace ws;
  robot.deflectedFrames(q, load_kg, kNoThermalExpansion, ws);
  const Pose& X_BaseJoint = ws.X_RootFrame[static_cast<size_t>(joint)];
  const Vec3 g = robot.gravityInBase();
  const Vec3 p_CoGInBase = framePose(robot.trueChain(), ws, robot.sensorFrame()) *
                           robot.p_CoGInSensor_m();
  Vec3 moment_Base = (p_CoGInBase - X_BaseJoint.translation()).cross(load_kg * g);
  for (const auto& [link, mass_kg, p_ComInLink] : masses) {
    if (link < joint) continue;  // carried by an earlier joint only
    const Vec3 p = ws.X_RootFrame[static_cast<size_t>(link)] * p_ComInLink;
    moment_Base += (p - X_BaseJoint.translation()).cross(mass_kg * g);
  }
  return X_BaseJoint.linear().transpose() * moment_Base;
}

TEST(TwinLoadEffects, BearingTiltIsTheComplianceTimesTheMomentPerpendicularToTheAxis) {
  TwinOptions o = noiselessPaper(5);
  const double c1 = 1.6e-7, c3 = 1.2e-6;
  const std::vector<std::tuple<int, double, Vec3>> masses = {{3, 35.0, Vec3(0.25, 0.03, 0.1)},
                                                             {5, 12.0, Vec3(0.02, 0.0, 0.05)}};
  nlohmann::json links = nlohmann::json::array();
  for (const auto& [link, kg, p] : masses) {
    links.push_back({{"link", link}, {"mass_kg", kg}, {"com_m", {p.x(), p.y(), p.z()}}});
  }
  o.hidden_effects = {bearingTilt(3, c3), {{"name", "self_weight"}, {"links", links}},
                      bearingTilt(1, c1)};
  const TwinRobot robot(o);
  double largest_rad = 0.0;
  for (const Measurement& m : someRows(o)) {
    const TwinRobot::Deflection d = robot.deflection(m.q_rad, m.load_kg);
    for (int joint = 1; joint <= 6; ++joint) {
      const Vec3& tilt = d.tilt_rad[static_cast<size_t>(joint - 1)];
      if (joint != 1 && joint != 3) {
        EXPECT_EQ(tilt, Vec3::Zero());
        continue;
      }
      const Vec3 axis = robot.trueChain().joints()[static_cast<size_t>(joint - 1)].twist_Local.tail<3>();
      // Perpendicular to the axis: the torsion is joint_compliance's.
      EXPECT_LT(std::abs(tilt.dot(axis)), 1e-18) << m.pose_id;
      const Vec3 M = momentAboutJoint(robot, m.q_rad, m.load_kg, joint, masses);
      const Vec3 expected = (joint == 1 ? c1 : c3) * (M - axis * axis.dot(M));
      // The fixed point to 1e-12 rad; the moment from the same frames.
      EXPECT_LT((tilt - expected).norm(), 1e-11) << m.pose_id << " joint " << joint;
      largest_rad = std::max(largest_rad, tilt.norm());
    }
  }
  // Unloaded rows tilt too (the links' weight): the check is not one of zeros.
  EXPECT_GT(largest_rad, 5e-5);
}

TEST(TwinLoadEffects, BearingTiltTurnsTheArmAboutTheJointsOriginLinearlyInSmallCompliance) {
  TwinOptions o = noiselessPaper(6);
  o.compliance = false;  // the tilt alone
  const TwinRobot plain(o);
  const auto robotWith = [&](double c) {
    TwinOptions t = o;
    t.hidden_effects = {bearingTilt(1, c)};
    return TwinRobot(t);
  };
  const double c = 1e-8;
  const TwinRobot once = robotWith(c), twice = robotWith(2.0 * c);
  int loaded = 0;
  for (const Measurement& m : someRows(o)) {
    if (m.load_kg == 0.0) continue;
    ++loaded;
    ChainWorkspace ws;
    plain.deflectedFrames(m.q_rad, m.load_kg, kNoThermalExpansion, ws);
    const Pose& X_BaseJoint1 = ws.X_RootFrame[1];
    const Vec3 p_TipInBase = tipPose(ws).translation();
    const Vec3 d1 = once.X_BaseTip(m.q_rad, m.load_kg).translation() - p_TipInBase;
    const Vec3 d2 = twice.X_BaseTip(m.q_rad, m.load_kg).translation() - p_TipInBase;
    // First order in c: a rotation by δ (joint 1's frame axes) about joint 1's origin moves
    // the tip by δ × r. The rest is second order, ~|δ| = 1e-5 of it.
    const Vec3 delta_Base = X_BaseJoint1.linear() * once.deflection(m.q_rad, m.load_kg).tilt_rad[0];
    const Vec3 first_order = delta_Base.cross(p_TipInBase - X_BaseJoint1.translation());
    EXPECT_LT((d1 - first_order).norm(), 1e-4 * first_order.norm()) << m.pose_id;
    EXPECT_LT((d2 - 2.0 * d1).norm(), 1e-4 * d1.norm()) << m.pose_id;
    EXPECT_GT(d1.norm(), 1e-6) << m.pose_id;
    // The payload hangs in front of joint 1's vertical axis: the arm sags under it.
    EXPECT_LT(d1.z(), 0.0) << m.pose_id;
  }
  EXPECT_GT(loaded, 50);
}

TEST(TwinLoadEffects, AngleDependentStiffnessFollowsItsClosedForm) {
  EffectSet set;
  set.add({{"name", "joint_compliance"},
           {"stiffness_nm_per_rad", {5e5, 6e5, 4e5, 1.2e5, 8e4, 7e4}}},
          6);
  set.add(angleDependentStiffness(3, 4, 0.15, 0.7), 6);
  ASSERT_EQ(set.link_angle.size(), 2u);
  const LinkAngleEffect& effect = *set.link_angle[1];
  JointVector tau(6);
  tau << 10.0, -250.0, 180.0, -30.0, 5.0, 0.5;
  for (double q3 : {-0.8, 0.0, 0.3, 1.1}) {
    JointVector q(6);
    q << 0.3, -0.7, q3, 2.5, -0.4, 0.9;
    JointVector theta = q;
    effect.apply(q, tau, theta);
    JointVector expected = JointVector::Zero(6);
    expected(2) = 0.15 * std::cos(4.0 * q3 + 0.7) * 180.0 / 4e5;
    // (q + Δ) − q: exact to the rounding of the sum, 1e-15 rad here.
    EXPECT_LT((theta - q - expected).cwiseAbs().maxCoeff(), 1e-15) << q3;
  }
  // Its truth.json object is the one given; K_j stays joint_compliance's.
  EXPECT_EQ(effect.toJson(), angleDependentStiffness(3, 4, 0.15, 0.7));
}

TEST(TwinLoadEffects, AngleDependentStiffnessScalesTheJointsDeflection) {
  TwinOptions o = noiselessPaper(7);
  const TwinRobot plain(o);
  o.hidden_effects = {angleDependentStiffness(2, 5, 0.2, -1.0)};
  const TwinRobot varying(o);
  for (const Measurement& m : someRows(o)) {
    const JointVector a = plain.linkAngles(m.q_rad, m.load_kg);
    const JointVector b = varying.linkAngles(m.q_rad, m.load_kg);
    // Joint 2's deflection scaled by 1 + ε cos(k q + φ); the torques move only to second order
    // (~1e-3 of the deflection), so the ratio holds to 1e-2 of ε.
    const double scale = 1.0 + 0.2 * std::cos(5.0 * m.q_rad(1) - 1.0);
    const double plain_rad = a(1) - m.q_rad(1), varying_rad = b(1) - m.q_rad(1);
    if (m.load_kg == 0.0) {
      EXPECT_EQ(plain_rad, 0.0);
      EXPECT_EQ(varying_rad, 0.0);
      continue;
    }
    EXPECT_NEAR(varying_rad, scale * plain_rad, 2e-3 * std::abs(plain_rad)) << m.pose_id;
  }
}

TEST(TwinLoadEffects, RoundTripThroughTruthJson) {
  TwinOptions o = noiselessPaper(8);
  o.hidden_effects = {bearingTilt(2, 1e-6), angleDependentStiffness(3, 6, 0.1, 0.2),
                      bearingTilt(1, 1.5e-7)};
  const TwinRobot robot(o);
  const nlohmann::json truth = robot.truthJson();
  const nlohmann::json& effects = truth.at("effects");
  ASSERT_EQ(effects.size(), 4u);
  EXPECT_EQ(effects.at(0).at("name"), "joint_compliance");
  EXPECT_EQ(effects.at(1), angleDependentStiffness(3, 6, 0.1, 0.2));
  EXPECT_EQ(effects.at(2), bearingTilt(1, 1.5e-7));  // by joint
  EXPECT_EQ(effects.at(3), bearingTilt(2, 1e-6));
  const TwinRobot copy = TwinRobot::fromTruthJson(nlohmann::json::parse(truth.dump()));
  EXPECT_EQ(copy.truthJson(), truth);
  for (const Measurement& m : someRows(o)) {
    EXPECT_EQ(robot.X_TrackerTip(m.q_rad, m.load_kg).matrix(),
              copy.X_TrackerTip(m.q_rad, m.load_kg).matrix());
    EXPECT_EQ(robot.sensorReading(m.q_rad, m.load_kg), copy.sensorReading(m.q_rad, m.load_kg));
  }
}

TEST(TwinLoadEffects, BadParametersAreRefusedWithTheKeyAndTheRange) {
  const std::vector<std::pair<nlohmann::json, std::string>> cases = {
      {bearingTilt(0, 1e-7), "bearing_tilt.joint = 0; expected a joint 1 … 6"},
      {bearingTilt(7, 1e-7), "bearing_tilt.joint = 7"},
      {bearingTilt(1, -1e-7),
       "bearing_tilt.compliance_rad_per_nm = -1e-07 rad/(N·m); expected a finite value in [0, "
       "1e-05)"},
      {bearingTilt(1, 2e-5), "bearing_tilt.compliance_rad_per_nm = 2e-05"},
      {{{"name", "bearing_tilt"}, {"joint", 1}}, "compliance_rad_per_nm"},
      {angleDependentStiffness(0, 3, 0.1, 0.0), "angle_dependent_stiffness.joint = 0"},
      {angleDependentStiffness(2, 0, 0.1, 0.0),
       "angle_dependent_stiffness.harmonic = 0; expected 1 … 64"},
      {angleDependentStiffness(2, 3, 1.0, 0.0),
       "angle_dependent_stiffness.amplitude = 1; expected a finite value in (0, 1)"},
      {angleDependentStiffness(2, 3, 0.0, 0.0), "angle_dependent_stiffness.amplitude = 0"},
      {angleDependentStiffness(2, 3, 0.1, std::nan("")), "angle_dependent_stiffness.phase_rad = nan"},
      {{{"name", "angle_dependent_stiffness"}, {"joint", 2}, {"harmonic", 3}, {"amplitude", 0.1}},
       "phase_rad"},
  };
  for (const auto& [spec, message] : cases) {
    TwinOptions o = noiselessPaper(1);
    o.hidden_effects = {spec};
    try {
      TwinRobot robot(o);
      ADD_FAILURE() << "accepted " << spec.dump();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
  TwinOptions twice = noiselessPaper(1);
  twice.hidden_effects = {bearingTilt(2, 1e-7), bearingTilt(2, 2e-7)};
  EXPECT_THROW(TwinRobot{twice}, InputError);
  TwinOptions rigid = noiselessPaper(1);
  rigid.compliance = false;
  rigid.hidden_effects = {angleDependentStiffness(2, 3, 0.1, 0.0)};
  try {
    TwinRobot robot(rigid);
    ADD_FAILURE() << "accepted a varying stiffness without a stiffness";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("has no joint_compliance"), std::string::npos) << e.what();
  }
}

// Sizes on the paper protocol (5 seeds, noiseless, mean |Δp| of the tip against the same robot
// without the effect, per load). Prints them; the stress run's draws (draws.hpp) span these.
TEST(TwinLoadEffects, SizesOnThePaperProtocol) {
  struct Case {
    const char* what;
    nlohmann::json effect;
    double at20_min_mm, at20_max_mm, at55_min_mm, at55_max_mm;
  };
  const std::vector<Case> cases = {
      {"bearing_tilt joint 1, c 1.6e-7", bearingTilt(1, 1.6e-7), 0.07, 0.11, 0.2, 0.3},
      {"bearing_tilt joint 2, c 1.2e-6", bearingTilt(2, 1.2e-6), 0.02, 0.06, 0.06, 0.16},
      {"angle_dependent_stiffness joint 2, k 6, eps 0.15",
       angleDependentStiffness(2, 6, 0.15, 0.0), 0.03, 0.08, 0.1, 0.25},
      {"angle_dependent_stiffness joint 3, k 6, eps 0.15",
       angleDependentStiffness(3, 6, 0.15, 0.0), 0.02, 0.06, 0.05, 0.15},
      // At most c m g (the sensor's axis vertical): 0.039 mm at 20 kg, 0.108 mm at 55 kg.
      {"tool_mount_compliance c 2e-7 m/N",
       {{"name", "tool_mount_compliance"}, {"compliance_m_per_n", 2e-7}}, 0.005, 0.0393, 0.015,
       0.108},
  };
  for (const Case& c : cases) {
    std::map<double, double> mean;
    for (uint64_t seed = 1; seed <= 5; ++seed) {
      for (const auto& [load, d] : meanTipDeflectionByLoad(noiselessPaper(seed), {c.effect})) {
        mean[load] += d / 5.0;
      }
    }
    std::printf("%-50s", c.what);
    for (const auto& [load, d] : mean) std::printf("  %2g kg %.3f mm", load, d * 1e3);
    std::printf("\n");
    EXPECT_EQ(mean.at(0.0), 0.0) << c.what;  // a load effect: nothing unloaded
    EXPECT_GT(mean.at(20.0) * 1e3, c.at20_min_mm) << c.what;
    EXPECT_LT(mean.at(20.0) * 1e3, c.at20_max_mm) << c.what;
    EXPECT_GT(mean.at(55.0) * 1e3, c.at55_min_mm) << c.what;
    EXPECT_LT(mean.at(55.0) * 1e3, c.at55_max_mm) << c.what;
  }
}


// The tool mount's shift against its closed form, and its compliance checked by name.
TEST(TwinLoadEffects, AToolMountShiftsAlongTheSensorsAxisByItsForce) {
  const ToolMountCompliance mount(2e-7);
  const Vec3 z = Vec3(1.0, 2.0, 2.0) / 3.0;
  const Vec3 force(0.0, 0.0, -539.0);
  const Vec3 shift = mount.shift(force, z);
  EXPECT_LT((shift - 2e-7 * (-539.0 * 2.0 / 3.0) * z).norm(), 1e-18);
  EXPECT_NEAR(shift.cross(z).norm(), 0.0, 1e-18);  // along the axis only
  EXPECT_EQ(mount.shift(Vec3(539.0, 0.0, 0.0), Vec3::UnitZ()), Vec3::Zero());
  for (const double bad : {-1e-7, 1e-5, std::nan("")}) {
    try {
      ToolMountCompliance refused(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("tool_mount_compliance.compliance_m_per_n = "),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(TwinLoadEffects, ForeignMixesAreTheirDesignsEffectsAtTheirSizes) {
  std::map<std::string, int> designs;
  for (uint64_t seed = 1; seed <= 40; ++seed) {
    const ForeignMix mix = drawForeignMix(seed);
    EXPECT_EQ(drawForeignMix(seed).foreign, mix.foreign);  // the same seed, the same mix
    ++designs[mix.design];
    const size_t foreign = mix.design == "both" ? 2u : 1u;
    ASSERT_EQ(mix.foreign.size(), foreign) << seed;
    EXPECT_EQ(mix.catalogued.size(), mix.design == "beside" ? 1u : 0u) << seed;
    TwinOptions o = noiselessPaper(seed);
    o.hidden_effects = mix.foreign;
    for (const DrawnMechanism& m : mix.catalogued) o.hidden_effects.push_back(m.effect);
    const TwinRobot robot(o);  // every draw a valid effect
    for (const nlohmann::json& e : mix.foreign) {
      if (e.at("name") == "bearing_tilt") {
        const double c = e.at("compliance_rad_per_nm");
        EXPECT_TRUE(e.at("joint") == 1 ? c >= 1.2e-7 && c <= 2.2e-7 : c >= 0.8e-6 && c <= 1.6e-6)
            << e.dump();
      } else {
        EXPECT_EQ(e.at("name"), "angle_dependent_stiffness");
        EXPECT_GE(e.at("amplitude").get<double>(), 0.1);
        EXPECT_LE(e.at("amplitude").get<double>(), 0.25);
      }
    }
  }
  EXPECT_EQ(designs, (std::map<std::string, int>{
                         {"angle_dependent_stiffness", 10}, {"bearing_tilt", 10}, {"beside", 10},
                         {"both", 10}}));
}

// Pearson correlation of two equally long series.
double correlation(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double mx = 0.0, my = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    mx += x[i] / n;
    my += y[i] / n;
  }
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxy / std::sqrt(sxx * syy);
}

// The fit rows' load against their time order (seq): Pearson r.
double loadTimeCorrelationOfFitRows(const Campaign& c) {
  std::vector<double> seq, load;
  for (const Measurement& m : c.rows) {
    if (m.set == RowSet::kValidation) continue;
    seq.push_back(static_cast<double>(m.seq));
    load.push_back(m.load_kg);
  }
  return correlation(seq, load);
}

TEST(TwinCampaignDesign, MixedLoadOrderShufflesTheFitRowsAndNothingElse) {
  TwinOptions blocks = noiselessPaper(9);
  blocks.tracker_position_sigma_m = 10e-6;  // noise on: it follows the time order, not the row
  blocks.hidden_effects = {bearingTilt(1, 1.6e-7)};
  TwinOptions mixed = blocks;
  mixed.load_order = "mixed";
  const Campaign a = simulateCampaign(blocks, nullptr);
  const Campaign b = simulateCampaign(mixed, nullptr);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  std::multiset<std::tuple<std::string, double, int>> fit_a, fit_b;
  int moved = 0;
  for (size_t i = 0; i < a.rows.size(); ++i) {
    const Measurement& x = a.rows[i];
    const Measurement& y = b.rows[i];
    EXPECT_EQ(x.seq, y.seq);
    EXPECT_EQ(x.set == RowSet::kValidation, y.set == RowSet::kValidation) << x.seq;
    if (x.set == RowSet::kValidation) {
      // Same place, same pose, load, noise and temperature: the same measurement.
      EXPECT_EQ(x.pose_id, y.pose_id);
      EXPECT_EQ(x.load_kg, y.load_kg);
      EXPECT_EQ(x.p_TipInTracker_m, y.p_TipInTracker_m);
      EXPECT_EQ(x.wrench_Sensor, y.wrench_Sensor);
      EXPECT_EQ(x.temp_c, y.temp_c);
      continue;
    }
    fit_a.insert({x.pose_id, x.load_kg, static_cast<int>(x.set)});
    fit_b.insert({y.pose_id, y.load_kg, static_cast<int>(y.set)});
    moved += x.pose_id != y.pose_id || x.load_kg != y.load_kg;
  }
  EXPECT_EQ(fit_a, fit_b);  // the same fit rows, in another order
  EXPECT_GT(moved, 650);  // of the 700 fit rows
  // Blocks: the load rises with the time order; mixed: it does not (|r| < 3/√780 ≈ 0.11).
  EXPECT_GT(loadTimeCorrelationOfFitRows(a), 0.5);
  EXPECT_LT(std::abs(loadTimeCorrelationOfFitRows(b)), 0.11);
  // A row keeps its own commanded pose and physics wherever it is measured.
  const TwinRobot robot(mixed);
  for (size_t i = 0; i < b.rows.size(); i += 11) {
    const Measurement& m = b.rows[i];
    EXPECT_LT((m.p_TipInTracker_m - robot.X_TrackerTip(m.q_rad, m.load_kg).translation()).norm(),
              6.0 * 10e-6 * std::sqrt(3.0))
        << m.pose_id;
  }
  // Seeded: the same order again; another seed's order is another.
  test::expectSameRows(b, simulateCampaign(mixed, nullptr));
  TwinOptions other = mixed;
  other.seed = 10;
  const Campaign o = simulateCampaign(other, nullptr);
  int same_place = 0;
  for (size_t i = 0; i < b.rows.size(); ++i) {
    same_place += b.rows[i].set != RowSet::kValidation && b.rows[i].pose_id == o.rows[i].pose_id &&
                  b.rows[i].load_kg == o.rows[i].load_kg;
  }
  EXPECT_LT(same_place, 20);
}

TEST(TwinCampaignDesign, TemperatureRampRisesSteadilyWithTheTimeOrder) {
  TwinOptions o = noiselessPaper(10);
  o.temperature_swing_c = 0.0;
  o.temperature_ramp_c = 4.0;
  const Campaign c = simulateCampaign(o, nullptr);
  const double rows = static_cast<double>(c.rows.size());
  std::vector<double> seq, temp;
  for (const Measurement& m : c.rows) {
    EXPECT_NEAR(*m.temp_c, 20.0 + 4.0 * static_cast<double>(m.seq - 1) / (rows - 1.0), 1e-12);
    seq.push_back(static_cast<double>(m.seq));
    temp.push_back(*m.temp_c);
  }
  EXPECT_NEAR(correlation(seq, temp), 1.0, 1e-12);
  // On top of the sinusoid; an explicit ramp of 0 is the default campaign bit for bit.
  TwinOptions both = noiselessPaper(10);
  both.temperature_ramp_c = -2.0;
  const Campaign d = simulateCampaign(both, nullptr);
  TwinOptions flat = noiselessPaper(10);
  flat.temperature_ramp_c = 0.0;
  const Campaign e = simulateCampaign(flat, nullptr);
  const Campaign f = simulateCampaign(noiselessPaper(10), nullptr);
  for (size_t i = 0; i < d.rows.size(); ++i) {
    const double sine = 3.0 * std::sin(2.0 * kPi * static_cast<double>(d.rows[i].seq) / 300.0);
    EXPECT_NEAR(*d.rows[i].temp_c, 20.0 + sine - 2.0 * static_cast<double>(i) / (rows - 1.0),
                1e-12);
    EXPECT_EQ(*e.rows[i].temp_c, *f.rows[i].temp_c);
  }
}

TEST(TwinCampaignDesign, BadLoadOrderOrRampIsRefusedWithTheKey) {
  TwinOptions order = noiselessPaper(1);
  order.load_order = "random";
  TwinOptions ramp = noiselessPaper(1);
  ramp.temperature_ramp_c = 45.0;
  TwinOptions nan_ramp = noiselessPaper(1);
  nan_ramp.temperature_ramp_c = std::nan("");
  const std::vector<std::pair<TwinOptions, std::string>> cases = {
      {order, "TwinOptions.load_order = 'random'; expected 'blocks'"},
      {ramp, "TwinOptions.temperature_ramp_c = 45; expected a finite rise"},
      {nan_ramp, "TwinOptions.temperature_ramp_c = nan"}};
  for (const auto& [o, message] : cases) {
    try {
      simulateCampaign(o, nullptr);
      ADD_FAILURE() << "accepted " << message;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace stepcal::twin
