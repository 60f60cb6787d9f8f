// Gram matrices of a design matrix made chunk by chunk of fit rows, never whole, so that a fit
// over many rows holds its parameters' Gram, not a row per equation (internal to
// stepcal::trainer).
#pragma once

#include <algorithm>
#include <vector>

#include <Eigen/Core>

#include "fit_rows.hpp"
#include "parallel.hpp"

namespace stepcal::trainer::diagnosis {

/// Fit rows per chunk: a chunk of A is its equations (≤ 6 per row) × the columns.
inline constexpr size_t kGramChunkRows = 512;
/// The chunks are summed in this many contiguous slices, each in order, then the slices in order:
/// the sums do not depend on the number of threads.
inline constexpr size_t kGramSlices = 4;

/// Runs body(begin, end) over every chunk of fit rows [begin, end), in kGramSlices slices on the
/// machine's cores; body(slice, begin, end) writes only its slice's result.
template <typename Body>
void forEachChunk(const FitRows& fit, const Body& body) {
  const size_t rows = fit.rows.size();
  const size_t per_slice = (rows + kGramSlices - 1) / kGramSlices;
  parallelFor(kGramSlices, [&](size_t slice) {
    const size_t first = std::min(rows, slice * per_slice);
    const size_t last = std::min(rows, first + per_slice);
    for (size_t begin = first; begin < last; begin += kGramChunkRows) {
      body(slice, begin, std::min(last, begin + kGramChunkRows));
    }
  });
}

/// AᵀA (width × width) and Aᵀr of the matrix whose rows for fit rows [begin, end) make(begin, end)
/// returns (their equations × width), r on every fit equation.
struct ChunkedGram {
  Eigen::MatrixXd H;
  Eigen::VectorXd rhs;
};
template <typename Make>
ChunkedGram chunkedGram(const FitRows& fit, Eigen::Index width, const Eigen::VectorXd& r,
                        const Make& make) {
  std::vector<Eigen::MatrixXd> H(kGramSlices, Eigen::MatrixXd::Zero(width, width));
  std::vector<Eigen::VectorXd> rhs(kGramSlices, Eigen::VectorXd::Zero(width));
  forEachChunk(fit, [&](size_t slice, size_t begin, size_t end) {
    const Eigen::MatrixXd A = make(begin, end);
    const Eigen::Index e = equationOf(fit, begin), count = equationOf(fit, end) - e;
    H[slice].selfadjointView<Eigen::Lower>().rankUpdate(A.transpose());
    rhs[slice].noalias() += A.transpose() * r.segment(e, count);
  });
  ChunkedGram out{Eigen::MatrixXd::Zero(width, width), Eigen::VectorXd::Zero(width)};
  for (size_t s = 0; s < kGramSlices; ++s) {
    out.H += H[s];
    out.rhs += rhs[s];
  }
  out.H.triangularView<Eigen::StrictlyUpper>() = out.H.transpose();
  return out;
}

/// |r − A x|² over every fit equation, A made as for chunkedGram.
template <typename Make>
double chunkedSse(const FitRows& fit, const Eigen::VectorXd& r, const Eigen::VectorXd& x,
                  const Make& make) {
  std::vector<double> sse(kGramSlices, 0.0);
  forEachChunk(fit, [&](size_t slice, size_t begin, size_t end) {
    const Eigen::Index e = equationOf(fit, begin), count = equationOf(fit, end) - e;
    sse[slice] += (r.segment(e, count) - make(begin, end) * x).squaredNorm();
  });
  double total = 0.0;
  for (double s : sse) total += s;
  return total;
}

}  // namespace stepcal::trainer::diagnosis
