// The Kirchhoff (combinatorial Laplacian) basis of a mesh's connectivity, paper eqs. (1)-(5).
#pragma once
#include <Eigen/Core>

#include "meshio/mesh.h"

namespace mm {

struct SpectralBasis {
  Eigen::VectorXd eigenvalues;  // ascending
  Eigen::MatrixXd W;            // columns are the eigenvectors, in eigenvalue order
};

// K = D - A (eq. 1, 2) from the mesh's edges.
Eigen::MatrixXd kirchhoff_matrix(const Mesh& mesh);

// Deterministic: same connectivity -> same basis bit for bit on the same build (sign convention
// fixed). Repeated eigenvalues make individual vectors arbitrary, so persist the basis used at
// embedding (see serialize) rather than recomputing it at extraction.
SpectralBasis compute_basis(const Mesh& mesh);

// Spectral coordinates (eq. 4) and back (eq. 5); points are n x 3.
Points to_spectral(const SpectralBasis& basis, const Points& points);
Points from_spectral(const SpectralBasis& basis, const Points& coefficients);

}  // namespace mm
