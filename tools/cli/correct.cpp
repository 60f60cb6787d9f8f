// `stepcal correct MODEL PROGRAM --out CORRECTED`: an offline program's targets (poses in a
// chosen frame, or the nominal joint targets of an offline programming tool), each with its
// tool and payload, corrected with a model: joint targets and pre-distorted poses that make the
// real robot reach them, with each line's status, predicted residual and coverage, and a
// summary. The file formats are in docs/runtime.md ("Correcting an offline program").
#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/atomic_file.hpp"
#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/exit_codes.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/programs/configuration.hpp"
#include "stepcal/programs/program.hpp"
#include "stepcal/report/text_format.hpp"
#include "stepcal/runtime/closed_form_seed.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/twin/twin.hpp"
#include "program_load.hpp"
#include "subcommands.hpp"
#include "tool_file.hpp"

namespace stepcal::cli {
namespace {

using report::format;

constexpr int kStatusCount = 7;

struct CorrectArgs {
  std::string model, program, out;
  std::string frame = "tracker";    ///< tracker | base | user: the frame of the pose targets
  std::vector<double> user_frame;   ///< --frame user: x y z (mm) qw qx qy qz, in the base frame
  std::vector<double> seed_deg;     ///< the first pose target's seed when the file has none, deg
  std::string truth;                ///< the twin's truth.json: each target run on it too
  bool json = false;                ///< the summary as JSON
  std::string format;               ///< csv | krl | rapid | urscript | tp; empty: from the file
  /// NAME=x,y,z,qw,qx,qy,qz (mm): a tool (flange frame) or base (robot base frame) the program
  /// names without its values (TOOL_DATA[1], UF 2, UT 9).
  std::vector<std::string> program_frames;
  /// NAME=kg,x,y,z (mm): a load the program names without its values (LOAD_DATA[1], PAYLOAD[2]).
  std::vector<std::string> program_loads;
  /// A robot program's tool calibrated on the model (stepcal tool --out): TOOL.json, or
  /// NAME=TOOL.json per tool the program names.
  std::vector<std::string> tool_files;
};

const std::array<const char*, 7> kPoseColumns = {"x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"};
const std::array<const char*, 7> kToolColumns = {"tool_x_mm", "tool_y_mm", "tool_z_mm", "tool_qw",
                                                 "tool_qx",   "tool_qy",   "tool_qz"};
const std::array<const char*, 3> kCogColumns = {"cog_x_mm", "cog_y_mm", "cog_z_mm"};

/// One target of the program, in SI.
struct ProgramLine {
  int line = 0;
  std::string id;
  bool joint_target = false;           ///< q_rad is a nominal joint target; else X_FrameTcp
  JointVector q_rad;                   ///< joint target, rad
  Pose X_FrameTcp = Pose::Identity();  ///< pose target in the program's frame, m
  std::optional<JointVector> seed_rad;
  runtime::CallTerms terms;
  double temp_c = runtime::kUnknownTemperature_c;
};

/// The header's columns and a line's fields, with errors that name the file, line and column.
class ProgramFile {
 public:
  ProgramFile(std::string path, std::string_view header) : path_(std::move(path)) {
    const std::vector<std::string_view> names = splitFields(header);
    names_.assign(names.begin(), names.end());
    for (size_t i = 0; i < names_.size(); ++i) {
      if (names_[i].empty()) {
        fail(1, "", "column " + std::to_string(i + 1) + " has an empty name");
      }
      if (!index_.emplace(names_[i], int(i)).second) {
        fail(1, names_[i], "appears twice (column " + std::to_string(i + 1) +
                               "); expected each column once");
      }
    }
  }

  [[noreturn]] void fail(int line, const std::string& column, const std::string& what) const {
    throw InputError(what, path_, line, column);
  }
  bool has(const std::string& name) const { return index_.count(name) > 0; }
  const std::vector<std::string>& names() const { return names_; }

  /// Splits a line into its fields; fails unless it has one per column.
  void read(int line, std::string_view text) {
    const std::vector<std::string_view> fields = splitFields(text);
    fields_.assign(fields.begin(), fields.end());
    line_ = line;
    if (fields_.size() != names_.size()) {
      fail(line, "", std::to_string(fields_.size()) + " fields; expected " +
                         std::to_string(names_.size()) + ", one per column of the header");
    }
  }
  const std::string& field(const std::string& name) const {
    return fields_[size_t(index_.at(name))];
  }
  /// Where a column is, for messages: "column 3".
  std::string where(const std::string& name) const {
    return "column " + std::to_string(index_.at(name) + 1);
  }
  double number(const std::string& name, const char* unit, int decimal_shift = 0) const {
    const std::string& text = field(name);
    const std::optional<double> value = parseFiniteShifted(text, decimal_shift);
    if (!value) {
      fail(line_, name, (text.empty() ? std::string("empty") : inQuotes(text) + " is not a number") +
                            " (" + where(name) + "); expected a finite number in " + unit);
    }
    return *value;
  }
  /// Whether every named column is empty on this line (false if any is not); fails when only
  /// some are.
  template <typename Names>
  bool allEmpty(const Names& columns, const std::string& what) const {
    int empty = 0;
    for (const auto& c : columns) empty += field(c).empty();
    if (empty != 0 && empty != int(columns.size())) {
      for (const auto& c : columns) {
        if (field(c).empty()) fail(line_, c, "empty (" + where(c) + ") while other " + what +
                                                 " columns are filled; expected all or none");
      }
    }
    return empty == int(columns.size());
  }
  /// A pose from 3 mm columns and a unit quaternion's 4.
  template <typename Names>
  Pose pose(const Names& columns) const {
    Vec3 p_m;
    for (int a = 0; a < 3; ++a) p_m[a] = number(columns[size_t(a)], "mm", -3);
    const Eigen::Quaterniond q(number(columns[3], "(unit quaternion)"),
                               number(columns[4], "(unit quaternion)"),
                               number(columns[5], "(unit quaternion)"),
                               number(columns[6], "(unit quaternion)"));
    if (!isUnitQuaternion(q)) {
      fail(line_, columns[3], "the quaternion " + std::string(columns[3]) + " … " + columns[6] +
                                  " has norm " + formatShortest(q.norm()) +
                                  "; expected a unit quaternion (within 1e-6)");
    }
    return poseFromPositionQuaternion(p_m, q);
  }
  /// One of `words` (its index).
  int word(const std::string& name, const std::vector<std::string>& words) const {
    const std::string& text = field(name);
    for (size_t i = 0; i < words.size(); ++i) {
      if (text == words[i]) return int(i);
    }
    std::string list;
    for (const std::string& w : words) list += (list.empty() ? "" : " or ") + w;
    fail(line_, name, inQuotes(text) + " (" + where(name) + "); expected " + list);
  }
  int line() const { return line_; }

 private:
  std::string path_;
  std::vector<std::string> names_;
  std::map<std::string, int> index_;
  std::vector<std::string> fields_;
  int line_ = 0;
};

std::string jointColumn(const char* prefix, int j) {
  return std::string(prefix) + "q" + std::to_string(j + 1) + "_deg";
}

std::vector<std::string> jointColumns(const char* prefix, int dof) {
  std::vector<std::string> columns;
  for (int j = 0; j < dof; ++j) columns.push_back(jointColumn(prefix, j));
  return columns;
}

/// The columns a program may have (for the unknown-column message).
std::vector<std::string> knownColumns(int dof) {
  std::vector<std::string> known = {"id"};
  known.insert(known.end(), kPoseColumns.begin(), kPoseColumns.end());
  for (const char* prefix : {"", "seed_"}) {
    const std::vector<std::string> joints = jointColumns(prefix, dof);
    known.insert(known.end(), joints.begin(), joints.end());
  }
  known.emplace_back("tool_from");
  known.insert(known.end(), kToolColumns.begin(), kToolColumns.end());
  known.emplace_back("payload_kg");
  known.insert(known.end(), kCogColumns.begin(), kCogColumns.end());
  known.emplace_back("cog_frame");
  known.emplace_back("temp_c");
  return known;
}

/// Whether a header has all or none of a group; fails when it has some.
template <typename Names>
bool headerHasGroup(const ProgramFile& file, const Names& columns, const std::string& what) {
  int present = 0;
  for (const auto& c : columns) present += file.has(c);
  if (present != 0 && present != int(columns.size())) {
    for (const auto& c : columns) {
      if (!file.has(c)) {
        file.fail(1, c, "missing while other " + what + " columns are there; expected all of " +
                            std::string(columns[0]) + " … " + std::string(columns[columns.size() - 1]));
      }
    }
  }
  return present != 0;
}

/// The program's lines (csv.hpp's end-of-file rule); fails on a NUL byte.
std::vector<std::string_view> programLines(std::string_view text, const std::string& path) {
  const std::vector<std::string_view> lines = splitLines(text);
  for (size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].find('\0') != std::string_view::npos) {
      throw InputError("holds a NUL byte; expected text", path, int(i + 1));
    }
  }
  return lines;
}

/// N when the header's joint-target columns are q1_deg … qN_deg, all of them; else 0 (none, or
/// some missing: the header checks name which).
int jointColumnCount(const ProgramFile& file) {
  int highest = 0;
  for (const std::string& name : file.names()) {
    if (name.size() < 6 || name[0] != 'q' || name.compare(name.size() - 4, 4, "_deg") != 0) continue;
    const std::string digits = name.substr(1, name.size() - 5);
    if (digits.empty() || digits.size() > 3 ||
        digits.find_first_not_of("0123456789") != std::string::npos) {
      continue;
    }
    highest = std::max(highest, std::stoi(digits));
  }
  for (int j = 0; j < highest; ++j) {
    if (!file.has(jointColumn("", j))) return 0;
  }
  return highest;
}

/// Refuses joint targets of a robot with another joint count than the model's, by name: a
/// program carries no robot name, only its q1_deg … qN_deg columns.
void requireModelJointCount(const ProgramFile& file, const KinematicChain& model_robot) {
  const int columns = jointColumnCount(file);
  const int dof = model_robot.dof();
  if (columns == 0 || columns == dof) return;
  file.fail(1, jointColumn("", columns - 1),
            "joint targets q1_deg … q" + std::to_string(columns) + "_deg are of a robot with " +
                std::to_string(columns) + " joints; the model was calibrated for a robot with " +
                std::to_string(dof) + " (" + jointNameList(model_robot) + "), expected q1_deg … q" +
                std::to_string(dof) + "_deg (hint: a model corrects only the robot it was "
                "calibrated for)");
}

/// Reads a program strictly: every error names the file, the line and the column.
std::vector<ProgramLine> readProgram(const std::string& path, const KinematicChain& model_robot,
                                     const runtime::CallTerms& frame_terms, bool have_seed_option) {
  const int dof = model_robot.dof();
  const std::string text = readTextFile(path);
  const std::vector<std::string_view> lines = programLines(text, path);
  if (lines.empty() || lines[0].empty()) {
    throw InputError("the header line is empty; expected the column names (x_mm,…,qz or "
                     "q1_deg,… and the optional ones, docs/runtime.md)",
                     path, 1);
  }
  ProgramFile file(path, lines[0]);
  requireModelJointCount(file, model_robot);
  const std::vector<std::string> known = knownColumns(dof);
  for (const std::string& name : file.names()) {
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      file.fail(1, name, "unknown column; expected only " + list);
    }
  }
  const std::vector<std::string> joints = jointColumns("", dof), seeds = jointColumns("seed_", dof);
  const bool has_pose = headerHasGroup(file, kPoseColumns, "pose");
  const bool has_joints = headerHasGroup(file, joints, "joint target");
  const bool has_seed = headerHasGroup(file, seeds, "seed");
  const bool has_tool = headerHasGroup(file, kToolColumns, "tool");
  const bool has_cog = headerHasGroup(file, kCogColumns, "centre of gravity");
  if (!has_pose && !has_joints) {
    file.fail(1, "", "no target columns; expected the pose x_mm,y_mm,z_mm,qw,qx,qy,qz or the "
                     "joint targets q1_deg … q" + std::to_string(dof) + "_deg (or both)");
  }
  if (file.has("tool_from") && !has_tool) {
    file.fail(1, "tool_from", "without the tool columns tool_x_mm … tool_qz");
  }
  if (has_cog && !file.has("payload_kg")) file.fail(1, "cog_x_mm", "without payload_kg");
  if (file.has("cog_frame") && !has_cog) file.fail(1, "cog_frame", "without cog_x_mm … cog_z_mm");

  std::vector<ProgramLine> program;
  size_t last = lines.size();
  if (last > 1 && lines[last - 1].empty()) --last;  // the final newline
  for (size_t i = 1; i < last; ++i) {
    const int line = int(i + 1);
    if (lines[i].empty()) file.fail(line, "", "empty line; expected a target");
    file.read(line, lines[i]);
    ProgramLine p;
    p.line = line;
    if (file.has("id")) p.id = file.field("id");
    const bool pose_empty = !has_pose || file.allEmpty(kPoseColumns, "pose");
    const bool joints_empty = !has_joints || file.allEmpty(joints, "joint target");
    if (pose_empty == joints_empty) {
      file.fail(line, "", pose_empty ? "no target: expected the pose (x_mm … qz) or the joint "
                                       "target (q1_deg …) filled"
                                     : "both a pose and a joint target; expected one per line");
    }
    p.terms = frame_terms;
    if (has_tool) {
      p.terms.X_Tool = file.pose(kToolColumns);
      if (file.has("tool_from")) {
        p.terms.tool_from = runtime::ToolFrom(file.word("tool_from", {"target", "flange"}));
      }
    }
    p.terms.load_from = runtime::LoadFrom::kPayload;  // unloaded unless payload_kg says
    if (file.has("payload_kg")) {
      p.terms.payload.mass_kg = file.number("payload_kg", "kg");
      if (p.terms.payload.mass_kg < 0.0) {
        file.fail(line, "payload_kg", "negative (" + file.where("payload_kg") +
                                          "); expected a mass ≥ 0 kg");
      }
    }
    if (has_cog) {
      for (int a = 0; a < 3; ++a) p.terms.payload.p_CoG_m[a] = file.number(kCogColumns[size_t(a)], "mm", -3);
      if (file.has("cog_frame")) {
        p.terms.payload.frame = runtime::CogFrame(file.word("cog_frame", {"flange", "tool"}));
      }
    }
    if (file.has("temp_c") && !file.field("temp_c").empty()) {
      p.temp_c = file.number("temp_c", "°C");
      if (!runtime::validTemperature(p.temp_c)) {
        file.fail(line, "temp_c", formatShortest(p.temp_c) + " °C (" + file.where("temp_c") +
                                      "); expected −50 … 150, or empty when not measured");
      }
    }
    if (has_seed && !file.allEmpty(seeds, "seed")) {
      JointVector seed(dof);
      for (int j = 0; j < dof; ++j) seed[j] = file.number(seeds[size_t(j)], "degrees") * kRadPerDeg;
      p.seed_rad = seed;
    }
    p.joint_target = pose_empty;
    if (p.joint_target) {
      p.q_rad.resize(dof);
      for (int j = 0; j < dof; ++j) p.q_rad[j] = file.number(joints[size_t(j)], "degrees") * kRadPerDeg;
    } else {
      p.X_FrameTcp = file.pose(kPoseColumns);
      if (!p.seed_rad && program.empty() && !have_seed_option) {
        file.fail(line, "x_mm", "a pose target needs a seed where the search starts: give "
                                "seed_q1_deg … on this line, a line before it, or --seed");
      }
    }
    program.push_back(std::move(p));
  }
  if (program.empty()) throw InputError("no targets after the header", path, 1);
  return program;
}

/// Where the twin's true robot puts a line's TCP at joints q [rad], tracker frame.
Pose trueTcp(const twin::TwinRobot& truth, const runtime::RuntimeModel& model,
             const ProgramLine& line, const JointVector& q_rad) {
  const double load_kg = line.terms.payload.mass_kg;
  if (line.terms.tool_from == runtime::ToolFrom::kTarget) {
    return truth.X_TrackerTip(q_rad, load_kg, line.temp_c) * line.terms.X_Tool;
  }
  // The twin's flange keeps its nominal place on the joint-n frame (as its sensor does); the
  // frames are the deflected robot's (link angles, bearing tilts, lengths at temp_c).
  ChainWorkspace ws;
  truth.deflectedFrames(q_rad, load_kg, line.temp_c, ws);
  return truth.X_TrackerBase() * ws.X_RootFrame[size_t(q_rad.size())] *
         model.X_LastFlange_nominal * line.terms.X_Tool;
}

/// The controller's own inverse: the model's nominal chain where the model registered it, no
/// compliance, no GPR (what it would command without a correction).
std::unique_ptr<const runtime::RuntimeModel> nominalModel(const runtime::RuntimeModel& model) {
  CalibratedModel nominal;
  nominal.nominal_Base = model.file.nominal_Base;
  nominal.chain_Tracker = model.file.nominal_Base.rerooted(model.file.X_TrackerBase);
  nominal.X_TrackerBase = model.file.X_TrackerBase;
  nominal.sensor_frame = model.file.sensor_frame;
  nominal.gravity_Base = model.file.gravity_Base;
  return runtime::RuntimeModel::fromModel(nominal, 0);
}

struct PoseError {
  double position_m = 0.0, orientation_rad = 0.0;
};
PoseError errorBetween(const Pose& a, const Pose& b) {
  return {(a.translation() - b.translation()).norm(), lie::angleBetween(a.linear(), b.linear())};
}

struct ErrorStats {
  int count = 0;
  double sum_m = 0.0, max_m = 0.0, sum_rad = 0.0;
  void add(const PoseError& e) {
    ++count;
    sum_m += e.position_m;
    max_m = std::max(max_m, e.position_m);
    sum_rad += e.orientation_rad;
  }
  nlohmann::json toJson() const {
    return {{"targets", count},
            {"mean_position_mm", count ? sum_m / count * kMmPerM : 0.0},
            {"max_position_mm", max_m * kMmPerM},
            {"mean_orientation_deg", count ? sum_rad / count / kRadPerDeg : 0.0}};
  }
};

std::string number(double v, const char* fmt = "%.6f") { return format(fmt, v); }

void appendPose(std::string& out, const Pose& X) {
  double p_m[3], q_wxyz[4];
  toPositionQuaternion(X, p_m, q_wxyz);
  for (const double p : p_m) out += "," + number(p * kMmPerM, "%.6f");
  for (const double c : q_wxyz) out += "," + number(c, "%.9f");
}

runtime::PoseFrame parseFrame(const std::string& frame) {
  if (frame == "tracker") return runtime::PoseFrame::kTracker;
  if (frame == "base") return runtime::PoseFrame::kBase;
  if (frame == "user") return runtime::PoseFrame::kUser;
  throw InputError("--frame '" + frame + "': expected tracker, base or user");
}

runtime::CallTerms frameTerms(const CorrectArgs& args) {
  runtime::CallTerms frame_terms;
  frame_terms.frame = parseFrame(args.frame);
  if ((frame_terms.frame == runtime::PoseFrame::kUser) != !args.user_frame.empty()) {
    throw InputError("--user-frame x y z qw qx qy qz goes with --frame user, and --frame user needs it");
  }
  if (!args.user_frame.empty()) {
    const std::vector<double>& u = args.user_frame;
    const Eigen::Quaterniond q(u[3], u[4], u[5], u[6]);
    if (!(std::abs(q.norm() - 1.0) <= kQuaternionNormTolerance)) {
      throw InputError("--user-frame: the quaternion has norm " + formatShortest(q.norm()) +
                       "; expected a unit quaternion (within 1e-6)");
    }
    frame_terms.X_BaseUser.linear() = q.normalized().toRotationMatrix();
    frame_terms.X_BaseUser.translation() = Vec3(u[0], u[1], u[2]) * kMPerMm;
    if (looksLikeMetres(u[0], u[1], u[2])) {
      std::cerr << "stepcal correct: warning: --user-frame x y z lie within "
                << kLooksLikeMetresBelow_mm << " mm of the base: metres given where mm are expected?\n";
    }
  }
  return frame_terms;
}

/// --seed in radians; none when not given.
std::optional<JointVector> seedOption(const CorrectArgs& args, int dof) {
  std::optional<JointVector> seed_option;
  if (!args.seed_deg.empty()) {
    if (int(args.seed_deg.size()) != dof) {
      throw InputError("--seed has " + std::to_string(args.seed_deg.size()) +
                       " angles; the model has " + std::to_string(dof) + " joints");
    }
    seed_option = JointVector(dof);
    for (int j = 0; j < dof; ++j) (*seed_option)[j] = args.seed_deg[size_t(j)] * kRadPerDeg;
  }
  return seed_option;
}

/// Refuses a line that needs the flange when the model knows none.
void checkFlangeNeeds(const std::vector<ProgramLine>& program, const runtime::RuntimeModel& model,
                      const std::string& program_path) {
  for (const ProgramLine& p : program) {
    if (p.terms.tool_from == runtime::ToolFrom::kFlange && !model.has_flange) {
      throw InputError("tool_from flange, but the model knows no flange (its campaign.yaml names "
                       "no flange_link); give the tool from the measured target, or calibrate "
                       "with flange_link",
                       program_path, p.line, "tool_from");
    }
    if (p.terms.payload.mass_kg > 0.0 && p.terms.payload.frame == runtime::CogFrame::kFlange &&
        !model.has_flange) {
      throw InputError("a centre of gravity in the flange frame, but the model knows no flange; "
                       "give cog_frame tool",
                       program_path, p.line, "payload_kg");
    }
  }
}

/// --truth: the twin's true robot, and the controller's own inverse that commands it without a
/// correction (nominalModel).
struct TwinTruth {
  twin::TwinRobot robot;
  std::unique_ptr<const runtime::RuntimeModel> nominal;
  runtime::Workspace nominal_ws;
};

std::optional<TwinTruth> readTruth(const std::string& path, const runtime::RuntimeModel& model) {
  if (path.empty()) return std::nullopt;
  std::ifstream in(path);
  if (!in) throw InputError("--truth: cannot read the file", path);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("--truth: not JSON: ") + e.what(), path);
  }
  twin::TwinRobot robot = twin::TwinRobot::fromTruthJson(j);
  std::unique_ptr<const runtime::RuntimeModel> nominal = nominalModel(model);
  runtime::Workspace nominal_ws = runtime::makeWorkspace(*nominal);
  return TwinTruth{std::move(robot), std::move(nominal), std::move(nominal_ws)};
}

/// What the corrected program's lines came to.
struct Tally {
  std::array<long, kStatusCount> statuses{};
  long in_coverage = 0;
  ErrorStats before, after;  ///< on the twin: as commanded, as corrected
};

std::string correctedHeader(int dof, bool with_truth) {
  std::string out = "line,id,target,status";
  for (int j = 0; j < dof; ++j) out += ",q" + std::to_string(j + 1) + "_deg";
  out += ",x_mm,y_mm,z_mm,qw,qx,qy,qz,residual_mm,residual_deg,gpr_std_mm,in_coverage,"
         "uncovered_joints,iterations,bound95_mm";
  if (with_truth) out += ",error_commanded_mm,error_commanded_deg,error_corrected_mm,error_corrected_deg";
  out += "\n";
  return out;
}

/// A line's target run on the twin as commanded without a correction and as corrected (q_rad):
/// the errors appended to its CSV line and counted.
void appendTwinErrors(std::string& out, TwinTruth& truth, const runtime::RuntimeModel& model,
                      const ProgramLine& p, const Pose& X_FrameTcp_desired, const JointVector& seed,
                      const JointVector& q_rad, Tally& tally) {
  const Pose X_TrackerTcp_desired =
      runtime::trackerFromFrame(model, p.terms.frame, p.terms.X_BaseUser) * X_FrameTcp_desired;
  JointVector commanded_rad = p.q_rad;
  if (!p.joint_target) {
    commanded_rad = runtime::solveInverse(*truth.nominal, truth.nominal_ws, X_FrameTcp_desired,
                                          p.terms, p.temp_c, seed, runtime::Clock::time_point::max())
                        .q_target_rad;
  }
  const PoseError e_before = errorBetween(trueTcp(truth.robot, model, p, commanded_rad),
                                          X_TrackerTcp_desired);
  const PoseError e_after = errorBetween(trueTcp(truth.robot, model, p, q_rad),
                                         X_TrackerTcp_desired);
  tally.before.add(e_before);
  tally.after.add(e_after);
  out += "," + number(e_before.position_m * kMmPerM) + "," +
         number(e_before.orientation_rad / kRadPerDeg) + "," +
         number(e_after.position_m * kMmPerM) + "," + number(e_after.orientation_rad / kRadPerDeg);
}

/// Corrects every line (each pose target's search starting where the previous line's ended):
/// the corrected program's CSV.
std::string correctProgram(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                           const std::vector<ProgramLine>& program,
                           std::optional<JointVector> previous_rad, std::optional<TwinTruth>& truth,
                           Tally& tally) {
  const int dof = model.file.chain_Tracker.dof();
  std::string out = correctedHeader(dof, truth.has_value());
  for (const ProgramLine& p : program) {
    const Pose X_FrameTcp_desired =
        p.joint_target ? runtime::nominalTcp(model, ws, p.q_rad, p.terms) : p.X_FrameTcp;
    const JointVector seed = p.seed_rad ? *p.seed_rad : p.joint_target ? p.q_rad : *previous_rad;
    const runtime::InverseResult r =
        runtime::solveInverse(model, ws, X_FrameTcp_desired, p.terms, p.temp_c, seed,
                              runtime::Clock::time_point::max());
    ++tally.statuses[size_t(r.status)];
    const bool answered = r.status != runtime::Status::kBadRequest;
    previous_rad = answered ? r.q_target_rad : seed;
    out += std::to_string(p.line) + "," + p.id + "," + (p.joint_target ? "joints" : "pose") + "," +
           runtime::toString(r.status);
    if (!answered) {
      out += std::string(size_t(dof + 14 + (truth ? 4 : 0)), ',') + "\n";
      continue;
    }
    for (int j = 0; j < dof; ++j) out += "," + number(r.q_target_rad[j] / kRadPerDeg, "%.8f");
    appendPose(out, r.X_ControllerTcp_commanded);
    const bool covered = runtime::withinDomain(model, r.gpr_std) && r.uncovered_joints == 0;
    tally.in_coverage += covered;
    std::string uncovered;
    for (int j = 0; j < dof; ++j) {
      if ((r.uncovered_joints >> j) & 1u) uncovered += (uncovered.empty() ? "" : ";") + std::to_string(j + 1);
    }
    out += "," + number(r.residual_position_m * kMmPerM, "%.6f") + "," +
           number(r.residual_orientation_rad / kRadPerDeg, "%.6f") + "," +
           number(r.gpr_std.head<3>().norm() * kMmPerM, "%.6f") + "," + (covered ? "yes" : "no") +
           "," + uncovered + "," + std::to_string(r.iterations) + "," +
           (std::isnan(r.accuracy.position_bound_m)
                ? std::string()
                : number(r.accuracy.position_bound_m * kMmPerM, "%.6f"));
    if (truth) appendTwinErrors(out, *truth, model, p, X_FrameTcp_desired, seed, r.q_target_rad, tally);
    out += "\n";
  }
  return out;
}

nlohmann::json summaryJson(const CorrectArgs& args, size_t lines, const Tally& tally,
                           bool with_truth, const runtime::RuntimeModel& model) {
  nlohmann::json summary = {{"program", args.program}, {"out", args.out},
                            {"lines", lines}, {"in_coverage", tally.in_coverage}};
  nlohmann::json by_status = nlohmann::json::object();
  for (int k = 0; k < kStatusCount; ++k) {
    by_status[runtime::toString(runtime::Status(k))] = tally.statuses[size_t(k)];
  }
  summary["statuses"] = by_status;
  summary["not_corrected"] = long(lines) - tally.statuses[size_t(runtime::Status::kOk)];
  if (with_truth) {
    summary["error_commanded"] = tally.before.toJson();
    summary["error_corrected"] = tally.after.toJson();
    for (const ValidationFigure& v : model.file.provenance.validation) {
      summary["model_validation"].push_back({{"method", v.method},
                                             {"load_kg", v.load_kg},
                                             {"rows", v.rows},
                                             {"mean_position_mm", v.mean_position_m * kMmPerM},
                                             {"max_position_mm", v.max_position_m * kMmPerM}});
    }
  }
  return summary;
}

/// --truth: the targets' errors on the twin as commanded and as corrected.
void printTwinErrors(const Tally& tally) {
  for (const auto& [name, stats] : {std::pair{"as commanded", &tally.before}, std::pair{"as corrected", &tally.after}}) {
    const nlohmann::json j = stats->toJson();
    std::cout << format("on the twin, %s: mean %.4f mm, max %.4f mm, mean %.4f deg over %d targets\n",
                        name, j["mean_position_mm"].get<double>(),
                        j["max_position_mm"].get<double>(),
                        j["mean_orientation_deg"].get<double>(), stats->count);
  }
}

void printSummary(const CorrectArgs& args, size_t lines, const Tally& tally, bool with_truth) {
  const std::array<long, kStatusCount>& statuses = tally.statuses;
  std::cout << "wrote " << args.out << ": " << lines << " lines: " << statuses[0]
            << " OK, " << statuses[3] << " OUT_OF_DOMAIN, " << statuses[4] << " UNREACHABLE, "
            << statuses[1] << " NOT_CONVERGED, " << statuses[5] << " NEAR_SINGULAR, "
            << statuses[6] << " BAD_REQUEST; " << tally.in_coverage << " in the model's coverage\n";
  if (with_truth) printTwinErrors(tally);
}

/// Says on stderr how many lines were not corrected (status not OK): exit status 3 then, 0 when
/// every line is OK.
int exitStatusFor(size_t lines, const Tally& tally) {
  const long not_corrected = long(lines) - tally.statuses[size_t(runtime::Status::kOk)];
  if (not_corrected == 0) return exit_code::kDone;
  std::cerr << "stepcal correct: " << not_corrected << " of " << lines
            << " lines not corrected (status not OK; see the status column of the output)\n";
  return exit_code::kDoneInPart;
}

/// --program-frame NAME=x,y,z,qw,qx,qy,qz (mm, unit quaternion), by upper-case name.
std::map<std::string, Pose> commandLineFrames(const CorrectArgs& args) {
  std::map<std::string, Pose> frames;
  for (const std::string& given : args.program_frames) {
    const auto named = namedNumbers(given, 7);
    if (!named) {
      throw InputError("--program-frame " + inQuotes(given) + ": expected NAME=x,y,z,qw,qx,qy,qz (mm and a unit quaternion)");
    }
    const std::vector<double>& v = named->second;
    const Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    if (!isUnitQuaternion(q)) {
      throw InputError("--program-frame " + inQuotes(given) + ": the quaternion has norm " + formatShortest(q.norm()) + "; expected a unit quaternion (within 1e-6)");
    }
    frames[named->first] = poseFromPositionQuaternion(Vec3(v[0], v[1], v[2]) * kMPerMm, q);
  }
  return frames;
}

/// Says on stderr which --program-frame names the program never names (a typo: UF1 for UF 1).
void warnOfUnusedFrames(const programs::Program& program, const std::map<std::string, Pose>& given) {
  for (const auto& [name, pose] : given) {
    bool named = name == "TOOL" || name == "BASE";
    for (const programs::Frame& f : program.frames) {
      std::string upper = f.name;
      for (char& c : upper) c = char(std::toupper(static_cast<unsigned char>(c)));
      named = named || upper == name;
    }
    if (!named) {
      std::string names;
      for (const programs::Frame& f : program.frames) names += (names.empty() ? "" : ", ") + f.name;
      std::cerr << "stepcal correct: warning: --program-frame " << name << ": the program names no such frame"
                << (names.empty() ? std::string(" (it names none)") : " (it names " + names + ")") << "\n";
    }
  }
}

/// A frame the program names: its values from the program, else from --program-frame.
const Pose& framePose(const programs::Program& program, int index, const std::map<std::string, Pose>& given,
                      const programs::Target& target, const std::string& path) {
  const programs::Frame& f = program.frames[size_t(index)];
  if (f.X) return *f.X;
  std::string name = f.name;
  for (char& c : name) c = char(std::toupper(static_cast<unsigned char>(c)));
  const auto found = given.find(name);
  if (found != given.end()) return found->second;
  throw InputError(std::string(target.kind == programs::TargetKind::kJoint ? "a joint" : "a") + " target uses " +
                       f.name + ", whose values the program does not give; expected them with --program-frame '" +
                       f.name + "=x,y,z,qw,qx,qy,qz' (mm)",
                   path, target.line, std::to_string(target.column));
}

/// A target as a line of the CSV driver: its pose or joints, its tool (flange frame; when the
/// program names none, --program-frame TOOL=…, else the flange itself) and its base (a user
/// frame; when none, --program-frame BASE=…, else the robot's base); unloaded (its load is
/// targetLoad's).
ProgramLine programLine(const programs::Program& program, const programs::Target& t,
                        const std::map<std::string, Pose>& given, const std::string& path) {
  ProgramLine p;
  p.line = t.line;
  p.id = t.name;
  p.joint_target = t.kind == programs::TargetKind::kJoint;
  p.q_rad = t.q_rad;
  p.X_FrameTcp = t.X_FrameTcp;
  p.terms.tool_from = runtime::ToolFrom::kFlange;
  p.terms.load_from = runtime::LoadFrom::kPayload;
  p.terms.frame = runtime::PoseFrame::kBase;
  if (t.tool >= 0) p.terms.X_Tool = framePose(program, t.tool, given, t, path);
  if (t.base >= 0) {
    p.terms.frame = runtime::PoseFrame::kUser;
    p.terms.X_BaseUser = framePose(program, t.base, given, t, path);
  }
  // A target whose program names no tool or base (a KRL .dat's points): --program-frame TOOL=…
  // and BASE=… where given.
  const auto default_tool = given.find("TOOL"), default_base = given.find("BASE");
  if (t.tool < 0 && default_tool != given.end()) p.terms.X_Tool = default_tool->second;
  if (t.base < 0 && default_base != given.end()) {
    p.terms.frame = runtime::PoseFrame::kUser;
    p.terms.X_BaseUser = default_base->second;
  }
  return p;
}

/// What became of one target of a robot program.
struct TargetOutcome {
  const programs::Target* target = nullptr;
  std::string outcome;  ///< corrected, unchanged, out of coverage, unreachable, …
  bool written = false;
  double correction_mm = 0.0, correction_deg = 0.0;  ///< how far the written target moved
  std::string detail;
  JointVector q_corrected_rad;  ///< written: the corrected joints
  TargetLoad load;              ///< what it was corrected under
};

/// Without a closed form (an arm of another layout), a corrected joint solution more than this
/// far from the controller's own (nominal) one on any joint is in another branch (a wrist flip,
/// an elbow down): reported, not written.
constexpr double kSameBranch_rad = 20.0 * kRadPerDeg;

/// What places a Cartesian target's joints in the branch its program names: the nominal chain's
/// closed-form inverse (closed_form_ik.hpp), the controller's joint convention (the URDF's own:
/// docs/runtime.md), and the chain's tip from the flange.
struct Branching {
  ClosedFormInverse closed;
  ControllerJoints joints;
  const KinematicChain* chain = nullptr;
  Pose X_FlangeTip = Pose::Identity();
  programs::Language language = programs::Language::kKrl;
  std::string path;
};

Branching branching(const runtime::RuntimeModel& model, programs::Language language, const std::string& path) {
  Branching b;
  b.chain = &model.file.nominal_Base;
  b.closed = ClosedFormInverse::recognise(*b.chain);
  const int n = b.chain->dof();
  b.X_FlangeTip = model.X_LastFlange_nominal.inverse() * b.chain->initialPose(n);
  b.language = language;
  b.path = path;
  return b;
}

/// The controller's joints for a Cartesian target: the closed form in the branch and turns its
/// word names, nearest where the robot was (`previous`), when the arm has a closed form and the
/// target a word; else the numeric nominal inverse from `previous` (the branch it is in).
std::optional<JointVector> controllerJoints(const Branching& b, const runtime::RuntimeModel& nominal,
                                            runtime::Workspace& nominal_ws, const ProgramLine& p,
                                            const std::optional<programs::ConfigurationWord>& word,
                                            const JointVector& previous, std::string& why_not) {
  JointVector seed = previous;
  if (word && b.closed.solvable()) {
    const Pose X_BaseTcp = p.terms.frame == runtime::PoseFrame::kUser ? p.terms.X_BaseUser * p.X_FrameTcp : p.X_FrameTcp;
    const Pose X_BaseTip = X_BaseTcp * p.terms.X_Tool.inverse() * b.X_FlangeTip;
    JointVector q_closed(6);
    const ClosedFormStatus status = b.closed.solve(X_BaseTip, programs::branchNamed(*word, b.joints), previous, q_closed);
    if (status != ClosedFormStatus::kOk && status != ClosedFormStatus::kSingular) {
      why_not = std::string("the nominal chain in the program's configuration: ") + toString(status);
      return std::nullopt;
    }
    JointVector q_controller = controllerFromChain(b.joints, q_closed);
    programs::applyTurns(*word, *b.chain, b.joints, q_controller);
    seed = chainFromController(b.joints, q_controller);
  }
  const runtime::InverseResult n = runtime::solveInverse(nominal, nominal_ws, p.X_FrameTcp, p.terms, p.temp_c, seed,
                                                         runtime::Clock::time_point::max());
  if (n.status != runtime::Status::kOk && n.status != runtime::Status::kNearSingular) {
    why_not = std::string("the nominal chain itself: ") + runtime::toString(n.status);
    return std::nullopt;
  }
  return n.q_target_rad;
}

/// Why corrected joints cannot be written in the target's configuration; empty when they can.
std::string configurationChange(const Branching& b, const std::optional<programs::ConfigurationWord>& word,
                                const JointVector& q_controller, const JointVector& q_corrected) {
  if (word && b.closed.solvable()) {
    std::string theirs;
    const JointVector q = controllerFromChain(b.joints, q_corrected);
    if (programs::sameConfiguration(*word, b.closed.branchOf(q_corrected), q, theirs)) return "";
    return "the corrected joints have the configuration " + theirs;
  }
  if (b.closed.solvable()) {
    if (b.closed.branchOf(q_corrected) == b.closed.branchOf(q_controller)) return "";
    return "the corrected joints are in branch " + std::to_string(b.closed.branchOf(q_corrected).index()) +
           ", the controller's in " + std::to_string(b.closed.branchOf(q_controller).index());
  }
  const double moved = (q_corrected - q_controller).cwiseAbs().maxCoeff();
  if (moved <= kSameBranch_rad) return "";
  return "the corrected joints leave the controller's by " + number(moved / kRadPerDeg, "%.1f") + " deg";
}

/// One target corrected: its outcome and, where written, its replacement. `previous_rad` is
/// where the robot is before it (the last target's joints) and becomes where it is after.
TargetOutcome correctTarget(const runtime::RuntimeModel& model, runtime::Workspace& ws,
                            const runtime::RuntimeModel& nominal, runtime::Workspace& nominal_ws,
                            const Branching& b, const programs::Target& t, const ProgramLine& p,
                            const ToolFile* tool_file, JointVector& previous_rad, std::optional<TwinTruth>& truth,
                            Tally& tally, programs::Replacement& replacement) {
  TargetOutcome o;
  const Pose X_desired = p.joint_target ? runtime::nominalTcp(model, ws, p.q_rad, p.terms) : p.X_FrameTcp;
  const std::optional<programs::ConfigurationWord> word = programs::readConfiguration(b.language, t, b.path);
  std::optional<JointVector> q_controller = p.q_rad;
  if (!p.joint_target) q_controller = controllerJoints(b, nominal, nominal_ws, p, word, previous_rad, o.detail);
  if (!q_controller) {
    o.outcome = "unreachable";
    return o;
  }
  previous_rad = *q_controller;
  // The model places the real TCP: the calibrated one from the measured target where a tool
  // file stands for the program's tool, else the program's tool on the model's flange.
  const runtime::CallTerms model_terms = tool_file ? calibratedTerms(p.terms, *tool_file, model) : p.terms;
  // A word the closed form places: the corrected inverse from the calibrated geometry's closed
  // form in that branch (closed_form_seed.hpp), its turns nearest the controller's joints.
  const runtime::InverseResult r =
      word && b.closed.solvable()
          ? runtime::solveInverseInBranch(model, ws, X_desired, model_terms, p.temp_c,
                                          programs::branchNamed(*word, b.joints), *q_controller,
                                          runtime::Clock::time_point::max())
          : runtime::solveInverse(model, ws, X_desired, model_terms, p.temp_c, *q_controller,
                                  runtime::Clock::time_point::max());
  ++tally.statuses[size_t(r.status)];
  const bool answered = r.status == runtime::Status::kOk || r.status == runtime::Status::kOutOfDomain;
  if (!answered) {
    o.outcome = r.status == runtime::Status::kUnreachable    ? "unreachable"
                : r.status == runtime::Status::kNearSingular ? "near singular"
                                                             : "not converged";
    return o;
  }
  o.detail = p.joint_target ? "" : configurationChange(b, word, *q_controller, r.q_target_rad);
  if (!o.detail.empty()) {
    o.outcome = "changed configuration";
    return o;
  }
  // What the controller is to be commanded: its own kinematics and tool data at the corrected
  // joints (the program's tool data stays as written; the targets compensate).
  replacement.X_FrameTcp =
      tool_file ? runtime::nominalTcp(model, ws, r.q_target_rad, p.terms) : r.X_ControllerTcp_commanded;
  replacement.q_rad = r.q_target_rad;
  o.q_corrected_rad = r.q_target_rad;
  o.written = true;
  o.outcome = r.status == runtime::Status::kOutOfDomain ? "out of coverage" : "corrected";
  if (p.joint_target) {
    o.correction_deg = (r.q_target_rad - p.q_rad).cwiseAbs().maxCoeff() / kRadPerDeg;
  } else {
    o.correction_mm = (replacement.X_FrameTcp.translation() - p.X_FrameTcp.translation()).norm() * kMmPerM;
    o.correction_deg = lie::angleBetween(replacement.X_FrameTcp.linear(), p.X_FrameTcp.linear()) / kRadPerDeg;
  }
  tally.in_coverage += runtime::withinDomain(model, r.gpr_std) && r.uncovered_joints == 0;
  if (truth) {
    std::string ignored;
    appendTwinErrors(ignored, *truth, model, p, X_desired, p.joint_target ? p.q_rad : *q_controller, r.q_target_rad, tally);
  }
  return o;
}

/// Where the robot is before the program's first target, for the first Cartesian target's
/// search: --seed, else the first joint target when it comes first, else (a first target whose
/// configuration word the closed form places) the zero pose; else a clear error.
JointVector firstSeed(const programs::Program& program, const std::optional<JointVector>& seed_option,
                      const Branching& b, int dof) {
  if (seed_option) return *seed_option;
  if (program.targets.empty() || program.targets[0].kind == programs::TargetKind::kJoint) {
    return program.targets.empty() ? JointVector::Zero(dof) : program.targets[0].q_rad;
  }
  const programs::Target& t = program.targets[0];
  if (b.closed.solvable() && programs::readConfiguration(program.language, t, b.path)) return JointVector::Zero(dof);
  throw InputError("the first target is a pose without a configuration word the closed form can place: its "
                   "inverse needs a seed where the search starts; expected --seed q1 … qn (deg)",
                   b.path, t.line, std::to_string(t.column));
}

/// Each target's tool as --tool-file names it.
std::vector<TargetTool> targetTools(const programs::Program& program, const std::vector<ProgramLine>& lines) {
  std::vector<TargetTool> tools;
  for (size_t i = 0; i < lines.size(); ++i) {
    const int index = program.targets[i].tool;
    std::string name = index >= 0 ? program.frames[size_t(index)].name : "TOOL";
    for (char& c : name) c = char(std::toupper(static_cast<unsigned char>(c)));
    tools.push_back({name, lines[i].terms.X_Tool, lines[i].line});
  }
  return tools;
}

/// A tool of the program that a tool file stands for, as the report names it.
struct CalibratedToolUse {
  std::string tool;
  const ToolFile* file = nullptr;
  int targets = 0;
  double from_program_m = 0.0;  ///< programToolOffset_m
};

std::vector<CalibratedToolUse> calibratedToolUses(const programs::Program& program, const std::vector<ProgramLine>& lines,
                                                  const std::vector<const ToolFile*>& files,
                                                  const runtime::RuntimeModel& model) {
  const std::vector<TargetTool> tools = targetTools(program, lines);
  std::vector<CalibratedToolUse> uses;
  for (size_t i = 0; i < files.size(); ++i) {
    if (!files[i]) continue;
    auto use = std::find_if(uses.begin(), uses.end(), [&](const CalibratedToolUse& u) { return u.tool == tools[i].name; });
    if (use == uses.end()) {
      uses.push_back({tools[i].name, files[i], 0, programToolOffset_m(tools[i].X_FlangeTcp, *files[i], model)});
      use = uses.end() - 1;
    }
    ++use->targets;
  }
  return uses;
}

void printToolUses(const std::vector<CalibratedToolUse>& uses) {
  for (const CalibratedToolUse& u : uses) {
    const Vec3 p_mm = u.file->p_TcpInTip_m * kMmPerM;
    std::cout << u.tool << ": the calibrated TCP of " << u.file->path << " (" << u.file->method << ", " << u.file->points
              << " points) for " << u.targets << " targets: "
              << format("%.4f %.4f %.4f mm on the measured target, 1-sigma %.4f %.4f %.4f mm; the program's tool "
                        "through the nominal flange is %.4f mm from it\n",
                        p_mm.x(), p_mm.y(), p_mm.z(), std::sqrt(u.file->covariance_m2(0, 0)) * kMmPerM,
                        std::sqrt(u.file->covariance_m2(1, 1)) * kMmPerM,
                        std::sqrt(u.file->covariance_m2(2, 2)) * kMmPerM, u.from_program_m * kMmPerM);
  }
}

nlohmann::json toolUsesJson(const std::vector<CalibratedToolUse>& uses) {
  nlohmann::json out = nlohmann::json::array();
  for (const CalibratedToolUse& u : uses) {
    out.push_back({{"tool", u.tool}, {"file", u.file->path}, {"targets", u.targets},
                   {"tcp_in_target_mm", {u.file->p_TcpInTip_m.x() * kMmPerM, u.file->p_TcpInTip_m.y() * kMmPerM,
                                         u.file->p_TcpInTip_m.z() * kMmPerM}},
                   {"program_tool_from_it_mm", u.from_program_m * kMmPerM}});
  }
  return out;
}

/// The outcome of every target, each on its line, and the targets the program computes at run time.
void printProgramOutcomes(const std::string& path, const programs::Program& program,
                          const std::vector<TargetOutcome>& outcomes) {
  for (const TargetOutcome& o : outcomes) {
    const programs::Target& t = *o.target;
    std::cout << path << ":" << t.line << ":" << t.column << ": " << (t.name.empty() ? "" : t.name + ": ")
              << (t.kind == programs::TargetKind::kJoint ? "joints" : "pose") << ": " << o.outcome;
    if (o.written && o.outcome != "unchanged") {
      std::cout << format(" (moved %.3f mm, %.4f deg)", o.correction_mm, o.correction_deg);
    }
    if (!o.detail.empty()) std::cout << " (" << o.detail << ")";
    std::cout << describeLoad(o.load);
    if (!t.other_loads.empty()) std::cout << " (also moved to at " << t.other_loads << ": corrected for the first)";
    std::cout << "\n";
  }
  for (const programs::NotLiteral& n : program.not_literals) {
    std::cout << path << ":" << n.line << ":" << n.column << ": not a literal, not corrected: " << n.text << "\n";
  }
}

/// The targets not written (reported) and those the program computes at run time.
long notCorrected(const programs::Program& program, const std::vector<TargetOutcome>& outcomes) {
  long count = long(program.not_literals.size());
  for (const TargetOutcome& o : outcomes) count += !o.written;
  return count;
}

void printProgramSummary(const CorrectArgs& args, const programs::Program& program,
                         const std::vector<TargetOutcome>& outcomes, const Tally& tally) {
  std::map<std::string, int> counts;
  for (const TargetOutcome& o : outcomes) ++counts[o.outcome];
  std::cout << "wrote " << args.out << " (" << programs::languageName(program.language) << "): "
            << outcomes.size() << " targets:";
  std::string separator = " ";
  for (const auto& [outcome, count] : counts) {
    std::cout << separator << count << " " << outcome;
    separator = ", ";
  }
  std::cout << "; " << program.not_literals.size() << " not a literal; " << tally.in_coverage
            << " in the model's coverage\n";
}

nlohmann::json programSummaryJson(const CorrectArgs& args, const programs::Program& program,
                                  const std::vector<TargetOutcome>& outcomes, const Tally& tally,
                                  bool with_truth, const runtime::RuntimeModel& model) {
  nlohmann::json summary = summaryJson(args, outcomes.size(), tally, with_truth, model);
  summary["language"] = programs::languageName(program.language);
  nlohmann::json counts = nlohmann::json::object(), targets = nlohmann::json::array();
  for (const TargetOutcome& o : outcomes) {
    counts[o.outcome] = counts.value(o.outcome, 0) + 1;
    nlohmann::json target = {{"line", o.target->line}, {"column", o.target->column}, {"name", o.target->name},
                             {"kind", o.target->kind == programs::TargetKind::kJoint ? "joints" : "pose"},
                             {"configuration", o.target->configuration}, {"outcome", o.outcome},
                             {"correction_mm", o.correction_mm}, {"correction_deg", o.correction_deg},
                             {"detail", o.detail}, {"load", loadJson(o.load)},
                             {"other_loads", o.target->other_loads}};
    if (o.written) {
      nlohmann::json q_deg = nlohmann::json::array();
      for (int j = 0; j < o.q_corrected_rad.size(); ++j) q_deg.push_back(o.q_corrected_rad[j] / kRadPerDeg);
      target["q_corrected_deg"] = q_deg;
    }
    targets.push_back(target);
  }
  counts["not a literal"] = program.not_literals.size();
  summary["outcomes"] = counts;
  summary["not_corrected"] = notCorrected(program, outcomes);
  summary["targets"] = targets;
  nlohmann::json not_literals = nlohmann::json::array();
  for (const programs::NotLiteral& n : program.not_literals) {
    not_literals.push_back({{"line", n.line}, {"column", n.column}, {"text", n.text}});
  }
  summary["not_literals"] = not_literals;
  return summary;
}

/// `stepcal correct` on a robot's own program: every literal target corrected in the program's
/// own units, frames and configuration, written back with every other byte kept. The file is
/// read whole first: one it does not understand is refused (file, line, column) before anything
/// is written. Exit status 3 when a target is not corrected or not a literal.
int runCorrectRobotProgram(const CorrectArgs& args, programs::Language language) {
  const std::unique_ptr<const runtime::RuntimeModel> model = runtime::RuntimeModel::load(args.model);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  const std::unique_ptr<const runtime::RuntimeModel> nominal = nominalModel(*model);
  runtime::Workspace nominal_ws = runtime::makeWorkspace(*nominal);
  const std::string text = readTextFile(args.program);
  const programs::Program program = programs::readProgram(language, text, args.program);
  if (!model->has_flange) {
    throw InputError("the model knows no flange (its campaign.yaml names no flange_link), and a robot "
                     "program's tools are given from the flange; calibrate with flange_link",
                     args.program);
  }
  const std::map<std::string, Pose> given = commandLineFrames(args);
  warnOfUnusedFrames(program, given);
  const std::map<std::string, GivenLoad> given_loads = commandLineLoads(args.program_loads);
  warnOfUnusedLoads(program, given_loads);
  const Branching b = branching(*model, language, args.program);
  const int dof = model->file.chain_Tracker.dof();
  JointVector previous_rad = firstSeed(program, seedOption(args, dof), b, dof);
  std::optional<TwinTruth> truth = readTruth(args.truth, *model);
  Tally tally;
  std::vector<TargetOutcome> outcomes;
  std::vector<programs::Replacement> replacements;
  std::vector<ProgramLine> lines;
  std::vector<TargetLoad> loads;
  for (const programs::Target& t : program.targets) {
    lines.push_back(programLine(program, t, given, args.program));
    loads.push_back(targetLoad(program, t, lines.back().terms.X_Tool, given_loads, args.program));
    lines.back().terms.payload = loads.back().payload;
  }
  const ProgramToolFiles tool_files = readProgramToolFiles(args.tool_files, *model, args.model);
  const std::vector<const ToolFile*> tool_of_target =
      toolFilesOfTargets(tool_files, targetTools(program, lines), args.program);
  const std::vector<CalibratedToolUse> tool_uses = calibratedToolUses(program, lines, tool_of_target, *model);
  for (size_t i = 0; i < program.targets.size(); ++i) {
    const programs::Target& t = program.targets[i];
    const ProgramLine& p = lines[i];
    programs::Replacement replacement;
    replacement.target = i;
    TargetOutcome o = correctTarget(*model, ws, *nominal, nominal_ws, b, t, p, tool_of_target[i], previous_rad, truth,
                                    tally, replacement);
    o.target = &t;
    o.load = loads[i];
    if (o.written && programs::unchangedWithinTolerance(t, replacement)) o.outcome = "unchanged";
    if (o.written) replacements.push_back(replacement);
    outcomes.push_back(o);
  }
  const std::string out = programs::writeProgram(program, text, replacements);
  writeFileAtomically(args.out, out.data(), out.size(), "corrected program");
  if (args.json) {
    nlohmann::json summary = programSummaryJson(args, program, outcomes, tally, truth.has_value(), *model);
    summary["tool_files"] = toolUsesJson(tool_uses);
    std::cout << summary.dump(2) << "\n";
  } else {
    printToolUses(tool_uses);
    printProgramOutcomes(args.program, program, outcomes);
    printProgramSummary(args, program, outcomes, tally);
    if (truth) printTwinErrors(tally);
  }
  const long not_corrected = notCorrected(program, outcomes);
  if (not_corrected == 0) return exit_code::kDone;
  std::cerr << "stepcal correct: " << not_corrected << " targets not corrected (see each target's line)\n";
  return exit_code::kDoneInPart;
}

/// Reads the model and the program, corrects every line, writes args.out (atomically) and prints
/// the summary. Throws InputError naming the file, line and column of bad input. Exit status 3
/// (done in part) when a line's status is not OK.
int runCorrect(const CorrectArgs& args) {
  const std::optional<programs::Language> language = programs::languageOf(args.program, args.format);
  if (language) return runCorrectRobotProgram(args, *language);
  if (!args.tool_files.empty()) {
    throw InputError("--tool-file is for a robot program's tools; stepcal's CSV takes the calibrated TCP "
                     "in its columns (tool_from target, tool_x_mm … tool_qz: docs/cell.md)",
                     args.program);
  }
  const std::unique_ptr<const runtime::RuntimeModel> model = runtime::RuntimeModel::load(args.model);
  const int dof = model->file.chain_Tracker.dof();
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  const runtime::CallTerms frame_terms = frameTerms(args);
  const std::optional<JointVector> seed_option = seedOption(args, dof);
  const std::vector<ProgramLine> program =
      readProgram(args.program, model->file.nominal_Base, frame_terms, seed_option.has_value());
  checkFlangeNeeds(program, *model, args.program);
  std::optional<TwinTruth> truth = readTruth(args.truth, *model);

  Tally tally;
  const std::string out = correctProgram(*model, ws, program, seed_option, truth, tally);
  writeFileAtomically(args.out, out.data(), out.size(), "corrected program");
  if (args.json) {
    std::cout << summaryJson(args, program.size(), tally, truth.has_value(), *model).dump(2)
              << "\n";
  } else {
    printSummary(args, program.size(), tally, truth.has_value());
  }
  return exitStatusFor(program.size(), tally);
}

}  // namespace

Subcommand addCorrectCommand(CLI::App& app) {
  auto args_owned = std::make_shared<CorrectArgs>();
  CorrectArgs& args = *args_owned;
  CLI::App* correct = app.add_subcommand(
      "correct", "correct an offline program's targets: joint targets and pre-distorted poses");
  correct->add_option("model", args.model, "model file")->required();
  correct->add_option("program", args.program,
                      "program: stepcal's CSV (a target per line), or the robot's own program in "
                      "KRL, RAPID, URScript or Fanuc TP (docs/runtime.md, \"Correcting an "
                      "offline program\", \"The robot's own programs\")")
      ->required();
  correct->add_option("--out", args.out,
                      "corrected program to write (CSV, or the program in its own language with "
                      "only its targets replaced)")->required();
  correct->add_option("--frame", args.frame, "frame of the pose targets: tracker | base | user")
      ->capture_default_str();
  correct->add_option("--user-frame", args.user_frame,
                      "--frame user: the user frame in the robot base frame, x y z (mm) qw qx qy qz")
      ->expected(7);
  correct->add_option("--seed", args.seed_deg,
                      "where the first pose target's search starts, q1 … qn (deg), when the "
                      "file gives no seed")
      ->expected(1, 16);
  correct->add_option("--truth", args.truth,
                      "the twin's truth.json: run every target on the simulated robot, as "
                      "commanded and as corrected (its payload at the twin's own centre of gravity)");
  correct->add_flag("--json", args.json, "print the summary as JSON");
  correct->add_option("--format", args.format,
                      "the program's language: csv, krl, rapid, urscript or tp (default: from the "
                      "extension: .src/.dat, .mod/.prg/.sys, .script, .ls; else csv)");
  correct->add_option("--program-frame", args.program_frames,
                      "a tool or base the program names without its values: NAME=x,y,z,qw,qx,qy,qz "
                      "(mm; a tool in the flange frame, a base in the robot's base frame), e.g. "
                      "'TOOL_DATA[1]=0,0,300,1,0,0,0' or 'UF 2=900,0,40,1,0,0,0'; TOOL=… and BASE=… "
                      "for the targets whose program names none (else the flange and the robot's "
                      "base); repeatable");
  correct->add_option("--program-load", args.program_loads,
                      "a load the program names without its values: NAME=kg,x,y,z (the mass, then "
                      "the centre of gravity in mm in the flange frame; a RAPID GripLoad's loaddata "
                      "in the tool frame), e.g. 'LOAD_DATA[1]=30,0,0,150' (KRL) or "
                      "'PAYLOAD[2]=12.5,0,0,80' (Fanuc: its payload schedule, cm × 10); LOAD=… for "
                      "the targets whose program names none (a KRL .dat's points; else unloaded); "
                      "each target's line says the load it was corrected under; repeatable");
  correct->add_option("--tool-file", args.tool_files,
                      "a robot program's tool calibrated with this model (stepcal tool --out): the "
                      "targets are corrected for that TCP, taken from the measured target, and the "
                      "program's tool data kept as written; TOOL.json for every tool the program "
                      "uses, or NAME=TOOL.json per tool as --program-frame names it (docs/cell.md); "
                      "repeatable");
  return {correct, [args_owned] { return runCorrect(*args_owned); }};
}

}  // namespace stepcal::cli
