// Closed-form registration of the tracker (and tool orientation) to the robot, so that
// iterative calibration starts close without the user giving a guess.
#pragma once

#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"

namespace stepcal::trainer {

/// Least-squares rigid transform X_BA with p_InB ≈ X_BA · p_InA (Kabsch/Horn, via SVD).
/// Throws InputError when the points are fewer than 3 or (nearly) collinear.
Pose fitRigidTransform(const std::vector<Vec3>& p_InA, const std::vector<Vec3>& p_InB);

/// Registers the tracker frame to the chain's root: X_TrackerRoot from the nominal tip
/// positions of the rows and the measured ones. Throws InputError on degenerate data.
Pose registerTracker(const KinematicChain& chain_Root, const std::vector<const Measurement*>& rows);

/// Average tool-frame rotation error R_ModelTipMeasuredTip over rows with orientation
/// (chordal mean); identity when no row has one. chain_Tracker must be rooted in the tracker.
Mat3 registerToolRotation(const KinematicChain& chain_Tracker,
                          const std::vector<const Measurement*>& rows);

}  // namespace stepcal::trainer
