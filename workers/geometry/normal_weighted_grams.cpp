#include "geometry/normal_weighted_grams.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>

namespace mm {

using SpMat = Eigen::SparseMatrix<double>;

// The six share their pattern, so each pair of a row's entries is found once and weighted six
// times, instead of six sparse products finding it six times.
std::array<SpMat, 6> normal_weighted_grams(const SpMat& rows, const SpMat& Rt, const Points& normals) {
  const Eigen::Index n = rows.cols();
  const Eigen::Index m = rows.rows();
  if (Rt.rows() != n || Rt.cols() != m || normals.rows() != m || normals.cols() != 3)
    throw std::invalid_argument("normal_weighted_grams: sizes differ");
  Eigen::MatrixXd w(6, m);
  for (Eigen::Index i = 0; i < m; ++i)
    for (int a = 0, p = 0; a < 3; ++a)
      for (int b = a; b < 3; ++b) w(p++, i) = normals(i, a) * normals(i, b);
  std::vector<int> outer(static_cast<std::size_t>(n) + 1, 0), inner;
  std::array<std::vector<double>, 6> values;
  std::vector<int> slot(static_cast<std::size_t>(n), -1), touched;
  std::vector<std::array<double, 6>> acc;
  std::vector<int> order;
  for (Eigen::Index j = 0; j < n; ++j) {
    touched.clear();
    acc.clear();
    for (SpMat::InnerIterator e(rows, j); e; ++e) {
      const Eigen::Index i = e.row();
      const double* wi = &w(0, i);
      for (SpMat::InnerIterator f(Rt, i); f; ++f) {
        const int k = static_cast<int>(f.row());
        int& s = slot[static_cast<std::size_t>(k)];
        if (s < 0) {
          s = static_cast<int>(touched.size());
          touched.push_back(k);
          acc.push_back({0, 0, 0, 0, 0, 0});
        }
        const double v = f.value() * e.value();
        std::array<double, 6>& x = acc[static_cast<std::size_t>(s)];
        for (int p = 0; p < 6; ++p) x[static_cast<std::size_t>(p)] += v * wi[p];
      }
    }
    order.resize(touched.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      return touched[static_cast<std::size_t>(a)] < touched[static_cast<std::size_t>(b)];
    });
    for (int s : order) {
      const int k = touched[static_cast<std::size_t>(s)];
      inner.push_back(k);
      for (int p = 0; p < 6; ++p) values[static_cast<std::size_t>(p)].push_back(acc[static_cast<std::size_t>(s)][static_cast<std::size_t>(p)]);
      slot[static_cast<std::size_t>(k)] = -1;
    }
    outer[static_cast<std::size_t>(j) + 1] = static_cast<int>(inner.size());
  }
  std::array<SpMat, 6> out;
  const auto nnz = static_cast<Eigen::Index>(inner.size());
  for (int p = 0; p < 6; ++p)
    out[static_cast<std::size_t>(p)] =
        Eigen::Map<const SpMat>(n, n, nnz, outer.data(), inner.data(), values[static_cast<std::size_t>(p)].data());
  return out;
}


}  // namespace mm
