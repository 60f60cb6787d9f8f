#include "stepcal/report/diagnosis_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "stepcal/common/mechanisms/campaign_joint_zero.hpp"
#include "stepcal/common/mechanisms/off_axis_compliance.hpp"
#include "stepcal/common/mechanisms/profile_geometry.hpp"
#include "stepcal/common/mechanisms/registration_drift.hpp"
#include "stepcal/common/mechanisms/self_weight.hpp"
#include "stepcal/common/mechanisms/session_frames.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"
#include "stepcal/common/mechanisms/transmission_error.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/text_format.hpp"
#include "stepcal/report/family_pairs_report.hpp"
#include "stepcal/report/unexplained_report.hpp"

namespace stepcal::report {
namespace {

std::vector<std::string> parameterNames(const Mechanism& m) {
  // self_weight's layout has 4 entries per joint: the count gives the dof.
  return mechanismParameterNames(m.kind, static_cast<int>(m.parameters.size() / 4), m.order);
}

// Harmonic k's amplitude √(a² + b²), rad.
double amplitude(const Mechanism& m, int k) {
  const mechanism::TransmissionError<const double> harmonics = view<mechanism::TransmissionError>(m);
  return std::hypot(harmonics.sin_rad(k), harmonics.cos_rad(k));
}

// Harmonics by amplitude, largest first (1-based).
std::vector<int> strongestHarmonics(const Mechanism& m, size_t count) {
  std::vector<int> order(static_cast<size_t>(m.order));
  for (int k = 1; k <= m.order; ++k) order[static_cast<size_t>(k - 1)] = k;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return amplitude(m, a) > amplitude(m, b); });
  if (order.size() > count) order.resize(count);
  return order;
}

nlohmann::json coverageJson(const AngleCoverage& c) {
  nlohmann::json arcs = nlohmann::json::array();
  for (size_t i = 0; i + 1 < c.arcs_rad.size(); i += 2) {
    arcs.push_back({kDegPerRad * c.arcs_rad[i], kDegPerRad * (c.arcs_rad[i] + c.arcs_rad[i + 1])});
  }
  return arcs;
}

// share: per harmonic, the share a geometric error could produce (empty: not computed).
nlohmann::json mechanismJson(const Mechanism& m, const std::vector<double>& share = {}) {
  nlohmann::json j;
  j["name"] = toString(m.kind);
  j["joint"] = m.joint >= 0 ? nlohmann::json(m.joint + 1) : nlohmann::json(nullptr);
  j["joints"] = m.source_joint >= 0 ? nlohmann::json::array({m.source_joint + 1, m.joint + 1})
                                    : nlohmann::json(nullptr);
  j["order"] = m.order > 0 ? nlohmann::json(m.order) : nlohmann::json(nullptr);
  if (m.kind != MechanismKind::kTransmissionError) {
    j["parameters"] = parametersJson(m, m.parameters);
    j["uncertainty"] = parametersJson(m, m.sigma);
    return j;
  }
  j["harmonics"] = nlohmann::json::array();
  for (int k = 1; k <= m.order; ++k) {
    const size_t a = static_cast<size_t>(mechanism::TransmissionError<double>::sinIndex(k));
    nlohmann::json h = {{"harmonic", k},
                        {"sin_rad", view<mechanism::TransmissionError>(m).sin_rad(k)},
                        {"cos_rad", view<mechanism::TransmissionError>(m).cos_rad(k)},
                        {"sin_sigma_rad", m.sigma[a]},
                        {"cos_sigma_rad", m.sigma[a + 1]}};
    if (static_cast<size_t>(k) <= share.size()) h["geometry_share"] = share[static_cast<size_t>(k - 1)];
    j["harmonics"].push_back(h);
  }
  j["strongest_harmonics"] = strongestHarmonics(m, 3);
  j["coverage_deg"] = coverageJson(m.coverage);
  return j;
}

// "name = value ± σ" for each parameter, skipping self_weight's links that carry nothing.
std::string parameterText(const Mechanism& m) {
  if (m.kind == MechanismKind::kTransmissionError) return transmissionSummary(m);
  const std::vector<std::string> names = parameterNames(m);
  std::string out;
  // A torsion curve without lost motion (smoothing 0) has none to show.
  const bool no_lost_motion = m.kind == MechanismKind::kTorsionCurve &&
                              view<mechanism::TorsionCurve>(m).smoothingTorque_nm() == 0.0;
  for (size_t i = 0; i < names.size(); ++i) {
    const double value = m.parameter(static_cast<int>(i));
    if (m.kind == MechanismKind::kSelfWeight && value == 0.0) continue;
    if (no_lost_motion && i <= mechanism::TorsionCurve<double>::kSmoothingTorque) continue;
    out += format("%s%s = %.4g", out.empty() ? "" : ", ", names[i].c_str(), value);
    if (m.sigma[i] > 0.0) out += format(" ± %.2g", m.sigma[i]);
  }
  return out;
}

std::string statisticsText(const char* title, const trainer::ResidualStatistics& s) {
  std::string out = format(
      "%s: %d fit rows, position error mean %.4f mm, RMS %.4f mm, max %.4f mm; orientation RMS "
      "%.5f deg; %.2f times the stated tracker noise\n",
      title, s.rows, kMmPerM * s.mean_position_m, kMmPerM * s.rms_position_m, kMmPerM * s.max_position_m,
      kDegPerRad * s.rms_orientation_rad, s.noise_ratio);
  int shown = 0;
  for (const trainer::TrendScore& t : s.trends) {
    if (shown == 6) break;
    out += format("    trend in %-9s held-out gain %8.4f mm  z %7.1f  %s\n", t.variable.c_str(),
                  t.cv_gain_mm, t.z_statistic, t.significant ? "significant" : "");
    ++shown;
  }
  return out;
}

// What the data can and cannot tell apart, and what the search changed, in sentences: the
// model changes in the order done, then each effect's alternatives, then what each effect is on
// the fit rows.
/// The joints whose axis is parallel to joint's at every pose of the chain, within a calibrated
/// chain's axis errors (tried at poses spread over the joints' ranges, ±π where unlimited),
/// 0-based.
std::vector<int> alwaysParallelJoints(const KinematicChain& chain, int joint) {
  constexpr int kPoses = 64;
  const int n = chain.dof();
  std::vector<bool> parallel(static_cast<size_t>(n), true);
  ChainWorkspace ws;
  JointVector q(n);
  for (int p = 0; p < kPoses; ++p) {
    for (int i = 0; i < n; ++i) {
      const ChainJoint& c = chain.joints()[static_cast<size_t>(i)];
      const double lower = std::max(c.lower_rad, -kPi), upper = std::min(c.upper_rad, kPi);
      const double share = std::fmod(0.5 + (p + 1) * 0.6180339887498949 * (i + 1), 1.0);
      q(i) = lower + share * (upper - lower);
    }
    forwardKinematics(chain, q, ws);
    const auto axisInRoot = [&](int k) -> Vec3 {
      return ws.X_RootFrame[static_cast<size_t>(k + 1)].linear() *
             chain.joints()[static_cast<size_t>(k)].twist_Local.tail<3>();
    };
    const Vec3 axis = axisInRoot(joint);
    for (int k = 0; k < n; ++k) {
      // Parallel within a calibration's axis errors (~1e-4 rad): 1 − cos 4.5 mrad = 1e-5.
      if (1.0 - std::abs(axis.dot(axisInRoot(k))) > 1e-5) parallel[static_cast<size_t>(k)] = false;
    }
  }
  std::vector<int> joints;
  for (int k = 0; k < n; ++k) {
    if (k != joint && parallel[static_cast<size_t>(k)]) joints.push_back(k);
  }
  return joints;
}

/// What the rows identify of a joint's compliance across its axis: each direction's size against
/// its σ, and the joints with a parallel axis, whose tilts turn the arm about the same directions.
std::string offAxisLine(const trainer::Diagnosis& d, const Mechanism& m) {
  const KinematicChain& chain = d.extended_model.chain_Tracker;
  Vec3 u, v;
  mechanism::tiltDirections(chain.joints()[static_cast<size_t>(m.joint)].twist_Local.tail<3>(), u, v);
  std::string text = describe(m) + format(": the tilt about u = (%.2f, %.2f, %.2f) and about v = "
                                          "(%.2f, %.2f, %.2f) of the joint's frame, %.3g ± %.2g and "
                                          "%.3g ± %.2g rad/(N·m), each from the load's moment about it",
                                          u.x(), u.y(), u.z(), v.x(), v.y(), v.z(), m.parameter(0),
                                          m.sigma[0], m.parameter(1), m.sigma[1]);
  const std::vector<int> parallel = alwaysParallelJoints(chain, m.joint);
  if (!parallel.empty()) {
    text += "; joint(s)";
    for (int k : parallel) text += format(" %d", k + 1);
    text += " have a parallel axis at every pose: their tilts turn the arm about the same "
            "directions, under moments that differ only by the load's force times the distance "
            "between the joints, so the rows tell the joints apart by that alone (the σ above and "
            "any alternative named say how well)";
  }
  return text;
}

/// What the rows identify of the tool mount's compliance: each axis's size against its σ (an
/// axis held at zero is a stiff one, or one the rows' force does not move along).
std::string toolMountLine(const Mechanism& m) {
  return describe(m) + format(": the tool's shift along the sensor's x, y and z per newton of "
                              "the load's force along it, %.3g ± %.2g, %.3g ± %.2g and %.3g ± "
                              "%.2g m/N; a shift beyond the last joint that turns nothing",
                              m.parameter(0), m.sigma[0], m.parameter(1), m.sigma[1],
                              m.parameter(2), m.sigma[2]);
}

// What a candidate's fit without the physics' bounds broke, and what the fit within them kept.
std::string impossibleText(const trainer::CandidateScore& c) {
  return format("%s: physically impossible unbounded (%s; held-out gain %.4f mm, z %.1f); within "
                "bounds %s (gain %.4f mm, z %.1f)",
                describe(c.mechanism).c_str(), c.impossible_unbounded.c_str(),
                c.unbounded_cv_gain_mm, c.unbounded_z_statistic,
                c.significant ? "significant" : "not significant", c.cv_gain_mm, c.z_statistic);
}

// The candidates not named because only their physically impossible fit explained the residual:
// each one's last round in which its unbounded fit was significant and the bounded one is not.
std::vector<std::string> impossibleLines(const trainer::Diagnosis& d) {
  std::vector<std::string> lines;
  for (size_t i = 0; i < d.candidates.size(); ++i) {
    const trainer::CandidateScore& c = d.candidates[i];
    if (!c.unbounded_significant || c.significant) continue;
    bool later = false;
    for (size_t k = i + 1; k < d.candidates.size(); ++k) {
      const trainer::CandidateScore& o = d.candidates[k];
      later = later || (o.unbounded_significant && !o.significant &&
                        o.mechanism.kind == c.mechanism.kind && o.mechanism.joint == c.mechanism.joint &&
                        o.mechanism.source_joint == c.mechanism.source_joint);
    }
    if (!later) lines.push_back(impossibleText(c));
  }
  return lines;
}

// The candidates not named because a joint's torque modulated by its angle explained their gain:
// one line per candidate (its last round's test), in the order of the candidates.
std::vector<std::string> standInLines(const trainer::Diagnosis& d) {
  std::vector<std::string> names, lines;
  for (const trainer::CandidateScore& c : d.candidates) {
    const trainer::CandidateScore::ModulatedStandIn& s = c.modulated_stand_in;
    if (s.joint < 0) continue;
    const std::string name = describe(c.mechanism);
    const std::string line = format(
        "%s: stands in for a stiffness that varies with joint %d's angle (round %d: the joint's "
        "torque times harmonics 1-%d of its angle adds %.4f mm held out beside it, z %.1f; it "
        "adds %.4f mm beside them, z %.1f), which the catalogue does not hold (left to the "
        "residual)",
        name.c_str(), s.joint + 1, c.round, s.modulated_order, s.modulated_gain_mm, s.modulated_z,
        s.gain_mm, s.z);
    const auto at = std::find(names.begin(), names.end(), name);
    if (at == names.end()) {
      names.push_back(name);
      lines.push_back(line);
    } else {
      lines[static_cast<size_t>(at - names.begin())] = line;
    }
  }
  return lines;
}

// The causes chosen significant only beside a joint's torque modulated by its angle (the
// round's causes significant alone all stood in for it): one line each.
std::vector<std::string> besideModulatedLines(const trainer::Diagnosis& d) {
  std::vector<std::string> lines;
  for (const trainer::CandidateScore& c : d.candidates) {
    const trainer::CandidateScore::BesideModulated& b = c.beside_modulated;
    if (b.joint < 0 || !c.chosen) continue;
    lines.push_back(format(
        "%s, round %d, is significant only beside a stiffness that varies with joint %d's angle "
        "(beside the joint's torque times harmonics 1-%d of its angle it adds %.4f mm held out, "
        "%.1f %% of the round's error, z %.1f; alone z %.1f)",
        describe(c.mechanism).c_str(), c.round, b.joint + 1, b.modulated_order, b.gain_mm,
        100.0 * b.reduction, b.z, c.z_statistic));
  }
  return lines;
}

std::vector<std::string> identifiabilityLines(const trainer::Diagnosis& d) {
  std::vector<std::string> lines;
  for (const trainer::ModelChange& c : d.changes) {
    using Kind = trainer::ModelChange::Kind;
    switch (c.kind) {
      case Kind::kComplianceHeldAtZero:
        lines.push_back(format("joint %d's compliance refitted with the rest goes below zero "
                               "(%.3g rad/(N·m) without its bound): held at zero, the data show "
                               "no deflection of it under load",
                               c.joint + 1, c.compliance_rad_per_nm));
        break;
      case Kind::kDroppedWrongSign:
        lines.push_back(describe(c.mechanism) + ": dropped, its " + parameterNames(c.mechanism)[0] +
                        " goes below zero once refitted with the other causes found (another of "
                        "them explains what it did)");
        break;
      case Kind::kPartDroppedWrongSign:
        lines.push_back(describe(c.mechanism) +
                        ": the parts whose lost motion or extra compliance go below zero once "
                        "refitted with the other causes were removed; kept as " +
                        describe(c.kept) + " (" + parameterText(c.kept) + ")");
        break;
      case Kind::kDroppedExplained:
        lines.push_back(describe(c.mechanism) +
                        format(": dropped, the causes named after it explain what it did (tried "
                               "again with them in the model it removes %.1f %% of the held-out "
                               "error, z = %.1f: not significant)",
                               100.0 * c.relative_reduction, c.z_statistic));
        break;
      case Kind::kDroppedWithoutSize:
        lines.push_back(describe(c.mechanism) +
                        format(": dropped, the final fit leaves it without a size (what the data "
                               "identify of it, %d direction(s), lies within one σ of zero: "
                               "chi2 %.2f); the other causes stand without it",
                               c.size_dof, c.size_chi2));
        break;
    }
  }
  for (const trainer::FoundEffect& f : d.effects) {
    for (const Mechanism& other : f.alternatives) {
      lines.push_back(describe(f.mechanism) + " and " + describe(other) +
                      " explain the same error: the second removed nearly as much held-out error "
                      "as the first (at least 80 %), and nothing once the first was in the model; "
                      "these rows cannot tell them apart (the first was named)");
    }
  }
  for (const trainer::FoundEffect& f : d.effects) {
    const Mechanism& m = f.mechanism;
    if (m.kind == MechanismKind::kTransmissionError) {
      if (!f.harmonics_separable) {
        lines.push_back(describe(m) +
                        format(": its harmonics cannot be told apart on the angles it covers (the "
                               "largest amplitude, %.0f urad, is %.0f times its RMS of %.0f urad: "
                               "they cancel each other there); its values over those angles are "
                               "determined, its single harmonics are not",
                               1e6 * f.largest_amplitude_rad, f.largest_amplitude_rad / f.rms_rad,
                               1e6 * f.rms_rad));
      }
      std::string shared;
      for (size_t k = 0; k < f.geometry_share.size(); ++k) {
        if (f.geometry_share[k] < 0.5) continue;
        shared += format("%s%zu %.0f %%", shared.empty() ? "harmonic " : ", ", k + 1,
                         100.0 * f.geometry_share[k]);
      }
      if (!shared.empty()) {
        lines.push_back(describe(m) + ": " + shared +
                        " within reach of a geometric error on these rows (a tilt, offset or "
                        "eccentricity of the joint): the profile and the geometry were fitted "
                        "together and the ridge keeps what they share small; what the geometry "
                        "took of the profile is its profile_geometry, switched with it");
      }
    } else if (m.kind == MechanismKind::kOffAxisCompliance) {
      lines.push_back(offAxisLine(d, m));
    } else if (m.kind == MechanismKind::kToolMountCompliance) {
      lines.push_back(toolMountLine(m));
    } else if (m.kind == MechanismKind::kSelfWeight && !f.gravity_torque_std_nm.empty()) {
      std::string text =
          "self_weight: link masses and centres of mass from the URDF; the compliance of joint(s)";
      for (int j : f.gravity_loaded_joints) text += format(" %d", j + 1);
      text += " is identified from the arm's own weight";
      for (int j : f.weak_gravity_joints) {
        text += format("; joint %d's gravity torque varies by %.2f N·m (std), too little for its "
                       "compliance",
                       j + 1, f.gravity_torque_std_nm[static_cast<size_t>(j)]);
      }
      lines.push_back(text);
    } else if (m.kind == MechanismKind::kSelfWeight) {
      lines.push_back(
          "self_weight: only the gravity torques of the lumped link masses on the compliant joints "
          "are identifiable; the masses themselves are a representative (a weak prior of 50 kg, "
          "50 kg·m holds the rest near zero)");
    }
  }
  return lines;
}

}  // namespace

// A registration drift in a line: its span and how far it turns the tracker's frame and moves
// the measured tip (its 6·degree coefficients are in the JSON).
std::string registrationDriftText(const trainer::FoundEffect& e) {
  const Mechanism& m = e.mechanism;
  const mechanism::RegistrationDrift<const double> span = view<mechanism::RegistrationDrift>(m);
  const double first = span.firstSeq(), last = span.lastSeq();
  double largest_turn_rad = 0.0;
  constexpr int kSamples = 200;
  for (int i = 0; i <= kSamples; ++i) {
    const Vec6 xi = registrationDrift(m, first + (last - first) * i / kSamples);
    largest_turn_rad = std::max(largest_turn_rad, xi.tail<3>().norm());
  }
  return format("seq %.0f .. %.0f; the tracker's frame turns by up to %.0f urad, the measured "
                "tip moves by %.4f mm RMS, %.4f mm at most",
                first, last, 1e6 * largest_turn_rad, kMmPerM * e.tip_motion_rms_m,
                kMmPerM * e.tip_motion_max_m);
}

std::string effectParameterText(const trainer::FoundEffect& e) {
  if (e.mechanism.kind == MechanismKind::kRegistrationDrift) return registrationDriftText(e);
  if (!e.compliance_joints.empty()) {  // self weight with the URDF's masses
    std::string masses = "link masses from the URDF (kg:";
    const int links = static_cast<int>(e.mechanism.parameters.size()) / mechanism::SelfWeight<double>::kPerLink;
    for (int k = 1; k <= links; ++k) {
      masses += format(" %.3g", view<mechanism::SelfWeight>(e.mechanism).mass_kg(k));
    }
    return masses + ")";
  }
  return e.harmonics_separable ? parameterText(e.mechanism)
                               : "harmonics not separable on its angles; " + coverageText(e.mechanism);
}

std::string torqueCurveText(const trainer::FoundEffect& e) {
  if (!isTorqueDeflection(e.mechanism.kind) || e.stiffness_segments.empty()) return {};
  std::string out = "stiffness";
  for (size_t i = 0; i < e.stiffness_segments.size(); ++i) {
    const auto& s = e.stiffness_segments[i];
    out += format("%s %.0f..%.0f N·m %.3g", i == 0 ? "" : ",", s.from_nm, s.to_nm,
                  s.stiffness_nm_per_rad);
  }
  return out + format(" N·m/rad (lost motion apart); identified up to %.0f N·m, the largest "
                      "torque on the fit rows",
                      e.max_torque_nm);
}

std::string selfWeightComplianceText(const trainer::Diagnosis& d, int joint) {
  return format("joint %d compliance %.3g rad/(N·m) ± %.2g, from the arm's own weight", joint + 1,
                d.extended_model.compliance_rad_per_nm(joint),
                d.extended_model.compliance_sigma_rad_per_nm(joint));
}

std::string transmissionSummary(const Mechanism& m) {
  std::string out = "strongest";
  const std::vector<int> top = strongestHarmonics(m, 3);
  for (size_t i = 0; i < top.size(); ++i) {
    out += format("%s h%d %.0f", i == 0 ? "" : ",", top[i], 1e6 * amplitude(m, top[i]));
  }
  return out + " urad; " + coverageText(m);
}

std::string profileGeometrySummary(const Mechanism& m) {
  double v = 0.0, w = 0.0;
  for (int k = 0; 6 * (k + 1) <= static_cast<int>(m.parameters.size()); ++k) {
    const Eigen::Map<const Vec6> delta = view<mechanism::ProfileGeometry>(m).poseDelta(k);
    v = std::max(v, std::hypot(delta(0), delta(1), delta(2)));
    w = std::max(w, std::hypot(delta(3), delta(4), delta(5)));
  }
  return format("initial poses moved by up to %.0f um, %.0f urad where joint %d's profile holds",
                1e6 * v, 1e6 * w, m.joint + 1);
}

std::string coverageText(const Mechanism& m) {
  std::string out = "covers";
  if (m.coverage.arcs_rad.empty()) return out + " every angle";
  for (size_t i = 0; i + 1 < m.coverage.arcs_rad.size(); i += 2) {
    const double from = kDegPerRad * m.coverage.arcs_rad[i];
    out += format("%s %.0f..%.0f", i == 0 ? "" : ",", from,
                  from + kDegPerRad * m.coverage.arcs_rad[i + 1]);
  }
  return out + " deg";
}

nlohmann::json parametersJson(const Mechanism& mechanism, const std::vector<double>& values) {
  const std::vector<std::string> names = parameterNames(mechanism);
  nlohmann::json j = nlohmann::json::object();
  for (size_t i = 0; i < names.size() && i < values.size(); ++i) j[names[i]] = values[i];
  return j;
}

std::string campaignFrameText(const Mechanism& m, bool tool) {
  using Frames = mechanism::SessionFrames<const double>;
  const size_t first = tool ? Frames::kTool : Frames::kStation;
  const auto largest = [&](size_t from) {
    return std::max({m.sigma[from], m.sigma[from + 1], m.sigma[from + 2]});
  };
  // A value that rounds to zero at the digits printed is printed as 0, not -0.
  const auto shown = [](double value, double unit) { return std::abs(value) < 0.5 * unit ? 0.0 : value; };
  const Frames frames = view<mechanism::SessionFrames>(m);
  const auto value = [&](int i) { return tool ? frames.tool(i) : frames.station(i); };  // t, r
  const auto mm = [&](int i) { return shown(kMmPerM * value(i), 1e-3); };
  const auto deg = [&](int i) { return shown(kDegPerRad * value(i), 1e-4); };
  return format("t (%.3f, %.3f, %.3f) mm ± %.2g, r (%.4f, %.4f, %.4f) deg ± %.2g", mm(0), mm(1),
                mm(2), kMmPerM * largest(first), deg(3), deg(4), deg(5), kDegPerRad * largest(first + 3));
}

namespace {

// Joint j's zero in campaign k (from 0) against the first's, e.g. "joint 2's zero differs from
// the first campaign's by +1593.2 ± 60.1 urad".
std::string campaignZeroText(const Mechanism& m, size_t k) {
  return format("joint %d's zero differs from the first campaign's by %+.1f ± %.1f urad", m.joint + 1,
                1e6 * view<mechanism::CampaignJointZero>(m).offset_rad(static_cast<int>(k)),
                1e6 * m.sigma[static_cast<size_t>(mechanism::CampaignJointZero<double>::offsetIndex(static_cast<int>(k)))]);
}

std::string campaignsText(const trainer::Diagnosis& d) {
  if (d.campaigns.empty()) return "";
  std::string out =
      "\nCampaigns fitted together (one robot; each later campaign its own tracker station and "
      "tool against the first's; fit rows' mean position error, starting model refitted -> "
      "extended):\n";
  for (size_t k = 0; k < d.campaigns.size(); ++k) {
    const trainer::DiagnosedCampaign& c = d.campaigns[k];
    out += format("  %zu %s: %d fit rows, %.4f -> %.4f mm", k + 1, c.directory.c_str(), c.fit_rows,
                  kMmPerM * c.before_mean_m, kMmPerM * c.after_mean_m);
    if (c.frames.parameters.empty()) {
      out += "; the extended model's tracker, tool and joint zeros\n";
      continue;
    }
    out += "\n    station " + campaignFrameText(c.frames, false) + "\n    tool    " +
           campaignFrameText(c.frames, true) + "\n";
    for (const trainer::FoundEffect& e : d.effects) {
      if (e.mechanism.kind != MechanismKind::kCampaignJointZero) continue;
      out += "    " + campaignZeroText(e.mechanism, k) + "\n";
    }
    for (const trainer::CampaignProfileDifference& p : c.profile_differences) {
      const trainer::CandidateScore& s = p.score;
      out += format("    joint %d's profile: %s (its own here removes %.1f %% held out, %.4f mm, "
                    "z %.1f; RMS difference %.0f urad)\n",
                    s.mechanism.joint + 1, s.significant ? "differs here" : "one serves both",
                    100.0 * s.relative_reduction, s.cv_gain_mm, s.z_statistic, 1e6 * p.rms_rad);
    }
  }
  return out;
}

nlohmann::json frameJson(const Mechanism& m, size_t first) {
  const std::vector<double>& p = m.parameters;
  const std::vector<double>& s = m.sigma;
  return {{"translation_mm", {kMmPerM * p[first], kMmPerM * p[first + 1], kMmPerM * p[first + 2]}},
          {"translation_sigma_mm", {kMmPerM * s[first], kMmPerM * s[first + 1], kMmPerM * s[first + 2]}},
          {"rotation_deg",
           {kDegPerRad * p[first + 3], kDegPerRad * p[first + 4], kDegPerRad * p[first + 5]}},
          {"rotation_sigma_deg",
           {kDegPerRad * s[first + 3], kDegPerRad * s[first + 4], kDegPerRad * s[first + 5]}}};
}

}  // namespace

std::string loadModulatedProfileText(const trainer::LoadModulatedProfile& f) {
  const std::string both = format(
      "the profile's harmonics up to %d times joint %d's torque (std %.0f N·m over the fit rows) "
      "remove %.1f %% of the held-out error beside the profile of order %d (z %.1f), the profile "
      "%.1f %% beside them (z %.1f)",
      f.modulated_order, f.joint + 1, f.torque_std_nm, 100.0 * f.modulated_reduction, f.order, f.modulated_z,
      100.0 * f.profile_reduction, f.profile_z);
  if (f.profile_named) {
    return format("transmission_error (joint %d) named, and a part that follows its angle in "
                  "proportion to its torque is left: ",
                  f.joint + 1) +
           both;
  }
  return format("no transmission_error named on joint %d: its error follows the angle in "
                "proportion to the joint's torque, a stiffness that varies with the angle, which "
                "the catalogue does not hold (left to the residual): ",
                f.joint + 1) +
         both + ", not significant";
}

std::string formatDiagnosis(const trainer::Diagnosis& d, double seconds_calibrate) {
  std::string out = format(
      "diagnosis on %d fit rows (%d poses, %d-fold cross-validation over poses), %d validation "
      "rows\n\n",
      d.fit_rows, d.fit_poses, d.folds, d.validation_rows);
  out += "What the physical model (geometry + compliance, refitted on every fit row) gets wrong\n";
  out += statisticsText("  before", d.before);
  out += "\nCandidates that stood out (held-out gain, signed-rank z; significant = family-wise 1 %):\n";
  std::vector<const trainer::CandidateScore*> sorted;
  for (const auto& c : d.candidates) sorted.push_back(&c);
  std::stable_sort(sorted.begin(), sorted.end(), [](const auto* a, const auto* b) {
    return a->round != b->round ? a->round < b->round : a->z_statistic > b->z_statistic;
  });
  int round = 0, shown = 0;
  for (const trainer::CandidateScore* c : sorted) {
    if (c->round != round) {
      round = c->round;
      shown = 0;
      out += format("  round %d\n", round);
    }
    if (shown++ >= 5 && !c->chosen) continue;
    out += format("    %-42s gain %8.4f mm  removes %5.1f %%  z %7.1f  %s\n",
                  describe(c->mechanism).c_str(), c->cv_gain_mm, 100.0 * c->relative_reduction,
                  c->z_statistic,
                  c->chosen ? "chosen" : c->significant ? "significant" : "");
    if (c->unbounded_significant && !c->significant) out += "      " + impossibleText(*c) + "\n";
  }
  for (const auto& u : d.untestable) {
    out += format("  not tried: %s (%s)\n", u.name.c_str(), u.reason.c_str());
  }
  out += format("\nVerdict: %s\n", toString(d.verdict));
  for (const trainer::FoundEffect& e : d.effects) {
    out += format("  round %d, %s: ", e.round, describe(e.mechanism).c_str());
    if (e.mechanism.kind == MechanismKind::kTransmissionError) {
      out += format("RMS %.0f urad over the fit rows, ", 1e6 * e.rms_rad);
    }
    out += format("%s (held-out gain %.4f mm, z %.1f)\n", effectParameterText(e).c_str(), e.cv_gain_mm,
                  e.z_statistic);
    for (int j : e.compliance_joints) out += "    " + selfWeightComplianceText(d, j) + "\n";
    if (const std::string curve = torqueCurveText(e); !curve.empty()) out += "    " + curve + "\n";
  }
  for (const std::string& line : impossibleLines(d)) out += "  not named: " + line + "\n";
  for (const std::string& line : standInLines(d)) out += "  not named: " + line + "\n";
  for (const std::string& line : besideModulatedLines(d)) out += "  beside a varying stiffness: " + line + "\n";
  for (const std::string& line : identifiabilityLines(d)) out += "  identifiability: " + line + "\n";
  for (const trainer::LoadModulatedProfile& f : d.load_modulated_profiles) {
    out += "  profile or load: " + loadModulatedProfileText(f) + "\n";
  }
  for (const std::string& line : familyPairLines(d)) out += "  cannot be told apart: " + line + "\n";
  if (!d.drift.text.empty()) out += "  drift: " + d.drift.text + "\n";
  if (!d.unexplained_trend.empty()) {
    out += "  " + std::string(d.verdict == trainer::Verdict::kUnexplained
                                  ? "unexplained structure: "
                                  : "structure left after the effects: ") +
           d.unexplained_trend + "\n";
  }
  out += unexplainedText(d.unexplained);
  if (!d.effects.empty()) out += "\n" + statisticsText("  after", d.after);
  out += campaignsText(d);
  if (const std::string pin = geometryPinText(d.geometry_pin); !pin.empty()) {
    out += "\nThe extended model's geometry: " + pin + "\n";
  }

  out += format("\nThe extended model's GPR: %d training rows, held-out reduction z %.1f: %s\n",
                d.extended_gpr_rows, d.extended_gpr_z,
                d.extended_gpr_taken ? "taken" : "not taken (it does not predict the residual on rows it was not fitted on)");
  if (!d.gain.empty()) {
    out += format(
        "\nGain on validation rows (position mean / max mm, orientation mean deg; noise floor "
        "%.4f mm)\n",
        kMmPerM * d.floor_position_m);
    out += format("  %7s %5s  %-22s  %-22s  %-22s  %-22s\n", "load", "rows", "before (physical)",
                  "after (extended)",
                  d.gpr_method.empty() ? "(no GPR)" : d.gpr_method.c_str(), "extended+gpr");
    auto cell = [](const trainer::AccuracySummary& s) {
      if (s.rows == 0) return format("%-22s", "-");
      return format("%7.4f %7.4f %6.4f", kMmPerM * s.mean_position_m, kMmPerM * s.max_position_m,
                    kDegPerRad * s.mean_orientation_rad);
    };
    for (const trainer::GainRow& g : d.gain) {
      out += format("  %4.0f kg %5d  %s  %s  %s  %s\n", g.load_kg, g.rows, cell(g.before).c_str(),
                    cell(g.after).c_str(), cell(g.gpr).c_str(), cell(g.after_gpr).c_str());
    }
  }
  out += format(
      "\nTime: calibration %.2f s, joint refits %.2f s, candidate screening %.2f s, trends "
      "%.2f s, GPR %.2f s, evaluation %.2f s\n",
      seconds_calibrate, d.seconds_refit, d.seconds_screening, d.seconds_trends, d.seconds_gpr,
      d.seconds_evaluation);
  return out;
}

namespace {

// diagnosisJson's sections, one function each.

nlohmann::json effectJson(const trainer::FoundEffect& e, const trainer::Diagnosis& d) {
  nlohmann::json x = mechanismJson(e.mechanism, e.geometry_share);
  if (e.mechanism.kind == MechanismKind::kTransmissionError) {
    x["rms_urad"] = 1e6 * e.rms_rad;
    x["ridge"] = e.ridge;
    x["harmonics_separable"] = e.harmonics_separable;
  }
  if (!e.compliance_joints.empty()) {
    x["compliance"] = nlohmann::json::array();
    for (int j : e.compliance_joints) {
      x["compliance"].push_back(
          {{"joint", j + 1},
           {"compliance_rad_per_nm", d.extended_model.compliance_rad_per_nm(j)},
           {"sigma_rad_per_nm", d.extended_model.compliance_sigma_rad_per_nm(j)}});
    }
  }
  x["alternatives"] = nlohmann::json::array();
  for (const Mechanism& m : e.alternatives) x["alternatives"].push_back(describe(m));
  x["cv_gain_mm"] = e.cv_gain_mm;
  x["z_statistic"] = e.z_statistic;
  x["p_value"] = e.p_value;
  x["round"] = e.round;
  x["size_chi2"] = e.size_chi2;
  x["size_dof"] = e.size_dof;
  if (e.mechanism.kind == MechanismKind::kRegistrationDrift ||
      e.mechanism.kind == MechanismKind::kJointZeroDrift) {
    x["tip_motion_rms_mm"] = kMmPerM * e.tip_motion_rms_m;
    x["tip_motion_max_mm"] = kMmPerM * e.tip_motion_max_m;
    x["applied_to_corrections"] = !isMeasurementOnly(e.mechanism.kind);
  }
  if (isTorqueDeflection(e.mechanism.kind)) {
    x["max_torque_nm"] = e.max_torque_nm;
    x["stiffness_segments"] = nlohmann::json::array();
    for (const auto& s : e.stiffness_segments) {
      x["stiffness_segments"].push_back({{"from_nm", s.from_nm},
                                         {"to_nm", s.to_nm},
                                         {"stiffness_nm_per_rad", s.stiffness_nm_per_rad}});
    }
  }
  return x;
}

nlohmann::json candidateJson(const trainer::CandidateScore& c) {
  nlohmann::json x = mechanismJson(c.mechanism);
  x["round"] = c.round;
  x["configurations"] = c.configurations;
  if (c.mechanism.kind == MechanismKind::kTransmissionError) x["ridge"] = c.ridge;
  x["cv_gain_mm"] = c.cv_gain_mm;
  x["relative_reduction"] = c.relative_reduction;
  x["z_statistic"] = c.z_statistic;
  x["p_value"] = c.p_value;
  x["significant"] = c.significant;
  x["chosen"] = c.chosen;
  if (!c.physical) x["physical"] = false;
  if (!c.impossible_unbounded.empty()) {
    x["impossible_unbounded"] = {{"reason", c.impossible_unbounded},
                                 {"cv_gain_mm", c.unbounded_cv_gain_mm},
                                 {"z_statistic", c.unbounded_z_statistic},
                                 {"significant", c.unbounded_significant}};
  }
  if (const trainer::CandidateScore::ModulatedStandIn& m = c.modulated_stand_in; m.joint >= 0) {
    x["modulated_stand_in"] = {{"joint", m.joint + 1},
                               {"modulated_order", m.modulated_order},
                               {"modulated_cv_gain_mm", m.modulated_gain_mm},
                               {"modulated_relative_reduction", m.modulated_reduction},
                               {"modulated_z_statistic", m.modulated_z},
                               {"cv_gain_mm", m.gain_mm},
                               {"relative_reduction", m.reduction},
                               {"z_statistic", m.z}};
  }
  if (const trainer::CandidateScore::BesideModulated& b = c.beside_modulated; b.joint >= 0) {
    x["beside_modulated"] = {{"joint", b.joint + 1},
                             {"modulated_order", b.modulated_order},
                             {"cv_gain_mm", b.gain_mm},
                             {"relative_reduction", b.reduction},
                             {"z_statistic", b.z}};
  }
  return x;
}

// A time-order family's test beside what moves with its driver (diagnose.hpp, ConfoundTest).
nlohmann::json confoundTestJson(const trainer::ConfoundTest& t) {
  nlohmann::json x = {{"name", toString(t.mechanism.kind)},
                      {"joint", t.mechanism.joint >= 0 ? nlohmann::json(t.mechanism.joint + 1)
                                                       : nlohmann::json(nullptr)},
                      {"order", t.mechanism.order > 0 ? nlohmann::json(t.mechanism.order)
                                                      : nlohmann::json(nullptr)},
                      {"round", t.round},
                      {"driver", t.driver},
                      {"z_statistic", t.z_statistic},
                      {"told_apart", t.told_apart},
                      {"beside", nlohmann::json::array()}};
  for (const trainer::ConfoundTest::Beside& b : t.beside) {
    x["beside"].push_back({{"variable", b.variable},
                           {"r", b.r},
                           {"cv_gain_mm", b.cv_gain_mm},
                           {"relative_reduction", b.relative_reduction},
                           {"z_statistic", b.z_statistic},
                           {"p_value", b.p_value},
                           {"told_apart", b.told_apart}});
  }
  return x;
}

nlohmann::json driftJson(const trainer::DriftVerdict& drift) {
  nlohmann::json zero_drift = nlohmann::json::array();
  for (int joint : drift.zero_drift_joints) zero_drift.push_back(joint + 1);
  nlohmann::json correlations = nlohmann::json::array();
  for (const trainer::DriverCorrelation& c : drift.time_order_correlations) {
    correlations.push_back({{"variable", c.variable}, {"r", c.r}});
  }
  nlohmann::json tests = nlohmann::json::array();
  for (const trainer::ConfoundTest& t : drift.confound_tests) tests.push_back(confoundTestJson(t));
  return {{"registration", drift.registration},
          {"zero_drift_joints", zero_drift},
          {"seq_temp_correlation", std::isfinite(drift.seq_temp_correlation)
                                       ? nlohmann::json(drift.seq_temp_correlation)
                                       : nlohmann::json(nullptr)},
          {"time_order_correlations", correlations},
          {"confound_tests", tests},
          {"text", drift.text}};
}

nlohmann::json residualStatisticsJson(const trainer::ResidualStatistics& s) {
  nlohmann::json x = {{"rows", s.rows},
                      {"mean_position_mm", kMmPerM * s.mean_position_m},
                      {"rms_position_mm", kMmPerM * s.rms_position_m},
                      {"max_position_mm", kMmPerM * s.max_position_m},
                      {"rms_orientation_deg", kDegPerRad * s.rms_orientation_rad},
                      {"noise_ratio", s.noise_ratio}};
  x["trends"] = nlohmann::json::array();
  for (const trainer::TrendScore& t : s.trends) {
    x["trends"].push_back({{"variable", t.variable},
                           {"cv_gain_mm", t.cv_gain_mm},
                           {"z_statistic", t.z_statistic},
                           {"p_value", t.p_value},
                           {"significant", t.significant}});
  }
  return x;
}

nlohmann::json campaignJson(const trainer::DiagnosedCampaign& c) {
  nlohmann::json x = {{"directory", c.directory},
                      {"fit_rows", c.fit_rows},
                      {"before_mean_position_mm", kMmPerM * c.before_mean_m},
                      {"after_mean_position_mm", kMmPerM * c.after_mean_m}};
  if (!c.frames.parameters.empty()) {
    x["station"] = frameJson(c.frames, 0);
    x["tool"] = frameJson(c.frames, 6);
  }
  x["profile_differences"] = nlohmann::json::array();
  for (const trainer::CampaignProfileDifference& p : c.profile_differences) {
    const trainer::CandidateScore& s = p.score;
    x["profile_differences"].push_back({{"joint", s.mechanism.joint + 1},
                                        {"order", s.mechanism.order},
                                        {"ridge", s.ridge},
                                        {"cv_gain_mm", s.cv_gain_mm},
                                        {"relative_reduction", s.relative_reduction},
                                        {"z_statistic", s.z_statistic},
                                        {"p_value", s.p_value},
                                        {"significant", s.significant},
                                        {"rms_difference_urad", 1e6 * p.rms_rad}});
  }
  return x;
}

nlohmann::json loadModulatedProfileJson(const trainer::LoadModulatedProfile& f) {
  return {{"joint", f.joint + 1},
          {"order", f.order},
          {"modulated_order", f.modulated_order},
          {"round", f.round},
          {"profile_named", f.profile_named},
          {"torque_std_nm", f.torque_std_nm},
          {"modulated",
           {{"cv_gain_mm", f.modulated_gain_mm},
            {"relative_reduction", f.modulated_reduction},
            {"z_statistic", f.modulated_z},
            {"p_value", f.modulated_p}}},
          {"profile",
           {{"cv_gain_mm", f.profile_gain_mm},
            {"relative_reduction", f.profile_reduction},
            {"z_statistic", f.profile_z},
            {"p_value", f.profile_p}}},
          {"text", loadModulatedProfileText(f)}};
}

/// A validation load's row of the gain table; null where a model has no rows there.
nlohmann::json gainRowJson(const trainer::GainRow& g) {
  auto optional_mm = [](const trainer::AccuracySummary& s, double v) {
    return s.rows > 0 ? nlohmann::json(kMmPerM * v) : nlohmann::json(nullptr);
  };
  auto optional_deg = [](const trainer::AccuracySummary& s, double v) {
    return s.rows > 0 ? nlohmann::json(kDegPerRad * v) : nlohmann::json(nullptr);
  };
  return {
      {"load_kg", g.load_kg},
      {"rows", g.rows},
      {"before_mean_position_mm", optional_mm(g.before, g.before.mean_position_m)},
      {"after_mean_position_mm", optional_mm(g.after, g.after.mean_position_m)},
      {"gpr_mean_position_mm", optional_mm(g.gpr, g.gpr.mean_position_m)},
      {"after_gpr_mean_position_mm", optional_mm(g.after_gpr, g.after_gpr.mean_position_m)},
      {"before_max_position_mm", optional_mm(g.before, g.before.max_position_m)},
      {"after_max_position_mm", optional_mm(g.after, g.after.max_position_m)},
      {"gpr_max_position_mm", optional_mm(g.gpr, g.gpr.max_position_m)},
      {"before_mean_orientation_deg", optional_deg(g.before, g.before.mean_orientation_rad)},
      {"after_mean_orientation_deg", optional_deg(g.after, g.after.mean_orientation_rad)},
      {"gpr_mean_orientation_deg", optional_deg(g.gpr, g.gpr.mean_orientation_rad)},
  };
}

}  // namespace

nlohmann::json diagnosisJson(const trainer::Diagnosis& d, double seconds_calibrate) {
  nlohmann::json j;
  j["verdict"] = toString(d.verdict);
  j["effects"] = nlohmann::json::array();
  for (const trainer::FoundEffect& e : d.effects) j["effects"].push_back(effectJson(e, d));
  j["candidates"] = nlohmann::json::array();
  for (const trainer::CandidateScore& c : d.candidates) j["candidates"].push_back(candidateJson(c));
  j["untestable"] = nlohmann::json::array();
  for (const auto& u : d.untestable) j["untestable"].push_back({{"name", u.name}, {"reason", u.reason}});
  j["identifiability"] = identifiabilityLines(d);
  j["extended_gpr"] = {{"training_rows", d.extended_gpr_rows},
                       {"z_statistic", d.extended_gpr_z},
                       {"taken", d.extended_gpr_taken}};
  j["unexplained_trend"] =
      d.unexplained_trend.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.unexplained_trend);
  if (!d.load_modulated_profiles.empty()) {
    j["load_modulated_profiles"] = nlohmann::json::array();
    for (const trainer::LoadModulatedProfile& f : d.load_modulated_profiles) {
      j["load_modulated_profiles"].push_back(loadModulatedProfileJson(f));
    }
  }
  j["family_pairs"] = familyPairsJson(d);
  j["geometry_pin"] = geometryPinJson(d.geometry_pin);
  j["drift"] = driftJson(d.drift);
  j["unexplained"] = unexplainedJson(d.unexplained);
  j["residual"] = {{"before", residualStatisticsJson(d.before)},
                   {"after", residualStatisticsJson(d.after)}};
  j["campaigns"] = nlohmann::json::array();
  for (const trainer::DiagnosedCampaign& c : d.campaigns) j["campaigns"].push_back(campaignJson(c));
  j["gpr_method"] = d.gpr_method;
  j["noise_floor_position_mm"] = kMmPerM * d.floor_position_m;
  j["gain"] = nlohmann::json::array();
  for (const trainer::GainRow& g : d.gain) j["gain"].push_back(gainRowJson(g));
  j["timing_s"] = {{"calibration", seconds_calibrate},     {"refit", d.seconds_refit},
                   {"screening", d.seconds_screening},     {"trends", d.seconds_trends},
                   {"gpr", d.seconds_gpr},                 {"evaluation", d.seconds_evaluation}};
  return j;
}

}  // namespace stepcal::report
