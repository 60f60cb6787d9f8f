#include "stepcal/common/mechanisms/self_weight.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

std::vector<std::string> names(int dof, int) {
  std::vector<std::string> names;
  for (int k = 1; k <= dof; ++k) {
    const std::string link = "link" + std::to_string(k) + "_";
    for (const char* p :
         {"mass_kg", "first_moment_x_kgm", "first_moment_y_kgm", "first_moment_z_kgm"}) {
      names.push_back(link + p);
    }
  }
  return names;
}

}  // namespace

const MechanismTraits& selfWeightTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kSelfWeight, "self_weight"};
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerModel;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = names;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism

namespace stepcal {

void selfWeightTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                       const Vec3& gravity_Root, const std::vector<double>& parameters,
                       JointVector& tau_nm) noexcept {
  const int n = chain.dof();
  const mechanism::SelfWeight<const double> links{parameters.data(), 0};
  tau_nm.setZero(n);
  // Suffix sums: joint j carries the weight of links j … n. W = (f, m about the root origin).
  Vec6 W_distal = Vec6::Zero();
  for (int k = n; k >= 1; --k) {
    const Pose& X = ws.X_RootFrame[static_cast<size_t>(k)];
    const double mass = links.mass_kg(k);
    const Vec3 h(links.firstMoment_kgm(k, 0), links.firstMoment_kgm(k, 1),
                 links.firstMoment_kgm(k, 2));
    const Vec3 first_moment_Root = X.linear() * h + mass * X.translation();
    W_distal.head<3>() += mass * gravity_Root;
    W_distal.tail<3>() += first_moment_Root.cross(gravity_Root);
    tau_nm(k - 1) = jointTwistInRoot(chain, ws, k).dot(W_distal);
  }
}

}  // namespace stepcal
