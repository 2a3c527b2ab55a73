// Normal equations of point-to-plane least squares through a linear map. A sample i with unit
// normal n_i whose position is row i of R x (R: samples x points, x: points x 3) contributes
// n_i . (R x)_i; the normal equations' 3 x 3 blocks are R^T diag(n_a n_b) R for the pairs of
// normal components (a, b), and forming those directly costs far less than the products of the
// stacked m x 3k system.
#pragma once
#include <Eigen/Sparse>
#include <array>

#include "meshio/mesh.h"

namespace mm {

// R^T diag(n_a n_b) R (n x n) for the six pairs a <= b in the order (0,0) (0,1) (0,2) (1,1)
// (1,2) (2,2); pair (a, b) is at a * (5 - a) / 2 + b. Rt = rows^T. Throws
// std::invalid_argument when the sizes disagree.
std::array<Eigen::SparseMatrix<double>, 6> normal_weighted_grams(const Eigen::SparseMatrix<double>& rows,
                                                                 const Eigen::SparseMatrix<double>& Rt,
                                                                 const Points& normals);

}  // namespace mm
