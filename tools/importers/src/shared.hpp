// Pieces the importers share (ipa.cpp, mapped.cpp): a rigid transform read from a text file,
// a fixed link added to a URDF, and a file that must exist.
#pragma once

#include <string>

#include "stepcal/common/types.hpp"

namespace stepcal::importers {

/// A whole file's text; throws InputError naming `what` and the path when it is missing or a
/// folder.
std::string readExistingFile(const std::string& path, const std::string& what);

/// The 4×4 homogeneous matrix of a text file (four lines of four numbers separated by spaces or
/// tabs, decimal point), translation in the file's unit times metres_per_unit. Refuses a matrix
/// that is not a rigid transform. what: how messages name the file.
Pose readRigidTransformFile(const std::string& path, const std::string& what,
                            double metres_per_unit);

/// The URDF with `child` added as a fixed link on `parent` at X_ParentChild (joint
/// "<parent>-<child>"), preceded by an XML comment saying where it comes from.
std::string withFixedLink(const std::string& urdf, const std::string& parent,
                          const std::string& child, const Pose& X_ParentChild,
                          const std::string& comment, const std::string& source);

}  // namespace stepcal::importers
