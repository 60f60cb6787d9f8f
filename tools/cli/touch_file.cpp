#include "touch_file.hpp"

#include <algorithm>
#include <array>
#include <fstream>
#include <map>
#include <sstream>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::cli {
namespace {

const std::array<const char*, 3> kPointColumns = {"x_mm", "y_mm", "z_mm"};
const std::array<const char*, 3> kNominalColumns = {"nx_mm", "ny_mm", "nz_mm"};
const std::array<const char*, 6> kWrenchColumns = {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"};
const std::array<const char*, 3> kPointWords = {"origin", "x", "xy"};

class TouchLine {
 public:
  TouchLine(const std::string& path, const std::map<std::string, int>& index, int line,
            std::vector<std::string_view> fields)
      : path_(path), index_(index), line_(line), fields_(std::move(fields)) {}

  [[noreturn]] void fail(const std::string& column, const std::string& what) const {
    throw InputError(what, path_, line_, column);
  }
  bool has(const std::string& column) const { return index_.count(column) > 0; }
  std::string_view field(const std::string& column) const {
    return fields_[size_t(index_.at(column))];
  }
  double number(const std::string& column, const char* unit) const {
    const std::string_view text = field(column);
    const std::optional<double> value = parseFinite(text);
    if (!value) {
      fail(column, (text.empty() ? std::string("empty") : inQuotes(text) + " is not a number") +
                       "; expected a finite number in " + unit);
    }
    return *value;
  }
  /// Whether the group's columns are all there and filled (false when absent or all empty on
  /// this line, if emptiness is allowed); fails when only some are filled.
  template <typename Names>
  bool filled(const Names& columns, bool may_be_empty) const {
    if (!has(columns[0])) return false;
    int empty = 0;
    for (const auto& c : columns) empty += field(c).empty();
    if (empty == int(columns.size()) && may_be_empty) return false;
    for (const auto& c : columns) {
      if (field(c).empty()) {
        fail(c, "empty while other columns of its group are filled; expected all of " +
                    std::string(columns[0]) + " … " + columns[columns.size() - 1]);
      }
    }
    return true;
  }

 private:
  const std::string& path_;
  const std::map<std::string, int>& index_;
  int line_;
  std::vector<std::string_view> fields_;
};

std::vector<std::string> jointColumns(int joints) {
  std::vector<std::string> names;
  for (int j = 1; j <= joints; ++j) names.push_back("q" + std::to_string(j) + "_deg");
  return names;
}

/// The header's columns, each once and each known; the joint columns complete or absent.
std::map<std::string, int> readHeader(const std::string& path, std::string_view header,
                                      const std::vector<std::string>& joint_names) {
  std::map<std::string, int> index;
  std::vector<std::string> known = {"id", "point"};
  known.insert(known.end(), joint_names.begin(), joint_names.end());
  for (const auto* group : {&kPointColumns, &kNominalColumns}) known.insert(known.end(), group->begin(), group->end());
  known.insert(known.end(), kWrenchColumns.begin(), kWrenchColumns.end());
  const std::vector<std::string_view> names = splitFields(header);
  for (size_t i = 0; i < names.size(); ++i) {
    const std::string name(names[i]);
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      throw InputError("unknown column " + inQuotes(name) + " (column " + std::to_string(i + 1) +
                           "); expected id, q1_deg … q" + std::to_string(joint_names.size()) +
                           "_deg, x_mm y_mm z_mm, fx_n … mz_nm, point, nx_mm ny_mm nz_mm",
                       path, 1, name);
    }
    if (!index.emplace(name, int(i)).second) {
      throw InputError("appears twice; expected each column once", path, 1, name);
    }
  }
  return index;
}

Touch readTouch(const TouchLine& in, int line, const std::vector<std::string>& joint_names) {
  Touch touch;
  touch.line = line;
  if (in.has("id")) touch.id = std::string(in.field("id"));
  if (in.filled(joint_names, true)) {
    JointVector q(Eigen::Index(joint_names.size()));
    for (size_t j = 0; j < joint_names.size(); ++j) q[Eigen::Index(j)] = in.number(joint_names[j], "degrees") * kRadPerDeg;
    touch.q_rad = q;
  }
  if (in.filled(kPointColumns, true)) {
    Vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = in.number(kPointColumns[size_t(a)], "mm") * kMPerMm;
    touch.p_InTracker_m = p;
  }
  if (!touch.q_rad && !touch.p_InTracker_m) {
    in.fail(joint_names[0], "neither joints nor a measured point; expected q1_deg … or x_mm …");
  }
  if (in.filled(kWrenchColumns, false)) {
    Vec6 w;
    for (int a = 0; a < 6; ++a) w[a] = in.number(kWrenchColumns[size_t(a)], a < 3 ? "N" : "N·m");
    touch.wrench_Sensor = w;
  }
  if (in.filled(kNominalColumns, false)) {
    Vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = in.number(kNominalColumns[size_t(a)], "mm") * kMPerMm;
    touch.p_NominalInFrame_m = p;
  }
  if (in.has("point")) {
    touch.point = std::string(in.field("point"));
    if (std::find(kPointWords.begin(), kPointWords.end(), touch.point) == kPointWords.end()) {
      in.fail("point", inQuotes(touch.point) + " is not a point of the three-point method; "
                       "expected origin, x or xy");
    }
  }
  return touch;
}

}  // namespace

double modelPointSigma(const CalibratedModel& model) {
  const std::string full = trainer::modelLayers(model).back().first;
  double mean_m = 0.0;
  for (const ValidationFigure& v : model.provenance.validation) {
    if (v.method == full) mean_m = std::max(mean_m, v.mean_position_m);
  }
  return mean_m / kMeanNormPerAxisSigma;
}

double modelOrientationSigma(const CalibratedModel& model) {
  const std::string full = trainer::modelLayers(model).back().first;
  double mean_rad = 0.0;
  for (const ValidationFigure& v : model.provenance.validation) {
    if (v.method == full) mean_rad = std::max(mean_rad, v.mean_orientation_rad);
  }
  return mean_rad / kMeanNormPerAxisSigma;
}

std::vector<Pose> touchPoses(const runtime::RuntimeModel& model, const std::vector<Touch>& touches,
                             const std::optional<runtime::Payload>& payload,
                             const std::string& path) {
  runtime::Workspace ws = runtime::makeWorkspace(model);
  std::vector<Pose> poses;
  for (const Touch& touch : touches) {
    if (!touch.q_rad) throw InputError("no joint reading; expected q1_deg …", path, touch.line);
    runtime::CallTerms terms;
    if (payload) {
      terms.load_from = runtime::LoadFrom::kPayload;
      terms.payload = *payload;
    } else {
      terms.wrench_Sensor = touch.wrench_Sensor.value_or(model.unloaded_wrench_Sensor);
    }
    const runtime::ForwardResult forward =
        runtime::correctForward(model, ws, *touch.q_rad, terms, runtime::kUnknownTemperature_c);
    if (forward.status != runtime::Status::kOk && forward.status != runtime::Status::kOutOfDomain) {
      throw InputError(std::string("the model cannot evaluate these joints: ") +
                           runtime::toString(forward.status),
                       path, touch.line);
    }
    poses.push_back(forward.X_TrackerTip);
  }
  return poses;
}

std::vector<Touch> readCampaignShots(const std::string& path, const CalibratedModel& model,
                                     const std::string& model_path) {
  const Campaign campaign = readCampaign(path);
  requireCampaignOfModelRobot(model, campaign, model_path);
  std::vector<Touch> touches;
  for (const Measurement& row : campaign.rows) {
    Touch touch;
    touch.line = row.source_line;
    touch.id = row.pose_id;
    touch.q_rad = row.q_rad;
    touch.p_InTracker_m = row.p_TipInTracker_m;
    if (row.has_orientation) touch.R_TrackerTcp = row.q_TrackerTip.toRotationMatrix();
    if (row.has_wrench) touch.wrench_Sensor = row.wrench_Sensor;
    touches.push_back(touch);
  }
  if (touches.empty()) throw InputError("the campaign has no rows", path);
  return touches;
}

std::vector<Touch> readTouchFile(const std::string& path, int joints) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw InputError("cannot open the touch file", path);
  std::stringstream buffer;
  buffer << file.rdbuf();
  const std::string text = buffer.str();
  const std::vector<std::string_view> lines = splitLines(withoutByteOrderMark(text));
  if (lines.empty()) throw InputError("empty; expected a header line of column names", path, 1);
  const std::vector<std::string> joint_names = jointColumns(joints);
  const std::map<std::string, int> index = readHeader(path, lines[0], joint_names);
  std::vector<Touch> touches;
  for (size_t i = 1; i < lines.size(); ++i) {
    const int line = int(i) + 1;
    if (lines[i].empty()) continue;
    std::vector<std::string_view> fields = splitFields(lines[i]);
    if (fields.size() != index.size()) {
      throw InputError(std::to_string(fields.size()) + " fields; expected " +
                           std::to_string(index.size()) + ", one per column of the header",
                       path, line);
    }
    touches.push_back(readTouch(TouchLine(path, index, line, std::move(fields)), line, joint_names));
  }
  if (touches.empty()) throw InputError("no touches after the header", path, 1);
  return touches;
}

}  // namespace stepcal::cli
