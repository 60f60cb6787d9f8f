// The TCP's axes from a 6-D target at the TCP (docs/cell.md, "The tool"): the mean of the rows'
// rotations from the model's target to the measured TCP, and its scatter.
#include <cmath>

#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/cell.hpp"

namespace stepcal::trainer {

ToolOrientationFit fitToolOrientation(const std::vector<Pose>& X_TrackerTip,
                                      const std::vector<Mat3>& R_TrackerTcp,
                                      double stated_sigma_rad) {
  ToolOrientationFit fit;
  const int n = int(X_TrackerTip.size());
  fit.points = n;
  if (n < 1 || R_TrackerTcp.size() != X_TrackerTip.size()) {
    fit.note = "no measured orientations: at least one row with the TCP's orientation is needed";
    return fit;
  }
  std::vector<Mat3> R_TipTcp;
  Mat3 sum = Mat3::Zero();
  for (int i = 0; i < n; ++i) {
    R_TipTcp.push_back(X_TrackerTip[size_t(i)].linear().transpose() * R_TrackerTcp[size_t(i)]);
    sum += R_TipTcp.back();
  }
  // The chordal mean: for scatter of a few mrad it is the geodesic one to well below the scatter.
  fit.R_TipTcp = lie::projectToSO3(sum / n);
  double sum_squared_rad2 = 0.0;
  for (const Mat3& R : R_TipTcp) {
    sum_squared_rad2 += lie::logSO3(fit.R_TipTcp.transpose() * R).squaredNorm();
  }
  fit.rms_residual_rad = std::sqrt(sum_squared_rad2 / n);
  fit.row_sigma_rad = n > 1 ? std::max(std::sqrt(sum_squared_rad2 / (3.0 * (n - 1))), stated_sigma_rad)
                            : stated_sigma_rad;
  fit.covariance_rad2 = Mat3::Identity() * (fit.row_sigma_rad * fit.row_sigma_rad / n);
  return fit;
}

}  // namespace stepcal::trainer
