// The physics' bounds on a mechanism's parameters (model.hpp PhysicalBound): what a fit may
// not cross, and what a fit that crosses them stands for instead of the mechanism.
#include <cmath>
#include <cstdio>

#include "families.hpp"

namespace stepcal::trainer::diagnosis {

double PhysicalBound::value(const Mechanism& m) const {
  double v = 0.0;
  for (const auto& [index, coefficient] : terms) v += coefficient * m.parameter(index);
  return v;
}

std::vector<PhysicalBound> physicalBounds(const Mechanism& m, const KinematicChain& chain) {
  std::vector<PhysicalBound> bounds;
  const std::vector<std::string> names =
      mechanismParameterNames(m.kind, chain.dof(), m.order);
  for (int i : signConstrained(m)) {
    PhysicalBound b;
    b.terms = {{i, 1.0}};
    // A millionth of a typical step: what a bounded solve leaves below zero by rounding.
    b.tolerance = 1e-6 * typicalStep(m, i);
    const std::string name = names[static_cast<size_t>(i)];
    b.broken = [i, name](const Mechanism& x) {
      char text[160];
      std::snprintf(text, sizeof text, "%s %.3g", name.c_str(), x.parameter(i));
      return std::string(text);
    };
    bounds.push_back(std::move(b));
  }
  const KindFit* fit = findKindFit(m.kind);
  if (fit != nullptr && fit->bounds != nullptr) {
    std::vector<PhysicalBound> own = fit->bounds(m, chain);
    for (PhysicalBound& b : own) bounds.push_back(std::move(b));
  }
  return bounds;
}

std::string brokenBound(const Mechanism& m, const std::vector<PhysicalBound>& bounds) {
  const PhysicalBound* worst = nullptr;
  double worst_ratio = 1.0;
  for (const PhysicalBound& b : bounds) {
    const double ratio = -b.value(m) / b.tolerance;
    if (ratio > worst_ratio) {
      worst_ratio = ratio;
      worst = &b;
    }
  }
  return worst != nullptr ? worst->broken(m) : std::string();
}

void makeFeasible(Mechanism& m, const KinematicChain& chain) {
  for (int i : signConstrained(m)) m.parameter(i) = std::max(0.0, m.parameter(i));
  const KindFit* fit = findKindFit(m.kind);
  if (fit != nullptr && fit->make_feasible != nullptr) fit->make_feasible(m, chain);
}

}  // namespace stepcal::trainer::diagnosis
