// The runtime's stated accuracy judged on measured rows (`stepcal validate`'s coverage table):
// how many of a campaign's rows the 95 % position and orientation bounds of correctForward hold,
// per row set and load, and on the rows outside the calibrated region.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"

namespace stepcal::cli {

/// One group of rows: a (set, load), or the rows outside the calibrated region of every set.
struct BoundCoverageRow {
  std::string group;  ///< "validation", …, or "outside" (OUT_OF_DOMAIN or a joint uncovered)
  double load_kg = 0.0;  ///< −1 for "outside" (every load)
  int rows = 0;
  int position_covered = 0;          ///< rows whose position error is within the bound
  int rows_with_orientation = 0;
  int orientation_covered = 0;
  double mean_bound_m = 0.0;         ///< mean stated 95 % position bound
  double mean_error_m = 0.0;         ///< mean position error (the runtime's prediction)
};

/// Coverage of the bound on every row of the campaign. The model's chain may be replaced by
/// refit_chain_Tracker (`--refit-frames`: the campaign's tracker and tool frames). Empty when
/// the model states no bound (no AccuracyFactors).
std::vector<BoundCoverageRow> boundCoverage(const CalibratedModel& model, const Campaign& campaign,
                                            const std::optional<KinematicChain>& refit_chain_Tracker);

/// The table as text: group, load, rows, % covered (position, orientation), mean bound and error.
std::string formatBoundCoverage(const std::vector<BoundCoverageRow>& rows);
/// The same as JSON: [{group, load_kg, rows, position_coverage_pct, orientation_coverage_pct,
/// mean_bound_mm, mean_error_mm}], coverage null where no row has it.
nlohmann::json boundCoverageJson(const std::vector<BoundCoverageRow>& rows);

}  // namespace stepcal::cli
