// The re-check after a crash, a motor change or a re-mastering (docs/cell.md, "The re-check"):
// a short campaign against a stored model, what changed (each joint's zero, the tool, the
// compliances where the rows are at several loads), with its
// significance, and the model updated.
#pragma once

#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"

namespace stepcal::trainer {

/// What the re-check fits beside the joint zeros.
struct RecheckOptions {
  /// Keep the model's tracker registration (the tracker has not moved since calibration): then
  /// joint 1's zero is seen; otherwise a new registration absorbs it (a turn about the base's
  /// first axis is a turn of the tracker).
  bool keep_registration = false;
  /// Keep the model's tool: then the last joint's zero is seen; otherwise the refitted tool
  /// absorbs it (on rows with orientation; position-only rows see it through the tool's offset).
  bool keep_tool = false;
};

/// One joint's zero: link angle = reading + delta_rad from now on.
struct ZeroChange {
  int joint = 0;        ///< 0-based
  bool fitted = false;  ///< false: absorbed by the registration or the tool (see options)
  double delta_rad = 0.0, sigma_rad = 0.0;
  bool changed = false;  ///< beyond 3σ and beyond kNegligibleZeroChange_rad
};

/// A size beyond which a zero change is worth acting on: 30 µrad moves a tip 1.5 m out by
/// 0.045 mm, three times a laser tracker's noise.
inline constexpr double kNegligibleZeroChange_rad = 30e-6;
/// A tool change worth acting on: 0.05 mm at the TCP.
inline constexpr double kNegligibleToolChange_m = 0.05e-3;
/// A compliance change worth acting on: 5 % of the joint's compliance.
inline constexpr double kNegligibleComplianceChange = 0.05;
/// A joint's compliance is tested only where its torque spans this much across the fit rows: a
/// torque that is the same in every row deflects the joint as a zero change does.
inline constexpr double kMinimumTorqueSpan_nm = 1.0;

/// One joint's compliance on a re-check campaign at several loads.
struct ComplianceChange {
  int joint = 0;        ///< 0-based
  bool tested = false;  ///< false: not identifiable from these rows (see torque_span_nm, sigma)
  double torque_span_nm = 0.0;  ///< max − min of the joint's torque over the fit rows
  double stored_rad_per_nm = 0.0, delta_rad_per_nm = 0.0, sigma_rad_per_nm = 0.0;
  bool changed = false;  ///< beyond 3σ and beyond kNegligibleComplianceChange
};

struct RecheckResult {
  int fit_rows = 0, validation_rows = 0;
  std::vector<ZeroChange> zeros;
  bool tool_fitted = false;
  Vec3 tool_translation_m = Vec3::Zero();  ///< the tip's move, in the tip frame
  double tool_translation_sigma_m = 0.0;   ///< largest 1-σ of its components
  bool tool_changed = false;
  bool registration_fitted = false;
  /// Mean position error of the fit rows, m: the stored model with only the tracker (and tool)
  /// refitted, then with the zeros too.
  double fit_error_frames_only_m = 0.0, fit_error_after_m = 0.0;
  /// The same on the validation rows (set=validation), never fitted; 0 without such rows.
  double validation_error_frames_only_m = 0.0, validation_error_after_m = 0.0;
  double chi2_reduced = 0.0;
  /// Compliance is tested where the fit rows carry wrenches at two loads or more and the model
  /// has a compliance step; otherwise why not, in words.
  bool compliance_tested = false;
  std::string compliance_not_tested;
  std::vector<ComplianceChange> compliances;  ///< one per joint when tested
  /// The model with the new zeros, tool, registration and tested compliances
  CalibratedModel updated;
};

/// Fits the model's registration, tool, joint zeros (and compliances, where the loads identify
/// them) on the campaign's fit rows (every row but
/// set=validation), the rest of the model kept. Throws InputError when the campaign is not of the
/// model's robot or has fewer rows than unknowns.
RecheckResult recheckModel(const CalibratedModel& model, const Campaign& campaign,
                           const RecheckOptions& options);

/// The operator's words: each changed zero and compliance with its 1-σ, the tool, or "nothing
/// changed".
std::string recheckVerdict(const RecheckResult& result);

}  // namespace stepcal::trainer
