// The Kirchhoff (combinatorial Laplacian) basis of a mesh's connectivity, paper eqs. (1)-(5).
//
// Conventions (see docs/watermark.md):
// - The basis is orthonormal and its columns are in a canonical order: column j has eigenvalue
//   eigenvalues[j], ascending, the zero-eigenvalue columns first. The paper's eq. (4) writes
//   Xs = W X with the eigenvectors as W's rows; here Xs = W^T X and, W being orthonormal,
//   X = W Xs (eq. 5, W^-1 = W^T).
// - The eigenvalue-0 space has one vector per connected component. Its columns are the exact
//   normalised component indicators (component order: by lowest vertex index), so they are
//   canonical even though the eigenvalue is repeated; their coefficients are the components'
//   scaled centroids.
// - Every other column's sign makes its entry of largest magnitude positive; entries within a
//   relative 1e-9 of the largest count as tied and the lowest index wins.
//
// Up to kDenseBasisVertices vertices the basis is the exact dense decomposition of the whole
// Kirchhoff matrix (one patch). Larger meshes are split into patches of at most kPatchVertices
// vertices by recursive bisection of the connectivity graph, and each patch gets the dense basis
// of its own Kirchhoff matrix (edges between patches dropped), as Ohbuchi, Mukaiyama and
// Takahashi do for large meshes ("A frequency-domain approach to watermarking 3D shapes",
// Eurographics 2002). The patches' bases together are still an orthonormal basis of all vertex
// positions, so marking and extraction work unchanged; the zero-eigenvalue columns are then one
// per connected piece of each patch, and the others are ordered by eigenvalue across patches.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct SpectralPatch {
  std::vector<int> vertices;    // ascending mesh vertex indices
  Eigen::VectorXd eigenvalues;  // ascending, the patch's components first (exactly 0)
  Eigen::MatrixXd W;            // p x p, columns are the patch's eigenvectors
};

struct SpectralBasis {
  Eigen::VectorXd eigenvalues;  // per column, ascending; the first num_components are exactly 0
  int num_components = 0;       // zero-eigenvalue columns (connected pieces, of each patch)
  std::vector<SpectralPatch> patches;
  std::vector<int> column_patch, column_local;  // column j = patches[column_patch[j]].W.col(column_local[j])
  int vertices = 0;
  int num_vertices() const { return vertices; }
};

// A dense decomposition of n vertices costs O(n^3) time and n^2 doubles. Up to this many vertices
// the whole mesh is still one patch, so that every basis the dense-only versions could compute
// is computed again bit for bit (copy records name bases by fingerprint).
constexpr int kDenseBasisVertices = 6000;
// Patch size above kDenseBasisVertices: a basis costs about n x kPatchVertices doubles.
constexpr int kPatchVertices = 500;
// Beyond this many vertices compute_basis refuses (InputError).
constexpr int kMaxBasisVertices = 100000;

// K = D - A (eq. 1, 2) from the mesh's unique edges. Throws InputError("mesh", ...) for face
// indices out of range.
Eigen::MatrixXd kirchhoff_matrix(const Mesh& mesh);

// Deterministic: same connectivity -> same basis bit for bit on the same build. Repeated non-zero
// eigenvalues still make individual vectors depend on rounding, so persist the basis used at
// embedding (serialize_basis) rather than recomputing it at extraction. Throws InputError for an
// empty mesh, bad indices or more than kMaxBasisVertices vertices.
SpectralBasis compute_basis(const Mesh& mesh);

// Spectral coordinates (eq. 4) and back (eq. 5); points are n x 3 (one column per X, Y, Z),
// coefficients n x 3 in column order.
Points to_spectral(const SpectralBasis& basis, const Points& points);
Points from_spectral(const SpectralBasis& basis, const Points& coefficients);

// Columns first .. first + count - 1 as a dense n x count matrix.
Eigen::MatrixXd basis_columns(const SpectralBasis& basis, int first, int count);

// Exact byte form for the store: magic "MMSPECB1", format version, n, num_components, then for a
// one-patch basis (version 1) its eigenvalues and W, for a patched basis (version 2) the patch
// count and each patch's size, vertices, eigenvalues and W, as little-endian u32 and IEEE
// doubles; then the SHA-256 of everything before it. Deserialisation checks all of it and throws
// InputError(source, reason) on any mismatch, never over-allocating.
std::vector<std::uint8_t> serialize_basis(const SpectralBasis& basis);
SpectralBasis deserialize_basis(const std::vector<std::uint8_t>& bytes,
                                const std::string& source = "spectral basis");

// Hex SHA-256 of serialize_basis(basis): names the exact basis a mark was embedded with.
std::string basis_fingerprint(const SpectralBasis& basis);

}  // namespace mm
