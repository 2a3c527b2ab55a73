#include "watermark/surface_evidence.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mm {
namespace {

constexpr double kRidgeFactor = 10;  // ridge = this x the residual variance (unit prior on beta)
constexpr int kRefits = 3;

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
  const Eigen::MatrixXd P = rows * basis_columns(basis, basis.num_components, K);  // m x K

  // A: m x 3K, column a K + k the normal offsets coefficient (k, axis a) makes at unit gain,
  // projected off the nuisance. The normal equations A^T A are formed once (by row blocks, so A
  // is never held whole: A^T A = sum of the blocks' products, less the projection's C^T C with
  // C = Q^T A) and solved directly for each refit's ridge.
  const Eigen::Index cols = 3 * static_cast<Eigen::Index>(K);
  auto block_of = [&](Eigen::Index begin, Eigen::Index count) {
    Eigen::MatrixXd B(count, cols);
    for (int a = 0; a < 3; ++a)
      B.middleCols(a * K, K) = (P.middleRows(begin, count).array().colwise() *
                                normals.col(a).segment(begin, count).array()).matrix() *
                               G.col(a).asDiagonal();
    return B;
  };
  constexpr Eigen::Index kBlock = 1024;
  Eigen::VectorXd d = offsets;
  project(d);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(cols, cols), C = Eigen::MatrixXd::Zero(Q.cols(), cols);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(cols);
  for (Eigen::Index b = 0; b < m; b += kBlock) {
    const Eigen::Index count = std::min(kBlock, m - b);
    const Eigen::MatrixXd B = block_of(b, count);
    H.selfadjointView<Eigen::Lower>().rankUpdate(B.transpose());
    C.noalias() += Q.middleRows(b, count).transpose() * B;
    rhs.noalias() += B.transpose() * d.segment(b, count);
  }
  H.selfadjointView<Eigen::Lower>().rankUpdate(C.transpose(), -1);
  // A x, projected: the offsets the gains x explain.
  auto explained = [&](const Eigen::VectorXd& x) {
    Eigen::VectorXd y(m);
    for (Eigen::Index b = 0; b < m; b += kBlock) {
      const Eigen::Index count = std::min(kBlock, m - b);
      y.segment(b, count).noalias() = block_of(b, count) * x;
    }
    project(y);
    return y;
  };

  Eigen::VectorXd x = Eigen::VectorXd::Zero(cols);
  double variance = d.squaredNorm() / static_cast<double>(m);
  for (int fit = 0; fit < kRefits && variance > 0; ++fit) {
    Eigen::MatrixXd M = H;
    M.diagonal().array() += kRidgeFactor * variance;
    x = M.selfadjointView<Eigen::Lower>().llt().solve(rhs);
    variance = (d - explained(x)).squaredNorm() / static_cast<double>(m);
  }
  Eigen::MatrixXd X(K, 3);
  for (int a = 0; a < 3; ++a) X.col(a) = x.segment(a * K, K);
  for (int j = 0; j < fitted; ++j)
    ev.u[static_cast<std::size_t>(j)] = X(j / 3, j % 3) * dir(j / 3, j % 3);
  return ev;
}

}  // namespace mm
