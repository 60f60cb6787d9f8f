#pragma once
// A target's configuration word as its language writes it (KUKA S and T, ABB confdata, Fanuc
// CONFIG), read to the arm branch and turns it names (common/robot_configuration.hpp), and
// checked against joints: `stepcal correct` seeds a Cartesian target's inverse with the closed
// form in the branch the word names and writes a correction only where the corrected joints
// have the same word.
#include <optional>
#include <string>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/closed_form_ik.hpp"
#include "stepcal/common/robot_configuration.hpp"
#include "stepcal/programs/program.hpp"

namespace stepcal::programs {

struct ConfigurationWord {
  Language language = Language::kKrl;
  std::optional<int> kuka_status, kuka_turn;  ///< KRL: S and T where written
  std::optional<AbbConfData> abb;              ///< RAPID
  std::optional<FanucConfig> fanuc;            ///< TP
};

/// The word of a Cartesian target; nullopt when it has none (URScript, a KRL POS without S).
/// Throws InputError (the program's file, the target's line and column) for a word that is not
/// one (S 'B2', [0,0,0], 'X U T, 0, 0, 0').
std::optional<ConfigurationWord> readConfiguration(Language language, const Target& target,
                                                   const std::string& path);

/// The branch the word names, through the controller's joint convention.
ArmBranch branchNamed(const ConfigurationWord& word, const ControllerJoints& joints);

/// The controller's joints moved by whole turns to the word's turns (KUKA T: each joint's
/// sign; ABB: the quadrants of 1, 4, 6; Fanuc: the turn numbers of J1, J4, J6), each only where
/// the chain's limits allow.
void applyTurns(const ConfigurationWord& word, const KinematicChain& chain,
                const ControllerJoints& joints, JointVector& q_controller_rad);

/// Whether joints (controller convention) in `branch` have the configuration the word names;
/// `theirs` is the word they have, as the language writes it, for a message.
bool sameConfiguration(const ConfigurationWord& word, const ArmBranch& branch,
                       const JointVector& q_controller_rad, std::string& theirs);

}  // namespace stepcal::programs
