#include "report.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

namespace stepcal::cli {
namespace {

constexpr double kMm = 1e3;
constexpr double kDeg = 180.0 / M_PI;

std::string printf_string(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string printf_string(const char* fmt, ...) {
  char buf[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  return buf;
}

// NaN (no orientation measured) becomes null in JSON.
nlohmann::json numberOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json summaryJson(const trainer::AccuracySummary& s) {
  return {{"method", s.method},
          {"set", toString(s.set)},
          {"load_kg", s.load_kg},
          {"rows", s.rows},
          {"mean_position_mm", s.mean_position_m * kMm},
          {"rms_position_mm", s.rms_position_m * kMm},
          {"max_position_mm", s.max_position_m * kMm},
          {"mean_orientation_deg", numberOrNull(s.mean_orientation_rad * kDeg)}};
}

std::vector<std::string> methodsOf(const std::vector<trainer::AccuracySummary>& summaries) {
  std::vector<std::string> methods;
  for (const auto& s : summaries) {
    bool seen = false;
    for (const auto& m : methods) seen |= m == s.method;
    if (!seen) methods.push_back(s.method);
  }
  return methods;
}

}  // namespace

std::string formatReport(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  std::ostringstream out;
  const trainer::GeometricResult& poe = outcome.poe;
  std::map<std::string, int> per_set;
  for (const Measurement& m : campaign.rows) ++per_set[toString(m.set)];
  out << "campaign " << campaign.directory << ": " << campaign.rows.size() << " rows (";
  bool first = true;
  for (const auto& [set, count] : per_set) {
    out << (first ? "" : ", ") << count << " " << set;
    first = false;
  }
  out << "), " << outcome.nominal_Base.dof() << " joints, tip " << campaign.tip_link << "\n";
  out << printf_string("tracker noise %.4f mm, %.4f deg per axis%s -> noise floor (mean) %.4f mm, %.4f deg\n",
                       campaign.tracker.position_sigma_m * kMm,
                       campaign.tracker.orientation_sigma_rad * kDeg,
                       campaign.tracker.stated ? "" : " (not stated in campaign.yaml; assumed)",
                       outcome.floor_position_m * kMm, outcome.floor_orientation_rad * kDeg);
  out << printf_string(
      "step 1, geometry (local POE): %d rows, %s after %d iterations; rank %d of %d, condition %.3g\n",
      poe.fit_rows, poe.converged ? "converged" : "NOT converged", poe.iterations,
      poe.observability.rank, poe.observability.parameter_count, poe.observability.condition_number);
  out << "  convergence (rms position mm, rms orientation deg):";
  for (const auto& h : poe.history) {
    out << printf_string(" [%d] %.4f %.5f", h.iteration, h.rms_position_m * kMm,
                         h.rms_orientation_rad * kDeg);
  }
  out << "\n  unobservable combinations, kept at their nominal values ("
      << poe.observability.unobservable.size() << "):\n";
  for (const auto& u : poe.observability.unobservable) out << "    - " << u.description << "\n";

  out << "\n" << formatAccuracyTable(outcome.accuracy);
  out << "methods: nominal = nominal URDF, tracker registered (closed form); frames = tracker and "
         "tool frames fitted; poe = every initial pose fitted (step 1)\n";
  return out.str();
}

std::string formatAccuracyTable(const std::vector<trainer::AccuracySummary>& summaries) {
  std::ostringstream out;
  const std::vector<std::string> methods = methodsOf(summaries);
  out << "accuracy: mean / max position error (mm), mean orientation error (deg)\n";
  out << printf_string("%-11s %7s %5s", "set", "load_kg", "rows");
  for (const auto& m : methods) out << printf_string("   %-24s", m.c_str());
  out << "\n";
  std::map<std::pair<int, double>, std::map<std::string, const trainer::AccuracySummary*>> table;
  for (const auto& s : summaries) table[{static_cast<int>(s.set), s.load_kg}][s.method] = &s;
  for (const auto& [key, by_method] : table) {
    const trainer::AccuracySummary* any = by_method.begin()->second;
    out << printf_string("%-11s %7.1f %5d", toString(any->set), any->load_kg, any->rows);
    for (const auto& m : methods) {
      const auto it = by_method.find(m);
      if (it == by_method.end()) {
        out << printf_string("   %-24s", "-");
        continue;
      }
      const auto& s = *it->second;
      out << printf_string("   %7.4f / %7.4f %7.4f", s.mean_position_m * kMm, s.max_position_m * kMm,
                           s.mean_orientation_rad * kDeg);
    }
    out << "\n";
  }
  return out.str();
}

nlohmann::json accuracyJson(const std::vector<trainer::AccuracySummary>& summaries) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& s : summaries) out.push_back(summaryJson(s));
  return out;
}

nlohmann::json reportJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  nlohmann::json validation = nlohmann::json::array(), fit = nlohmann::json::array();
  for (const auto& s : outcome.accuracy) {
    nlohmann::json row = summaryJson(s);
    if (s.set == RowSet::kValidation) {
      row.erase("set");
      validation.push_back(row);
    } else {
      fit.push_back(row);
    }
  }
  const trainer::GeometricResult& poe = outcome.poe;
  nlohmann::json history = nlohmann::json::array();
  for (const auto& h : poe.history) {
    history.push_back({{"iteration", h.iteration},
                       {"rms_position_mm", h.rms_position_m * kMm},
                       {"rms_orientation_deg", h.rms_orientation_rad * kDeg}});
  }
  nlohmann::json unobservable = nlohmann::json::array();
  for (const auto& u : poe.observability.unobservable) {
    unobservable.push_back({{"description", u.description}, {"structural", u.structural}});
  }
  return {{"campaign", campaign.directory},
          {"rows", campaign.rows.size()},
          {"noise_floor",
           {{"mean_position_mm", outcome.floor_position_m * kMm},
            {"mean_orientation_deg", outcome.floor_orientation_rad * kDeg},
            {"tracker_stated", campaign.tracker.stated}}},
          {"geometry",
           {{"fit_rows", poe.fit_rows},
            {"iterations", poe.iterations},
            {"converged", poe.converged},
            {"rank", poe.observability.rank},
            {"parameters", poe.observability.parameter_count},
            {"condition_number", poe.observability.condition_number},
            {"convergence", history},
            {"unobservable", unobservable}}},
          {"validation", validation},
          {"fit", fit}};
}

}  // namespace stepcal::cli
