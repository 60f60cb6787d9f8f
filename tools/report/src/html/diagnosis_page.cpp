// The diagnosis report (diagnosisHtml): the effects found with their signatures, the residual
// against the telling variables, each round's candidates, the gain.
#include <algorithm>
#include <sstream>
#include <vector>

#include "stepcal/common/mechanisms/nonlinear_stiffness.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"
#include "stepcal/report/diagnosis_report.hpp"
#include "stepcal/report/html/charts.hpp"
#include "stepcal/report/html/drift_confounds.hpp"
#include "stepcal/report/html/page.hpp"
#include "stepcal/report/report_html.hpp"
#include "stepcal/report/text_format.hpp"
#include "stepcal/report/family_pairs_report.hpp"
#include "stepcal/report/unexplained_report.hpp"

namespace stepcal::report {
namespace {

using namespace html;

// Candidates shown per round (the chosen one always among them).
constexpr size_t kCandidatesShown = 10;

const SeriesStyle kBefore{"#d62728", MarkerShape::kCircle}, kAfter{"#1f77b4", MarkerShape::kSquare};
const SeriesStyle kFittedCurve{"#111111", MarkerShape::kCircle};

/// A trend variable's name for people, with its unit: "q2_deg" → "joint 2 angle (deg)".
std::string variableLabel(const std::string& name) {
  auto joint_of = [&](size_t prefix, size_t suffix) { return name.substr(prefix, name.size() - prefix - suffix); };
  auto ends_with = [&](const std::string& end) {
    return name.size() > end.size() && name.compare(name.size() - end.size(), end.size(), end) == 0;
  };
  if (name[0] == 'q' && ends_with("_deg")) return "joint " + joint_of(1, 4) + " angle (deg)";
  if (name.rfind("tau", 0) == 0 && ends_with("_nm")) return "joint " + joint_of(3, 3) + " torque (N·m)";
  if (name == "load_kg") return "payload (kg)";
  if (name == "temp_c") return "temperature (°C)";
  if (name == "seq") return "row order (seq)";
  return name;
}

std::string signatureXLabel(const trainer::EffectSignature& s) {
  const std::string joint = std::to_string(s.variable_joint + 1);
  switch (s.variable) {
    case trainer::SignatureVariable::kJointAngle: return "joint " + joint + " angle (deg)";
    case trainer::SignatureVariable::kJointTorque:
      return s.mechanism.kind == MechanismKind::kSelfWeight ? "links' gravity torque on joint " + joint + " (N·m)"
                                                            : "joint " + joint + " torque (N·m)";
    case trainer::SignatureVariable::kTemperature: return "temperature (°C)";
    case trainer::SignatureVariable::kMomentAcrossAxis:
      return "joint " + joint + " moment about " + (s.direction == 0 ? "u" : "v") + " (N·m)";
    case trainer::SignatureVariable::kForceAlongMountAxis:
      return std::string("force along the mount's ") + "xyz"[s.direction] + " (N)";
  }
  return "";
}

/// The variable in the plot's unit: deg for an angle, else as it is.
double signatureX(const trainer::EffectSignature& s, double x) {
  return s.variable == trainer::SignatureVariable::kJointAngle ? x * kDegPerRad : x;
}

std::string signatureYLabel(const trainer::EffectSignature& s) {
  switch (s.response) {
    case trainer::SignatureResponse::kLinkAngle:
      return "joint " + std::to_string(s.joint + 1) + " link-angle offset (µrad)";
    case trainer::SignatureResponse::kLengthScale: return "link length change (ppm)";
    case trainer::SignatureResponse::kFrameTilt:
      return "joint " + std::to_string(s.joint + 1) + " frame tilt about " +
             (s.direction == 0 ? "u" : "v") + " (µrad)";
    case trainer::SignatureResponse::kToolShift:
      return std::string("tool shift along the mount's ") + "xyz"[s.direction] + " (µm)";
  }
  return "";
}

std::string signatureTitle(const trainer::EffectSignature& s) {
  const std::string name = describe(s.mechanism);
  return s.mechanism.kind == MechanismKind::kSelfWeight
             ? name + ": joint " + std::to_string(s.joint + 1) + "'s compliance"
             : name;
}

Panel signaturePanel(const trainer::EffectSignature& s) {
  Panel panel;
  panel.title = signatureTitle(s);
  panel.x_label = signatureXLabel(s);
  panel.y_label = signatureYLabel(s);
  Series points{"fitted effect + what the extended model leaves", kAfter, {}, {}, false};
  for (size_t i = 0; i < s.x.size(); ++i) {
    points.x.push_back(signatureX(s, s.x[i]));
    points.y.push_back(s.partial_residual[i] * kMicro);
  }
  Series curve{"fitted effect", kFittedCurve, {}, {}, true, false};
  for (size_t i = 0; i < s.curve_x.size(); ++i) {
    curve.x.push_back(signatureX(s, s.curve_x[i]));
    curve.y.push_back(s.curve_y[i] * kMicro);
  }
  panel.series = {std::move(points), std::move(curve)};
  return panel;
}

/// A candidate's name, with what tells apart the families of one mechanism on one joint.
std::string candidateLabel(const Mechanism& m) {
  if (m.kind == MechanismKind::kNonlinearStiffness) {
    return describe(m) +
           format(", τ₀ %.0f N·m", view<mechanism::NonlinearStiffness>(m).saturationTorque_nm());
  }
  if (m.kind != MechanismKind::kTorsionCurve) return describe(m);
  const mechanism::TorsionCurve<const double> curve = view<mechanism::TorsionCurve>(m);
  std::string label = describe(m) + (curve.smoothingTorque_nm() > 0.0 ? ", lost motion" : "");
  for (int k = 1; k <= m.order; ++k) label += format(", T%d %.0f N·m", k, curve.kneeTorque_nm(k));
  return label;
}

class DiagnosisPage {
 public:
  DiagnosisPage(const Campaign& campaign, const trainer::Diagnosis& d) : campaign_(campaign), d_(d) {}

  std::string write() {
    const std::string name = campaign_.directory.empty() ? "(campaign built in memory)" : campaign_.directory;
    out_ << pageHead("stepcal diagnosis: " + name);
    out_ << "<h1>stepcal diagnosis</h1>\n<nav><a href=\"#effects\">effects found</a>"
            "<a href=\"#signatures\">signatures</a><a href=\"#unexplained\">unexplained</a>"
            "<a href=\"#residual\">residual</a>"
            "<a href=\"#candidates\">candidates</a>"
        << (d_.campaigns.empty() ? "" : "<a href=\"#campaigns\">campaigns</a>")
        << "<a href=\"#gain\">gain</a></nav>\n<p>"
        << escape(name) << ": " << d_.fit_rows << " fit rows, " << d_.validation_rows
        << " validation rows. Verdict: <b>" << toString(d_.verdict) << "</b>";
    for (const trainer::FoundEffect& e : d_.effects) out_ << "; " << escape(describe(e.mechanism));
    out_ << ".</p>\n";
    if (!d_.unexplained_trend.empty()) {
      out_ << "<p>Structure no catalogued mechanism explains: " << escape(d_.unexplained_trend) << "</p>\n";
    }
    for (const trainer::LoadModulatedProfile& f : d_.load_modulated_profiles) {
      out_ << "<p>A profile or a load effect: " << escape(loadModulatedProfileText(f)) << ".</p>\n";
    }
    if (!d_.drift.text.empty()) out_ << "<p>What drifted: " << escape(d_.drift.text) << ".</p>\n";
    out_ << driftConfoundsSection(d_.drift);
    out_ << familyPairsSection(d_);
    writeEffects();
    writeSignatures();
    out_ << unexplainedSection(d_.unexplained);
    writeResidual();
    writeCandidates();
    writeCampaigns();
    writeGain();
    out_ << pageEnd();
    return out_.str();
  }

 private:
  /// An effect's parameters; for self weight with the URDF's masses, the compliances it identifies.
  std::string effectParameters(const trainer::FoundEffect& e) const {
    std::string text = effectParameterText(e);
    for (const int j : e.compliance_joints) text += "; " + selfWeightComplianceText(d_, j);
    if (const std::string curve = torqueCurveText(e); !curve.empty()) text += "; " + curve;
    return text;
  }

  void writeEffects() {
    out_ << "<h2 id=\"effects\">Effects found</h2>\n";
    if (d_.effects.empty()) {
      out_ << "<p class=\"muted\">None: no catalogued mechanism removes a significant part of the held-out "
              "error.</p>\n";
      return;
    }
    out_ << "<table>\n<tr><th>round</th><th class=\"l\">effect</th><th>held-out gain (mm)</th><th>z</th>"
            "<th class=\"l\">parameters (SI)</th></tr>\n";
    for (const trainer::FoundEffect& e : d_.effects) {
      out_ << "<tr><td>" << e.round << "</td><td class=\"l item\">" << escape(describe(e.mechanism)) << "</td><td>"
           << format("%.4f", e.cv_gain_mm) << "</td><td>" << format("%.1f", e.z_statistic) << "</td><td class=\"l\">"
           << escape(effectParameters(e)) << "</td></tr>\n";
    }
    out_ << "</table>\n";
  }

  void writeSignatures() {
    out_ << "<h2 id=\"signatures\">Signatures: each effect against its own variable</h2>\n";
    const std::vector<trainer::EffectSignature> signatures = trainer::effectSignatures(campaign_, d_);
    if (signatures.empty()) {
      out_ << "<p class=\"muted\">No effect with a variable of its own was found.</p>\n";
      return;
    }
    int left_out = 0;
    out_ << "<figure><div class=\"panels\">\n";
    for (const trainer::EffectSignature& s : signatures) {
      out_ << renderPanel(signaturePanel(s), marker_ids_.next());
      left_out = std::max(left_out, s.rows_left_out);
    }
    out_ << "</div><figcaption>Partial residuals on the fit rows: each dot is the fitted effect at a row plus "
            "what the extended model leaves there along the effect (the row's residual projected on the tip's "
            "motion per unit of the effect); the line is the fitted effect. Dots spread evenly about the line "
            "say its form describes the data; structure left about it says it does not. A profile's line "
            "falls to zero where it fades out of its coverage."
         << (left_out > 0 ? format(" Up to %d rows per panel are left out: there the effect barely moves the tip.", left_out)
                          : std::string())
         << "</figcaption></figure>\n";
  }

  void writeResidual() {
    // The telling variables: significant trends before the extension, else the strongest three.
    std::vector<std::string> telling;
    for (const trainer::TrendScore& t : d_.before.trends) {
      if (t.significant || telling.size() < 3) telling.push_back(t.variable);
      if (telling.size() == 4) break;
    }
    out_ << "<h2 id=\"residual\">Residual of the physical model against the telling variables</h2>\n"
            "<p>Position error of every fit row (mm) before and after the extension; the variables are those "
            "the residual trends with most (cross-validated).</p>\n<div class=\"panels\">";
    auto mm = [](const std::vector<double>& v) {
      std::vector<double> out;
      for (double e : v) out.push_back(e * kMmPerM);
      return out;
    };
    for (const std::string& variable : telling) {
      const auto it = std::find(d_.variable_names.begin(), d_.variable_names.end(), variable);
      if (it == d_.variable_names.end()) continue;
      const std::vector<double>& x = d_.variable_values[static_cast<size_t>(it - d_.variable_names.begin())];
      Panel panel;
      panel.title = "position error against " + variableLabel(variable);
      panel.x_label = variableLabel(variable);
      panel.y_label = "position error (mm)";
      panel.series.push_back({"physical model", kBefore, x, mm(d_.before.position_error_m), false});
      if (!d_.effects.empty()) panel.series.push_back({"extended", kAfter, x, mm(d_.after.position_error_m), false});
      panel.references.push_back({"noise floor", d_.floor_position_m * kMmPerM});
      out_ << "<figure>" << renderPanel(panel, marker_ids_.next()) << "</figure>";
    }
    out_ << "</div>\n";
  }

  void writeCandidates() {
    out_ << "<h2 id=\"candidates\">Candidates of each round</h2>\n<div class=\"panels\">";
    int rounds = 0;
    for (const trainer::CandidateScore& c : d_.candidates) rounds = std::max(rounds, c.round);
    for (int round = 1; round <= rounds; ++round) {
      std::vector<const trainer::CandidateScore*> in_round;
      for (const trainer::CandidateScore& c : d_.candidates) {
        if (c.round == round) in_round.push_back(&c);
      }
      std::sort(in_round.begin(), in_round.end(),
                [](const auto* a, const auto* b) { return a->z_statistic > b->z_statistic; });
      // The chosen one is shown even when simpler or physical candidates won with a lower z.
      std::vector<const trainer::CandidateScore*> shown(in_round.begin(),
                                                        in_round.begin() + std::min(in_round.size(), kCandidatesShown));
      for (const auto* c : in_round) {
        if (c->chosen && std::find(shown.begin(), shown.end(), c) == shown.end()) shown.push_back(c);
      }
      HorizontalBarChart chart;
      chart.title = format("Round %d: the best %zu of %zu candidates", round, shown.size(), in_round.size());
      chart.value_label = "held-out signed-rank z of the per-pose reduction";
      chart.legend = {{"chosen", "#1f77b4"}, {"significant", "#9ecae1"}, {"not significant", "#cccccc"}};
      for (const auto* c : shown) {
        chart.bars.push_back({candidateLabel(c->mechanism), c->z_statistic,
                              c->chosen ? "#1f77b4" : c->significant ? "#9ecae1" : "#cccccc",
                              c->chosen ? "\u25c0 chosen" : "", c->chosen});
      }
      out_ << "<figure class=\"bars\">" << renderHorizontalBars(chart) << "</figure>";
    }
    out_ << "</div>\n<p class=\"muted\">Significant: a one-sided signed-rank test over the folds' poses below "
            "1 % divided by every configuration tried in the round, at least 1 % of the held-out error "
            "removed and parameters of the sign their physics needs (docs/diagnosis.md).</p>\n";
  }

  // The joints whose profile a later campaign would need its own of, with its held-out share.
  static std::string differingProfiles(const trainer::DiagnosedCampaign& c) {
    if (c.profile_differences.empty()) return "–";
    std::string text;
    for (const trainer::CampaignProfileDifference& p : c.profile_differences) {
      if (!p.score.significant) continue;
      text += (text.empty() ? "" : ", ") +
              format("joint %d (%.1f %%)", p.score.mechanism.joint + 1, 100.0 * p.score.relative_reduction);
    }
    return text.empty() ? "none: one serves every campaign" : text;
  }

  void writeCampaigns() {
    if (d_.campaigns.empty()) return;
    out_ << "<h2 id=\"campaigns\">Campaigns fitted together</h2>\n<p>One robot; each later campaign "
            "with its own tracker station and tool against the first's, which are the extended "
            "model's.</p>\n<table><tr><th>campaign</th><th>fit rows</th><th>starting model "
            "mean mm</th><th>extended mean mm</th><th>station</th><th>tool</th><th>profiles "
            "that differ here</th></tr>\n";
    for (const trainer::DiagnosedCampaign& c : d_.campaigns) {
      const bool own = !c.frames.parameters.empty();
      out_ << "<tr><td>" << escape(c.directory) << "</td><td>" << c.fit_rows << "</td><td>"
           << cell("%.4f", c.before_mean_m * kMmPerM) << "</td><td>"
           << cell("%.4f", c.after_mean_m * kMmPerM) << "</td><td>"
           << (own ? escape(campaignFrameText(c.frames, false)) : "the model's") << "</td><td>"
           << (own ? escape(campaignFrameText(c.frames, true)) : "the model's") << "</td><td>"
           << escape(differingProfiles(c)) << "</td></tr>\n";
    }
    out_ << "</table>\n";
  }

  void writeGain() {
    if (d_.gain.empty()) return;
    out_ << "<h2 id=\"gain\">Gain on validation rows</h2>\n<table><tr><th>load</th><th>rows</th>"
            "<th>before mean mm</th><th>after mean mm</th><th>"
         << escape(d_.gpr_method.empty() ? "(no GPR)" : d_.gpr_method)
         << " mean mm</th><th>extended+gpr mean mm</th></tr>\n";
    for (const trainer::GainRow& g : d_.gain) {
      out_ << "<tr><td>" << loadLabel(g.load_kg) << "</td><td>" << g.rows << "</td><td>"
           << cell("%.4f", g.before.mean_position_m * kMmPerM) << "</td><td>"
           << cell("%.4f", g.after.mean_position_m * kMmPerM) << "</td><td>"
           << (g.gpr.rows > 0 ? cell("%.4f", g.gpr.mean_position_m * kMmPerM) : "&#8211;") << "</td><td>"
           << cell("%.4f", g.after_gpr.mean_position_m * kMmPerM) << "</td></tr>\n";
    }
    out_ << "</table>\n";
    if (const std::string pin = geometryPinText(d_.geometry_pin); !pin.empty()) {
      out_ << "<p>The extended model's geometry: " << escape(pin) << ".</p>\n";
    }
  }

  const Campaign& campaign_;
  const trainer::Diagnosis& d_;
  std::ostringstream out_;
  MarkerIds marker_ids_;
};

}  // namespace

std::string diagnosisHtml(const Campaign& campaign, const trainer::Diagnosis& diagnosis) {
  return DiagnosisPage(campaign, diagnosis).write();
}

}  // namespace stepcal::report
