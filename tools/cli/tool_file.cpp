#include "tool_file.hpp"

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include <nlohmann/json.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::cli {

std::string modelIdHex(const runtime::RuntimeModel& model) {
  char text[20];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(model.model_id));
  return text;
}

namespace {

/// The model the file was fitted with is this one: its model_id, or (a file without one) the
/// same model file.
void checkModel(const nlohmann::json& j, const std::string& path, const runtime::RuntimeModel& model,
                const std::string& model_path) {
  const std::string named = j.at("model").get<std::string>();
  if (j.contains("model_id")) {
    const std::string id = j.at("model_id").get<std::string>();
    if (id == modelIdHex(model)) return;
    throw InputError("model_id " + id + " is not that of " + model_path + " (" + modelIdHex(model) +
                         "): the TCP was fitted with another model (the file names " + named +
                         "); expected a tool file stepcal tool wrote with this model (run it again on the "
                         "same touches)",
                     path, 0, "model_id");
  }
  std::error_code error;
  if (std::filesystem::equivalent(named, model_path, error)) return;
  throw InputError("model " + named + ": not " + model_path + "; expected a tool file stepcal tool wrote with " +
                       "this model (run it again on the same touches)",
                   path, 0, "model");
}

}  // namespace

ToolFile readToolFile(const std::string& path, const runtime::RuntimeModel& model, const std::string& model_path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot open the tool file", path);
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.at("format") != "stepcal-tool/1") {
      throw InputError("format " + j.at("format").dump() + "; expected \"stepcal-tool/1\" (written "
                       "by stepcal tool --out)", path, 0, "format");
    }
    checkModel(j, path, model, model_path);
    ToolFile tool;
    tool.path = path;
    tool.method = j.at("method").get<std::string>();
    tool.points = j.at("points").get<int>();
    for (int a = 0; a < 3; ++a) {
      tool.p_TcpInTip_m[a] = j.at("tcp_in_target_mm").at(size_t(a)).get<double>() * kMPerMm;
      for (int b = 0; b < 3; ++b) {
        tool.covariance_m2(a, b) =
            j.at("tcp_covariance_in_target_mm2").at(size_t(a)).at(size_t(b)).get<double>() * kMPerMm * kMPerMm;
      }
    }
    tool.point_sigma_m = j.at("point_sigma_mm").get<double>() * kMPerMm;
    if (!tool.p_TcpInTip_m.allFinite() || !tool.covariance_m2.allFinite()) {
      throw InputError("a number that is not finite; expected the TCP and its covariance in mm", path, 0,
                       "tcp_in_target_mm");
    }
    return tool;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("not a tool file: ") + e.what() +
                         "; expected the JSON that stepcal tool --out writes",
                     path);
  }
}

namespace {

std::string upperCase(std::string text) {
  for (char& c : text) c = char(std::toupper(static_cast<unsigned char>(c)));
  return text;
}

bool samePose(const Pose& a, const Pose& b) {
  return (a.translation() - b.translation()).norm() <= 1e-9 && (a.linear() - b.linear()).norm() <= 1e-9;
}

}  // namespace

ProgramToolFiles readProgramToolFiles(const std::vector<std::string>& given, const runtime::RuntimeModel& model,
                                      const std::string& model_path) {
  ProgramToolFiles files;
  for (const std::string& option : given) {
    const size_t eq = option.find('=');
    std::error_code error;
    if (eq == std::string::npos || std::filesystem::exists(option, error)) {
      if (files.every) {
        throw InputError("--tool-file " + option + ": a second file for every tool (after " + files.every->path +
                         "); expected one TOOL.json, or NAME=TOOL.json for each tool the program names");
      }
      files.every = readToolFile(option, model, model_path);
      continue;
    }
    if (eq == 0) throw InputError("--tool-file " + option + ": no tool name before '='; expected NAME=TOOL.json");
    files.named.emplace_back(upperCase(option.substr(0, eq)), readToolFile(option.substr(eq + 1), model, model_path));
  }
  return files;
}

std::vector<const ToolFile*> toolFilesOfTargets(const ProgramToolFiles& files, const std::vector<TargetTool>& tools,
                                                const std::string& program_path) {
  std::map<std::string, int> first_line;  // each tool the targets use, where first
  for (const TargetTool& t : tools) first_line.emplace(t.name, t.line);
  for (const auto& [name, file] : files.named) {
    if (first_line.count(name)) continue;
    std::string names;
    for (const auto& [used, line] : first_line) names += (names.empty() ? "" : ", ") + used;
    throw InputError("--tool-file " + name + "=" + file.path + ": no target of the program uses the tool " + name +
                         "; expected one of the tools it uses: " + (names.empty() ? "none" : names),
                     program_path);
  }
  std::vector<const ToolFile*> of_targets;
  const TargetTool* every_first = nullptr;  // the first target the file for every tool stands for
  for (const TargetTool& t : tools) {
    const ToolFile* file = files.every ? &*files.every : nullptr;
    for (const auto& [name, named] : files.named) {
      if (name == t.name) file = &named;
    }
    if (files.every && file == &*files.every) {
      if (!every_first) every_first = &t;
      if (!samePose(every_first->X_FlangeTcp, t.X_FlangeTcp)) {
        throw InputError("--tool-file " + files.every->path + " stands for every tool, but the program uses two of "
                             "different values: " + every_first->name + " (line " + std::to_string(every_first->line) +
                             ") and " + t.name + "; expected --tool-file NAME=TOOL.json for each tool calibrated",
                         program_path, t.line);
      }
    }
    of_targets.push_back(file);
  }
  return of_targets;
}

runtime::CallTerms calibratedTerms(const runtime::CallTerms& program_terms, const ToolFile& tool,
                                   const runtime::RuntimeModel& model) {
  runtime::CallTerms terms = program_terms;
  terms.tool_from = runtime::ToolFrom::kTarget;
  terms.X_Tool.linear() = model.X_TipFlange.linear() * program_terms.X_Tool.linear();
  terms.X_Tool.translation() = tool.p_TcpInTip_m;
  return terms;
}

double programToolOffset_m(const Pose& X_FlangeTcp, const ToolFile& tool, const runtime::RuntimeModel& model) {
  return ((model.X_TipFlange * X_FlangeTcp).translation() - tool.p_TcpInTip_m).norm();
}

}  // namespace stepcal::cli
