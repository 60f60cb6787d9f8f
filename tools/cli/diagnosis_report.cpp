#include "diagnosis_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "text_format.hpp"

namespace stepcal::cli {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

std::vector<std::string> parameterNames(const Mechanism& m) {
  return mechanismParameterNames(m.kind, static_cast<int>(m.parameters.size() / 4));
}

nlohmann::json mechanismJson(const Mechanism& m) {
  nlohmann::json j;
  j["name"] = toString(m.kind);
  j["joint"] = m.joint >= 0 ? nlohmann::json(m.joint + 1) : nlohmann::json(nullptr);
  j["joints"] = m.source_joint >= 0 ? nlohmann::json::array({m.source_joint + 1, m.joint + 1})
                                    : nlohmann::json(nullptr);
  j["harmonic"] = m.harmonic > 0 ? nlohmann::json(m.harmonic) : nlohmann::json(nullptr);
  j["parameters"] = parametersJson(m, m.parameters);
  return j;
}

// "name = value ± σ" for each parameter, skipping self_weight's links that carry nothing.
std::string parameterText(const Mechanism& m) {
  const std::vector<std::string> names = parameterNames(m);
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) {
    if (m.kind == MechanismKind::kSelfWeight && m.parameters[i] == 0.0) continue;
    out += format("%s%s = %.4g", out.empty() ? "" : ", ", names[i].c_str(), m.parameters[i]);
    if (m.sigma[i] > 0.0) out += format(" ± %.2g", m.sigma[i]);
  }
  return out;
}

std::string statisticsText(const char* title, const trainer::ResidualStatistics& s) {
  std::string out = format(
      "%s: %d fit rows, position error mean %.4f mm, RMS %.4f mm, max %.4f mm; orientation RMS "
      "%.5f deg; %.2f times the stated tracker noise\n",
      title, s.rows, 1e3 * s.mean_position_m, 1e3 * s.rms_position_m, 1e3 * s.max_position_m,
      kRadToDeg * s.rms_orientation_rad, s.noise_ratio);
  int shown = 0;
  for (const trainer::TrendScore& t : s.trends) {
    if (shown == 6) break;
    out += format("    trend in %-9s held-out gain %8.4f mm  t %7.1f  %s\n", t.variable.c_str(),
                  t.cv_gain_mm, t.t_statistic, t.significant ? "significant" : "");
    ++shown;
  }
  return out;
}

}  // namespace

nlohmann::json parametersJson(const Mechanism& mechanism, const std::vector<double>& values) {
  const std::vector<std::string> names = parameterNames(mechanism);
  nlohmann::json j = nlohmann::json::object();
  for (size_t i = 0; i < names.size() && i < values.size(); ++i) j[names[i]] = values[i];
  return j;
}

std::string formatDiagnosis(const trainer::Diagnosis& d, double seconds_calibrate) {
  std::string out = format(
      "diagnosis on %d fit rows (%d poses, %d-fold cross-validation over poses), %d validation "
      "rows\n\n",
      d.fit_rows, d.fit_poses, d.folds, d.validation_rows);
  out += "What the physical model (geometry + compliance, refitted on every fit row) gets wrong\n";
  out += statisticsText("  before", d.before);
  out += "\nCandidates that stood out (held-out gain, t; significant = family-wise 1 %):\n";
  std::vector<const trainer::CandidateScore*> sorted;
  for (const auto& c : d.candidates) sorted.push_back(&c);
  std::stable_sort(sorted.begin(), sorted.end(), [](const auto* a, const auto* b) {
    return a->round != b->round ? a->round < b->round : a->t_statistic > b->t_statistic;
  });
  int round = 0, shown = 0;
  for (const trainer::CandidateScore* c : sorted) {
    if (c->round != round) {
      round = c->round;
      shown = 0;
      out += format("  round %d\n", round);
    }
    if (shown++ >= 5 && !c->chosen) continue;
    out += format("    %-42s gain %8.4f mm  removes %5.1f %%  t %7.1f  %s\n",
                  describe(c->mechanism).c_str(), c->cv_gain_mm, 100.0 * c->relative_reduction,
                  c->t_statistic,
                  c->chosen ? "chosen" : c->significant ? "significant" : "");
  }
  for (const auto& u : d.untestable) {
    out += format("  not tried: %s (%s)\n", u.name.c_str(), u.reason.c_str());
  }
  out += format("\nVerdict: %s\n", toString(d.verdict));
  for (const trainer::FoundEffect& e : d.effects) {
    out += format("  %s: %s (held-out gain %.4f mm, t %.1f)\n", describe(e.mechanism).c_str(),
                  parameterText(e.mechanism).c_str(), e.cv_gain_mm, e.t_statistic);
  }
  if (!d.unexplained_trend.empty()) {
    out += "  " + std::string(d.verdict == trainer::Verdict::kUnexplained
                                  ? "unexplained structure: "
                                  : "structure left after the effects: ") +
           d.unexplained_trend + "\n";
  }
  if (!d.effects.empty()) out += "\n" + statisticsText("  after", d.after);

  if (!d.gain.empty()) {
    out += format(
        "\nGain on validation rows (position mean / max mm, orientation mean deg; noise floor "
        "%.4f mm)\n",
        1e3 * d.floor_position_m);
    out += format("  %7s %5s  %-22s  %-22s  %-22s  %-22s\n", "load", "rows", "before (physical)",
                  "after (extended)",
                  d.gpr_method.empty() ? "(no GPR)" : d.gpr_method.c_str(), "extended+gpr");
    auto cell = [](const trainer::AccuracySummary& s) {
      if (s.rows == 0) return format("%-22s", "-");
      return format("%7.4f %7.4f %6.4f", 1e3 * s.mean_position_m, 1e3 * s.max_position_m,
                    kRadToDeg * s.mean_orientation_rad);
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

nlohmann::json diagnosisJson(const trainer::Diagnosis& d, double seconds_calibrate) {
  nlohmann::json j;
  j["verdict"] = toString(d.verdict);
  j["effects"] = nlohmann::json::array();
  for (const trainer::FoundEffect& e : d.effects) {
    nlohmann::json x = mechanismJson(e.mechanism);
    x["uncertainty"] = parametersJson(e.mechanism, e.mechanism.sigma);
    x["cv_gain_mm"] = e.cv_gain_mm;
    x["t_statistic"] = e.t_statistic;
    x["p_value"] = e.p_value;
    x["round"] = e.round;
    j["effects"].push_back(x);
  }
  j["candidates"] = nlohmann::json::array();
  for (const trainer::CandidateScore& c : d.candidates) {
    nlohmann::json x = mechanismJson(c.mechanism);
    x["round"] = c.round;
    x["cv_gain_mm"] = c.cv_gain_mm;
    x["relative_reduction"] = c.relative_reduction;
    x["t_statistic"] = c.t_statistic;
    x["p_value"] = c.p_value;
    x["significant"] = c.significant;
    x["chosen"] = c.chosen;
    j["candidates"].push_back(x);
  }
  j["untestable"] = nlohmann::json::array();
  for (const auto& u : d.untestable) j["untestable"].push_back({{"name", u.name}, {"reason", u.reason}});
  j["unexplained_trend"] =
      d.unexplained_trend.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.unexplained_trend);
  auto stats = [](const trainer::ResidualStatistics& s) {
    nlohmann::json x = {{"rows", s.rows},
                        {"mean_position_mm", 1e3 * s.mean_position_m},
                        {"rms_position_mm", 1e3 * s.rms_position_m},
                        {"max_position_mm", 1e3 * s.max_position_m},
                        {"rms_orientation_deg", kRadToDeg * s.rms_orientation_rad},
                        {"noise_ratio", s.noise_ratio}};
    x["trends"] = nlohmann::json::array();
    for (const trainer::TrendScore& t : s.trends) {
      x["trends"].push_back({{"variable", t.variable},
                             {"cv_gain_mm", t.cv_gain_mm},
                             {"t_statistic", t.t_statistic},
                             {"p_value", t.p_value},
                             {"significant", t.significant}});
    }
    return x;
  };
  j["residual"] = {{"before", stats(d.before)}, {"after", stats(d.after)}};
  j["gpr_method"] = d.gpr_method;
  j["noise_floor_position_mm"] = 1e3 * d.floor_position_m;
  j["gain"] = nlohmann::json::array();
  auto optional_mm = [](const trainer::AccuracySummary& s, double v) {
    return s.rows > 0 ? nlohmann::json(1e3 * v) : nlohmann::json(nullptr);
  };
  auto optional_deg = [](const trainer::AccuracySummary& s, double v) {
    return s.rows > 0 ? nlohmann::json(kRadToDeg * v) : nlohmann::json(nullptr);
  };
  for (const trainer::GainRow& g : d.gain) {
    j["gain"].push_back({
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
    });
  }
  j["timing_s"] = {{"calibration", seconds_calibrate},     {"refit", d.seconds_refit},
                   {"screening", d.seconds_screening},     {"trends", d.seconds_trends},
                   {"gpr", d.seconds_gpr},                 {"evaluation", d.seconds_evaluation}};
  return j;
}

}  // namespace stepcal::cli
