#include "watermark/surface_evidence.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mm {
namespace {

constexpr double kRidgeFactor = 10;  // ridge = this x the residual variance (unit prior on beta)
constexpr int kRefits = 3;
constexpr int kMaxIterations = 300;  // conjugate gradient, per fit
// Relative residual of the normal equations: the statistic moves by under 1 % between 1e-4 and
// 1e-8 on the shared parts, at a third of the iterations.
constexpr double kTolerance = 1e-4;

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
  const Eigen::MatrixXd P = rows * basis.W.middleCols(basis.num_components, K);  // m x K

  // A X: each sample's normal offset from gains X (K x 3), with the nuisance projected out.
  auto apply = [&](const Eigen::MatrixXd& X) -> Eigen::VectorXd {
    const Eigen::MatrixXd moved = P * G.cwiseProduct(X);  // m x 3
    Eigen::VectorXd y = moved.cwiseProduct(normals).rowwise().sum();
    project(y);
    return y;
  };
  // A^T y for a projected y.
  auto adjoint = [&](const Eigen::VectorXd& y) -> Eigen::MatrixXd {
    const Eigen::MatrixXd ny = normals.array().colwise() * y.array();
    return G.cwiseProduct(P.transpose() * ny);
  };
  Eigen::VectorXd d = offsets;
  project(d);
  // Jacobi preconditioner: the diagonal of A^T A, without the projection (close enough).
  Eigen::MatrixXd diag(K, 3);
  for (int a = 0; a < 3; ++a)
    diag.col(a) = (P.array().colwise() * normals.col(a).array()).matrix().colwise().squaredNorm().transpose().cwiseProduct(
        G.col(a).cwiseAbs2());

  const Eigen::MatrixXd rhs = adjoint(d);
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(K, 3);
  double variance = d.squaredNorm() / static_cast<double>(m);
  for (int fit = 0; fit < kRefits && variance > 0; ++fit) {
    const double ridge = kRidgeFactor * variance;
    auto normal_op = [&](const Eigen::MatrixXd& V) -> Eigen::MatrixXd { return adjoint(apply(V)) + ridge * V; };
    const Eigen::MatrixXd precond = (diag.array() + ridge).inverse().matrix();
    // Preconditioned conjugate gradient on (A^T A + ridge I) X = A^T d, from the last fit.
    Eigen::MatrixXd r = rhs - normal_op(X);
    Eigen::MatrixXd z = r.cwiseProduct(precond);
    Eigen::MatrixXd p = z;
    double rz = r.cwiseProduct(z).sum();
    const double stop = kTolerance * kTolerance * rhs.squaredNorm();
    for (int it = 0; it < kMaxIterations && r.squaredNorm() > stop; ++it) {
      const Eigen::MatrixXd q = normal_op(p);
      const double alpha = rz / p.cwiseProduct(q).sum();
      X += alpha * p;
      r -= alpha * q;
      z = r.cwiseProduct(precond);
      const double next = r.cwiseProduct(z).sum();
      p = z + (next / rz) * p;
      rz = next;
    }
    variance = (d - apply(X)).squaredNorm() / static_cast<double>(m);
  }
  for (int j = 0; j < fitted; ++j)
    ev.u[static_cast<std::size_t>(j)] = X(j / 3, j % 3) * dir(j / 3, j % 3);
  return ev;
}

}  // namespace mm
