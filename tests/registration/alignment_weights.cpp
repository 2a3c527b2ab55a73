// Why the similarity is re-estimated on Laplacian coordinates (docs/registration.md): the scale
// error a similarity fit makes on a Method-1-marked, noisy copy of fandisk_quads, for spectral
// weightings K^0 (plain least squares) .. K^3 and relative weights 1/(|C|^2 + tau^2), RMS over
// 20 keys. A program, not a ctest test. Usage: alignment_weights [fandisk_quads.off]
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "watermark/watermark.h"

namespace {

using namespace mm;

// Scale of the best similarity mapping the original's coefficients C0 onto the copy's Cm, with
// per-coefficient weights w (rows below `skip` are the zero-eigenvalue ones: translation).
double fitted_scale(const Points& C0, const Points& Cm, const Eigen::VectorXd& w, int skip) {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double var = 0;
  for (int k = skip; k < C0.rows(); ++k) {
    cov += w[k] * Cm.row(k).transpose() * C0.row(k);
    var += w[k] * C0.row(k).squaredNorm();
  }
  // Sum of singular values = trace norm, via the symmetric square cov^T cov (no JacobiSVD: GCC 12
  // warns falsely about its inline storage).
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov.transpose() * cov);
  return es.eigenvalues().cwiseMax(0.0).cwiseSqrt().sum() / var;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : std::string(MESHMARK_SHARED_MESHES) + "/fandisk_quads.off";
  Mesh control = read_mesh(path);
  apply(unit_box_normalization(control.points), control.points);
  const SpectralBasis basis = compute_basis(control);
  const Points C = to_spectral(basis, control.points);
  const int n = static_cast<int>(C.rows()), z = basis.num_components;
  Eigen::VectorXd rows(n);
  for (int k = 0; k < n; ++k) rows[k] = C.row(k).norm();
  std::vector<double> sorted(rows.data() + z, rows.data() + n);
  std::sort(sorted.begin(), sorted.end());
  const double tau = sorted[sorted.size() / 2];
  std::printf("RMS scale error over 20 keys, M1 a = 0.01, uniform noise A on the control points\n");
  std::printf("%-8s %10s %10s %10s %10s %12s\n", "A", "K^0", "K^1", "K^2", "K^3", "1/(C^2+t^2)");
  for (double noise : {0.0, 0.0005, 0.001, 0.002}) {
    double acc[5] = {0};
    const int trials = 20;
    for (int seed = 1; seed <= trials; ++seed) {
      Key key{};
      Nonce nonce{};
      key[0] = static_cast<std::uint8_t>(seed);
      nonce[0] = 2;
      std::mt19937_64 rng(seed);
      std::vector<bool> msg(64);
      for (int i = 0; i < 64; ++i) msg[i] = (rng() >> 63) != 0;
      Points marked = embed(basis, control.points, msg, key, nonce, {Method::Multiplicative, 0.01, 0.05});
      for (Eigen::Index i = 0; i < marked.size(); ++i)
        marked.data()[i] += noise * (static_cast<double>(rng() >> 11) * 0x1.0p-52 - 1);
      const Points Cm = to_spectral(basis, marked);
      for (int power = 0; power <= 3; ++power) {
        Eigen::VectorXd w(n);
        for (int k = 0; k < n; ++k) w[k] = std::pow(basis.eigenvalues[k], 2 * power);
        const double e = fitted_scale(C, Cm, w, z) - 1;
        acc[power] += e * e / trials;
      }
      Eigen::VectorXd w(n);
      for (int k = 0; k < n; ++k) w[k] = 1 / (rows[k] * rows[k] + tau * tau);
      const double e = fitted_scale(C, Cm, w, z) - 1;
      acc[4] += e * e / trials;
    }
    std::printf("%-8.4f %10.1e %10.1e %10.1e %10.1e %12.1e\n", noise, std::sqrt(acc[0]), std::sqrt(acc[1]),
                std::sqrt(acc[2]), std::sqrt(acc[3]), std::sqrt(acc[4]));
  }
}
