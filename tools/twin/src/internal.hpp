// Helpers shared by the twin's sources (internal).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/common/chain.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal::twin {

/// options.urdf_path, or the shipped irb4400.urdf when it is empty.
std::string resolvedUrdfPath(const TwinOptions& options);

/// Checks every option; nominal is the chain read from the URDF. Throws InputError.
void validateOptions(const TwinOptions& options, const KinematicChain& nominal);

/// Reads the nominal chain base_link → tip_link with sensor_link attached. Throws InputError.
KinematicChain nominalChain(const std::string& urdf_xml, const TwinOptions& options,
                            const std::string& source);

/// Row-major 4×4 matrix as nested arrays.
nlohmann::json poseToJson(const Pose& X);
/// Inverse of poseToJson; throws InputError unless a rigid transform.
Pose poseFromJson(const nlohmann::json& j, const std::string& key);

}  // namespace stepcal::twin
