// `stepcal calibrate`: a campaign calibrated, its tables printed; demo.cpp calibrates with it too.
#pragma once

#include <string>
#include <vector>

namespace stepcal::cli {

/// Calibrates the campaigns in dirs together, writes the report and the model file (each when
/// its path is not empty) and prints the report, as text or JSON.
void runCalibrate(const std::vector<std::string>& dirs, const std::string& model_out,
                  const std::string& report_out, bool json, int gpr_points);

}  // namespace stepcal::cli
