// Hidden mechanisms drawn at random (draws.hpp).
#include "stepcal/twin/draws.hpp"

#include <algorithm>
#include <cmath>
#include <initializer_list>

#include <Eigen/Core>

#include "stepcal/common/units.hpp"

namespace stepcal::twin {
namespace {

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

int pick(std::mt19937_64& rng, std::initializer_list<int> choices) {
  const auto i = std::uniform_int_distribution<size_t>(0, choices.size() - 1)(rng);
  return *(choices.begin() + static_cast<long>(i));
}

bool torqueDriven(const DrawnMechanism& m) { return isTorqueDeflection(m.kind); }

}  // namespace

DrawnMechanism drawMechanism(int kind, std::mt19937_64& rng) {
  DrawnMechanism d;
  switch (kind) {
    case 0: {
      const int joint = pick(rng, {2, 3, 5});
      const double b = uniform(rng, 1.7e-4, 4e-4);
      d.effect = {{"name", "backlash"}, {"joint", joint}, {"lost_motion_rad", b}};
      d.kind = MechanismKind::kBacklash;
      d.joint = joint - 1;
      break;
    }
    case 1: {
      // A harmonic whose period fits at least twice into the joint's arc on the paper's campaign
      // (joints 1–3 sweep 90–120°, 4–6 over 200°): a slower one is not separable from the
      // joint's geometry there. Wrist joints at twice the size: their lever to the T-Mac is a
      // decimetre, so 10 arcsec there move it by less than the tracker's noise (and wrist gears
      // are the less accurate).
      const int joint = pick(rng, {1, 2, 3, 4, 5, 6});
      const int harmonic = std::uniform_int_distribution<int>(joint <= 3 ? 9 : 4, 16)(rng);
      const double size = joint <= 3 ? 1.0 : 2.0;
      const double amplitude = uniform(rng, 5e-5 * size, 1.2e-4 * size);
      const double phase = uniform(rng, -kPi, kPi);
      const double a = amplitude * std::cos(phase), b = amplitude * std::sin(phase);
      d.effect = {{"name", "transmission_error"}, {"joint", joint}, {"harmonic", harmonic},
                  {"sin_rad", a},                  {"cos_rad", b}};
      d.kind = MechanismKind::kTransmissionError;
      d.joint = joint - 1;
      break;
    }
    case 2: {
      const int joint = pick(rng, {2, 3});
      const double c = uniform(rng, 0.6e-6, 1.5e-6), t0 = uniform(rng, 120.0, 300.0);
      d.effect = {{"name", "nonlinear_stiffness"},
                  {"joint", joint},
                  {"extra_compliance_rad_per_nm", c},
                  {"saturation_torque_nm", t0}};
      d.kind = MechanismKind::kNonlinearStiffness;
      d.joint = joint - 1;
      break;
    }
    case 4: {  // steel/aluminium arm, 8–24 ppm/K
      const double alpha = uniform(rng, 8e-6, 2.4e-5);
      d.effect = {{"name", "thermal_expansion"}, {"expansion_per_k", alpha}, {"reference_temp_c", 20.0}};
      d.kind = MechanismKind::kThermalExpansion;
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
      d.effect = {{"name", "sensor_bias"},
                  {"force_n", {f(0), f(1), f(2)}},
                  {"moment_nm", {m(0), m(1), m(2)}}};
      d.kind = MechanismKind::kSensorBias;
      break;
    }
    case 6: {  // upper arm and forearm imbalance left by the counterbalance
      nlohmann::json links = nlohmann::json::array();
      for (int link : {2, 3}) {
        const double mass = uniform(rng, 30.0, 80.0);
        const Eigen::Vector3d com(uniform(rng, -0.1, 0.4), uniform(rng, -0.05, 0.05),
                                  uniform(rng, -0.1, 0.4));
        links.push_back({{"link", link}, {"mass_kg", mass}, {"com_m", {com(0), com(1), com(2)}}});
      }
      d.effect = {{"name", "self_weight"}, {"links", links}};
      d.kind = MechanismKind::kSelfWeight;
      break;
    }
    case 7: {  // a gear catalogue's curve: lost motion or not, one or two softer segments
      const int joint = pick(rng, {2, 3});
      const double lost = uniform(rng, 0.0, 1.0) < 0.5 ? 0.0 : uniform(rng, 1e-4, 2.4e-4);
      const double t1 = uniform(rng, 80.0, 250.0);
      nlohmann::json extra = {uniform(rng, 0.5e-6, 1.5e-6)}, ends = {t1};
      if (uniform(rng, 0.0, 1.0) < 0.5) {
        extra.push_back(uniform(rng, 0.2e-6, 0.6e-6));
        ends.push_back(t1 + uniform(rng, 100.0, 400.0));
      }
      d.effect = {{"name", "torsion_curve"},
                  {"joint", joint},
                  {"lost_motion_rad", lost},
                  {"extra_compliance_rad_per_nm", extra},
                  {"segment_end_torque_nm", ends}};
      d.kind = MechanismKind::kTorsionCurve;
      d.joint = joint - 1;
      break;
    }
    default: {  // 3
      const int from = pick(rng, {4, 5, 6});
      int to = pick(rng, {4, 5, 6});
      if (to == from) to = from == 6 ? 5 : from + 1;
      const double ratio = uniform(rng, 5e-4, 2e-3);
      d.effect = {{"name", "joint_coupling"}, {"joints", {from, to}}, {"ratio", ratio}};
      d.kind = MechanismKind::kJointCoupling;
      d.joint = to - 1;
      d.source_joint = from - 1;
      break;
    }
  }
  return d;
}

std::vector<DrawnMechanism> drawMechanismMix(uint64_t seed) {
  std::mt19937_64 rng(seed * 2654435761u + 17);
  const int count = std::uniform_int_distribution<int>(0, 3)(rng);
  std::vector<DrawnMechanism> mix;
  while (static_cast<int>(mix.size()) < count) {
    const int kind = std::uniform_int_distribution<int>(0, kDrawnKinds - 1)(rng);
    DrawnMechanism m = drawMechanism(kind, rng);
    if (m.kind == MechanismKind::kSelfWeight && uniform(rng, 0.0, 1.0) < 0.5) {
      // A few kilograms out of balance as well as tens: the lumped masses' single parameters
      // are then not identifiable, only their gravity torques.
      for (nlohmann::json& link : m.effect.at("links")) link["mass_kg"] = uniform(rng, 2.0, 6.0);
    }
    if (torqueDriven(m) && uniform(rng, 0.0, 1.0) < 0.5) {
      // On a joint another torque-driven mechanism already loads, if any: one curve of its torque.
      for (const DrawnMechanism& o : mix) {
        if (torqueDriven(o) && o.kind != m.kind) {
          m.joint = o.joint;
          m.effect["joint"] = o.joint + 1;
          break;
        }
      }
    }
    // Self weight, thermal expansion and sensor bias are one each; a joint holds one of each
    // other kind (and one coupling from each other joint).
    const bool twice = std::any_of(mix.begin(), mix.end(), [&](const DrawnMechanism& o) {
      return o.kind == m.kind && o.joint == m.joint && o.source_joint == m.source_joint;
    });
    if (twice) continue;
    mix.push_back(std::move(m));
  }
  return mix;
}

nlohmann::json drawBearingTilt(std::mt19937_64& rng) {
  const bool base = uniform(rng, 0.0, 1.0) < 2.0 / 3.0;
  const double c = base ? uniform(rng, 1.2e-7, 2.2e-7) : uniform(rng, 0.8e-6, 1.6e-6);
  return {{"name", "bearing_tilt"}, {"joint", base ? 1 : 2}, {"compliance_rad_per_nm", c}};
}

nlohmann::json drawAngleDependentStiffness(std::mt19937_64& rng) {
  const int joint = pick(rng, {2, 3});
  const int harmonic = std::uniform_int_distribution<int>(3, 12)(rng);
  const double amplitude = uniform(rng, 0.1, 0.25);
  const double phase = uniform(rng, -kPi, kPi);
  return {{"name", "angle_dependent_stiffness"}, {"joint", joint}, {"harmonic", harmonic},
          {"amplitude", amplitude}, {"phase_rad", phase}};
}

ForeignMix drawForeignMix(uint64_t seed) {
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15u + 43);
  ForeignMix mix;
  switch (seed % 4) {
    case 1:
      mix.design = "bearing_tilt";
      mix.foreign = {drawBearingTilt(rng)};
      break;
    case 2:
      mix.design = "angle_dependent_stiffness";
      mix.foreign = {drawAngleDependentStiffness(rng)};
      break;
    case 3: {
      mix.design = "beside";
      mix.foreign = {uniform(rng, 0.0, 1.0) < 0.5 ? drawBearingTilt(rng)
                                                   : drawAngleDependentStiffness(rng)};
      const int kind = std::uniform_int_distribution<int>(0, kDrawnKinds - 1)(rng);
      mix.catalogued = {drawMechanism(kind, rng)};
      break;
    }
    default:
      mix.design = "both";
      mix.foreign = {drawBearingTilt(rng), drawAngleDependentStiffness(rng)};
      break;
  }
  return mix;
}

}  // namespace stepcal::twin
