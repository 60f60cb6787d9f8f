// What drifted while the campaign was measured (search.hpp, DriftVerdict): the tracker's
// registration in time order, a joint's zero with temperature, and what the rows tell apart.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "confounds.hpp"
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

// A variable in words: "the load", "joint 2's torque", "the wrench's fz", "the time order".
std::string variableWords(const std::string& name) {
  if (name == "load_kg") return "the load";
  if (name == "temp_c") return "the temperature";
  if (name == "seq") return "the time order";
  if (name.size() > 1 && (name[0] == 'q' || name.rfind("tau", 0) == 0)) {
    const bool angle = name[0] == 'q';
    const std::string joint = name.substr(angle ? 1 : 3, name.find('_') - (angle ? 1 : 3));
    return "joint " + joint + (angle ? "'s angle" : "'s torque");
  }
  return "the wrench's " + name.substr(0, name.find('_'));
}

// The variables beside which a family could not be told apart, with r and its score beside each.
std::string notToldApartFrom(const ConfoundTest& test) {
  std::string words;
  for (const ConfoundTest::Beside& b : test.beside) {
    if (b.told_apart) continue;
    words += (words.empty() ? "" : ", ") + variableWords(b.variable) +
             printed(" (r = %.2f; beside it z %.1f, %.1f %% held out)", b.r, b.z_statistic,
                     100.0 * b.relative_reduction);
  }
  return words;
}

// A test told apart from every variable beside: how many, and the weakest score beside one.
std::string toldApartFromAll(const ConfoundTest& test) {
  const ConfoundTest::Beside* weakest = nullptr;
  for (const ConfoundTest::Beside& b : test.beside) {
    if (weakest == nullptr || b.z_statistic < weakest->z_statistic) weakest = &b;
  }
  const size_t count = test.beside.size();
  return std::string("told apart from what moves with ") +
         (test.driver == "seq" ? "the time order" : "the temperature") +
         printed(" (%.0f variable", static_cast<double>(count)) + (count == 1 ? "" : "s") +
         printed("; alone z %.1f; weakest beside ", test.z_statistic) +
         variableWords(weakest->variable) +
         printed(", r = %.2f: z %.1f, %.1f %% held out)", weakest->r, weakest->z_statistic,
                 100.0 * weakest->relative_reduction);
}

bool sameFamily(const Mechanism& a, const Mechanism& b) {
  return a.kind == b.kind && a.joint == b.joint;
}

// Per time-order family, the test that stands: the one of the round it was named in (at its
// order), else its last round's, the configuration told apart if any, else the strongest alone.
std::vector<ConfoundTest> standingTests(const Diagnosis& d) {
  std::vector<ConfoundTest> standing;
  for (const ConfoundTest& t : d.drift.confound_tests) {
    const FoundEffect* named = nullptr;
    for (const FoundEffect& e : d.effects) {
      if (sameFamily(e.mechanism, t.mechanism)) named = &e;
    }
    if (named && (t.round != named->round || t.mechanism.order != named->mechanism.order)) continue;
    auto it = std::find_if(standing.begin(), standing.end(), [&](const ConfoundTest& s) {
      return sameFamily(s.mechanism, t.mechanism);
    });
    if (it == standing.end()) {
      standing.push_back(t);
      continue;
    }
    const bool later = t.round > it->round;
    const bool better = t.round == it->round &&
                        (t.told_apart != it->told_apart ? t.told_apart
                                                        : t.z_statistic > it->z_statistic);
    if (later || better) *it = t;
  }
  return standing;
}

// How far each candidate confounder moves with the time order over the fit rows, largest first.
std::vector<DriverCorrelation> timeOrderCorrelations(const Search& search) {
  const Evaluation e = evaluate(search.model.combined(), search.fit);
  const std::vector<ConfounderPtr> variables = confounderVariables(search.fit, e);
  std::vector<DriverCorrelation> out;
  const auto seq = std::find_if(variables.begin(), variables.end(),
                                [](const ConfounderPtr& v) { return v->name == "seq"; });
  if (seq == variables.end()) return out;
  for (const ConfounderPtr& v : variables) {
    if (v != *seq) out.push_back({v->name, driverCorrelation((*seq)->values, *v)});
  }
  std::stable_sort(out.begin(), out.end(), [](const DriverCorrelation& a, const DriverCorrelation& b) {
    return a.r > b.r;
  });
  return out;
}

// The confound numbers in a sentence: what moves with the time order, and how far (the three
// that move most by name).
std::string timeOrderLine(const std::vector<DriverCorrelation>& correlations) {
  if (correlations.empty()) return "";
  std::string moving;
  int count = 0;
  for (const DriverCorrelation& c : correlations) {
    if (c.r < 0.3) break;
    if (++count <= 3) {
      moving += (moving.empty() ? "" : ", ") + variableWords(c.variable) + printed(" r = %.2f", c.r);
    }
  }
  if (count == 0) {
    return "nothing else moves with the time order (largest, " +
           variableWords(correlations.front().variable) +
           printed(": r = %.2f)", correlations.front().r);
  }
  if (count > 3) moving += printed(" and %.0f more at r ≥ 0.3", count - 3.0);
  return "what moves with the time order over the fit rows: " + moving;
}

// A time-order family significant alone whose last test could not tell it from a variable.
std::string confoundedLine(const ConfoundTest& t) {
  const bool registration = t.mechanism.kind == MechanismKind::kRegistrationDrift;
  const std::string what =
      registration ? "a trend in time order (" + describe(t.mechanism) + ")"
                   : "joint " + std::to_string(t.mechanism.joint + 1) +
                         "'s zero following the temperature";
  return what +
         printed(", significant alone in round %.0f (z %.1f), that cannot be told apart from ",
                 static_cast<double>(t.round), t.z_statistic) +
         notToldApartFrom(t) + ": not named" +
         (registration ? ", so what it explained stays with the robot's model, not the measurement"
                       : "");
}

}  // namespace

void judgeDrift(Search& search) {
  Diagnosis& d = search.d;
  DriftVerdict& v = d.drift;
  v.seq_temp_correlation = seqTemperatureCorrelation(search.fit);
  v.time_order_correlations = timeOrderCorrelations(search);
  v.confound_tests = standingTests(d);
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
  bool confounded_registration = false, confounded_zero = false;
  for (const ConfoundTest& t : v.confound_tests) {
    const bool named = std::any_of(d.effects.begin(), d.effects.end(), [&](const FoundEffect& e) {
      return sameFamily(e.mechanism, t.mechanism);
    });
    if (named) {
      if (!t.beside.empty()) {
        parts.push_back(describe(t.mechanism) + " is " + toldApartFromAll(t));
      }
      continue;
    }
    if (t.told_apart) continue;
    parts.push_back(confoundedLine(t));
    const bool registration = t.mechanism.kind == MechanismKind::kRegistrationDrift;
    confounded_registration = confounded_registration || registration;
    confounded_zero = confounded_zero || !registration;
  }
  if (!v.registration && !confounded_registration) {
    parts.push_back(notFound(d, MechanismKind::kRegistrationDrift,
                             "a drift of the tracker's registration in time order"));
  }
  if (v.zero_drift_joints.empty() && !confounded_zero) {
    parts.push_back(notFound(d, MechanismKind::kJointZeroDrift,
                             "a drift of a joint's zero with temperature"));
  }
  if (const std::string line = timeOrderLine(v.time_order_correlations); !line.empty()) {
    parts.push_back(line);
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
      const bool confounded = t.variable == "seq" ? confounded_registration : confounded_zero;
      parts.push_back("a trend in " + t.variable +
                      printed(" is left (%.4f mm held out, z %.1f): ", t.cv_gain_mm, t.z_statistic) +
                      (confounded ? "the one above, which the rows cannot tell from what moves "
                                    "with it"
                                  : "what drifts there has a form neither of these takes"));
    }
  }
  v.text.clear();
  for (const std::string& part : parts) v.text += (v.text.empty() ? "" : "; ") + part;
}

}  // namespace stepcal::trainer::diagnosis
