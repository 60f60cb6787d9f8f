// Hidden mechanisms drawn at random at realistic sizes, as the twin's effects (effects.hpp): what
// the diagnosis tests and the stress run (stepcal-diagnose-stress) hide in a campaign.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::twin {

/// A mechanism drawn for a twin, and what a diagnosis names for it.
struct DrawnMechanism {
  nlohmann::json effect;  ///< the twin's JSON object (stepcal simulate --effect)
  MechanismKind kind = MechanismKind::kBacklash;  ///< the catalogue kind that describes it
  int joint = -1;         ///< 0-based: the joint it moves (−1: none)
  int source_joint = -1;  ///< joint_coupling: the joint whose angle drives it
};

/// The kinds drawMechanism draws: 0 backlash, 1 transmission error, 2 nonlinear stiffness,
/// 3 joint coupling, 4 thermal expansion, 5 sensor bias, 6 self weight, 7 a gear's torsion curve.
inline constexpr int kDrawnKinds = 8;

/// One mechanism of a kind at a size a laser tracker sees on the paper's campaign: lost motion
/// of 0.6–1.4 arcmin, cyclic errors of 10–25 arcsec (20–50 on the wrist), couplings of
/// 0.05–0.2 %, a joint up to twice as soft at small torque, thermal expansion of steel or
/// aluminium, a mistared sensor (15–40 N, 0.3–1.5 N·m), an upper arm and forearm out of balance
/// by 30–80 kg, a gear's curve with up to 0.8 arcmin of lost motion and one or two softer
/// segments; the torque-driven ones on the joints the protocol loads (2, 3, 5). The draws of
/// kinds 0–6 are those the diagnosis tests were validated on: do not change their sequence.
DrawnMechanism drawMechanism(int kind, std::mt19937_64& rng);

/// A stress mix for seed: 0 to 3 mechanisms of any kinds (self weight, thermal expansion and
/// sensor bias at most once each, as a twin holds them); a torque-driven one may land on the
/// joint another already loads (then the two are one curve of its torque); self weight from a
/// few kilograms up. The same seed gives the same mix.
std::vector<DrawnMechanism> drawMechanismMix(uint64_t seed);

/// A stress mix with load effects outside the diagnosis's catalogue (issue 43): what
/// stepcal-diagnose-stress --foreign hides.
struct ForeignMix {
  /// "bearing_tilt", "angle_dependent_stiffness", "beside" (one of them beside a catalogued
  /// mechanism) or "both".
  std::string design;
  /// bearing_tilt and angle_dependent_stiffness objects (stepcal simulate --effect).
  std::vector<nlohmann::json> foreign;
  /// The catalogued mechanism beside ("beside" only), one of drawMechanism's.
  std::vector<DrawnMechanism> catalogued;
};

/// One bearing_tilt at a size a tracker sees: joint 1 (two draws in three) with c in
/// [1.2e-7, 2.2e-7] rad/(N·m), 0.07–0.12 mm mean at 20 kg and 0.17–0.32 mm at 55 kg on the
/// paper protocol, or joint 2 with c in [0.8e-6, 1.6e-6] (its bearing carries only the payload's
/// moment out of the arm's plane), 0.025–0.05 mm and 0.07–0.14 mm.
nlohmann::json drawBearingTilt(std::mt19937_64& rng);
/// One angle_dependent_stiffness: joint 2 or 3, harmonic 3 … 12, ε in [0.1, 0.25], φ uniform:
/// 0.025–0.085 mm mean at 20 kg, 0.06–0.22 mm at 55 kg (the sizes scale with c and ε from
/// those TwinLoadEffects.SizesOnThePaperProtocol measures).
nlohmann::json drawAngleDependentStiffness(std::mt19937_64& rng);

/// The foreign mix of seed: the design by seed mod 4 (1 bearing_tilt, 2
/// angle_dependent_stiffness, 3 one of the two beside one catalogued mechanism of any kind
/// drawn by drawMechanism, 0 both), its draws from a stream of its own (drawMechanismMix's
/// seeds keep theirs). The same seed gives the same mix.
ForeignMix drawForeignMix(uint64_t seed);

}  // namespace stepcal::twin
