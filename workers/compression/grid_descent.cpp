#include "compression/grid_descent.h"

#include <Eigen/Sparse>

#include "codec/quantize.h"
#include "subdivision/subdivide.h"

namespace mm {

// Enough for every case measured (the sweeps stop after 2-5); a bound on the work regardless.
constexpr int kMaxSweeps = 20;

Mesh descended_on_grid(const Mesh& control, int bits, int levels) {
  const Quantization q = quantization_for(control.points, bits);
  GridPoints grid = quantize(control.points, q);
  RefinedTopology topology;
  // Column access: a move of control value j changes the refined vertices of column j.
  const Eigen::SparseMatrix<double> S = subdivision_operator(control, levels, topology);
  const int n = control.num_vertices();
  Eigen::VectorXd column_norm2(n);
  for (int j = 0; j < n; ++j) column_norm2[j] = S.col(j).squaredNorm();
  // Each axis moves only its own column, so the nearest values' offsets serve every axis.
  const Points rounding = dequantize(grid, q) - control.points;
  for (int a = 0; a < 3 && n > 0; ++a) {
    const std::int32_t lo = grid.col(a).minCoeff(), hi = grid.col(a).maxCoeff();
    // The refined vertices' offsets from the unquantised surface along this axis.
    Eigen::VectorXd r = S * rounding.col(a);
    for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
      bool any = false;
      for (int j = 0; j < n; ++j) {
        if (grid(j, a) == lo || grid(j, a) == hi) continue;
        double g = 0;
        for (Eigen::SparseMatrix<double>::InnerIterator it(S, j); it; ++it) g += it.value() * r[it.row()];
        for (const int s : {-1, 1}) {
          const std::int32_t to = grid(j, a) + s;
          const double delta = s * q.step;
          // The change of ||r||^2 when r moves by delta * S(:, j); strictly down, so sweeps end.
          if (to <= lo || to >= hi || !(2 * delta * g + delta * delta * column_norm2[j] < 0)) continue;
          grid(j, a) = to;
          for (Eigen::SparseMatrix<double>::InnerIterator it(S, j); it; ++it) r[it.row()] += delta * it.value();
          any = true;
          break;
        }
      }
      if (!any) break;
    }
  }
  Mesh out = control;
  out.points = dequantize(grid, q);
  return out;
}

}  // namespace mm
