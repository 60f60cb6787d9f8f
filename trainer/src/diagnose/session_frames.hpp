// Several campaigns of one robot in one diagnosis (internal to stepcal::trainer): each later
// campaign's own tracker station and tool as a session_frames mechanism beside the robot's
// model, and a model's tracker and tool frames fitted again on a campaign's rows.
#pragma once

#include <string>
#include <vector>

#include "fit_rows.hpp"

namespace stepcal::trainer::diagnosis {

/// The tracker registered in closed form to the model's tips on these rows (gravity turns with
/// it): where refitFrames starts, since Gauss–Newton from a station metres away may not converge.
void registerInClosedForm(PhysicalModel& model, const FitRows& fit);

/// The model with its tracker and tool frames (docs/method.md eq. 7, blocks 0 and n) fitted on these
/// rows, the joint frames kept: the tracker registered in closed form to the model's tips
/// (gravity turns with it), then Gauss–Newton on those 12 parameters.
PhysicalModel refitFrames(PhysicalModel model, const FitRows& fit);

/// Per campaign after the first among the rows (Measurement::session, 1 … sessions − 1), its
/// session_frames against the model's own frames: refitFrames on that campaign's rows alone.
/// The σ are left zero (the diagnosis's refit sets them). Throws InputError naming the campaign
/// (directories: per campaign, its folder) when it has fewer than 4 of the rows.
std::vector<Mechanism> startingSessionFrames(const PhysicalModel& model,
                                             const std::vector<const Measurement*>& rows,
                                             int sessions, const TrackerNoise& noise,
                                             const std::vector<std::string>& directories);

/// Per campaign (0 … sessions − 1), the mean position error of its rows, m: |measured − modelled|
/// from the weighted residual r of the fit (evaluate).
std::vector<double> sessionMeanErrors(const Eigen::VectorXd& r, const FitRows& fit, int sessions);

}  // namespace stepcal::trainer::diagnosis
