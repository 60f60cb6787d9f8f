// The load of a robot program's targets (program_load.hpp).
#include "program_load.hpp"

#include <cctype>
#include <iostream>
#include <optional>

#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::cli {
namespace {

std::string upperCase(std::string text) {
  for (char& c : text) c = char(std::toupper(static_cast<unsigned char>(c)));
  return text;
}

/// The load's values: the program's own, else --program-load's; refused when neither.
GivenLoad loadValues(const programs::Load& load, const std::map<std::string, GivenLoad>& given,
                     const programs::Target& target, const std::string& path) {
  if (load.mass_kg) {
    if (*load.mass_kg < 0.0) {
      throw InputError("a target is moved under " + load.name + ", of mass " + formatShortest(*load.mass_kg) +
                           " kg; expected a mass ≥ 0 kg",
                       path, target.line, std::to_string(target.column));
    }
    return {*load.mass_kg, load.p_CoG_m};
  }
  const auto found = given.find(upperCase(load.name));
  if (found != given.end()) return found->second;
  const std::string why = load.without_values.empty() ? ", whose values the program does not give"
                                                      : ", which the program gives as " + load.without_values;
  throw InputError("a target is moved under " + load.name + why + "; expected them with --program-load '" +
                       load.name + "=kg,x,y,z' (the mass, then the centre of gravity in mm in the flange frame)",
                   path, target.line, std::to_string(target.column));
}

}  // namespace

std::optional<std::pair<std::string, std::vector<double>>> namedNumbers(const std::string& given,
                                                                        size_t count) {
  const size_t eq = given.rfind('=');
  if (eq == 0 || eq == std::string::npos) return std::nullopt;
  const std::vector<std::string_view> numbers = splitFields(std::string_view(given).substr(eq + 1));
  std::vector<double> v;
  for (const std::string_view n : numbers) {
    const std::optional<double> value = parseFinite(n);
    if (value) v.push_back(*value);
  }
  if (v.size() != count || numbers.size() != count) return std::nullopt;
  return std::make_pair(upperCase(given.substr(0, eq)), std::move(v));
}

std::map<std::string, GivenLoad> commandLineLoads(const std::vector<std::string>& program_loads) {
  std::map<std::string, GivenLoad> loads;
  for (const std::string& given : program_loads) {
    const auto named = namedNumbers(given, 4);
    if (!named) {
      throw InputError("--program-load " + inQuotes(given) +
                       ": expected NAME=kg,x,y,z (the mass, then the centre of gravity in mm in the flange frame)");
    }
    const std::vector<double>& v = named->second;
    if (v[0] < 0.0) throw InputError("--program-load " + inQuotes(given) + ": a negative mass; expected kg ≥ 0");
    loads[named->first] = GivenLoad{v[0], Vec3(v[1], v[2], v[3]) * kMPerMm};
  }
  return loads;
}

void warnOfUnusedLoads(const programs::Program& program, const std::map<std::string, GivenLoad>& given) {
  for (const auto& [name, load] : given) {
    bool named = name == "LOAD";
    std::string names;
    for (const programs::Load& l : program.loads) {
      named = named || upperCase(l.name) == name;
      names += (names.empty() ? "" : ", ") + l.name;
    }
    if (!named) {
      std::cerr << "stepcal correct: warning: --program-load " << name << ": the program names no such load"
                << (names.empty() ? std::string(" (it names none)") : " (it names " + names + ")") << "\n";
    }
  }
}

TargetLoad targetLoad(const programs::Program& program, const programs::Target& target, const Pose& X_FlangeTool,
                      const std::map<std::string, GivenLoad>& given, const std::string& path) {
  TargetLoad out;
  out.payload.frame = runtime::CogFrame::kFlange;
  if (target.load >= 0) {
    const programs::Load& load = program.loads[size_t(target.load)];
    const GivenLoad values = loadValues(load, given, target, path);
    out.payload.mass_kg = values.mass_kg;
    out.payload.p_CoG_m = values.p_CoG_m;
    out.name = load.name;
    return out;  // everything the flange carries (a RAPID \TLoad: GripLoad's payload with it)
  }
  if (target.tool >= 0 && program.frames[size_t(target.tool)].mass_kg > 0.0) {
    const programs::Frame& tool = program.frames[size_t(target.tool)];
    out.payload.mass_kg = tool.mass_kg;
    out.payload.p_CoG_m = tool.p_CoG_m;
    out.name = tool.name + "'s load";
  }
  // A target whose program names no load (a KRL .dat's points): --program-load LOAD=… where given.
  const auto default_load = given.find("LOAD");
  if (out.name.empty() && default_load != given.end()) {
    out.payload.mass_kg = default_load->second.mass_kg;
    out.payload.p_CoG_m = default_load->second.p_CoG_m;
    out.name = "LOAD";
  }
  if (target.grip_load >= 0) {
    const programs::Load& part = program.loads[size_t(target.grip_load)];
    const GivenLoad values = loadValues(part, given, target, path);
    const double mass_kg = out.payload.mass_kg + values.mass_kg;
    if (mass_kg > 0.0) {
      out.payload.p_CoG_m = (out.payload.mass_kg * out.payload.p_CoG_m + values.mass_kg * (X_FlangeTool * values.p_CoG_m)) / mass_kg;
    }
    out.payload.mass_kg = mass_kg;
    out.name += (out.name.empty() ? "" : " + ") + part.name;
  }
  return out;
}

std::string describeLoad(const TargetLoad& load) {
  if (load.payload.mass_kg <= 0.0) return load.name.empty() ? "; unloaded" : "; unloaded (" + load.name + ": 0 kg)";
  const Vec3 c_mm = load.payload.p_CoG_m * kMmPerM;
  return "; load " + load.name + ": " + formatShortest(load.payload.mass_kg) + " kg at " +
         report::format("%.1f %.1f %.1f", c_mm.x(), c_mm.y(), c_mm.z()) + " mm in the flange";
}

nlohmann::json loadJson(const TargetLoad& load) {
  const Vec3 c_mm = load.payload.p_CoG_m * kMmPerM;
  return {{"name", load.name}, {"mass_kg", load.payload.mass_kg}, {"cog_flange_mm", {c_mm.x(), c_mm.y(), c_mm.z()}}};
}

}  // namespace stepcal::cli
