// A transmission profile told apart from the same profile modulated by its joint's torque (a
// stiffness that varies with the angle, which the catalogue does not hold), held out as the
// families are (internal to stepcal::trainer; docs/diagnosis.md "A profile or a stiffness that
// varies with the angle").
#pragma once

#include <vector>

#include "cross_validation.hpp"
#include "model.hpp"
#include "scoring.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// Before a round chooses among its significant families: each significant profile of the robot
/// that has torque-modulated columns (Family::torque_modulated) is fitted alone, beside them, and
/// they alone, on held-out poses, with its ridge: it at its order, they at the order of
/// DiagnoseOptions::profile_orders that fits best alone. When they explain significantly more
/// beside it and it adds nothing significant beside them, it leaves `significant` (the rows say
/// its error follows the angle in proportion to the torque); when both add, it stays, with the
/// modulated part reported as left; when neither adds beside the other, it stays unremarked.
/// The outcome is recorded per joint in d.load_modulated_profiles (the latest round's stands;
/// one that kept a profile the model never took is dropped).
void setAsideLoadModulatedProfiles(const std::vector<Scored>& scored,
                                   std::vector<size_t>& significant, const CrossValidation& cv,
                                   const DiagnosisModel& model, const DiagnoseOptions& options,
                                   int round, Diagnosis& d);

}  // namespace stepcal::trainer::diagnosis
