#include "profiles.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "chunked_gram.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/mechanisms/transmission_error.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr double kTwoPi = 2.0 * kPi;

double wrap(double angle_rad) {
  const double a = std::fmod(angle_rad, kTwoPi);
  return a < 0.0 ? a + kTwoPi : a;
}

}  // namespace

AngleCoverage coverageOfAngles(std::vector<double> angles_rad, double max_gap_rad,
                               double fade_rad) {
  AngleCoverage coverage;
  coverage.fade_rad = fade_rad;
  if (angles_rad.empty()) return coverage;
  for (double& a : angles_rad) a = wrap(a);
  std::sort(angles_rad.begin(), angles_rad.end());
  // Gaps wider than max_gap_rad, each as the index of the angle after it (cyclically).
  std::vector<size_t> after_gap;
  const size_t m = angles_rad.size();
  for (size_t i = 0; i < m; ++i) {
    const double next = i + 1 < m ? angles_rad[i + 1] : angles_rad[0] + kTwoPi;
    if (next - angles_rad[i] > max_gap_rad) after_gap.push_back((i + 1) % m);
  }
  if (after_gap.empty()) {
    coverage.arcs_rad = {0.0, kTwoPi};
    return coverage;
  }
  // Each run of angles, widened by the fade on both sides: the gate is 1 on every fitted angle
  // and fades out beyond the outermost ones.
  std::vector<std::pair<double, double>> arcs;
  for (size_t g = 0; g < after_gap.size(); ++g) {
    const size_t first = after_gap[g];
    const size_t last = (after_gap[(g + 1) % after_gap.size()] + m - 1) % m;
    double length = angles_rad[last] - angles_rad[first];
    if (length < 0.0) length += kTwoPi;
    arcs.emplace_back(wrap(angles_rad[first] - fade_rad), std::min(kTwoPi, length + 2.0 * fade_rad));
  }
  if (arcs.size() == 1 && arcs[0].second >= kTwoPi) {
    coverage.arcs_rad = {0.0, kTwoPi};
    return coverage;
  }
  std::sort(arcs.begin(), arcs.end());
  if (arcs.size() > static_cast<size_t>(kMaxCoverageArcs)) {
    // Keep the longest; a profile over more scattered angles than that is not one.
    std::sort(arcs.begin(), arcs.end(),
              [](const auto& a, const auto& b) { return a.second > b.second; });
    arcs.resize(static_cast<size_t>(kMaxCoverageArcs));
    std::sort(arcs.begin(), arcs.end());
  }
  for (const auto& [start, length] : arcs) {
    coverage.arcs_rad.push_back(start);
    coverage.arcs_rad.push_back(length);
  }
  return coverage;
}

void profileFeatures(const AngleCoverage& coverage, int order, double q_rad, double* out) {
  const double g = coverageGate(coverage, q_rad);
  const double s1 = std::sin(q_rad), c1 = std::cos(q_rad);
  double s = s1, c = c1;
  for (int k = 0; k < order; ++k) {
    out[2 * k] = g * s;
    out[2 * k + 1] = g * c;
    const double s_next = s * c1 + c * s1;
    c = c * c1 - s * s1;
    s = s_next;
  }
}

Eigen::MatrixXd profileColumns(const Eigen::MatrixXd& link_angle, const FitRows& fit, int joint,
                               const AngleCoverage& coverage, int order, size_t begin,
                               size_t end) {
  const Eigen::Index first = equationOf(fit, begin);
  Eigen::MatrixXd B(equationOf(fit, end) - first, 2 * order);
  Eigen::VectorXd f(2 * order);
  for (size_t i = begin; i < end; ++i) {
    profileFeatures(coverage, order, fit.rows[i]->q_rad(joint), f.data());
    const Eigen::Index e = fit.start[i] - first, k = fit.equations(i);
    B.middleRows(e, k) = link_angle.block(e, joint, k, 1) * f.transpose();
  }
  return B;
}

Eigen::MatrixXd profilesColumns(const std::vector<Profile>& profiles,
                                const Eigen::MatrixXd& link_angle, const FitRows& fit,
                                size_t begin, size_t end) {
  Eigen::Index width = 0;
  for (const Profile& p : profiles) width += 2 * p.mechanism.order;
  Eigen::MatrixXd B(equationOf(fit, end) - equationOf(fit, begin), width);
  Eigen::Index c = 0;
  for (const Profile& p : profiles) {
    const Mechanism& m = p.mechanism;
    B.middleCols(c, 2 * m.order) = profileColumns(link_angle, fit, m.joint, m.coverage, m.order, begin, end);
    c += 2 * m.order;
  }
  return B;
}

void storeStage2(DiagnosisModel& model, const Eigen::MatrixXd& H, const Eigen::VectorXd& x,
                 double variance) {
  const Eigen::Index geometry = 6 * (model.global.chain_Tracker.dof() + 1);
  const Eigen::Index width = H.rows();
  const Eigen::MatrixXd covariance =
      variance * Eigen::LLT<Eigen::MatrixXd>(H).solve(Eigen::MatrixXd::Identity(width, width));
  const Eigen::LLT<Eigen::MatrixXd> geometry_gram(H.topLeftCorner(geometry, geometry));
  Eigen::Index at = geometry;
  for (Profile& p : model.profiles) {
    const Eigen::Index w = 2 * p.mechanism.order;
    for (Eigen::Index i = 0; i < w; ++i) {
      p.mechanism.parameter(static_cast<int>(i)) = x(at + i);
      p.mechanism.sigma[static_cast<size_t>(i)] = std::sqrt(std::max(0.0, covariance(at + i, at + i)));
    }
    const Eigen::VectorXd c = x.segment(at, w);
    p.coefficient_covariance = covariance.block(at, at, w, w);
    p.size_chi2 = c.dot(p.coefficient_covariance.ldlt().solve(c));
    // The geometry's least-squares answer to this profile's effect, with the opposite sign.
    const Eigen::MatrixXd response = geometry_gram.solve(H.block(0, at, geometry, w));
    p.geometry = -response * x.segment(at, w);
    p.geometry_sigma = (response * covariance.block(at, at, w, w) * response.transpose())
                           .diagonal()
                           .cwiseMax(0.0)
                           .cwiseSqrt();
    at += w;
  }
  STEPCAL_INVARIANT(at == width, "stage 2 holds the geometry and every profile");
}

void fitProfiles(DiagnosisModel& model, const FitRows& fit) {
  if (model.profiles.empty()) return;
  const Eigen::Index geometry = 6 * (model.global.chain_Tracker.dof() + 1);
  Eigen::Index width = geometry;
  for (const Profile& p : model.profiles) width += 2 * p.mechanism.order;
  // Linear at the global model (profiles off): a profile moves the link angles by ~1e-3 rad, so
  // the Jacobian's change it causes moves the tip by ~1 µm at most.
  const Eigen::VectorXd r_global = residuals(model.global, fit);
  // The geometry and every profile's columns, chunk by chunk of rows.
  const auto rowsOfA = [&](size_t begin, size_t end) {
    const Linearisation lin =
        linearise(model.global, fit, begin, end, equationsOf(r_global, fit, begin, end));
    Eigen::MatrixXd A(lin.geometry.rows(), width);
    A << lin.geometry, profilesColumns(model.profiles, lin.link_angle, fit, begin, end);
    return A;
  };
  ChunkedGram gram = chunkedGram(fit, width, r_global, rowsOfA);
  Eigen::VectorXd ridge(width);
  ridge.head(geometry) =
      kProfileGeometryRidge * gram.H.diagonal().head(geometry).cwiseMax(1e-300);
  Eigen::Index c = geometry;
  for (const Profile& p : model.profiles) {
    ridge.segment(c, 2 * p.mechanism.order).setConstant(p.ridge);
    c += 2 * p.mechanism.order;
  }
  gram.H.diagonal() += ridge;
  const Eigen::VectorXd x = gram.H.llt().solve(gram.rhs);
  const double sse = chunkedSse(fit, r_global, x, rowsOfA);
  storeStage2(model, gram.H, x, sse / std::max<double>(1.0, double(fit.count - width)));
}

double profileRms(const Mechanism& profile, const FitRows& fit) {
  double sum = 0.0;
  for (const Measurement* row : fit.rows) {
    const double v = transmissionOffset(profile, row->q_rad(profile.joint));
    sum += v * v;
  }
  return fit.rows.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(fit.rows.size()));
}

double largestAmplitude(const Mechanism& profile) {
  double largest = 0.0;
  const mechanism::TransmissionError<const double> harmonics =
      view<mechanism::TransmissionError>(profile);
  for (int k = 1; k <= profile.order; ++k) {
    largest = std::max(largest, std::hypot(harmonics.sin_rad(k), harmonics.cos_rad(k)));
  }
  return largest;
}

bool harmonicsSeparable(const Mechanism& profile, double rms_rad) {
  return largestAmplitude(profile) <= 3.0 * rms_rad;
}

std::vector<double> geometryShare(const PhysicalModel& model, const Eigen::VectorXd& r,
                                  const Mechanism& profile, const FitRows& fit) {
  // GᵀG, GᵀB and B's columns' squared norms, chunk by chunk of rows (G and B are never whole).
  const Eigen::Index g = 6 * (model.chain_Tracker.dof() + 1), w = 2 * profile.order;
  const ChunkedGram gram =
      chunkedGram(fit, g + w, Eigen::VectorXd::Zero(fit.count), [&](size_t begin, size_t end) {
        const Linearisation lin = linearise(model, fit, begin, end, equationsOf(r, fit, begin, end));
        Eigen::MatrixXd A(lin.geometry.rows(), g + w);
        A << lin.geometry, profileColumns(lin.link_angle, fit, profile.joint, profile.coverage,
                                          profile.order, begin, end);
        return A;
      });
  // P_G B = G (GᵀG)⁺ GᵀB, the pseudo-inverse truncated as step 1 truncates the geometry, on the
  // geometry's columns scaled to unit norm.
  const Eigen::VectorXd scale = gram.H.diagonal().head(g).cwiseSqrt().cwiseMax(1e-300);
  const Eigen::MatrixXd GsTGs =
      scale.cwiseInverse().asDiagonal() * gram.H.topLeftCorner(g, g) * scale.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(GsTGs);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double cutoff = 1e-15 * lambda.maxCoeff();
  const Eigen::MatrixXd GtB = scale.cwiseInverse().asDiagonal() * gram.H.topRightCorner(g, w);
  std::vector<double> share;
  for (Eigen::Index k = 0; k + 1 < w; k += 2) {
    double reached = 0.0;
    for (Eigen::Index i = 0; i < lambda.size(); ++i) {
      if (lambda(i) <= cutoff) continue;
      const Eigen::RowVector2d proj = eig.eigenvectors().col(i).transpose() * GtB.middleCols(k, 2);
      reached += proj.squaredNorm() / lambda(i);
    }
    const double total = gram.H(g + k, g + k) + gram.H(g + k + 1, g + k + 1);
    share.push_back(total > 0.0 ? std::min(1.0, reached / total) : 0.0);
  }
  return share;
}

double profileRidgeScale(const PhysicalModel& model, const Eigen::VectorXd& r,
                         const Mechanism& profile, const FitRows& fit) {
  std::vector<double> sum(kGramSlices, 0.0);
  forEachChunk(fit, [&](size_t slice, size_t begin, size_t end) {
    const Linearisation lin = linearise(model, fit, begin, end, equationsOf(r, fit, begin, end));
    sum[slice] += profileColumns(lin.link_angle, fit, profile.joint, profile.coverage,
                                 profile.order, begin, end)
                      .squaredNorm();
  });
  double total = 0.0;
  for (double s : sum) total += s;
  return total / static_cast<double>(2 * profile.order);
}

}  // namespace stepcal::trainer::diagnosis
