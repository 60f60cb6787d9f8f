// Whether a found cause has a size: what the data identify of it, in the final fit, against its
// uncertainty (internal to stepcal::trainer).
#pragma once

#include <vector>

#include "fit_rows.hpp"
#include "model.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

/// The size of a cause: χ² = pᵀ S p / s² over the directions of its parameters that the data
/// determine, and their number (dof). S is the information the fit rows hold on its parameters
/// once every other parameter of the model (geometry, the other causes, the profiles, their
/// ridges and priors) is fitted with them (the Schur complement of the model's weighted Gram), s²
/// the residual variance. A direction is determined by the data where its information exceeds the
/// cause's own prior there (the lumped masses' 50 kg / 50 kg·m), or is not numerically zero.
/// χ² > dof: the cause lies more than one σ from zero where the data see it (for one parameter,
/// |p| > σ). For a lumped self weight the masses themselves are not identifiable, only their
/// gravity torques on the compliant joints: those directions are what S determines. A profile's
/// size is its coefficients' cᵀ Σ_c⁻¹ c (Profile::size_chi2) against 2·order.
struct CauseSize {
  double chi2 = 0.0;
  int dof = 0;
  /// Whether its fit ended on a bound of its physics (a lumped link mass at zero, a centre of
  /// mass at its link's reach; never a profile): there the linearised χ² measures the bounded
  /// estimate, not what the fit loses without the cause.
  bool on_bound = false;
  double variance = 0.0;  ///< the residual variance χ² is in units of
  bool hasSize() const { return dof > 0 && chi2 > static_cast<double>(dof); }
};

/// The size of every found effect (d.effects order) at the model as it stands: global causes
/// from index base_globals on in model.global.mechanisms, profiles from base_profiles on.
/// self_weight under the URDF's masses is judged on the compliances of the joints it loads.
std::vector<CauseSize> causeSizes(const DiagnosisModel& model, const FitRows& fit,
                                  const Diagnosis& d, size_t base_globals, size_t base_profiles);

}  // namespace stepcal::trainer::diagnosis
