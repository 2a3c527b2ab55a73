// The surface evidence (watermark/surface_evidence.h) forms its normal equations through the
// control points; here it is held to the ridge regression written out over the samples.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <random>

#include "meshio/normalize.h"
#include "spectral/synthetic_meshes.h"
#include "watermark/surface_evidence.h"

namespace mm {
namespace {

TEST(SurfaceEvidence, EqualsTheRidgeRegressionOverTheSamples) {
  Mesh control = test::quad_torus(12, 8, 5);
  apply(unit_box_normalization(control.points), control.points);
  const SpectralBasis basis = compute_basis(control);
  const int n = basis.num_vertices();
  const EmbedParams params{Method::Multiplicative, 0.01, 0.05};
  const int bits = 8;

  // Samples: each a barycentric mix of three control points, a random unit normal, an offset.
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> vertex(0, n - 1);
  std::uniform_real_distribution<double> unit(0.05, 1.0);
  std::normal_distribution<double> gauss(0, 1);
  const int m = 900;
  std::vector<Eigen::Triplet<double>> t;
  Points normals(m, 3);
  Eigen::VectorXd offsets(m);
  Eigen::MatrixXd nuisance(m, 2);
  for (int i = 0; i < m; ++i) {
    const double w[3] = {unit(rng), unit(rng), unit(rng)};
    for (double wi : w) t.emplace_back(i, vertex(rng), wi / (w[0] + w[1] + w[2]));
    normals.row(i) = Eigen::RowVector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    offsets[i] = 1e-3 * gauss(rng);
    nuisance.row(i) << normals(i, 0), normals(i, 1) * normals(i, 2);
  }
  Eigen::SparseMatrix<double> rows(m, n);
  rows.setFromTriplets(t.begin(), t.end());
  const CoefficientEvidence ev = surface_evidence(basis, control.points, rows, normals, offsets, nuisance, bits, params);

  // The regression written out: A's columns, projected off [1, nuisance], ridge the residual
  // variance, refitted three times.
  const int len = usable_coefficients(basis) / bits * bits;
  const int fitted = std::min(len, kSurfaceEvidenceCoefficients);
  const int K = (fitted + 2) / 3;
  const Points cs = to_spectral(basis, control.points);
  const Eigen::MatrixXd W = basis_columns(basis, basis.num_components, K);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, 3 * K);
  for (int j = 0; j < fitted; ++j) {
    const int k = j / 3, a = j % 3;
    const double g = coefficient_move(params, cs(basis.num_components + k, a)).size;
    A.col(a * K + k) = normals.col(a).cwiseProduct(rows * W.col(k)) * g;
  }
  Eigen::MatrixXd Z(m, 3);
  Z << Eigen::VectorXd::Ones(m), nuisance;
  const Eigen::MatrixXd P = Eigen::MatrixXd::Identity(m, m) - Z * (Z.transpose() * Z).ldlt().solve(Z.transpose());
  const Eigen::MatrixXd Ap = P * A;
  const Eigen::VectorXd d = P * offsets;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(3 * K);
  double variance = d.squaredNorm() / m;
  for (int fit = 0; fit < 3; ++fit) {
    Eigen::MatrixXd M = Ap.transpose() * Ap;
    M.diagonal().array() += variance;
    x = M.ldlt().solve(Ap.transpose() * d);
    variance = (d - Ap * x).squaredNorm() / m;
  }
  ASSERT_EQ(static_cast<int>(ev.u.size()), len);
  double scale = 0;
  for (int j = 0; j < fitted; ++j) scale = std::max(scale, std::abs(x[(j % 3) * K + j / 3]));
  ASSERT_GT(scale, 0);
  for (int j = 0; j < fitted; ++j) {
    const double direction = coefficient_move(params, cs(basis.num_components + j / 3, j % 3)).direction;
    EXPECT_NEAR(ev.u[static_cast<std::size_t>(j)], x[(j % 3) * K + j / 3] * direction, 1e-8 * scale) << j;
  }
  for (int j = fitted; j < len; ++j) EXPECT_EQ(ev.u[static_cast<std::size_t>(j)], 0.0);
}

}  // namespace
}  // namespace mm
