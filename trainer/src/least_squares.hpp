// Truncated-SVD least squares shared by the trainer's fits (internal to stepcal::trainer).
#pragma once

#include <Eigen/Core>
#include <Eigen/QR>
#include <Eigen/SVD>

namespace stepcal::trainer {

// Truncated-SVD least squares on column-normalised J (via QR when tall).
struct SvdSolution {
  Eigen::VectorXd x;
  Eigen::VectorXd column_scale;  // x = z / column_scale
  Eigen::VectorXd singular_values;
  Eigen::MatrixXd V;              // right singular vectors in scaled coordinates
  int rank = 0;
};

inline SvdSolution solveTruncated(const Eigen::MatrixXd& J, const Eigen::VectorXd& r, double tol) {
  SvdSolution s;
  const Eigen::Index p = J.cols();
  s.column_scale = J.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!(s.column_scale(c) > 0.0)) s.column_scale(c) = 1.0;
  }
  const Eigen::MatrixXd Js = J * s.column_scale.cwiseInverse().asDiagonal();
  Eigen::MatrixXd R;
  Eigen::VectorXd rhs;
  if (Js.rows() >= p) {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Js);
    R = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
    rhs = (qr.householderQ().adjoint() * r).head(p);
  } else {
    R = Js;
    rhs = r;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(R, Eigen::ComputeThinU | Eigen::ComputeFullV);
  s.singular_values = svd.singularValues();
  s.V = svd.matrixV();
  const double cutoff = tol * s.singular_values(0);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(p);
  for (Eigen::Index i = 0; i < s.singular_values.size(); ++i) {
    if (s.singular_values(i) <= cutoff) break;
    ++s.rank;
    z += s.V.col(i) * (svd.matrixU().col(i).dot(rhs) / s.singular_values(i));
  }
  s.x = z.cwiseQuotient(s.column_scale);
  return s;
}

}  // namespace stepcal::trainer
