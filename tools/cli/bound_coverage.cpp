#include "bound_coverage.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::cli {
namespace {

void count(BoundCoverageRow& group, const runtime::ForwardResult& answer, const Measurement& row) {
  const double error_m = (row.p_TipInTracker_m - answer.X_TrackerTip.translation()).norm();
  ++group.rows;
  group.mean_bound_m += answer.accuracy.position_bound_m;
  group.mean_error_m += error_m;
  if (error_m <= answer.accuracy.position_bound_m) ++group.position_covered;
  if (row.has_orientation) {
    const Mat3 R_error =
        row.q_TrackerTip.toRotationMatrix() * answer.X_TrackerTip.linear().transpose();
    ++group.rows_with_orientation;
    if (lie::logSO3(R_error).norm() <= answer.accuracy.orientation_bound_rad) {
      ++group.orientation_covered;
    }
  }
}

double percent(int part, int whole) { return whole > 0 ? 100.0 * part / whole : std::nan(""); }

}  // namespace

std::vector<BoundCoverageRow> boundCoverage(const CalibratedModel& model, const Campaign& campaign,
                                            const std::optional<KinematicChain>& refit_chain_Tracker) {
  if (!model.accuracy) return {};
  CalibratedModel judged = model;
  if (refit_chain_Tracker) judged.chain_Tracker = *refit_chain_Tracker;
  const auto runtime_model = runtime::RuntimeModel::fromModel(std::move(judged), 0);
  runtime::Workspace ws = runtime::makeWorkspace(*runtime_model);
  std::map<std::pair<int, double>, BoundCoverageRow> groups;
  BoundCoverageRow outside{"outside", -1.0};
  for (const Measurement& row : campaign.rows) {
    const runtime::ForwardResult answer = runtime::correctForward(
        *runtime_model, ws, row.q_rad, row.wrenchOrZero(),
        row.temp_c.value_or(runtime::kUnknownTemperature_c));
    if (answer.status != runtime::Status::kOk && answer.status != runtime::Status::kOutOfDomain) {
      continue;
    }
    BoundCoverageRow& group = groups[{static_cast<int>(row.set), row.load_kg}];
    group.group = toString(row.set);
    group.load_kg = row.load_kg;
    count(group, answer, row);
    if (answer.status == runtime::Status::kOutOfDomain || answer.uncovered_joints != 0) {
      count(outside, answer, row);
    }
  }
  std::vector<BoundCoverageRow> out;
  for (auto& [key, group] : groups) out.push_back(group);
  if (outside.rows > 0) out.push_back(outside);
  for (BoundCoverageRow& group : out) {
    group.mean_bound_m /= group.rows;
    group.mean_error_m /= group.rows;
  }
  return out;
}

std::string formatBoundCoverage(const std::vector<BoundCoverageRow>& rows) {
  std::ostringstream out;
  out << "stated 95 % bound against the rows (runtime correctForward):\n";
  char line[160];
  std::snprintf(line, sizeof line, "  %-11s %8s %6s %12s %12s %11s %11s\n", "rows", "load kg",
                "n", "position %", "orient. %", "bound mm", "error mm");
  out << line;
  for (const BoundCoverageRow& r : rows) {
    const std::string load = r.load_kg < 0 ? "all" : std::to_string(r.load_kg).substr(0, 6);
    std::snprintf(line, sizeof line, "  %-11s %8s %6d %12.1f %12.1f %11.4f %11.4f\n",
                  r.group.c_str(), load.c_str(), r.rows, percent(r.position_covered, r.rows),
                  percent(r.orientation_covered, r.rows_with_orientation),
                  r.mean_bound_m * kMmPerM, r.mean_error_m * kMmPerM);
    out << line;
  }
  return out.str();
}

nlohmann::json boundCoverageJson(const std::vector<BoundCoverageRow>& rows) {
  nlohmann::json out = nlohmann::json::array();
  for (const BoundCoverageRow& r : rows) {
    const auto pct = [](int part, int whole) {
      return whole > 0 ? nlohmann::json(percent(part, whole)) : nlohmann::json(nullptr);
    };
    out.push_back({{"group", r.group},
                   {"load_kg", r.load_kg < 0 ? nlohmann::json(nullptr) : nlohmann::json(r.load_kg)},
                   {"rows", r.rows},
                   {"position_coverage_pct", pct(r.position_covered, r.rows)},
                   {"orientation_coverage_pct", pct(r.orientation_covered, r.rows_with_orientation)},
                   {"mean_bound_mm", r.mean_bound_m * kMmPerM},
                   {"mean_error_mm", r.mean_error_m * kMmPerM}});
  }
  return out;
}

}  // namespace stepcal::cli
