// The mechanism catalogue's joint-angle pieces (common/mechanisms.hpp): the coverage gate, the
// transmission profile's offset and its derivative, the joints outside coverage; the link masses
// read from a URDF (urdf.hpp); the trainer's coverage of fitted angles. Checked against closed
// forms, finite differences and direct sums, at the edges, near 0/2π and at random angles.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>

#include "../trainer/src/diagnose/profiles.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal {
namespace {


AngleCoverage arcs(std::vector<double> pairs, double fade) { return {std::move(pairs), fade}; }

Mechanism profile(std::vector<double> coefficients, AngleCoverage coverage = {}) {
  Mechanism m;
  m.kind = MechanismKind::kTransmissionError;
  m.joint = 0;
  m.order = static_cast<int>(coefficients.size() / 2);
  m.parameters = std::move(coefficients);
  m.sigma.assign(m.parameters.size(), 0.0);
  m.coverage = std::move(coverage);
  return m;
}

TEST(MechanismRegistry, EveryKindOnceInTheOrderOfItsValueWithItsName) {
  const std::vector<const MechanismTraits*>& registry = mechanismRegistry();
  ASSERT_EQ(registry.size(), 15u);
  for (size_t i = 0; i < registry.size(); ++i) {
    const MechanismTraits& traits = *registry[i];
    EXPECT_EQ(static_cast<size_t>(traits.kind), i + 1);
    EXPECT_EQ(findMechanismTraits(traits.kind), &traits);
    EXPECT_EQ(mechanismKindFromString(traits.name), traits.kind);
    EXPECT_STREQ(toString(traits.kind), traits.name);
    EXPECT_TRUE(traits.order_fits != nullptr && traits.parameter_names != nullptr) << traits.name;
    EXPECT_EQ(traits.torque_deflection, traits.deflection != nullptr) << traits.name;
  }
  EXPECT_EQ(findMechanismTraits(static_cast<MechanismKind>(0)), nullptr);
  EXPECT_EQ(findMechanismTraits(static_cast<MechanismKind>(16)), nullptr);
  EXPECT_STREQ(toString(static_cast<MechanismKind>(16)), "unknown");
  EXPECT_FALSE(mechanismKindFromString("no_such_kind").has_value());
}

TEST(MechanismView, NamedAccessorsFollowTheParameterNames) {
  Mechanism m;
  m.kind = MechanismKind::kTorsionCurve;
  m.order = 2;
  const std::vector<std::string> names = mechanismParameterNames(m.kind, 6, m.order);
  m.parameters.resize(names.size());
  for (size_t i = 0; i < names.size(); ++i) m.parameters[i] = static_cast<double>(i);
  const mechanism::TorsionCurve<const double> curve = view<mechanism::TorsionCurve>(std::as_const(m));
  EXPECT_EQ(names[static_cast<size_t>(curve.smoothingTorque_nm())], "smoothing_torque_nm");
  EXPECT_EQ(names[static_cast<size_t>(curve.extraCompliance_rad_per_nm(2))], "extra_compliance2_rad_per_nm");
  EXPECT_EQ(names[static_cast<size_t>(curve.kneeTorque_nm(1))], "knee_torque1_nm");
  EXPECT_EQ(names[static_cast<size_t>(curve.linearAbove_nm())], "linear_above_nm");
  view<mechanism::TorsionCurve>(m).kneeTorque_nm(2) = -1.0;
  EXPECT_EQ(m.parameter(mechanism::TorsionCurve<double>::kneeIndex(2)), -1.0);
}

TEST(CoverageGate, ClosedFormInsideOnTheRampAndOutside) {
  const AngleCoverage c = arcs({1.0, 2.0}, 0.2);  // [1, 3] rad, ramps [1, 1.2] and [2.8, 3]
  EXPECT_EQ(coverageGate(c, 2.0), 1.0);
  EXPECT_EQ(coverageGate(c, 1.2), 1.0);
  EXPECT_EQ(coverageGate(c, 0.9), 0.0);
  EXPECT_EQ(coverageGate(c, 3.1), 0.0);
  // smoothstep(x) = 3x² − 2x³ at x = d / fade.
  const double x = 0.05 / 0.2;
  EXPECT_NEAR(coverageGate(c, 1.05), x * x * (3 - 2 * x), 1e-15);
  EXPECT_NEAR(coverageGate(c, 2.95), x * x * (3 - 2 * x), 1e-15);
  EXPECT_NEAR(coverageGate(c, 1.1), 0.5, 1e-15);
  // No arcs: no gate. The full turn: no edge anywhere.
  EXPECT_EQ(coverageGate(AngleCoverage{}, 123.0), 1.0);
  EXPECT_EQ(coverageGate(arcs({0.0, 2 * kPi}, 0.1), 1e-9), 1.0);
}

TEST(CoverageGate, PeriodicInTheJointAngleAndAcrossZero) {
  const AngleCoverage c = arcs({6.0, 0.8}, 0.1);  // 6.0 … 6.8 rad, across 2π
  for (double q : {-0.2, 0.0, 0.3, 6.1, 6.5}) {
    EXPECT_NEAR(coverageGate(c, q), coverageGate(c, q + 2 * kPi), 1e-12) << q;
    EXPECT_NEAR(coverageGate(c, q), coverageGate(c, q - 4 * kPi), 1e-12) << q;
  }
  EXPECT_EQ(coverageGate(c, 0.0), 1.0);   // 2π lies inside
  EXPECT_EQ(coverageGate(c, 0.55), 0.0);  // past 6.8 − 2π = 0.517
  EXPECT_EQ(coverageGate(c, 5.8), 0.0);
}

TEST(CoverageGate, DerivativeMatchesFiniteDifferencesAndTheGateIsContinuous) {
  const AngleCoverage c = arcs({0.5, 1.0, 2.0, 3.0}, 0.3);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(-7.0, 7.0);
  const double h = 1e-7;
  for (int i = 0; i < 2000; ++i) {
    const double q = angle(rng);
    double slope = 0.0;
    const double g = coverageGate(c, q, &slope);
    EXPECT_GE(g, 0.0);
    EXPECT_LE(g, 1.0);
    const double fd = (coverageGate(c, q + h) - coverageGate(c, q - h)) / (2 * h);
    EXPECT_NEAR(slope, fd, 1e-5) << q;
  }
  // No step anywhere: along a fine sweep, neighbouring values differ by at most the largest
  // slope (1.5 / fade) times the step.
  double previous = coverageGate(c, -1.0);
  for (double q = -1.0; q < 7.0; q += 1e-4) {
    const double g = coverageGate(c, q);
    EXPECT_LE(std::abs(g - previous), 1.5 / 0.3 * 1e-4 + 1e-12) << q;
    previous = g;
  }
}

TEST(CoverageGate, MalformedCoveragesAreNamed) {
  EXPECT_EQ(coverageProblem(AngleCoverage{}), "");
  EXPECT_EQ(coverageProblem(arcs({0.0, 1.0, 2.0, 1.0}, 0.1)), "");
  EXPECT_NE(coverageProblem(arcs({0.0}, 0.1)).find("pairs"), std::string::npos);
  EXPECT_NE(coverageProblem(arcs({0.0, 1.0}, 0.0)).find("fade"), std::string::npos);
  EXPECT_NE(coverageProblem(arcs({-0.1, 1.0}, 0.1)).find("arc 0"), std::string::npos);
  EXPECT_NE(coverageProblem(arcs({0.0, 0.0}, 0.1)).find("length 0"), std::string::npos);
  EXPECT_NE(coverageProblem(arcs({0.0, 7.0}, 0.1)).find("arc 0"), std::string::npos);
  EXPECT_NE(coverageProblem(arcs({0.0, 2.0, 1.0, 1.0}, 0.1)).find("overlapping"), std::string::npos);
  EXPECT_NE(coverageProblem(arcs({1.0, 1.0, 6.0, 2.0}, 0.1)).find("wraps"), std::string::npos);
  // A malformed coverage makes the mechanism malformed; a backlash may not have one.
  EXPECT_NE(mechanismProblem(profile({1e-4, 0.0}, arcs({0.0, 1.0}, -1.0)), 6).find("fade"),
            std::string::npos);
  Mechanism backlash;
  backlash.kind = MechanismKind::kBacklash;
  backlash.joint = 1;
  backlash.parameters = {1e-4, 5.0};
  backlash.sigma = {0.0, 0.0};
  EXPECT_EQ(mechanismProblem(backlash, 6), "");
  backlash.coverage = arcs({0.0, 1.0}, 0.1);
  EXPECT_NE(mechanismProblem(backlash, 6).find("only for transmission_error"), std::string::npos);
}

TEST(TransmissionOffset, EqualsTheDirectSumAndItsDerivativeTheFiniteDifference) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> coefficient(-3e-4, 3e-4), angle(-6.5, 6.5);
  std::vector<double> c(96);
  for (double& v : c) v = coefficient(rng);
  const Mechanism everywhere = profile(c);
  const Mechanism gated = profile(c, arcs({0.3, 2.5, 4.0, 1.5}, 0.2));
  for (int i = 0; i < 500; ++i) {
    const double q = angle(rng);
    double direct = 0.0;
    for (int k = 1; k <= 48; ++k) {
      direct += c[size_t(2 * (k - 1))] * std::sin(k * q) + c[size_t(2 * k - 1)] * std::cos(k * q);
    }
    // The recurrence for sin(kq), cos(kq) drifts by rounding only.
    EXPECT_NEAR(transmissionOffset(everywhere, q), direct, 1e-15) << q;
    EXPECT_NEAR(transmissionOffset(gated, q), coverageGate(gated.coverage, q) * direct, 1e-15);
    for (const Mechanism* m : {&everywhere, &gated}) {
      double slope = 0.0;
      transmissionOffset(*m, q, &slope);
      const double h = 1e-6;
      const double fd = (transmissionOffset(*m, q + h) - transmissionOffset(*m, q - h)) / (2 * h);
      EXPECT_NEAR(slope, fd, 1e-7) << q;
    }
  }
}

TEST(TransmissionOffset, EveryOrderEqualsTheDirectSumAndItsDerivative) {
  // Orders on either side of the evaluation's blocks of four harmonics, up to kMaxHarmonics.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> coefficient(-3e-4, 3e-4), angle(-6.5, 6.5);
  for (const int order : {1, 2, 3, 4, 5, 6, 7, 9, 13, 31, 32, 33, 61, 63, kMaxHarmonics}) {
    std::vector<double> c(size_t(2 * order));
    for (double& v : c) v = coefficient(rng);
    const Mechanism m = profile(c);
    for (int i = 0; i < 200; ++i) {
      const double q = angle(rng);
      double direct = 0.0, direct_slope = 0.0;
      for (int k = 1; k <= order; ++k) {
        const double a = c[size_t(2 * (k - 1))], b = c[size_t(2 * k - 1)];
        direct += a * std::sin(k * q) + b * std::cos(k * q);
        direct_slope += k * (a * std::cos(k * q) - b * std::sin(k * q));
      }
      double slope = 0.0;
      EXPECT_NEAR(transmissionOffset(m, q, &slope), direct, 1e-15) << order << " " << q;
      EXPECT_NEAR(slope, direct_slope, 1e-13) << order << " " << q;  // |slope| up to ~0.6
    }
  }
}

TEST(TransmissionOffset, JointsOutsideCoverageAreFlagged) {
  PhysicalModel model;
  Mechanism on_joint_2 = profile({1e-4, 0.0}, arcs({0.0, 1.0}, 0.1));
  on_joint_2.joint = 1;
  Mechanism on_joint_4 = profile({1e-4, 0.0}, arcs({2.0, 1.0}, 0.1));
  on_joint_4.joint = 3;
  model.mechanisms = {on_joint_2, on_joint_4};
  JointVector q = JointVector::Zero(6);
  q(1) = 0.5;
  q(3) = 2.5;
  EXPECT_EQ(jointsOutsideCoverage(model, q), 0u);
  q(1) = 0.95;  // on joint 2's ramp
  EXPECT_EQ(jointsOutsideCoverage(model, q), 1u << 1);
  q(3) = -1.0;  // outside joint 4's arc
  EXPECT_EQ(jointsOutsideCoverage(model, q), (1u << 1) | (1u << 3));
}

// Link masses from <inertial>: each moving body gathers every link rigidly attached to it, its
// centre of mass carried through the fixed joints into the body's frame.
Mechanism torqueMechanism(MechanismKind kind, int order, std::vector<double> parameters) {
  Mechanism m;
  m.kind = kind;
  m.joint = 1;
  m.order = order;
  m.parameters = std::move(parameters);
  m.sigma.assign(m.parameters.size(), 0.0);
  return m;
}

// Backlash and nonlinear stiffness are their closed forms; a torsion curve is lost motion plus
// knees: odd in the torque, its derivative the finite difference everywhere (at zero, at and
// between the knees, far beyond), its compliance the segments' sums well away from the knees.
TEST(TorqueDeflection, ClosedFormsKneesAndTheirDerivative) {
  const double b = 2e-4, tau_b = 5.0, c1 = 3e-6, t1 = 100.0, c2 = 1e-6, t2 = 400.0;
  const Mechanism backlash = torqueMechanism(MechanismKind::kBacklash, 0, {b, tau_b});
  const Mechanism nonlinear = torqueMechanism(MechanismKind::kNonlinearStiffness, 0, {c1, t1, 0.0});
  const Mechanism curve =
      torqueMechanism(MechanismKind::kTorsionCurve, 2, {b, tau_b, c1, t1, c2, t2, 0.0});
  for (const Mechanism* m : {&backlash, &nonlinear, &curve}) EXPECT_EQ(mechanismProblem(*m, 6), "");
  for (const double tau : {-700.0, -30.0, 0.0, 0.4, 12.0, 99.0, 100.0, 250.0, 1e4}) {
    EXPECT_DOUBLE_EQ(torqueDeflection(backlash, tau), b * std::tanh(tau / tau_b)) << tau;
    EXPECT_DOUBLE_EQ(torqueDeflection(nonlinear, tau), c1 * tau * t1 / (t1 + std::abs(tau))) << tau;
    EXPECT_DOUBLE_EQ(torqueDeflection(curve, -tau), -torqueDeflection(curve, tau)) << tau;
    for (const Mechanism* m : {&backlash, &nonlinear, &curve}) {
      double slope = 0.0;
      torqueDeflection(*m, tau, &slope);
      const double h = 1e-4 * std::max(1.0, std::abs(tau));
      const double fd = (torqueDeflection(*m, tau + h) - torqueDeflection(*m, tau - h)) / (2 * h);
      EXPECT_NEAR(slope, fd, 1e-6 * (std::abs(fd) + 1e-9)) << describe(*m) << " at " << tau;
      EXPECT_GE(slope, 0.0) << describe(*m) << " at " << tau;
    }
  }
  // The knees' compliance: c1 + c2 below T1, c2 between, none above (lost motion taken up);
  // five knee widths from a knee its logistic has e⁻⁵ ≈ 0.7 % left.
  const auto slopeAt = [&](double tau) {
    double slope = 0.0;
    torqueDeflection(curve, tau, &slope);
    return slope;
  };
  EXPECT_NEAR(slopeAt(50.0), c1 + c2, 1e-2 * (c1 + c2));
  EXPECT_NEAR(slopeAt(200.0), c2, 1e-2 * c2);
  EXPECT_NEAR(slopeAt(1000.0), 0.0, 1e-2 * c2);
  // Far beyond the last knee the curve is the lost motion plus each knee's c·T.
  EXPECT_NEAR(torqueDeflection(curve, 5000.0), b + c1 * t1 + c2 * t2, 1e-3 * (c1 * t1 + c2 * t2));
}

// Above τ_lin (the largest torque the curve was fitted over) a curve is its tangent there: the
// same deflection and slope at τ_lin from either side, the slope constant beyond, odd in the
// torque; below τ_lin the formula itself. Backlash, which saturates, has none.
TEST(TorqueDeflection, AboveItsLinearTorqueACurveCarriesOnWithItsSlopeThere) {
  const double c1 = 3e-6, t1 = 100.0, c2 = 1e-6, t2 = 400.0, limit = 300.0;
  const Mechanism nonlinear = torqueMechanism(MechanismKind::kNonlinearStiffness, 0, {c1, t1, limit});
  const Mechanism curve =
      torqueMechanism(MechanismKind::kTorsionCurve, 2, {2e-4, 5.0, c1, t1, c2, t2, limit});
  for (const Mechanism* m : {&nonlinear, &curve}) {
    SCOPED_TRACE(describe(*m));
    EXPECT_EQ(mechanismProblem(*m, 6), "");
    Mechanism formula = *m;
    formula.parameters.back() = 0.0;
    for (const double tau : {0.0, 50.0, 120.0, 299.0, 300.0}) {
      EXPECT_EQ(torqueDeflection(*m, tau), torqueDeflection(formula, tau)) << tau;
    }
    double edge_slope = 0.0;
    const double at_edge = torqueDeflection(formula, limit, &edge_slope);
    for (const double tau : {300.5, 450.0, 2000.0}) {
      double slope = 0.0;
      EXPECT_NEAR(torqueDeflection(*m, tau, &slope), at_edge + edge_slope * (tau - limit),
                  1e-12 * at_edge) << tau;
      EXPECT_EQ(slope, edge_slope) << tau;
      EXPECT_DOUBLE_EQ(torqueDeflection(*m, -tau), -torqueDeflection(*m, tau)) << tau;
    }
    // The formula bends on above τ_lin, the tangent does not: at 2000 N·m they differ.
    EXPECT_GT(torqueDeflection(*m, 2000.0) - torqueDeflection(formula, 2000.0), 1e-4);
  }
}

TEST(TorqueDeflection, MalformedTorsionCurvesAreNamed) {
  const auto problem = [](int order, std::vector<double> p) {
    return mechanismProblem(torqueMechanism(MechanismKind::kTorsionCurve, order, std::move(p)), 6);
  };
  EXPECT_EQ(problem(0, {2e-4, 5.0, 0.0}), "");
  EXPECT_EQ(problem(1, {0.0, 0.0, 1e-6, 80.0, 500.0}), "");
  EXPECT_NE(problem(0, {0.0, 0.0, 0.0}).find("neither lost motion nor"), std::string::npos);
  EXPECT_NE(problem(1, {2e-4, 0.0, 1e-6, 80.0, 0.0}).find("or 0 with no lost motion"), std::string::npos);
  EXPECT_NE(problem(1, {0.0, -1.0, 1e-6, 80.0, 0.0}).find("smoothing_torque_nm"), std::string::npos);
  EXPECT_NE(problem(2, {0.0, 0.0, 1e-6, 80.0, 1e-6, 60.0, 0.0}).find("knee_torque2_nm"), std::string::npos);
  EXPECT_NE(problem(1, {0.0, 0.0, 1e-6, 0.0, 0.0}).find("knee_torque1_nm"), std::string::npos);
  EXPECT_NE(problem(1, {0.0, 0.0, 1e-6, 80.0, -5.0}).find("linear_above_nm"), std::string::npos);
  EXPECT_NE(problem(5, std::vector<double>(13, 1.0)).find("0 to 4 terms"), std::string::npos);
  EXPECT_NE(problem(1, {0.0, 0.0, 1e-6, 80.0}).find("expected 5"), std::string::npos);
}

TEST(UrdfMasses, BodiesGatherTheirRigidLinksInTheirOwnFrame) {
  const std::string urdf = R"(<robot name="r">
    <link name="base"/>
    <link name="a"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
    <link name="b"><inertial><origin xyz="0 0.5 0"/><mass value="3"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
    <link name="tool"><inertial><origin xyz="0 0 0.1"/><mass value="1"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
    <link name="side"><inertial><origin xyz="0 0 0"/><mass value="0.5"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
    <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
      <origin xyz="0 0 1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
    <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
      <origin xyz="1 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
    <joint name="fix" type="fixed"><parent link="b"/><child link="tool"/>
      <origin xyz="0 0 0.2" rpy="1.5707963267948966 0 0"/></joint>
    <joint name="branch" type="fixed"><parent link="b"/><child link="side"/>
      <origin xyz="0.3 0 0"/></joint>
  </robot>)";
  const auto masses = bodyMassesFromUrdf(urdf, "base", "tool");
  ASSERT_TRUE(masses.has_value());
  ASSERT_EQ(masses->size(), 8u);
  // Body 1: link a alone.
  EXPECT_DOUBLE_EQ((*masses)[0], 2.0);
  EXPECT_NEAR((*masses)[1], 0.2, 1e-15);
  // Body 2: b (3 kg at y 0.5), tool (1 kg at z 0.2 + Rx(90°)·(0, 0, 0.1) = (0, −0.1, 0.2)), side
  // (0.5 kg at x 0.3).
  EXPECT_DOUBLE_EQ((*masses)[4], 4.5);
  EXPECT_NEAR((*masses)[5], 0.15, 1e-12);
  EXPECT_NEAR((*masses)[6], 1.5 - 0.1, 1e-12);
  EXPECT_NEAR((*masses)[7], 0.2, 1e-12);
  // Without any <inertial>: none. A negative mass: refused with the link's name.
  std::string massless = urdf;
  for (size_t at; (at = massless.find("<inertial>")) != std::string::npos;) {
    massless.erase(at, massless.find("</inertial>", at) + 11 - at);
  }
  EXPECT_FALSE(bodyMassesFromUrdf(massless, "base", "tool").has_value());
  std::string negative = urdf;
  negative.replace(negative.find("value=\"3\""), 9, "value=\"-3\"");
  try {
    bodyMassesFromUrdf(negative, "base", "tool", "robot.urdf");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("link 'b'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("expected a finite mass >= 0"), std::string::npos);
  }
}

// The shipped UR10 carries its published masses (ROS-Industrial's ur_description): 32.7 kg in
// all, the upper arm's centre of mass 0.388 m out along it.
TEST(UrdfMasses, Ur10HasItsPublishedLinkMasses) {
  const std::string urdf = readTextFile(std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf");
  const auto masses = bodyMassesFromUrdf(urdf, "base_link", "tool0");
  ASSERT_TRUE(masses.has_value());
  double total = 0.0;
  for (size_t k = 0; k < 6; ++k) total += (*masses)[4 * k];
  EXPECT_NEAR(total, 7.778 + 12.93 + 3.87 + 1.96 + 1.96 + 0.202, 1e-9);
  EXPECT_NEAR((*masses)[5] / (*masses)[4], -0.38757, 1e-9);
}

// The trainer's coverage of the angles a profile is fitted on: arcs between gaps wider than the
// limit, across 0/2π, widened by the fade so the gate is 1 on every fitted angle; the full turn
// when nothing is missing.
TEST(ProfileCoverage, ArcsBetweenWideGapsAcrossZero) {
  using trainer::diagnosis::coverageOfAngles;
  const double deg = kRadPerDeg;
  std::vector<double> angles;
  for (double a = -30.0; a <= 40.0; a += 1.0) angles.push_back(a * deg);   // across 0
  for (double a = 100.0; a <= 160.0; a += 2.0) angles.push_back(a * deg);  // 60° later
  AngleCoverage c = coverageOfAngles(angles, 10 * deg, 5 * deg);
  ASSERT_EQ(c.arcs_rad.size(), 4u) << "two arcs";
  EXPECT_NEAR(c.arcs_rad[0], 95 * deg, 1e-12);
  EXPECT_NEAR(c.arcs_rad[1], 70 * deg, 1e-12);
  EXPECT_NEAR(c.arcs_rad[2], 325 * deg, 1e-12);
  EXPECT_NEAR(c.arcs_rad[3], 80 * deg, 1e-12);
  EXPECT_EQ(coverageProblem(c), "");
  for (double a : angles) EXPECT_EQ(coverageGate(c, a), 1.0) << a / deg;
  EXPECT_EQ(coverageGate(c, 70 * deg), 0.0);
  EXPECT_NEAR(coverageGate(c, 45 * deg), 0.0, 1e-12);  // the arc's end
  EXPECT_NEAR(coverageGate(c, 42.5 * deg), 0.5, 1e-12);
  // Every degree: the full turn. A lone angle: an arc of twice the fade, peaking at it.
  std::vector<double> all;
  for (double a = 0.0; a < 360.0; a += 1.0) all.push_back(a * deg);
  c = coverageOfAngles(all, 10 * deg, 5 * deg);
  EXPECT_EQ(c.arcs_rad, (std::vector<double>{0.0, 2 * kPi}));
  c = coverageOfAngles({1.0}, 10 * deg, 5 * deg);
  EXPECT_NEAR(c.arcs_rad[1], 10 * deg, 1e-12);
  EXPECT_EQ(coverageGate(c, 1.0), 1.0);
}

}  // namespace
}  // namespace stepcal
