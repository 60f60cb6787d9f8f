// The columns of a round's screening matrix and what they are made from (internal to
// stepcal::trainer): the screening (candidates.cpp) and each kind's families (families/) append
// to them, makeColumns fills them chunk by chunk.
#pragma once

#include <vector>

#include "confounds.hpp"
#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"

namespace stepcal::trainer::diagnosis {

// A scaled column of the screening matrix (cross_validation.hpp, ColumnLayout): what multiplies
// its joint's link-angle column in each row.
struct ScaledSource {
  enum class Kind {
    kTorquePart,     // a unit part of a torque–deflection curve at the row's torque of the joint
    kJointAngle,     // another joint's angle (a coupling)
    kGravityTorque,  // the joint's gravity torque under the URDF's masses at the row's link angles
    kProfile,        // a profile's gated harmonics, 2·order columns
    kProfileTorque,  // a profile's gated harmonics times a part of the row's torque of the
                     // joint over torque_scale_nm, 2·order columns (a stiffness varying with
                     // the angle): the model's torque less the weight of self_weight_masses,
                     // or with weight_part that weight alone
    kTemperature,    // the row's temperature less a reference (0 where it is not known)
    kCampaign,       // 1 on the rows of one campaign, 0 on the others
    kConfounder,     // a function of a variable that moves with a time-order family's driver
  };
  Kind kind = Kind::kTorquePart;
  Mechanism unit;            // kTorquePart
  int source_joint = -1;     // kJointAngle
  double reference_c = 0.0;  // kTemperature
  int campaign = 0;          // kCampaign; kProfile: ≥ 1, its columns on that campaign's rows only
  AngleCoverage coverage;    // kProfile
  int order = 0;             // kProfile
  ConfounderPtr variable;    // kConfounder: the variable, and which of its functions
  int function = 0;
  double torque_scale_nm = 1.0;  // kProfileTorque
  // kProfileTorque: the model's self weight ((m, m·com) per link; empty: none), and whether the
  // columns carry its gravity torque rather than the rest of the torque
  std::vector<double> self_weight_masses;
  bool weight_part = false;
  bool isProfile() const { return kind == Kind::kProfile || kind == Kind::kProfileTorque; }
  Eigen::Index first = 0;    // its first column among the joint's scaled ones
  bool sameColumn(const ScaledSource& other) const {
    return kind == other.kind && !isProfile() && source_joint == other.source_joint &&
           reference_c == other.reference_c && campaign == other.campaign &&
           unit.kind == other.unit.kind && unit.parameters == other.unit.parameters &&
           variable == other.variable && function == other.function;
  }
};

// A dense column of the screening matrix that is a geometry column times a polynomial of the
// row's time order: the tracker registration's columns moved in time (registration_drift). Made
// from the linearisation, no evaluation of its own.
struct TimeScaled {
  Eigen::Index dense = 0;     // its place among a chunk's dense columns
  Eigen::Index geometry = 0;  // the geometry column it scales
  int degree = 1;             // P_degree(s), s the row's time order mapped onto [−1, 1]
  double first_seq = 0.0, last_seq = 1.0;
};

// A dense column of the screening matrix that is a geometry column times a function of a
// variable that moves with the time order: a registration drift re-made as a function of that
// variable, the nuisance it is told apart from (confounds.hpp).
struct VariableScaled {
  Eigen::Index dense = 0;     // its place among a chunk's dense columns
  Eigen::Index geometry = 0;  // the geometry column it scales
  ConfounderPtr variable;
  int function = 0;           // ConfounderVariable::function
};

// What a round's screening matrix is made from, chunk by chunk of fit rows: the model it is
// linearised at (its geometry and link-angle columns, its torques and link angles for the
// features), the models whose finite differences are its other dense columns, the geometry
// columns scaled by time, and each joint's scaled sources.
struct ColumnRecipe {
  PhysicalModel whole;
  std::vector<PhysicalModel> moved;  // per finite-difference column, the model moved by its step
  std::vector<double> step;
  std::vector<Eigen::Index> moved_dense;  // per finite-difference column, its dense place
  std::vector<TimeScaled> time_scaled;
  std::vector<VariableScaled> variable_scaled;
  Eigen::Index dense = 0;                         // dense columns of a chunk
  std::vector<std::vector<ScaledSource>> scaled;  // per joint
  std::vector<double> masses;                     // the URDF's, for kGravityTorque
};

// Appends columns to a growing screening matrix: the geometry's, finite differences of a
// model, a repeat of a column, a joint's scaled features (one column per distinct feature) and
// profile blocks. Each column gets a ridge (0: none).
struct ColumnSink {
  ColumnSink(ColumnLayout& layout, ColumnRecipe& recipe, Eigen::Index geometry, int joints)
      : layout_(layout), recipe_(recipe) {
    layout_.dense = geometry;
    recipe_.dense = geometry;
    layout_.scaled.assign(static_cast<size_t>(joints), 0);
    recipe_.scaled.resize(static_cast<size_t>(joints));
  }
  std::vector<double> ridge;  // per column

  Eigen::Index geometry(Eigen::Index c) { return added({-1, c}, 0.0); }
  Eigen::Index difference(const PhysicalModel& model, const Parameter& p, double column_ridge) {
    PhysicalModel moved = model;
    shift(moved, p, p.step);
    recipe_.moved.push_back(std::move(moved));
    recipe_.step.push_back(p.step);
    recipe_.moved_dense.push_back(layout_.dense);
    recipe_.dense = layout_.dense + 1;
    return added({-1, layout_.dense++}, column_ridge);
  }
  // Geometry column c times P_degree of the time order (one column per distinct pair).
  Eigen::Index timeScaled(Eigen::Index c, int degree, double first_seq, double last_seq) {
    for (const TimeScaled& t : recipe_.time_scaled) {
      if (t.geometry == c && t.degree == degree) return added({-1, t.dense}, 0.0);
    }
    recipe_.time_scaled.push_back({layout_.dense, c, degree, first_seq, last_seq});
    recipe_.dense = layout_.dense + 1;
    return added({-1, layout_.dense++}, 0.0);
  }
  // Geometry column c times a function of a variable (one column per distinct triple).
  Eigen::Index variableScaled(Eigen::Index c, const ConfounderPtr& variable, int function) {
    for (const VariableScaled& v : recipe_.variable_scaled) {
      if (v.geometry == c && v.variable == variable && v.function == function) {
        return added({-1, v.dense}, 0.0);
      }
    }
    recipe_.variable_scaled.push_back({layout_.dense, c, variable, function});
    recipe_.dense = layout_.dense + 1;
    return added({-1, layout_.dense++}, 0.0);
  }
  Eigen::Index repeat(Eigen::Index column, double column_ridge) {
    return added(layout_.place[static_cast<size_t>(column)], column_ridge);
  }
  Eigen::Index feature(int joint, ScaledSource source) {
    std::vector<ScaledSource>& sources = recipe_.scaled[static_cast<size_t>(joint)];
    for (const ScaledSource& other : sources) {
      if (other.sameColumn(source)) return added({joint, other.first}, 0.0);
    }
    source.first = layout_.scaled[static_cast<size_t>(joint)]++;
    sources.push_back(std::move(source));
    return added({joint, sources.back().first}, 0.0);
  }
  std::vector<Eigen::Index> profile(int joint, const AngleCoverage& coverage, int order,
                                    int campaign = 0) {
    ScaledSource source;
    source.kind = ScaledSource::Kind::kProfile;
    source.coverage = coverage;
    source.order = order;
    source.campaign = campaign;
    return profileBlock(joint, std::move(source));
  }
  // The same profile's harmonics times a part of the joint's torque over torque_scale_nm
  // (columns of a size like the profile's, so that one ridge serves both).
  std::vector<Eigen::Index> torqueModulatedProfile(int joint, const AngleCoverage& coverage,
                                                   int order, double torque_scale_nm,
                                                   std::vector<double> self_weight_masses,
                                                   bool weight_part) {
    ScaledSource source;
    source.kind = ScaledSource::Kind::kProfileTorque;
    source.coverage = coverage;
    source.order = order;
    source.torque_scale_nm = torque_scale_nm;
    source.self_weight_masses = std::move(self_weight_masses);
    source.weight_part = weight_part;
    return profileBlock(joint, std::move(source));
  }

 private:
  std::vector<Eigen::Index> profileBlock(int joint, ScaledSource source) {
    const int order = source.order;
    source.first = layout_.scaled[static_cast<size_t>(joint)];
    layout_.scaled[static_cast<size_t>(joint)] += 2 * order;
    recipe_.scaled[static_cast<size_t>(joint)].push_back(source);
    std::vector<Eigen::Index> columns;
    for (int k = 0; k < 2 * order; ++k) columns.push_back(added({joint, source.first + k}, 0.0));
    return columns;
  }
  Eigen::Index added(ColumnLayout::Place place, double column_ridge) {
    layout_.place.push_back(place);
    ridge.push_back(column_ridge);
    return layout_.size() - 1;
  }
  ColumnLayout& layout_;
  ColumnRecipe& recipe_;
};

}  // namespace stepcal::trainer::diagnosis
