// backlash, nonlinear_stiffness and torsion_curve: a joint's torque–deflection curve, one per
// joint, its kinds competing (families.hpp).
//
// Torque-driven mechanisms need load torque on the joint; their torque scales come from the
// loads the joint sees. Lost motion is taken up at a tenth of the typical load (far above the
// sensor's noise, far below the loads); a nonlinear stiffness fades at, and a torsion curve's
// knee sits at, a torque of a grid (the deflection is linear in the compliance for a given
// torque; far below the loads either is lost motion, far above them linear compliance). A
// joint has one torque–deflection curve: without one yet, backlash alone, nonlinear stiffness
// alone and torsion curves (lost motion or not, one or two knees) compete; a backlash or a
// torsion curve found is extended by the part it lacks (lost motion, a knee at another torque),
// and a nonlinear stiffness by a backlash beside it.
#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>

#include "families.hpp"
#include "stepcal/common/mechanisms/backlash.hpp"
#include "stepcal/common/mechanisms/nonlinear_stiffness.hpp"
#include "stepcal/common/mechanisms/torsion_curve.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr double kTorqueFactors[] = {0.1, 0.25, 0.5, 1.0, 2.0};

using Knees = std::vector<std::pair<double, double>>;  // (compliance, torque) per knee

// One joint's curve families: its torque scales and the columns of a curve's parts.
class JointCurves {
 public:
  JointCurves(const FamilyContext& c, int joint, double typical, double largest)
      : c_(c), j_(joint), typical_(typical), largest_(largest), smoothing_(0.1 * typical) {}

  // Without a curve yet: backlash, nonlinear stiffness and torsion curves compete.
  void fresh() const {
    addBacklash();
    for (double factor : kTorqueFactors) {
      Family f;
      f.mechanism = blank(MechanismKind::kNonlinearStiffness, c_.n, j_);
      const double t0 = factor * typical_;
      view<mechanism::NonlinearStiffness>(f.mechanism).saturationTorque_nm() = t0;
      view<mechanism::NonlinearStiffness>(f.mechanism).linearAbove_nm() = largest_;
      f.free = {mechanism::NonlinearStiffness<double>::kExtraCompliance};
      f.chosen = 1;
      c_.addGlobal(std::move(f), {partColumn(MechanismKind::kNonlinearStiffness, t0)}, {1e-4 / t0});
    }
    for (const bool with_lost : {true, false}) {
      for (size_t a = 0; a < std::size(kTorqueFactors); ++a) {
        for (size_t b = a; b < std::size(kTorqueFactors); ++b) {
          Knees knees = {{0.0, kTorqueFactors[a] * typical_}};
          if (b > a) knees.push_back({0.0, kTorqueFactors[b] * typical_});
          // A single knee without lost motion: nonlinear stiffness's part.
          if (!with_lost && knees.size() == 1) continue;
          Family f;
          f.mechanism = curve(0.0, with_lost ? smoothing_ : 0.0, knees);
          f.free = signConstrained(f.mechanism);
          f.chosen = static_cast<int>(knees.size());
          std::vector<Eigen::Index> columns;
          std::vector<double> steps;
          if (with_lost) {
            columns.push_back(lostColumn());
            steps.push_back(1e-4);
          }
          for (const auto& knee : knees) {
            columns.push_back(kneeColumn(knee.second));
            steps.push_back(1e-4 / knee.second);
          }
          c_.addGlobal(std::move(f), std::move(columns), std::move(steps));
        }
      }
    }
  }

  // A backlash or a torsion curve (global mechanism `existing`), extended by one part at a time.
  void extend(int existing) const {
    const Mechanism& m = c_.global.mechanisms[static_cast<size_t>(existing)];
    // A backlash's two parameters are a torsion curve's first two (lost motion, smoothing).
    const mechanism::TorsionCurve<const double> have = view<mechanism::TorsionCurve>(m);
    const bool lost = have.smoothingTorque_nm() > 0.0;
    Knees knees;
    for (int term = 1; term <= m.order; ++term) {
      knees.push_back({have.extraCompliance_rad_per_nm(term), have.kneeTorque_nm(term)});
    }
    if (!lost) {
      Family f;
      f.mechanism = curve(0.0, smoothing_, knees);
      f.free = {mechanism::TorsionCurve<double>::kLostMotion};
      f.extends = existing;
      c_.addGlobal(std::move(f), {lostColumn()}, {1e-4});
    }
    if (static_cast<int>(knees.size()) >= kMaxTorsionTerms) return;
    for (double factor : kTorqueFactors) {
      const double knee = factor * typical_;
      // A knee within a factor 1.5 of one the curve has is that knee again.
      bool near = false;
      for (const auto& k : knees) near = near || (knee < 1.5 * k.second && k.second < 1.5 * knee);
      if (near) continue;
      Knees more = knees;
      more.push_back({0.0, knee});
      std::sort(more.begin(), more.end(),
                [](const auto& x, const auto& y) { return x.second < y.second; });
      const auto at =
          std::find_if(more.begin(), more.end(), [&](const auto& x) { return x.second == knee; });
      Family f;
      f.mechanism = curve(have.lostMotion_rad(), have.smoothingTorque_nm(), more);
      f.free = {mechanism::TorsionCurve<double>::complianceIndex(
          1 + static_cast<int>(at - more.begin()))};
      f.chosen = 1;
      f.extends = existing;
      c_.addGlobal(std::move(f), {kneeColumn(knee)}, {1e-4 / knee});
    }
  }

  void addBacklash() const {
    Family f;
    f.mechanism = blank(MechanismKind::kBacklash, c_.n, j_);
    view<mechanism::Backlash>(f.mechanism).smoothingTorque_nm() = smoothing_;
    f.free = {mechanism::Backlash<double>::kLostMotion};
    c_.addGlobal(std::move(f), {lostColumn()},
                 {typicalStep(blank(MechanismKind::kBacklash, c_.n, j_), 0)});
  }

 private:
  // The link-angle column of one part of a curve at unit size (torqueDeflection's shapes).
  Eigen::Index partColumn(MechanismKind kind, double scale_nm) const {
    Mechanism unit = blank(kind, c_.n, j_, -1, kind == MechanismKind::kTorsionCurve ? 1 : 0);
    if (kind == MechanismKind::kBacklash) {
      view<mechanism::Backlash>(unit).lostMotion_rad() = 1.0;
      view<mechanism::Backlash>(unit).smoothingTorque_nm() = scale_nm;
    } else if (kind == MechanismKind::kNonlinearStiffness) {
      view<mechanism::NonlinearStiffness>(unit).extraCompliance_rad_per_nm() = 1.0;
      view<mechanism::NonlinearStiffness>(unit).saturationTorque_nm() = scale_nm;
    } else {  // a knee alone: c = 1 at T = scale
      view<mechanism::TorsionCurve>(unit).extraCompliance_rad_per_nm(1) = 1.0;
      view<mechanism::TorsionCurve>(unit).kneeTorque_nm(1) = scale_nm;
    }
    ScaledSource source;
    source.unit = std::move(unit);
    return c_.sink.feature(j_, std::move(source));
  }
  Eigen::Index lostColumn() const { return partColumn(MechanismKind::kBacklash, smoothing_); }
  Eigen::Index kneeColumn(double knee) const {
    return partColumn(MechanismKind::kTorsionCurve, knee);
  }

  // A curve of lost motion (b, smoothing; 0: none) and knees (compliance, torque).
  Mechanism curve(double b, double lost_smoothing, const Knees& knees) const {
    Mechanism m = blank(MechanismKind::kTorsionCurve, c_.n, j_, -1, static_cast<int>(knees.size()));
    const mechanism::TorsionCurve<double> c = view<mechanism::TorsionCurve>(m);
    c.lostMotion_rad() = b;
    c.smoothingTorque_nm() = lost_smoothing;
    for (int term = 1; term <= m.order; ++term) {
      c.extraCompliance_rad_per_nm(term) = knees[static_cast<size_t>(term - 1)].first;
      c.kneeTorque_nm(term) = knees[static_cast<size_t>(term - 1)].second;
    }
    c.linearAbove_nm() = largest_;
    return m;
  }

  const FamilyContext& c_;
  const int j_;
  const double typical_;
  const double largest_;  // a curve's τ_lin: above it no row shows the curve
  const double smoothing_;
};

// A torsion curve's sizes: its lost motion (when it has one) and each term's compliance.
std::vector<int> curveSizes(const Mechanism& m) {
  using Curve = mechanism::TorsionCurve<const double>;
  std::vector<int> constrained;
  if (view<mechanism::TorsionCurve>(m).smoothingTorque_nm() > 0.0) {
    constrained.push_back(Curve::kLostMotion);
  }
  for (int term = 1; term <= m.order; ++term) constrained.push_back(Curve::complianceIndex(term));
  return constrained;
}

}  // namespace

void torqueDeflectionFamilies(const FamilyContext& c) {
  const auto wantedTorque = [&](int joint) {
    return c.scope.families &&
           (c.scope.only == nullptr ||
            (isTorqueDeflection(c.scope.only->kind) && c.scope.only->joint == joint));
  };
  for (int j = 0; j < c.n; ++j) {
    std::vector<double> loaded;
    double largest = 0.0;
    for (const JointVector& tau : c.start.tau_nm) {
      if (std::abs(tau(j)) > 1.0) loaded.push_back(std::abs(tau(j)));
      largest = std::max(largest, std::abs(tau(j)));
    }
    const double typical = median(loaded);
    if (loaded.size() < 10 || typical < 10.0) {
      for (const char* name : {"backlash", "nonlinear_stiffness", "torsion_curve"}) {
        c.s.untestable.push_back({std::string(name) + " (joint " + std::to_string(j + 1) + ")",
                                  "the joint carries too little load torque on these rows"});
      }
      continue;
    }
    if (!wantedTorque(j)) continue;
    int existing = -1, count = 0;
    for (size_t k = 0; k < c.global.mechanisms.size(); ++k) {
      const Mechanism& m = c.global.mechanisms[k];
      if (!isTorqueDeflection(m.kind) || m.joint != j) continue;
      if (existing < 0 || m.kind == MechanismKind::kNonlinearStiffness) {
        existing = static_cast<int>(k);
      }
      ++count;
    }
    if (count > 1) continue;  // a nonlinear stiffness and a backlash beside it: the whole curve
    const JointCurves curves(c, j, typical, largest);
    if (existing < 0) {
      curves.fresh();
    } else if (c.global.mechanisms[static_cast<size_t>(existing)].kind ==
               MechanismKind::kNonlinearStiffness) {
      curves.addBacklash();  // its fade is no knee: lost motion joins it as a backlash of its own
    } else {
      curves.extend(existing);
    }
  }
}

const KindFit& backlashFit() {
  static const KindFit fit = [] {
    using Backlash = mechanism::Backlash<double>;
    KindFit f{MechanismKind::kBacklash};
    f.sign_constrained = [](const Mechanism&) { return std::vector<int>{Backlash::kLostMotion}; };
    // The smoothing torque is chosen from the loads.
    f.free_parameters = [](const Mechanism&) { return std::vector<int>{Backlash::kLostMotion}; };
    return f;
  }();
  return fit;
}

const KindFit& nonlinearStiffnessFit() {
  static const KindFit fit = [] {
    using Stiffness = mechanism::NonlinearStiffness<const double>;
    KindFit f{MechanismKind::kNonlinearStiffness};
    f.typical_step = [](const Mechanism& m, int index) {
      const double t0 = view<mechanism::NonlinearStiffness>(m).saturationTorque_nm();
      return index == Stiffness::kExtraCompliance ? 1e-4 / t0 : 0.01 * t0;
    };
    f.sign_constrained = [](const Mechanism&) {
      return std::vector<int>{Stiffness::kExtraCompliance};
    };
    // τ_lin is the rows', τ₀ is free once the curve has a size.
    f.free_parameters = [](const Mechanism& m) {
      std::vector<int> free = {Stiffness::kExtraCompliance};
      if (view<mechanism::NonlinearStiffness>(m).extraCompliance_rad_per_nm() != 0.0) {
        free.push_back(Stiffness::kSaturationTorque);
      }
      return free;
    };
    f.is_shape = [](int index) { return index == Stiffness::kSaturationTorque; };
    return f;
  }();
  return fit;
}

const KindFit& torsionCurveFit() {
  using Curve = mechanism::TorsionCurve<const double>;
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kTorsionCurve};
    f.typical_step = [](const Mechanism& m, int index) {  // lost motion; a knee's compliance, torque
      const Curve curve = view<mechanism::TorsionCurve>(m);
      if (index == Curve::kLostMotion) return 1e-4;
      if (index == Curve::kSmoothingTorque) return 0.01 * curve.smoothingTorque_nm();
      const int term = index / 2;
      return index == Curve::complianceIndex(term) ? 1e-4 / curve.kneeTorque_nm(term)
                                                   : 0.01 * curve.kneeTorque_nm(term);
    };
    f.sign_constrained = curveSizes;
    // The sizes, then each knee's torque once its compliance is not zero.
    f.free_parameters = [](const Mechanism& m) {
      std::vector<int> free = curveSizes(m);
      const Curve curve = view<mechanism::TorsionCurve>(m);
      for (int term = 1; term <= m.order; ++term) {
        if (curve.extraCompliance_rad_per_nm(term) != 0.0) free.push_back(Curve::kneeIndex(term));
      }
      return free;
    };
    f.is_shape = [](int index) {
      return index > Curve::kSmoothingTorque && index == Curve::kneeIndex(index / 2);
    };
    return f;
  }();
  return fit;
}

namespace {

/// The joint's torque–deflection beyond its linear compliance, drawn over the torques the rows
/// span: the curve a gear catalogue gives, less its linear part.
void torqueDeflectionSignature(const SignatureContext& c, size_t index,
                               std::vector<EffectSignature>& signatures) {
  const Mechanism& m = c.model.mechanisms[index];
  EffectSignature s =
      linkAngleSignature(c, m, m.joint, c.without(index), SignatureVariable::kJointTorque, m.joint,
                         jointTorques(c.with, nullptr, m.joint));
  if (s.x.empty()) return;
  curveSampled(s, [&](double tau) { return torqueDeflection(m, tau); });
  signatures.push_back(std::move(s));
}

}  // namespace

const KindSignature& backlashSignature() {
  static const KindSignature signature{MechanismKind::kBacklash, torqueDeflectionSignature};
  return signature;
}

const KindSignature& nonlinearStiffnessSignature() {
  static const KindSignature signature{MechanismKind::kNonlinearStiffness,
                                       torqueDeflectionSignature};
  return signature;
}

const KindSignature& torsionCurveSignature() {
  static const KindSignature signature{MechanismKind::kTorsionCurve, torqueDeflectionSignature};
  return signature;
}

}  // namespace stepcal::trainer::diagnosis
