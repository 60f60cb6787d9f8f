// stepcal-client --check-model: every reply recomputed offline with the model file whose
// model_id it carries, through the daemon's own code (decodeRequest, the runtime's calls,
// service::writeAnswer).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "client.hpp"
#include "stepcal/common/campaign.hpp"

namespace stepcal::client {

/// Recomputes replies offline with the model each names (--check-model).
class ReplyChecker {
 public:
  /// Largest difference of any value from its offline recomputation. The daemon and this
  /// client run the same library code on the same inputs, so they agree to the last bit; the
  /// margin only forgives a client built with other flags than the daemon.
  static constexpr double kTolerance = 1e-12;

  explicit ReplyChecker(const std::vector<std::string>& model_paths);

  /// Throws InputError when a campaign is not of the robot every model was calibrated for
  /// (model_robot.hpp): its requests would be another robot's joints.
  void requireRobotOf(const Campaign& campaign) const;

  void check(const correction_request_t& request, const correction_reply_t& reply);
  bool passed() const { return mismatched_ == 0 && unknown_model_ == 0; }
  nlohmann::json toJson() const;

 private:
  struct Known {
    std::string path;
    std::unique_ptr<const runtime::RuntimeModel> model;
    runtime::Workspace workspace;
    long replies = 0;
    long status_counts[kStatusCount] = {};  ///< its replies per status
  };

  static correction_reply_t recompute(const correction_request_t& request,
                                      const correction_reply_t& reply, Known& known);
  static double maxDifference(const correction_reply_t& a, const correction_reply_t& b);
  void noteProblem(const correction_reply_t& reply, const std::string& what);

  std::vector<Known> models_;
  long checked_ = 0, mismatched_ = 0, unknown_model_ = 0, model_changes_ = 0;
  int64_t last_model_id_ = 0;
  double max_difference_ = 0.0;
  std::string first_problem_;
};

}  // namespace stepcal::client
