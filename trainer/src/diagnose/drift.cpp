// What drifted while the campaign was measured (search.hpp, DriftVerdict): the tracker's
// registration in time order, a joint's zero with temperature, and what the rows tell apart.
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "search.hpp"
#include "stepcal/common/mechanisms/joint_zero_drift.hpp"

#include "stepcal/common/units.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Above this |r| between temp_c and the time order the two act at the same rows.
constexpr double kAlikeCorrelation = 0.8;

std::string printed(const char* fmt, double a, double b = 0.0, double c = 0.0) {
  char text[400];
  std::snprintf(text, sizeof text, fmt, a, b, c);
  return text;
}

// Pearson correlation of temp_c and seq over the rows with a temperature (NaN: not defined).
double seqTemperatureCorrelation(const FitRows& fit) {
  double n = 0.0, st = 0.0, ss = 0.0, stt = 0.0, sss = 0.0, sts = 0.0;
  for (const Measurement* row : fit.rows) {
    if (!row->temp_c) continue;
    const double t = *row->temp_c, s = static_cast<double>(row->seq);
    n += 1.0;
    st += t;
    ss += s;
    stt += t * t;
    sss += s * s;
    sts += t * s;
  }
  const double var_t = stt - st * st / n, var_s = sss - ss * ss / n;
  if (n < 3.0 || !(var_t > 0.0) || !(var_s > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return (sts - st * ss / n) / std::sqrt(var_t * var_s);
}

// What the last round said of a kind not found: not tried (and why), no effect, or its best
// candidate's score.
std::string notFound(const Diagnosis& d, MechanismKind kind, const char* what) {
  const std::string name = toString(kind);
  for (const UntestableCandidate& u : d.untestable) {
    if (u.name.rfind(name, 0) == 0) return std::string(what) + " could not be tried (" + u.reason + ")";
  }
  int last_round = 0;
  for (const CandidateScore& c : d.candidates) last_round = std::max(last_round, c.round);
  const CandidateScore* best = nullptr;
  for (const CandidateScore& c : d.candidates) {
    if (c.round == last_round && c.mechanism.kind == kind &&
        (best == nullptr || c.z_statistic > best->z_statistic)) {
      best = &c;
    }
  }
  if (best == nullptr) return std::string(what) + " was not among the last round's candidates";
  return std::string(what) + " is not significant" +
         (d.effects.empty() ? "" : " beside the effects found") + " (best, " +
         describe(best->mechanism) +
         printed(": removes %.1f %% held out, z %.1f)", 100.0 * best->relative_reduction,
                 best->z_statistic);
}

}  // namespace

void judgeDrift(Search& search) {
  Diagnosis& d = search.d;
  DriftVerdict& v = d.drift;
  v.seq_temp_correlation = seqTemperatureCorrelation(search.fit);
  std::vector<std::string> parts;
  for (const FoundEffect& e : d.effects) {
    const Mechanism& m = e.mechanism;
    if (m.kind == MechanismKind::kRegistrationDrift) {
      v.registration = true;
      parts.push_back("the tracker's registration drifts in time order (" + describe(m) +
                      printed("): the measured tip moves by %.4f mm RMS, %.4f mm at most; the "
                              "measurement's, not the robot's, so it is left out of the model "
                              "file and never applied to corrections",
                              kMmPerM * e.tip_motion_rms_m, kMmPerM * e.tip_motion_max_m));
    } else if (m.kind == MechanismKind::kJointZeroDrift) {
      v.zero_drift_joints.push_back(m.joint);
      parts.push_back("joint " + std::to_string(m.joint + 1) +
                      printed("'s zero drifts with temperature by %.1f ± %.1f urad/K (the tip "
                              "moves by %.4f mm RMS over the rows' temperatures); the runtime "
                              "applies it where a request gives temp_c",
                              1e6 * view<mechanism::JointZeroDrift>(m).driftRate_rad_per_k(),
                              1e6 * m.sigma[mechanism::JointZeroDrift<double>::kDriftRate],
                              kMmPerM * e.tip_motion_rms_m));
    }
    for (const Mechanism& alt : e.alternatives) {
      if (alt.kind == MechanismKind::kRegistrationDrift || alt.kind == MechanismKind::kJointZeroDrift) {
        parts.push_back("the rows cannot tell " + describe(alt) + " from " + describe(m) +
                        ": it removed nearly as much in that round, and nothing once " +
                        describe(m) + " was in");
      }
    }
  }
  if (!v.registration) {
    parts.push_back(notFound(d, MechanismKind::kRegistrationDrift,
                             "a drift of the tracker's registration in time order"));
  }
  if (v.zero_drift_joints.empty()) {
    parts.push_back(notFound(d, MechanismKind::kJointZeroDrift,
                             "a drift of a joint's zero with temperature"));
  }
  if (std::isfinite(v.seq_temp_correlation)) {
    std::string line = printed("temp_c and the time order correlate at r = %.2f over the fit rows",
                               v.seq_temp_correlation);
    if (std::abs(v.seq_temp_correlation) >= kAlikeCorrelation) {
      line += ": a drift with temperature and one in time act on the same rows, and are told "
              "apart only by how they move the tip (the tracker's whole frame, or one joint's "
              "angle)";
    }
    parts.push_back(line);
  }
  for (const TrendScore& t : d.after.trends) {
    if (t.significant && (t.variable == "seq" || t.variable == "temp_c")) {
      parts.push_back("a trend in " + t.variable +
                      printed(" is left (%.4f mm held out, z %.1f): what drifts there has a form "
                              "neither of these takes",
                              t.cv_gain_mm, t.z_statistic));
    }
  }
  v.text.clear();
  for (const std::string& part : parts) v.text += (v.text.empty() ? "" : "; ") + part;
}

}  // namespace stepcal::trainer::diagnosis
