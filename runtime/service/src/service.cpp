#include "stepcal/service/service.hpp"

#include <time.h>

#include <algorithm>
#include <utility>

#include "stepcal/common/error.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/service/latency.hpp"
#include "stepcal/service/reply.hpp"

namespace stepcal::service {
namespace {

using runtime::Clock;
using runtime::Status;


int64_t steadyNanoseconds(Clock::time_point t) noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

void writeVector(const Vec6& v, double* out) noexcept {
  for (int i = 0; i < 6; ++i) out[i] = v[i];
}

void writeAccuracy(const PoseAccuracy& accuracy, stepcal_lcm::correction_reply_t& reply) noexcept {
  reply.position_rms_m = accuracy.position_rms_m;
  reply.position_bound_m = accuracy.position_bound_m;
  reply.orientation_rms_rad = accuracy.orientation_rms_rad;
  reply.orientation_bound_rad = accuracy.orientation_bound_rad;
}

/// Whether a result of this status carries an answer (poses, joints) worth sending.
bool carriesAnswer(Status status) noexcept {
  return status != Status::kBadRequest && status != Status::kStaleWrench;
}

}  // namespace

void writeAnswer(const runtime::ForwardResult& r, stepcal_lcm::correction_reply_t& reply) noexcept {
  if (!carriesAnswer(r.status)) return;
  toPositionQuaternion(r.X_FrameTcp, reply.predicted_position_m, reply.predicted_quaternion_wxyz);
  writeVector(r.gpr_std, reply.gpr_std);
  writeVector(r.wrench_Sensor, reply.wrench);
  reply.uncovered_joints = static_cast<int32_t>(r.uncovered_joints);
  writeAccuracy(r.accuracy, reply);
}

void writeAnswer(const runtime::InverseResult& r, stepcal_lcm::correction_reply_t& reply) noexcept {
  if (!carriesAnswer(r.status)) return;
  for (int i = 0; i < kMessageJoints; ++i) reply.q_target_rad[i] = r.q_target_rad[i];
  toPositionQuaternion(r.X_ControllerTcp_commanded, reply.commanded_position_m,
                       reply.commanded_quaternion_wxyz);
  toPositionQuaternion(r.X_FrameTcp_predicted, reply.predicted_position_m,
                       reply.predicted_quaternion_wxyz);
  writeVector(r.gpr_std, reply.gpr_std);
  writeVector(r.wrench_Sensor, reply.wrench);
  reply.uncovered_joints = static_cast<int32_t>(r.uncovered_joints);
  writeAccuracy(r.accuracy, reply);
  reply.iterations = r.iterations;
  reply.residual_position_m = r.residual_position_m;
  reply.residual_orientation_rad = r.residual_orientation_rad;
}

int64_t unixMicroseconds() noexcept {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return int64_t(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
}

void checkMessageJoints(const runtime::RuntimeModel& model, const std::string& source) {
  const int dof = model.file.chain_Tracker.dof();
  if (dof != kMessageJoints) {
    throw InputError("the model has " + std::to_string(dof) +
                         " joints; the runtime's LCM messages carry exactly " +
                         std::to_string(kMessageJoints) + " (lcmtypes/*.lcm)",
                     source);
  }
}

Service::Service(std::unique_ptr<const runtime::RuntimeModel> model, std::string model_path,
                 ServiceOptions options)
    : options_(std::move(options)) {
  STEPCAL_INVARIANT(model != nullptr, "a service needs a model");
  if (options_.key) {
    verifier_.emplace(*options_.key, options_.auth_window_us);
    signer_.emplace(*options_.key);
  }
  checkMessageJoints(*model, model_path);
  slots_[0].workspace = runtime::makeWorkspace(*model);
  slots_[0].model_path = std::move(model_path);
  slots_[0].model.store(model.get(), std::memory_order_release);
  models_.swap(std::move(model));
}

int Service::replyBytes() noexcept { return service::replyBytes(); }

int Service::refuseOldVersion(int version, int64_t request_id, uint8_t* reply,
                              int capacity) noexcept {
  const int bytes =
      encodeOldVersionRefusal(version, request_id, unixMicroseconds(),
                              static_cast<int64_t>(models_.currentModelId()), reply, capacity);
  if (bytes <= 0) return 0;
  ++counters_.replies;
  ++counters_.status_counts[static_cast<size_t>(Status::kBadRequest)];
  return bytes;
}

Service::WorkspaceSlot& Service::slotOf(const runtime::RuntimeModel* model) noexcept {
  for (WorkspaceSlot& slot : slots_) {
    if (slot.model.load(std::memory_order_acquire) == model) return slot;
  }
  invariantFailed("slotOf(model)", __FILE__, __LINE__, "no workspace for the model in service");
}

int Service::handleRequest(const void* data, int size, Clock::time_point received,
                           uint8_t* reply, int capacity) noexcept {
  ++counters_.requests;
  Request request;
  Status status = decodeRequest(data, size, request);
  if (request.old_version == 1) {
    // Refused by name before any key: a version-1 client can carry no code.
    ++counters_.old_version;
    if (verifier_ || capacity < replyBytes()) return 0;
    return refuseOldVersion(1, request.request_id, reply, capacity);
  }
  if (verifier_) {
    const Verdict verdict =
        verifier_->verify(static_cast<const uint8_t*>(data), size, unixMicroseconds());
    if (verdict != Verdict::kAuthentic) {
      ++(verdict == Verdict::kForged ? counters_.forged : counters_.replayed);
      return 0;
    }
  }
  if (!request.request_id_known) {
    ++counters_.unaddressable;
    return 0;
  }
  if (capacity < replyBytes()) return 0;
  if (request.old_version != 0) {
    // A version-2 client carries the cell's code (checked above) and reads a sealed reply.
    ++counters_.old_version;
    const int bytes = refuseOldVersion(request.old_version, request.request_id, reply, capacity);
    if (bytes > 0 && signer_) signer_->seal(reply, bytes);
    return bytes;
  }
  reply_ = stepcal_lcm::correction_reply_t{};
  reply_.message_version = stepcal_lcm::correction_reply_t::VERSION;
  reply_.request_id = request.request_id;
  {
    const runtime::ModelHandle::Guard model = models_.acquire(kServingReaderSlot);
    STEPCAL_INVARIANT(model, "the serving reader slot is held twice or no model is in service");
    reply_.model_id = static_cast<int64_t>(model->model_id);
    if (status == Status::kOk) {
      status = answer(request, *model, slotOf(model.get()).workspace, received);
    }
  }
  reply_.status = static_cast<int8_t>(status);
  reply_.utime = unixMicroseconds();
  const double compute_ns = double(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                       Clock::now() - received)
                                       .count());
  reply_.compute_ns = static_cast<int64_t>(compute_ns);
  recordCompute(compute_ns * 1e-3);
  ++counters_.status_counts[static_cast<size_t>(status)];
  const int bytes = encodeReply(reply_, reply, capacity);
  if (bytes <= 0) return 0;
  if (signer_) signer_->seal(reply, bytes);
  ++counters_.replies;
  return bytes;
}

Status Service::answer(const Request& request, const runtime::RuntimeModel& model,
                       runtime::Workspace& ws, Clock::time_point received) noexcept {
  runtime::CallTerms terms = request.terms;
  if (request.wrench_source == WrenchSource::kLiveSensor) {
    // A model that needs no wrench takes none: never STALE_WRENCH for a missing sensor.
    if (!model.needs_wrench) {
      terms.wrench_Sensor = model.unloaded_wrench_Sensor;
    } else {
      const Status wrench_status =
          runtime::wrenchFor(wrench_, steadyNanoseconds(Clock::now()),
                             options_.max_wrench_age_ns, terms.wrench_Sensor,
                             &reply_.wrench_stamp_ns);
      if (wrench_status != Status::kOk) return wrench_status;
    }
  }
  if (request.mode == Mode::kForward) {
    const runtime::ForwardResult r =
        runtime::correctForward(model, ws, request.q_rad, terms, request.temp_c);
    writeAnswer(r, reply_);
    return r.status;
  }
  const int64_t request_budget_ns =
      request.deadline_us > 0 ? int64_t(request.deadline_us) * 1000 : options_.budget_ns;
  const Clock::time_point deadline =
      received + std::chrono::nanoseconds(std::min(request_budget_ns, options_.budget_ns));
  const runtime::InverseResult r =
      runtime::solveInverse(model, ws, request.X_FrameTcp_desired, terms, request.temp_c,
                            request.seed_q_rad, deadline);
  writeAnswer(r, reply_);
  return r.status;
}

void Service::recordCompute(double compute_us) noexcept {
  window_us_[window_count_ % kWindowSamples] = compute_us;
  ++window_count_;
  window_max_us_ = std::max(window_max_us_, compute_us);
}

void Service::reload(std::unique_ptr<const runtime::RuntimeModel> next, const std::string& path) {
  STEPCAL_INVARIANT(next != nullptr, "reload needs a model");
  checkMessageJoints(*next, path);
  const std::lock_guard<std::mutex> lock(reload_mutex_);
  WorkspaceSlot* in_service = nullptr;
  WorkspaceSlot* incoming = nullptr;
  for (WorkspaceSlot& slot : slots_) {
    (slot.model.load(std::memory_order_acquire) != nullptr ? in_service : incoming) = &slot;
  }
  STEPCAL_INVARIANT(in_service != nullptr && incoming != nullptr,
                    "one workspace slot holds the model in service, the other is free");
  incoming->workspace = runtime::makeWorkspace(*next);
  incoming->model_path = path;
  incoming->model.store(next.get(), std::memory_order_release);
  models_.swap(std::move(next));  // returns once no request holds the previous model
  in_service->model.store(nullptr, std::memory_order_release);
  in_service->workspace = runtime::Workspace{};
  in_service->model_path.clear();
}

void Service::reloadFile(const std::string& path) {
  reload(runtime::RuntimeModel::load(path), path);
}

const stepcal_lcm::runtime_status_t& Service::status(bool realtime) {
  status_.utime = unixMicroseconds();
  {
    const runtime::ModelHandle::Guard model = models_.acquire(kServingReaderSlot);
    STEPCAL_INVARIANT(model, "the serving reader slot is held twice or no model is in service");
    status_.model_id = static_cast<int64_t>(model->model_id);
    const std::string& path = slotOf(model.get()).model_path;
    if (status_.model_path != path) status_.model_path = path;
  }
  status_.requests = counters_.requests;
  status_.replies = counters_.replies;
  std::copy(counters_.status_counts.begin(), counters_.status_counts.end(),
            status_.status_counts);
  const size_t kept = std::min(window_count_, kWindowSamples);
  std::copy(window_us_.begin(), window_us_.begin() + long(kept), window_sorted_us_.begin());
  const LatencySummary window = summarizeLatencies(window_sorted_us_.data(), kept);
  status_.p50_us = window.p50_us;
  status_.p99_us = window.p99_us;
  status_.max_us = window_max_us_;
  status_.realtime = realtime ? 1 : 0;
  status_.old_version_requests = counters_.old_version;
  status_.authenticated = verifier_ ? 1 : 0;
  status_.forged_requests = counters_.forged;
  status_.replayed_requests = counters_.replayed;
  window_count_ = 0;
  window_max_us_ = 0.0;
  return status_;
}

}  // namespace stepcal::service
