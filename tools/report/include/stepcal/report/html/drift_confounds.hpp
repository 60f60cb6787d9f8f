// The diagnosis page's section on what moves with the time order and whether each time-order
// family was told apart from it (internal to stepcal::report).
#pragma once

#include <string>

#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::report::html {

/// "What moves with the time order": the variables' r with the time order (those at r ≥ 0.3, or
/// the largest when none is), and per time-order family tested, its score alone and beside each
/// variable that moves with its driver, told apart or not. Empty when there is nothing to show.
std::string driftConfoundsSection(const trainer::DriftVerdict& drift);

}  // namespace stepcal::report::html
