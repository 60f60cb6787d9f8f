// A global cause told apart from a stiffness that varies with the angle: each joint's torque
// modulated by harmonics of its angle, which the catalogue does not hold, held out as the
// families are (internal to stepcal::trainer; docs/diagnosis.md "A cause standing in for a
// stiffness that varies with the angle").
#pragma once

#include <functional>
#include <vector>

#include "cross_validation.hpp"
#include "scoring.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// Before a round chooses among its significant families: each joint's torque-modulated columns
/// (a profile family's Family::torque_modulated and weight_modulated, in stage 1) at the order of
/// DiagnoseOptions::profile_orders that fits best alone, where they alone are significant
/// (p < family_alpha, at least min_relative_reduction); each significant global family fitted
/// beside them (within its bounds where its score needed them). A family leaves `significant`
/// (its score's modulated_stand_in says why) when some joint's modulated columns add
/// significantly beside it and it is no longer significant (is_significant, the round's level,
/// on the reduction of the round's error) beside them: what it explained is the joint's torque
/// varying with its angle. Where neither adds beside the other the family stays: the rows cannot
/// tell them apart and the catalogue's cause is named. Where only global families stay
/// significant, each is ranked (its outcome and total, what choose() compares) by its per-pose
/// reduction beside the block that leaves it least, taken from the round's base: a curve of the
/// joint next to the varying one that explains part of it through the torques they share does
/// not win the round on that part. Where a profile competes, every family keeps its reduction
/// alone (a profile is not fitted beside the block; like is compared with like).
void setAsideModulatedStandIns(std::vector<Scored>& scored, std::vector<size_t>& significant,
                               const CrossValidation& cv, const DiagnoseOptions& options,
                               const std::function<bool(const CandidateScore&)>& is_significant);

}  // namespace stepcal::trainer::diagnosis
