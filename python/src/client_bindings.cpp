// stepcal.Client: requests to the stepcal-runtime daemon and their replies over LCM, through
// LCM's C library and the wire contract and requester stepcal-client uses too
// (stepcal/service/request.hpp, lcm_requester.hpp; docs/python.md, "The daemon from Python").
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include <lcm/lcm.h>
#include <stepcal_lcm/correction_reply_t.hpp>
#include <stepcal_lcm/correction_request_t.hpp>

#include "bindings.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_requester.hpp"
#include "stepcal/service/request.hpp"

namespace stepcal::python {
namespace {

using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_request_t;
constexpr int kJoints = service::kMessageJoints;

template <size_t N>
py::array_t<double> arrayOf(const double (&values)[N]) {
  py::array_t<double> out(static_cast<ssize_t>(N));
  std::copy(values, values + N, out.mutable_data());
  return out;
}

/// Copies `count` numbers of a Python sequence or array into out; ValueError names `what`.
void copyValues(const py::handle& value, int count, double* out, const char* what) {
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!array || array.ndim() != 1 || array.shape(0) != count) {
    throw py::value_error(std::string(what) + ": expected " + std::to_string(count) + " numbers");
  }
  std::copy(array.data(), array.data() + count, out);
}

class Client {
 public:
  Client(std::string lcm_url, double timeout_ms, const py::object& key_file)
      : url_(std::move(lcm_url)), timeout_ms_(timeout_ms) {
    if (!(timeout_ms_ > 0.0)) throw py::value_error("timeout_ms: expected a time > 0");
    std::optional<service::CellKey> key;
    if (!key_file.is_none()) key = service::CellKey::load(py::str(key_file).cast<std::string>());
    lcm_ = lcm_create(url_.c_str());
    if (lcm_ == nullptr) throw InputError("lcm_url '" + url_ + "': LCM cannot open it");
    requester_.emplace(lcm_, key);
    next_id_ = int64_t(getpid()) << 32;
  }
  ~Client() {
    requester_.reset();  // unsubscribes: before the LCM instance goes
    lcm_destroy(lcm_);
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  py::object forward(const py::handle& q, const py::object& wrench, double temp_c,
                     int deadline_us, const py::object& terms) {
    correction_request_t request = newRequest(wrench, temp_c, deadline_us, terms);
    request.mode = correction_request_t::MODE_FORWARD;
    copyValues(q, kJoints, request.q_rad, "q");
    return exchange(request);
  }

  py::object inverse(const py::handle& position_m, const py::handle& quaternion_wxyz,
                     const py::handle& seed, const py::object& wrench, double temp_c,
                     int deadline_us, const py::object& terms) {
    correction_request_t request = newRequest(wrench, temp_c, deadline_us, terms);
    request.mode = correction_request_t::MODE_INVERSE;
    copyValues(position_m, 3, request.desired_position_m, "position_m");
    copyValues(quaternion_wxyz, 4, request.desired_quaternion_wxyz, "quaternion_wxyz");
    copyValues(seed, kJoints, request.seed_q_rad, "seed");
    return exchange(request);
  }

  const std::string& url() const { return url_; }

 private:
  /// A version-3 request with the call's terms; the pose fields of the mode are the caller's.
  correction_request_t newRequest(const py::object& wrench, double temp_c, int deadline_us,
                                  const py::object& terms_arg) {
    const runtime::CallTerms terms = termsOf(terms_arg);
    correction_request_t request = service::blankRequest();
    request.request_id = ++next_id_;
    request.temp_c = temp_c;
    request.deadline_us = deadline_us;
    request.frame = int8_t(terms.frame);
    toPositionQuaternion(terms.X_BaseUser, request.user_frame_position_m,
                         request.user_frame_quaternion_wxyz);
    request.tool_from = int8_t(terms.tool_from);
    toPositionQuaternion(terms.X_Tool, request.tool_position_m, request.tool_quaternion_wxyz);
    if (terms.load_from == runtime::LoadFrom::kPayload) {
      if (!wrench.is_none()) throw py::value_error("wrench and terms.payload_kg: give one load, not both");
      request.wrench_source = correction_request_t::WRENCH_PAYLOAD;
      request.payload_kg = terms.payload.mass_kg;
      request.payload_cog_frame = int8_t(terms.payload.frame);
      for (int k = 0; k < 3; ++k) request.payload_cog_m[k] = terms.payload.p_CoG_m(k);
    } else if (wrench.is_none()) {
      request.wrench_source = correction_request_t::WRENCH_LIVE_SENSOR;
    } else {
      request.wrench_source = correction_request_t::WRENCH_GIVEN;
      copyValues(wrench, 6, request.wrench, "wrench");
    }
    return request;
  }

  /// Sends the request and waits for its reply (LcmRequester: sealed, verified, a daemon of
  /// message version 1 or 2 told apart). No reply: TimeoutError, saying why when the refused replies
  /// do.
  py::object exchange(correction_request_t& request) {
    const int64_t request_id = request.request_id;
    const service::RequesterCounters before = requester_->counters();
    std::optional<correction_reply_t> reply;
    {
      const py::gil_scoped_release unlocked;
      try {
        reply = requester_->exchange(request, request_id,
                                     std::chrono::microseconds(int64_t(timeout_ms_ * 1e3)));
      } catch (const InputError&) {
        throw InputError("lcm_url '" + url_ + "': the request could not be sent");
      }
    }
    if (!reply) {
      std::string message = "no reply from stepcal-runtime on " + url_ + " within " +
                            std::to_string(int(timeout_ms_)) + " ms (request " +
                            std::to_string(request_id) + ")";
      for (const std::string& reason : requester_->explainSilence("key_file", before)) {
        message += "; " + reason;
      }
      PyErr_SetString(PyExc_TimeoutError, message.c_str());
      throw py::error_already_set();
    }
    return replyObject(*reply);
  }

  static py::object replyObject(const correction_reply_t& r) {
    py::dict f;
    f["request_id"] = r.request_id;
    f["status"] = statusObject(r.status);
    f["q_target_rad"] = arrayOf(r.q_target_rad);
    f["commanded_position_m"] = arrayOf(r.commanded_position_m);
    f["commanded_quaternion_wxyz"] = arrayOf(r.commanded_quaternion_wxyz);
    f["predicted_position_m"] = arrayOf(r.predicted_position_m);
    f["predicted_quaternion_wxyz"] = arrayOf(r.predicted_quaternion_wxyz);
    f["gpr_std"] = arrayOf(r.gpr_std);
    f["uncovered_joints"] = r.uncovered_joints;
    f["iterations"] = r.iterations;
    f["compute_ns"] = r.compute_ns;
    f["wrench_stamp_ns"] = r.wrench_stamp_ns;
    f["wrench"] = arrayOf(r.wrench);
    f["model_id"] = modelIdObject(uint64_t(r.model_id));
    f["residual_position_m"] = r.residual_position_m;
    f["residual_orientation_rad"] = r.residual_orientation_rad;
    f["position_rms_m"] = r.position_rms_m;
    f["position_bound_m"] = r.position_bound_m;
    f["orientation_rms_rad"] = r.orientation_rms_rad;
    f["orientation_bound_rad"] = r.orientation_bound_rad;
    return py::module_::import("types").attr("SimpleNamespace")(**f);
  }

  std::string url_;
  double timeout_ms_;
  lcm_t* lcm_ = nullptr;
  std::optional<service::LcmRequester> requester_;
  int64_t next_id_ = 0;
};

}  // namespace

void bindClient(py::module_& m) {
  m.attr("DEFAULT_LCM_URL") = service::kDefaultLcmUrl;
  py::class_<Client>(m, "Client",
                     "The controller's side of the daemon's wire: one request at a time, the "
                     "reply matched by its request id (LCM's C library; no Python LCM needed)")
      .def(py::init<std::string, double, py::object>(), py::arg("lcm_url") = service::kDefaultLcmUrl,
           py::arg("timeout_ms") = 100.0, py::arg("key_file") = py::none(),
           "Opens LCM at lcm_url (the daemon's); a reply later than timeout_ms raises "
           "TimeoutError. key_file: the cell key of a daemon run with --key-file (requests are "
           "signed with it, and only replies it verifies are taken); None: no authentication.")
      .def_property_readonly("lcm_url", &Client::url)
      .def("forward", &Client::forward, py::arg("q"), py::arg("wrench") = py::none(),
           py::arg("temp_c") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("deadline_us") = 0, py::arg("terms") = py::none(),
           "The pose the robot's TCP reaches at joints q (6 values, rad): the daemon's reply "
           "(status, predicted_position_m, predicted_quaternion_wxyz, gpr_std, wrench, model_id, "
           "…). wrench: 6 values on the F/T sensor [N, N·m], or None for the daemon's live "
           "sensor (or the payload of terms). terms: a stepcal.CallTerms (frame, tool, payload), "
           "None for the tracker frame and the measured target.")
      .def("inverse", &Client::inverse, py::arg("position_m"), py::arg("quaternion_wxyz"),
           py::arg("seed"), py::arg("wrench") = py::none(),
           py::arg("temp_c") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("deadline_us") = 0, py::arg("terms") = py::none(),
           "Joint targets that bring the TCP to the desired pose (m, unit quaternion; in the "
           "frame of terms, None: the tracker frame) from seed (6 values, rad): the daemon's "
           "reply (status, q_target_rad, commanded_*, predicted_*, iterations, residuals, …).");
}

}  // namespace stepcal::python
