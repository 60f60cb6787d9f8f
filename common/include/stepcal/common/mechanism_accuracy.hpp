// What the mechanisms' fitted uncertainty adds to a pose's covariance (docs/method.md, "The
// accuracy bound"): each mechanism parameter's 1-σ (the model file's MECH section) propagated
// to the tip, analytically for the transmission profiles and their geometry, else by a central
// finite difference of the physical model, the parameters taken as independent (the model file
// keeps no correlations between them).
#pragma once

#include "stepcal/common/chain.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal {

/// The scratch of addMechanismCovariance, sized once for a model (allocates; off the real-time
/// path): a copy of the model whose parameters are moved one at a time and put back.
struct MechanismAccuracyWorkspace {
  PhysicalModel perturbed;
  ChainWorkspace chain;
  JointVector link_rad, torque_nm;
  /// The frames at θ₀ of a call's first evaluation, reused by the parameters that leave θ₀ and
  /// the initial poses as they are (the torque side: FirstPass).
  FirstPass first_pass;
};
MechanismAccuracyWorkspace makeMechanismAccuracyWorkspace(const PhysicalModel& model);

/// Whether any mechanism that moves the robot states a σ > 0 (else the sum adds nothing).
bool hasMechanismUncertainty(const PhysicalModel& model) noexcept;

/// Relative step of the finite difference: each parameter moves by ± kMechanismStep · σ_i.
inline constexpr double kMechanismStep = 1e-3;

/// covariance += Σ g gᵀ over every parameter i of every mechanism with σ_i > 0, g the pose's
/// change per 1-σ, the tip position and the rotation vector in the tracker's axes: of a
/// profile_geometry analytically (its gate times the identification matrix's column at
/// at_link_angles, the call's frames), of a transmission_error too (its gate times the harmonic's
/// sine or cosine at q_j times joint j's twist at the tip point, its coefficients correlated as
/// its factor in profile_factors says where it has one (the model's AccuracyFactors, may be
/// null); both first order: the deflection's change with the pose is left out), of every other
/// kind (tip(p + ε σ_i) ⊖ tip(p − ε σ_i)) / 2ε, the tip that of
/// physicalLinkAngles at (q, wrench, temp_c, payload), its model's full fixed point. constants:
/// physicalConstants(model) or null (no profile_geometry parameter is moved, so they hold).
/// Allocation-free; false when ws does not fit the model (nothing added).
bool addMechanismCovariance(const PhysicalModel& model, const PhysicalConstants* constants,
                            const std::vector<ProfileCovarianceFactor>* profile_factors,
                            const ChainWorkspace& at_link_angles, const JointVector& q_rad,
                            const Vec6& wrench_Sensor, double temp_c, const PointPayload* payload,
                            MechanismAccuracyWorkspace& ws, Mat6& covariance) noexcept;

}  // namespace stepcal
