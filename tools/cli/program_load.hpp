#pragma once
// The load a robot program's target is corrected under (`stepcal correct PROGRAM`): the
// program's own (KRL $LOAD/LOAD_DATA, RAPID tooldata/\TLoad/GripLoad, URScript set_payload, Fanuc
// PAYLOAD[n]) or, for a load it names without values, --program-load's; how each target's report
// line and --json name it.
#include <map>
#include <optional>
#include <utility>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/programs/program.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::cli {

/// A load as --program-load gives it: NAME=kg,x,y,z (mm, in the flange frame; a RAPID GripLoad's
/// loaddata in the tool frame, as the program would hold it).
struct GivenLoad {
  double mass_kg = 0.0;
  Vec3 p_CoG_m = Vec3::Zero();
};

/// An option's NAME=a,b,… (--program-load, --program-frame): the name in upper case and exactly
/// `count` finite numbers; nullopt when it is not of that form.
std::optional<std::pair<std::string, std::vector<double>>> namedNumbers(const std::string& given,
                                                                        size_t count);

/// --program-load's values by upper-case name. Throws InputError for a malformed one.
std::map<std::string, GivenLoad> commandLineLoads(const std::vector<std::string>& program_loads);

/// Says on stderr which --program-load names the program never names (a typo: PAYLOAD[01]).
void warnOfUnusedLoads(const programs::Program& program, const std::map<std::string, GivenLoad>& given);

/// What a target is corrected under: the payload (flange frame) and its name ("" unloaded).
struct TargetLoad {
  runtime::Payload payload;  ///< frame kFlange; mass 0 when unloaded
  std::string name;          ///< LOAD_DATA[1], tGripper's tload + piece, set_payload line 4
};

/// The target's load: the load in force where the program names one (its values, else
/// --program-load's), else its tool's load, else --program-load LOAD=… where given; plus a RAPID GripLoad payload carried in the tool
/// (X_FlangeTool). A load named without values and not given is refused with the target's file,
/// line and column, naming the option.
TargetLoad targetLoad(const programs::Program& program, const programs::Target& target, const Pose& X_FlangeTool,
                      const std::map<std::string, GivenLoad>& given, const std::string& path);

/// "; load LOAD_DATA[1]: 30 kg at 0 0 150 mm" or "; unloaded", for a target's report line.
std::string describeLoad(const TargetLoad& load);

/// {"name", "mass_kg", "cog_flange_mm"} for --json.
nlohmann::json loadJson(const TargetLoad& load);

}  // namespace stepcal::cli
