#include "watermark/surface_evidence.h"

#include "geometry/normal_weighted_grams.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace mm {
namespace {

// ridge = this x the residual variance: the posterior mean under a unit prior on each gain and
// white residuals. On a noisy copy it sharpens the test far more than a stiffer ridge (chained
// remesh, noise and simplification: -log10 p 8 -> 20 on fandisk, 7 -> 16 on abc9).
constexpr double kRidgeFactor = 1;
constexpr int kRefits = 3;

using SpMat = Eigen::SparseMatrix<double>;

}  // namespace

CoefficientEvidence surface_evidence(const SpectralBasis& basis, const Points& original,
                                     const Eigen::SparseMatrix<double>& rows, const Points& normals,
                                     const Eigen::VectorXd& offsets, const Eigen::MatrixXd& nuisance,
                                     int message_bits, const EmbedParams& params) {
  const int n = basis.num_vertices();
  const Eigen::Index m = offsets.size();
  if (original.rows() != n || rows.cols() != n || rows.rows() != m || normals.rows() != m ||
      (nuisance.size() > 0 && nuisance.rows() != m))
    throw std::invalid_argument("surface_evidence: sizes differ");
  if (message_bits <= 0) throw std::invalid_argument("surface_evidence: message_bits must be positive");
  const int usable = usable_coefficients(basis);
  CoefficientEvidence ev;
  ev.message_bits = message_bits;
  ev.repeat = usable / message_bits;
  const int len = ev.repeat * message_bits;
  ev.u.assign(static_cast<std::size_t>(std::max(0, len)), 0.0);
  const int fitted = std::min(len, kSurfaceEvidenceCoefficients);
  const int K = (fitted + 2) / 3;
  if (m <= nuisance.cols() + 1 || K == 0) return ev;
  // Orthonormal basis of the nuisance patterns and the constant; residuals are taken orthogonal
  // to it (y - Q Q^T y), which fits them freely.
  Eigen::MatrixXd Z(m, nuisance.cols() + 1);
  Z << Eigen::VectorXd::Ones(m), nuisance;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Z);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(m, Z.cols());
  auto project = [&Q](Eigen::VectorXd& y) { y -= Q * (Q.transpose() * y); };

  // Moves g and directions per (eigenvector, axis), zero past the fitted coefficients.
  const Points cs = to_spectral(basis, original);
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(K, 3), dir = Eigen::MatrixXd::Zero(K, 3);
  for (int j = 0; j < fitted; ++j) {
    const CoefficientMove mv = coefficient_move(params, cs(basis.num_components + j / 3, j % 3));
    G(j / 3, j % 3) = mv.size;
    dir(j / 3, j % 3) = mv.direction;
  }
  const Eigen::MatrixXd Wk = basis_columns(basis, basis.num_components, K);  // n x K

  // A: m x 3K, column a K + k the normal offsets coefficient (k, axis a) makes at unit gain:
  // A_a = diag(n_a) R W_k G_a, projected off the nuisance. Its normal equations are formed through
  // the control points, A_a^T A_b = G_a W_k^T (R^T diag(n_a n_b) R) W_k G_b, so their cost does
  // not grow with the samples (every suspect vertex can be used) and A is never held.
  const Eigen::Index cols = 3 * static_cast<Eigen::Index>(K);
  const SpMat Rt = rows.transpose();
  const std::array<SpMat, 6> grams = normal_weighted_grams(rows, Rt, normals);
  Eigen::VectorXd d = offsets;
  project(d);
  Eigen::MatrixXd H(cols, cols), C(Q.cols(), cols);
  Eigen::VectorXd rhs(cols);
  for (int a = 0; a < 3; ++a) {
    const Eigen::VectorXd na = normals.col(a);
    for (int b = a; b < 3; ++b) {
      const SpMat& M = grams[static_cast<std::size_t>(a * (5 - a) / 2 + b)];  // pair (a, b) in order
      const Eigen::MatrixXd block = G.col(a).asDiagonal() * (Wk.transpose() * (M * Wk)) * G.col(b).asDiagonal();
      H.block(a * K, b * K, K, K) = block;
      H.block(b * K, a * K, K, K) = block.transpose();
    }
    const Eigen::MatrixXd RtQ = Rt * (na.asDiagonal() * Q);  // n x q
    C.middleCols(a * K, K) = (RtQ.transpose() * Wk) * G.col(a).asDiagonal();
    rhs.segment(a * K, K) = G.col(a).asDiagonal() * (Wk.transpose() * (Rt * na.cwiseProduct(d)));
  }
  H.noalias() -= C.transpose() * C;
  // A x, projected: the offsets the gains x explain.
  auto explained = [&](const Eigen::VectorXd& x) {
    Eigen::VectorXd y = Eigen::VectorXd::Zero(m);
    for (int a = 0; a < 3; ++a)
      y += normals.col(a).cwiseProduct(rows * (Wk * G.col(a).cwiseProduct(x.segment(a * K, K))));
    project(y);
    return y;
  };

  Eigen::VectorXd x = Eigen::VectorXd::Zero(cols);
  double variance = d.squaredNorm() / static_cast<double>(m);
  for (int fit = 0; fit < kRefits && variance > 0; ++fit) {
    Eigen::MatrixXd M = H;
    M.diagonal().array() += kRidgeFactor * variance;
    x = M.llt().solve(rhs);
    variance = (d - explained(x)).squaredNorm() / static_cast<double>(m);
  }
  Eigen::MatrixXd X(K, 3);
  for (int a = 0; a < 3; ++a) X.col(a) = x.segment(a * K, K);
  for (int j = 0; j < fitted; ++j)
    ev.u[static_cast<std::size_t>(j)] = X(j / 3, j % 3) * dir(j / 3, j % 3);
  return ev;
}

}  // namespace mm
