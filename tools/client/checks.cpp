#include "checks.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "stepcal/common/model_robot.hpp"
#include "stepcal/service/request.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::client {

ReplyChecker::ReplyChecker(const std::vector<std::string>& model_paths) {
  for (const std::string& path : model_paths) {
    Known known{path, runtime::RuntimeModel::load(path), {}, 0};
    known.workspace = runtime::makeWorkspace(*known.model);
    models_.push_back(std::move(known));
  }
}

void ReplyChecker::requireRobotOf(const Campaign& campaign) const {
  for (const Known& k : models_) requireCampaignOfModelRobot(k.model->file, campaign, k.path);
}

void ReplyChecker::check(const correction_request_t& request, const correction_reply_t& reply) {
  ++checked_;
  if (last_model_id_ != 0 && reply.model_id != last_model_id_) ++model_changes_;
  last_model_id_ = reply.model_id;
  Known* known = nullptr;
  for (Known& k : models_) {
    if (int64_t(k.model->model_id) == reply.model_id) known = &k;
  }
  if (known == nullptr) {
    ++unknown_model_;
    noteProblem(reply, "model " + modelIdText(reply.model_id) + " is none of --check-model's");
    return;
  }
  ++known->replies;
  if (reply.status >= 0 && reply.status < kStatusCount) ++known->status_counts[reply.status];
  const correction_reply_t expected = recompute(request, reply, *known);
  const double difference = maxDifference(expected, reply);
  max_difference_ = std::max(max_difference_, difference);
  if (expected.status != reply.status || expected.iterations != reply.iterations ||
      expected.uncovered_joints != reply.uncovered_joints || !(difference <= kTolerance)) {
    ++mismatched_;
    char what[160];
    std::snprintf(what, sizeof what,
                  "status %s, %d iterations offline with model %s; the reply: %s, %d, values "
                  "off by up to %.3g",
                  runtime::toString(runtime::Status(expected.status)), expected.iterations,
                  modelIdText(reply.model_id).c_str(),
                  runtime::toString(runtime::Status(reply.status)), reply.iterations, difference);
    noteProblem(reply, what);
  }
}

nlohmann::json ReplyChecker::toJson() const {
  nlohmann::json models = nlohmann::json::array();
  for (const Known& k : models_) {
    models.push_back({{"path", k.path}, {"model_id", modelIdText(int64_t(k.model->model_id))},
                      {"replies", k.replies}, {"statuses", statusesJson(k.status_counts)}});
  }
  return {{"checked", checked_},         {"mismatched", mismatched_},
          {"unknown_model", unknown_model_}, {"max_difference", max_difference_},
          {"model_changes", model_changes_}, {"models", models},
          {"first_problem", first_problem_}};
}

correction_reply_t ReplyChecker::recompute(const correction_request_t& request,
                                           const correction_reply_t& reply, Known& known) {
  const std::vector<uint8_t> bytes = service::encodeRequest(request);
  service::Request decoded;
  correction_reply_t expected{};
  expected.status = int8_t(service::decodeRequest(bytes.data(), int(bytes.size()), decoded));
  if (expected.status != int8_t(runtime::Status::kOk)) return expected;
  if (decoded.mode == service::Mode::kForward) {
    const runtime::ForwardResult r = runtime::correctForward(
        *known.model, known.workspace, decoded.q_rad, decoded.terms, decoded.temp_c);
    expected.status = int8_t(r.status);
    service::writeAnswer(r, expected);
    return expected;
  }
  runtime::InverseOptions options;
  options.max_iterations = reply.iterations;
  const runtime::InverseResult r = runtime::solveInverse(
      *known.model, known.workspace, decoded.X_FrameTcp_desired, decoded.terms,
      decoded.temp_c, decoded.seed_q_rad, runtime::Clock::time_point::max(), options);
  expected.status = int8_t(r.status);
  service::writeAnswer(r, expected);
  return expected;
}

double ReplyChecker::maxDifference(const correction_reply_t& a, const correction_reply_t& b) {
  double largest = 0.0;
  const auto compare = [&](const double* x, const double* y, int n) {
    for (int i = 0; i < n; ++i) {
      const double d = std::abs(x[i] - y[i]);
      largest = std::isnan(d) ? std::numeric_limits<double>::infinity() : std::max(largest, d);
    }
  };
  compare(a.q_target_rad, b.q_target_rad, 6);
  compare(a.commanded_position_m, b.commanded_position_m, 3);
  compare(a.commanded_quaternion_wxyz, b.commanded_quaternion_wxyz, 4);
  compare(a.predicted_position_m, b.predicted_position_m, 3);
  compare(a.predicted_quaternion_wxyz, b.predicted_quaternion_wxyz, 4);
  compare(a.gpr_std, b.gpr_std, 6);
  compare(&a.residual_position_m, &b.residual_position_m, 1);
  compare(&a.residual_orientation_rad, &b.residual_orientation_rad, 1);
  // NaN in both: the model states no accuracy, and the two agree on that.
  const auto compareStated = [&](double x, double y) {
    if (!(std::isnan(x) && std::isnan(y))) compare(&x, &y, 1);
  };
  compareStated(a.position_rms_m, b.position_rms_m);
  compareStated(a.position_bound_m, b.position_bound_m);
  compareStated(a.orientation_rms_rad, b.orientation_rms_rad);
  compareStated(a.orientation_bound_rad, b.orientation_bound_rad);
  return largest;
}

void ReplyChecker::noteProblem(const correction_reply_t& reply, const std::string& what) {
  if (first_problem_.empty()) {
    first_problem_ = "reply to request " + std::to_string(reply.request_id) + ": " + what;
  }
}

}  // namespace stepcal::client
