// Importer of the IPA UR10 accuracy data set (Landgraf et al., CASE 2021;
// github.com/christianlandgraf/ipa-robot-accuracy): a UR10 measured with a Leica laser
// tracker and T-Mac, joint angles from the controller.
#pragma once

#include <string>

#include "stepcal/common/campaign.hpp"

namespace stepcal::importers {

/// Reads one series of the IPA UR10 data set (…/Series_X/<measurements>.csv, plus
/// Trafo_TM_F_init.txt in the same folder) into a campaign with tip_link `tmac`.
/// Rows from validation_from_row on (0-based, counted after the header) get set=validation,
/// the rest set=geometry; -1 = none.
/// ur10_urdf_path: the nominal UR10 URDF (robots/ur10.urdf). Throws InputError.
Campaign importIpaSeries(const std::string& series_csv, int validation_from_row,
                         const std::string& ur10_urdf_path);

}  // namespace stepcal::importers
