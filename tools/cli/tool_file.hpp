// The tool file `stepcal tool --out` writes (JSON, format `stepcal-tool/1`, docs/cell.md): the
// calibrated TCP on the model's measured target. `stepcal frame --tool` and `stepcal correct
// --tool-file` read it; it belongs to the model it was fitted with (its model_id).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "stepcal/common/types.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::cli {

struct ToolFile {
  std::string path;
  std::string method;  ///< tracker | four-point
  int points = 0;
  Vec3 p_TcpInTip_m = Vec3::Zero();       ///< the TCP in the measured target's frame
  Mat3 covariance_m2 = Mat3::Zero();      ///< its covariance, target axes
  double point_sigma_m = 0;               ///< one touch's scatter per axis
};

/// The model's id as the tool file writes it: FNV-1a 64 of the model (RuntimeModel::model_id), hex.
std::string modelIdHex(const runtime::RuntimeModel& model);

/// Reads a tool file fitted with `model` (loaded from model_path). Throws InputError naming the
/// file and field of a file that is not one, or of a file fitted with another model (its
/// model_id; a file without one: the model path it names).
ToolFile readToolFile(const std::string& path, const runtime::RuntimeModel& model, const std::string& model_path);

/// `stepcal correct --tool-file`: TOOL.json for every tool the program's targets use, or
/// NAME=TOOL.json for the tool the program names NAME (TOOL_DATA[1], tGripper, UT 1; TOOL for
/// the targets whose program names none), as --program-frame names them.
struct ProgramToolFiles {
  std::vector<std::pair<std::string, ToolFile>> named;  ///< NAME in upper case, its file
  std::optional<ToolFile> every;                        ///< the one file given without a name
};
ProgramToolFiles readProgramToolFiles(const std::vector<std::string>& given, const runtime::RuntimeModel& model,
                                      const std::string& model_path);

/// One target's tool as the program gives it.
struct TargetTool {
  std::string name;  ///< as --program-frame and --tool-file name it (upper case)
  Pose X_FlangeTcp = Pose::Identity();
  int line = 0;
};

/// The tool file standing for each target's tool (null: none, the program's own tool). Throws
/// InputError when a NAME is no tool of the program, or when the file for every tool is given
/// to a program whose targets use tools of different values (expected NAME=TOOL.json each).
std::vector<const ToolFile*> toolFilesOfTargets(const ProgramToolFiles& files, const std::vector<TargetTool>& tools,
                                                const std::string& program_path);

/// The model's terms for a target whose tool a tool file stands for: the program's terms with
/// the calibrated TCP from the measured target, where no nominal transform enters. A point fixes
/// no orientation: the TCP's axes are the program's tool's, placed on the model's flange.
runtime::CallTerms calibratedTerms(const runtime::CallTerms& program_terms, const ToolFile& tool,
                                   const runtime::RuntimeModel& model);

/// How far the program's own tool, through the model's flange (its unidentifiable part nominal),
/// puts the TCP from the calibrated one, m.
double programToolOffset_m(const Pose& X_FlangeTcp, const ToolFile& tool, const runtime::RuntimeModel& model);

}  // namespace stepcal::cli
