// The Kirchhoff (combinatorial Laplacian) basis of a mesh's connectivity, paper eqs. (1)-(5).
//
// Conventions (see docs/watermark.md):
// - W's columns are the unit eigenvectors of K in ascending eigenvalue order. The paper's eq. (4)
//   writes Xs = W X with the eigenvectors as W's rows; in code W holds them as columns, so
//   Xs = W^T X and, W being orthonormal, X = W Xs (eq. 5, W^-1 = W^T).
// - The eigenvalue-0 space has one vector per connected component. Its columns come first and are
//   the exact normalised component indicators (component order: by lowest vertex index), so they
//   are canonical even though the eigenvalue is repeated; their coefficients are the components'
//   scaled centroids.
// - Every other column's sign makes its entry of largest magnitude positive; entries within a
//   relative 1e-9 of the largest count as tied and the lowest index wins.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct SpectralBasis {
  Eigen::VectorXd eigenvalues;  // ascending; the first num_components are exactly 0
  Eigen::MatrixXd W;            // n x n, columns are the eigenvectors, in eigenvalue order
  int num_components = 0;       // connected components (isolated vertices count), = zero eigenvalues
  int num_vertices() const { return static_cast<int>(W.rows()); }
};

// A dense full decomposition costs O(n^3) time and 2 n^2 doubles of memory; beyond this many
// vertices compute_basis refuses (InputError) instead of running for minutes.
constexpr int kMaxBasisVertices = 6000;

// K = D - A (eq. 1, 2) from the mesh's unique edges. Throws InputError("mesh", ...) for face
// indices out of range.
Eigen::MatrixXd kirchhoff_matrix(const Mesh& mesh);

// Deterministic: same connectivity -> same basis bit for bit on the same build. Repeated non-zero
// eigenvalues still make individual vectors depend on rounding, so persist the basis used at
// embedding (serialize_basis) rather than recomputing it at extraction. Throws InputError for an
// empty mesh, bad indices or more than kMaxBasisVertices vertices.
SpectralBasis compute_basis(const Mesh& mesh);

// Spectral coordinates (eq. 4) and back (eq. 5); points are n x 3 (one column per X, Y, Z).
Points to_spectral(const SpectralBasis& basis, const Points& points);
Points from_spectral(const SpectralBasis& basis, const Points& coefficients);

// Exact byte form for the store: magic "MMSPECB1", format version, n, num_components, eigenvalues
// and W as little-endian IEEE doubles, then the SHA-256 of everything before it. Deserialisation
// checks all of it and throws InputError(source, reason) on any mismatch, never over-allocating.
std::vector<std::uint8_t> serialize_basis(const SpectralBasis& basis);
SpectralBasis deserialize_basis(const std::vector<std::uint8_t>& bytes,
                                const std::string& source = "spectral basis");

// Hex SHA-256 of serialize_basis(basis): names the exact basis a mark was embedded with.
std::string basis_fingerprint(const SpectralBasis& basis);

}  // namespace mm
