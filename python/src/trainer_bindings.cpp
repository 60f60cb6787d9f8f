// stepcal.Campaign, stepcal.calibrate and stepcal.diagnose (docs/python.md, "The trainer").
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <pybind11/stl.h>

#include "bindings.hpp"
#include "model_handle.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/diagnosis_report.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::python {
namespace {

using CampaignPtr = std::shared_ptr<const Campaign>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

py::object namespaceOf(const py::dict& fields) {
  return py::module_::import("types").attr("SimpleNamespace")(**fields);
}

/// The campaign's rows as columns: numpy arrays (SI: rad, N, N·m, m; NaN where a row has no
/// value) and lists of text.
py::dict measurementColumns(const Campaign& c) {
  const auto rows = ssize_t(c.rows.size());
  const ssize_t n = c.joint_count;
  py::array_t<int64_t> seq(rows);
  using Shape = std::vector<ssize_t>;
  py::array_t<double> load(Shape{rows}), q(Shape{rows, n}), wrench(Shape{rows, 6}),
      position(Shape{rows, 3}), quaternion(Shape{rows, 4}), temp(Shape{rows}),
      pose(Shape{rows, 4, 4});
  py::list pose_id, set;
  auto qm = q.mutable_unchecked<2>();
  auto wm = wrench.mutable_unchecked<2>();
  auto pm = position.mutable_unchecked<2>();
  auto om = quaternion.mutable_unchecked<2>();
  auto xm = pose.mutable_unchecked<3>();
  for (ssize_t i = 0; i < rows; ++i) {
    const Measurement& r = c.rows[size_t(i)];
    seq.mutable_data()[i] = r.seq;
    load.mutable_data()[i] = r.load_kg;
    temp.mutable_data()[i] = r.temp_c ? *r.temp_c : kNaN;
    pose_id.append(r.pose_id);
    set.append(toString(r.set));
    for (ssize_t k = 0; k < n; ++k) qm(i, k) = r.q_rad(k);
    for (int k = 0; k < 6; ++k) wm(i, k) = r.has_wrench ? r.wrench_Sensor(k) : kNaN;
    for (int k = 0; k < 3; ++k) pm(i, k) = r.p_TipInTracker_m(k);
    const double quat[4] = {r.q_TrackerTip.w(), r.q_TrackerTip.x(), r.q_TrackerTip.y(),
                            r.q_TrackerTip.z()};
    for (int k = 0; k < 4; ++k) om(i, k) = r.has_orientation ? quat[k] : kNaN;
    const Eigen::Matrix4d X = r.X_TrackerTip().matrix();
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) xm(i, a, b) = X(a, b);
    }
  }
  py::dict out;
  out["seq"] = seq;
  out["pose_id"] = pose_id;
  out["set"] = set;
  out["load_kg"] = load;
  out["q_rad"] = q;
  out["wrench"] = wrench;
  out["position_m"] = position;
  out["quaternion_wxyz"] = quaternion;
  out["temp_c"] = temp;
  out["pose"] = pose;
  return out;
}

/// A list of JSON objects with the same keys as columns: numpy arrays of numbers (NaN for null),
/// lists of anything else.
py::dict columnsOf(const nlohmann::json& records) {
  py::dict out;
  if (!records.is_array() || records.empty()) return out;
  for (const auto& item : records.front().items()) {
    const std::string key = item.key();
    bool numeric = true, any_number = false;
    for (const auto& record : records) {
      const auto& v = record.contains(key) ? record.at(key) : nlohmann::json();
      numeric = numeric && (v.is_number() || v.is_null());
      any_number = any_number || v.is_number();
    }
    if (numeric && any_number) {
      py::array_t<double> column(ssize_t(records.size()));
      for (size_t i = 0; i < records.size(); ++i) {
        const auto& v = records[i].contains(key) ? records[i].at(key) : nlohmann::json();
        column.mutable_data()[i] = v.is_null() ? kNaN : v.get<double>();
      }
      out[py::str(key)] = column;
    } else {
      py::list column;
      for (const auto& record : records) {
        column.append(toPython(record.contains(key) ? record.at(key) : nlohmann::json()));
      }
      out[py::str(key)] = column;
    }
  }
  return out;
}

trainer::CalibrationOptions calibrationOptions(int gpr_points) {
  if (gpr_points < 2) {
    throw InputError("gpr_points " + std::to_string(gpr_points) +
                     ": expected at least 2 training points (default " +
                     std::to_string(trainer::CalibrationOptions{}.gpr_max_points) + ")");
  }
  trainer::CalibrationOptions options;
  options.gpr_max_points = gpr_points;
  return options;
}

py::object calibrate(const CampaignPtr& campaign, int gpr_points) {
  const trainer::CalibrationOptions options = calibrationOptions(gpr_points);
  std::optional<trainer::CalibrationOutcome> outcome;
  std::optional<CalibratedModel> model;
  nlohmann::json report;
  {
    const py::gil_scoped_release unlocked;
    outcome = trainer::calibrateCampaign(*campaign, options);
    model = trainer::modelFromOutcome(*campaign, *outcome);
    report = report::reportJson(*campaign, *outcome);
  }
  py::dict row_errors;
  for (const auto& [method, errors] : outcome->row_errors) {
    py::array_t<double> mm(ssize_t(errors.size()));
    for (size_t i = 0; i < errors.size(); ++i) mm.mutable_data()[i] = kMmPerM * errors[i].position_m;
    row_errors[py::str(method)] = mm;
  }
  py::dict fields;
  fields["report"] = toPython(report);
  // Every row group (the report's validation and fit tables), each with its set.
  fields["accuracy"] = columnsOf(report::accuracyJson(outcome->accuracy));
  fields["stiffness"] = columnsOf(report.at("stiffness_nm_per_rad"));
  fields["row_position_errors_mm"] = row_errors;
  fields["model"] = py::cast(ModelHandle(std::move(*model)));
  return namespaceOf(fields);
}

/// The gain table with names that say which model each column is: the report's gpr_* (the
/// starting model with its own GPR) as before_gpr_*, beside after_gpr_* (the extended model with
/// its refitted GPR), before_* and after_* (the physical models).
nlohmann::json gainColumnsNamed(const nlohmann::json& gain) {
  constexpr std::string_view kStartingGpr = "gpr_";
  nlohmann::json out = nlohmann::json::array();
  for (const nlohmann::json& row : gain) {
    nlohmann::json named = nlohmann::json::object();
    for (const auto& item : row.items()) {
      const std::string& key = item.key();
      const bool starting_gpr = key.compare(0, kStartingGpr.size(), kStartingGpr) == 0;
      named[starting_gpr ? "before_" + key : key] = item.value();
    }
    out.push_back(std::move(named));
  }
  return out;
}

py::object diagnose(const CampaignPtr& campaign, const std::optional<ModelHandle>& start,
                    int gpr_points) {
  trainer::DiagnoseOptions options;
  options.calibration = calibrationOptions(gpr_points);
  std::optional<trainer::Diagnosis> diagnosis;
  nlohmann::json report;
  {
    const py::gil_scoped_release unlocked;
    const auto begin = std::chrono::steady_clock::now();
    const CalibratedModel model =
        start ? start->runtime()->file
              : trainer::modelFromOutcome(
                    *campaign, trainer::calibrateCampaign(*campaign, options.calibration));
    const double seconds_calibrate =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    diagnosis = trainer::diagnose(*campaign, model, options);
    report = report::diagnosisJson(*diagnosis, seconds_calibrate);
  }
  py::dict fields;
  fields["verdict"] = report.at("verdict").get<std::string>();
  fields["effects"] = toPython(report.at("effects"));
  fields["gain"] = columnsOf(gainColumnsNamed(report.at("gain")));
  fields["report"] = toPython(report);
  fields["model"] = py::cast(ModelHandle(diagnosis->extended_model));
  return namespaceOf(fields);
}

}  // namespace

void bindTrainer(py::module_& m) {
  py::class_<Campaign, std::shared_ptr<Campaign>>(
      m, "Campaign", "A measurement campaign (docs/campaign-format.md), read strictly")
      .def_static("load", [](const std::string& path) {
             return std::make_shared<Campaign>(readCampaign(path));
           }, py::arg("path"),
           "Reads a campaign folder; raises stepcal.InputError naming the file, line and column")
      .def_static("merge", [](const std::vector<std::shared_ptr<Campaign>>& campaigns) {
             std::vector<Campaign> copies;
             for (const auto& c : campaigns) copies.push_back(*c);
             return std::make_shared<Campaign>(mergeCampaigns(std::move(copies)));
           }, py::arg("campaigns"),
           "Several campaigns of one robot as one, for calibrate (`stepcal calibrate DIR DIR ...`: "
           "one geometry, each campaign its own tracker registration and tool); raises "
           "stepcal.InputError naming the campaign and the field that differs")
      .def_property_readonly("sessions", [](const Campaign& c) { return c.sessionCount(); },
           "number of campaigns merged into it (1 for a campaign read from one folder)")
      .def_readonly("directory", &Campaign::directory)
      .def_readonly("joint_count", &Campaign::joint_count)
      .def_readonly("base_link", &Campaign::base_link)
      .def_readonly("tip_link", &Campaign::tip_link)
      .def_readonly("sensor_link", &Campaign::sensor_link)
      .def("__len__", [](const Campaign& c) { return c.rows.size(); })
      .def_property_readonly("measurements", &measurementColumns,
           "the rows as columns: seq, pose_id, set, load_kg, q_rad (N, n), wrench (N, 6; NaN: no "
           "reading), position_m (N, 3), quaternion_wxyz (N, 4; NaN: position only), temp_c (N; "
           "NaN: none), pose (N, 4, 4; the measured pose, identity rotation where position only)");

  m.def("calibrate", &calibrate, py::arg("campaign"),
        py::arg("gpr_points") = trainer::CalibrationOptions{}.gpr_max_points,
        "All three steps on a campaign (`stepcal calibrate`). Returns report (the dict `stepcal "
        "calibrate --json` prints), accuracy (one row per method, set and load: method, set, "
        "load_kg, rows, mean/rms/max_position_mm, mean_orientation_deg) and stiffness (as "
        "columns: numpy arrays and lists), row_position_errors_mm (method -> one error per "
        "campaign row) and model (stepcal.Model).");
  m.def("diagnose", &diagnose, py::arg("campaign"), py::arg("model") = py::none(),
        py::arg("gpr_points") = trainer::CalibrationOptions{}.gpr_max_points,
        "What the physical model gets wrong (`stepcal diagnose`), from the given model or a "
        "calibration of the campaign. Returns verdict ('found', 'none', 'unexplained'), effects "
        "(each with its name, joint(s), parameters and uncertainty (1-σ), cross-validated gain "
        "and p-value), gain (per validation load, as columns: before_* the starting physical "
        "model, before_gpr_* it with its GPR, after_* the extended physical model, after_gpr_* it "
        "with its refitted GPR), report (the dict `stepcal diagnose --json` prints; its gain "
        "says gpr_* for before_gpr_*) and model (the extended stepcal.Model).");
}

}  // namespace stepcal::python
