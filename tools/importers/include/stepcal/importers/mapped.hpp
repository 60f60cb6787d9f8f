// The general importer: a tracker export beside a joint log from the controller, columns and
// units named by a mapping file (docs/cell.md, "Importing a cell's own measurements").
#pragma once

#include <string>

#include "stepcal/common/campaign.hpp"

namespace stepcal::importers {

/// Reads the mapping file (YAML, format stepcal-import-mapping/1), the tracker export and the
/// joint log it names (paths relative to the mapping file), joins their rows by row, by
/// timestamp (nearest within the stated tolerance) or by point name, and returns the campaign.
/// All or nothing: any bad key, row or value throws InputError naming the file, the line, the
/// column, the value and what was expected.
Campaign importMapped(const std::string& mapping_path);

}  // namespace stepcal::importers
