// transmission_error: a joint's transmission profile (families.hpp), screened at the highest
// order (lower orders are its leading columns).
#include <cmath>

#include "../candidates.hpp"
#include "../profiles.hpp"
#include "families.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::trainer::diagnosis {

namespace {

// A joint whose torque over the fit rows has an RMS below this carries none: its profile has no
// torque-modulated twin to be told apart from.
constexpr double kNoTorqueNm = 1e-6;

// RMS of a series; 0 for none.
double rmsOf(const std::vector<double>& v) {
  double squares = 0.0;
  for (double x : v) squares += x * x;
  return v.empty() ? 0.0 : std::sqrt(squares / static_cast<double>(v.size()));
}

// The profile's columns times the joint's torque (scaled by its RMS over the fit rows, so that
// the profile's ridge serves them too): a stiffness varying with the angle, the profile's
// competitor (profile_load_check.cpp). Where the model holds a self weight, the torque without
// its weight and its weight apart.
void addTorqueModulated(const FamilyContext& c, Family& f) {
  const int j = f.mechanism.joint;
  std::vector<double> masses;
  for (const Mechanism& m : c.global.mechanisms) {
    if (m.kind == MechanismKind::kSelfWeight) masses = m.parameters;
  }
  std::vector<double> rest, weight;
  for (size_t i = 0; i < c.start.tau_nm.size(); ++i) {
    weight.push_back(modelWeightTorque(c.whole, masses, c.start.theta_rad[i], j));
    rest.push_back(c.start.tau_nm[i](j) - weight.back());
  }
  std::vector<double> whole = rest;
  for (size_t i = 0; i < whole.size(); ++i) whole[i] += weight[i];
  if (rmsOf(whole) < kNoTorqueNm) return;
  f.torque_std_nm = stdOf(whole);
  const AngleCoverage& coverage = f.mechanism.coverage;
  const int order = f.mechanism.order;
  if (rmsOf(rest) >= kNoTorqueNm) {
    f.torque_modulated =
        c.sink.torqueModulatedProfile(j, coverage, order, rmsOf(rest), masses, false);
  }
  if (rmsOf(weight) >= kNoTorqueNm) {
    f.weight_modulated =
        c.sink.torqueModulatedProfile(j, coverage, order, rmsOf(weight), masses, true);
  }
}

}  // namespace

void transmissionErrorFamilies(const FamilyContext& c) {
  // Each current profile's difference in one later campaign: whether one profile serves them.
  for (const Profile& p : c.model.profiles) {
    if (c.scope.campaign_profiles < 1) break;
    Family f;
    f.stage = Stage::kProfile;
    f.campaign = c.scope.campaign_profiles;
    f.mechanism =
        blank(MechanismKind::kTransmissionError, c.n, p.mechanism.joint, -1, p.mechanism.order);
    f.mechanism.coverage = p.mechanism.coverage;
    f.columns =
        c.sink.profile(f.mechanism.joint, f.mechanism.coverage, f.mechanism.order, f.campaign);
    c.s.families.push_back(std::move(f));
  }
  // One profile per joint not yet profiled, over the angles the fit rows cover.
  for (int j = 0; j < c.n && c.scope.families && c.scope.only == nullptr; ++j) {
    bool profiled = false;
    for (const Profile& p : c.model.profiles) profiled = profiled || p.mechanism.joint == j;
    if (profiled) continue;
    std::vector<double> angles;
    for (const Measurement* row : c.fit.rows) angles.push_back(row->q_rad(j));
    Family f;
    f.stage = Stage::kProfile;
    f.mechanism = blank(MechanismKind::kTransmissionError, c.n, j, -1, c.max_order);
    f.mechanism.coverage = coverageOfAngles(angles, c.options.coverage_gap_deg * kRadPerDeg,
                                            c.options.coverage_fade_deg * kRadPerDeg);
    f.columns = c.sink.profile(j, f.mechanism.coverage, c.max_order);
    addTorqueModulated(c, f);
    c.s.families.push_back(std::move(f));
  }
}

const KindSignature& transmissionErrorSignature() {
  // The profile against its joint's commanded angle, drawn across the angles the rows span.
  static const KindSignature signature{
      MechanismKind::kTransmissionError,
      [](const SignatureContext& c, size_t index, std::vector<EffectSignature>& signatures) {
        const Mechanism& m = c.model.mechanisms[index];
        EffectSignature s =
            linkAngleSignature(c, m, m.joint, c.without(index), SignatureVariable::kJointAngle,
                               m.joint, jointAngles(c.fit, m.joint));
        if (s.x.empty()) return;
        curveSampled(s, [&](double q) { return transmissionOffset(m, q); });
        signatures.push_back(std::move(s));
      }};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
