#include "stepcal/common/mechanisms/registration_drift.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

std::vector<std::string> names(int, int order) {
  std::vector<std::string> names = {"first_seq", "last_seq"};
  for (int d = 1; d <= order; ++d) {
    for (const char* p : {"vx_m", "vy_m", "vz_m", "wx_rad", "wy_rad", "wz_rad"}) {
      names.push_back("p" + std::to_string(d) + "_" + p);
    }
  }
  return names;
}

std::string problem(const Mechanism& m, int) {
  const RegistrationDrift<const double> d = view<RegistrationDrift>(m);
  if (!(d.lastSeq() > d.firstSeq())) {
    return std::string(toString(m.kind)) + " last_seq = " + std::to_string(d.lastSeq()) +
           " with first_seq = " + std::to_string(d.firstSeq()) + "; expected last_seq > first_seq";
  }
  return {};
}

std::string describeSuffix(const Mechanism& m) {
  static const char* const kDegrees[] = {"", "linear", "quadratic", "cubic"};
  return " (" +
         (m.order < 4 ? std::string(kDegrees[m.order]) : "degree " + std::to_string(m.order)) +
         " in time order)";
}

}  // namespace

const MechanismTraits& registrationDriftTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kRegistrationDrift, "registration_drift"};
    t.measurement_only = true;
    t.order_fits = [](int order) { return order >= 1 && order <= kMaxDriftDegree; };
    t.parameter_names = names;
    t.problem = problem;
    t.describe_suffix = describeSuffix;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism

namespace stepcal {

double legendrePolynomial(int degree, double s) noexcept {
  // (d + 1) P_{d+1} = (2d + 1) s P_d − d P_{d−1}, from P_0 = 1, P_1 = s.
  double previous = 1.0, current = s;
  if (degree == 0) return previous;
  for (int d = 1; d < degree; ++d) {
    const double next = ((2 * d + 1) * s * current - d * previous) / (d + 1);
    previous = current;
    current = next;
  }
  return current;
}

Vec6 registrationDrift(const Mechanism& drift, double seq) noexcept {
  const mechanism::RegistrationDrift<const double> d = view<mechanism::RegistrationDrift>(drift);
  const double first = d.firstSeq(), last = d.lastSeq();
  // Outside the span it was fitted on, the drift holds its value at the nearer end: a
  // polynomial is not extrapolated.
  const double s = std::clamp(2.0 * (seq - first) / (last - first) - 1.0, -1.0, 1.0);
  Vec6 xi = Vec6::Zero();
  for (int degree = 1; degree <= drift.order; ++degree) {
    xi += legendrePolynomial(degree, s) * d.term(degree);
  }
  return xi;
}

}  // namespace stepcal
