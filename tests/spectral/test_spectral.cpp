#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "common/shared_meshes.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "spectral/spectral_basis.h"
#include "spectral/synthetic_meshes.h"

namespace mm {
namespace {

// The basis as an n x n matrix, columns in the basis's order.
Eigen::MatrixXd matrix(const SpectralBasis& b) { return basis_columns(b, 0, b.num_vertices()); }

// max |K W - W diag(lambda)| / max |K|
double eigen_residual(const Mesh& mesh, const SpectralBasis& b) {
  const Eigen::MatrixXd K = kirchhoff_matrix(mesh);
  const Eigen::MatrixXd W = matrix(b);
  const Eigen::MatrixXd R = K * W - W * b.eigenvalues.asDiagonal();
  return R.cwiseAbs().maxCoeff() / K.cwiseAbs().maxCoeff();
}

double orthonormality_error(const SpectralBasis& b) {
  const Eigen::MatrixXd W = matrix(b);
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(W.cols(), W.cols());
  return (W.transpose() * W - I).cwiseAbs().maxCoeff();
}

double reconstruction_error(const SpectralBasis& b, const Points& x) {
  return (from_spectral(b, to_spectral(b, x)) - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
}

void expect_sound_basis(const Mesh& mesh, const SpectralBasis& b) {
  ASSERT_EQ(b.num_vertices(), mesh.num_vertices());
  ASSERT_EQ(b.eigenvalues.size(), mesh.num_vertices());
  EXPECT_LT(eigen_residual(mesh, b), 1e-10);
  EXPECT_LT(orthonormality_error(b), 1e-12);
  EXPECT_LT(reconstruction_error(b, mesh.points), 1e-12);
  for (int i = 1; i < b.eigenvalues.size(); ++i) EXPECT_LE(b.eigenvalues[i - 1], b.eigenvalues[i]);
  for (int i = 0; i < b.num_components; ++i) EXPECT_EQ(b.eigenvalues[i], 0.0);
  if (b.num_components < b.eigenvalues.size()) {
    EXPECT_GT(b.eigenvalues[b.num_components], 1e-9);
  }
}

Mesh fandisk() {
  Mesh m = read_mesh(test::shared_mesh("fandisk_quads.off"));
  apply(unit_box_normalization(m.points), m.points);
  return m;
}

TEST(Kirchhoff, CubeIsDegreeMinusAdjacency) {
  const Eigen::MatrixXd K = kirchhoff_matrix(test::cube());
  EXPECT_TRUE(K.isApprox(K.transpose()));
  EXPECT_EQ(K.rowwise().sum().cwiseAbs().maxCoeff(), 0.0);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(K(i, i), 3.0);
  EXPECT_EQ(K(0, 1), -1.0);  // edge
  EXPECT_EQ(K(0, 3), 0.0);   // face diagonal, not an edge
}

TEST(Kirchhoff, RejectsOutOfRangeIndices) {
  Mesh m = test::cube();
  m.faces[2][1] = 8;
  EXPECT_THROW(kirchhoff_matrix(m), InputError);
  m.faces[2][1] = -1;
  EXPECT_THROW(compute_basis(m), InputError);
}

TEST(SpectralBasis, CubeEigenvaluesAreKnown) {
  const SpectralBasis b = compute_basis(test::cube());
  const double expected[8] = {0, 2, 2, 2, 4, 4, 4, 6};
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(b.eigenvalues[i], expected[i], 1e-12);
  expect_sound_basis(test::cube(), b);
}

TEST(SpectralBasis, CycleEigenvaluesAreKnown) {
  const int n = 37;
  const SpectralBasis b = compute_basis(test::polygon(n));
  std::vector<double> expected;
  for (int k = 0; k < n; ++k) expected.push_back(2 - 2 * std::cos(2 * std::acos(-1.0) * k / n));
  std::sort(expected.begin(), expected.end());
  for (int i = 0; i < n; ++i) EXPECT_NEAR(b.eigenvalues[i], expected[i], 1e-12);
  expect_sound_basis(test::polygon(n), b);
}

TEST(SpectralBasis, SyntheticMeshesDecomposeExactly) {
  for (const Mesh& m : {test::quad_torus(12, 9), test::quad_grid(10, 7), test::cube()}) {
    const SpectralBasis b = compute_basis(m);
    EXPECT_EQ(b.num_components, 1);
    expect_sound_basis(m, b);
  }
}

TEST(SpectralBasis, FandiskDecomposesExactly) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = fandisk();
  ASSERT_EQ(m.num_vertices(), 766);
  const SpectralBasis b = compute_basis(m);
  expect_sound_basis(m, b);
  std::cout << "fandisk_quads: components " << b.num_components << ", residual "
            << eigen_residual(m, b) << ", W^T W - I " << orthonormality_error(b)
            << ", reconstruction " << reconstruction_error(b, m.points) << "\n";
}

TEST(SpectralBasis, ComponentsGiveExactIndicatorNullSpace) {
  const Mesh m = test::two_pieces_and_a_point();
  const SpectralBasis b = compute_basis(m);
  ASSERT_EQ(b.num_components, 3);
  expect_sound_basis(m, b);
  const Eigen::MatrixXd W = matrix(b);
  // Component order by lowest vertex: torus (30 vertices), grid (20), the lone point.
  const int sizes[3] = {30, 20, 1};
  int start = 0;
  for (int c = 0; c < 3; ++c) {
    for (int v = 0; v < m.num_vertices(); ++v) {
      const bool inside = v >= start && v < start + sizes[c];
      EXPECT_EQ(W(v, c), inside ? 1.0 / std::sqrt(double(sizes[c])) : 0.0);
    }
    start += sizes[c];
  }
}

TEST(SpectralBasis, SignConventionLargestEntryPositive) {
  const SpectralBasis b = compute_basis(test::quad_torus(9, 7));
  const Eigen::MatrixXd W = matrix(b);
  for (int j = b.num_components; j < W.cols(); ++j) {
    const double largest = W.col(j).cwiseAbs().maxCoeff();
    for (int i = 0; i < W.rows(); ++i)
      if (std::abs(W(i, j)) >= largest * (1 - 1e-9)) {
        EXPECT_GT(W(i, j), 0.0) << "column " << j;
        break;
      }
  }
}

TEST(SpectralBasis, DeterministicBitForBit) {
  const Mesh m = test::quad_torus(15, 11, 7);
  const auto a = serialize_basis(compute_basis(m)), b = serialize_basis(compute_basis(m));
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size()), 0);
  // Geometry does not enter the basis, only connectivity.
  Mesh moved = m;
  moved.points *= 3.0;
  EXPECT_EQ(basis_fingerprint(compute_basis(moved)), basis_fingerprint(compute_basis(m)));
}

TEST(SpectralBasis, FandiskDeterministicBitForBit) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = fandisk();
  EXPECT_EQ(serialize_basis(compute_basis(m)), serialize_basis(compute_basis(m)));
}

TEST(SpectralBasis, SerializationRoundTripsExactly) {
  const SpectralBasis b = compute_basis(test::two_pieces_and_a_point());
  const auto bytes = serialize_basis(b);
  const SpectralBasis c = deserialize_basis(bytes);
  EXPECT_EQ(c.num_components, b.num_components);
  const Eigen::MatrixXd cw = matrix(c), bw = matrix(b);
  ASSERT_EQ(cw.rows(), bw.rows());
  EXPECT_EQ(std::memcmp(cw.data(), bw.data(), sizeof(double) * bw.size()), 0);
  EXPECT_EQ(std::memcmp(c.eigenvalues.data(), b.eigenvalues.data(),
                        sizeof(double) * b.eigenvalues.size()),
            0);
  EXPECT_EQ(serialize_basis(c), bytes);
  EXPECT_EQ(basis_fingerprint(c), basis_fingerprint(b));
  EXPECT_EQ(basis_fingerprint(b).size(), 64u);
  EXPECT_NE(basis_fingerprint(b), basis_fingerprint(compute_basis(test::cube())));
}

TEST(SpectralBasis, DeserializationRejectsDamage) {
  const auto good = serialize_basis(compute_basis(test::cube()));
  auto expect_error = [](const std::vector<std::uint8_t>& bytes, const std::string& what) {
    try {
      deserialize_basis(bytes, "basis.bin");
      ADD_FAILURE() << "accepted: " << what;
    } catch (const InputError& e) {
      EXPECT_EQ(e.source(), "basis.bin");
      EXPECT_NE(e.reason().find(what), std::string::npos) << e.what();
    }
  };
  expect_error({}, "truncated");
  expect_error(std::vector<std::uint8_t>(good.begin(), good.end() - 1), "size");
  auto flipped = good;
  flipped[100] ^= 1;
  expect_error(flipped, "checksum");
  auto magic = good;
  magic[0] = 'X';
  expect_error(magic, "magic");
  auto version = good;
  version[8] = 9;
  expect_error(version, "version");
  // A hostile header claiming 2^32-1 vertices must be refused before any allocation.
  auto huge = good;
  huge[12] = huge[13] = huge[14] = huge[15] = 0xff;
  expect_error(huge, "out of range");
}

TEST(SpectralBasis, EveryTruncationAndByteFlipIsRejected) {
  const auto good = serialize_basis(compute_basis(test::cube()));
  for (std::size_t len = 0; len < good.size(); ++len)
    EXPECT_THROW(deserialize_basis(std::vector<std::uint8_t>(good.begin(), good.begin() + len)),
                 InputError)
        << len;
  for (std::size_t i = 0; i < good.size(); ++i) {
    auto bad = good;
    bad[i] ^= 0x40;
    EXPECT_THROW(deserialize_basis(bad), InputError) << i;
  }
  auto longer = good;
  longer.push_back(0);
  EXPECT_THROW(deserialize_basis(longer), InputError);
}

// Past kDenseBasisVertices the basis is patched: each patch is the dense basis of its own
// Kirchhoff matrix, and together they are an orthonormal basis of every vertex position.
TEST(SpectralBasis, PatchedBasisIsExactPerPatchAndOrthonormalOverall) {
  const Mesh m = test::quad_torus(90, 70, 5);  // 6,300 vertices
  ASSERT_GT(m.num_vertices(), kDenseBasisVertices);
  const SpectralBasis b = compute_basis(m);
  ASSERT_GT(b.patches.size(), 1u);
  EXPECT_EQ(b.num_vertices(), m.num_vertices());
  std::vector<int> seen(m.num_vertices(), 0), patch_of(m.num_vertices()), local(m.num_vertices());
  for (std::size_t p = 0; p < b.patches.size(); ++p) {
    const SpectralPatch& patch = b.patches[p];
    EXPECT_LE(static_cast<int>(patch.vertices.size()), kPatchVertices);
    EXPECT_GE(static_cast<int>(patch.vertices.size()), kPatchVertices / 2);
    EXPECT_TRUE(std::is_sorted(patch.vertices.begin(), patch.vertices.end()));
    for (std::size_t i = 0; i < patch.vertices.size(); ++i) {
      ++seen[patch.vertices[i]];
      patch_of[patch.vertices[i]] = static_cast<int>(p);
      local[patch.vertices[i]] = static_cast<int>(i);
    }
  }
  for (int v = 0; v < m.num_vertices(); ++v) ASSERT_EQ(seen[v], 1) << v;
  // Each patch: K_p W_p = W_p diag(lambda_p), its own edges only.
  std::vector<Eigen::MatrixXd> K(b.patches.size());
  for (std::size_t p = 0; p < b.patches.size(); ++p)
    K[p] = Eigen::MatrixXd::Zero(b.patches[p].vertices.size(), b.patches[p].vertices.size());
  for (auto [x, y] : unique_edges(m))
    if (patch_of[x] == patch_of[y]) {
      Eigen::MatrixXd& k = K[patch_of[x]];
      k(local[x], local[y]) = k(local[y], local[x]) = -1;
      k(local[x], local[x]) += 1;
      k(local[y], local[y]) += 1;
    }
  for (std::size_t p = 0; p < b.patches.size(); ++p) {
    const SpectralPatch& patch = b.patches[p];
    const Eigen::MatrixXd R = K[p] * patch.W - patch.W * patch.eigenvalues.asDiagonal();
    EXPECT_LT(R.cwiseAbs().maxCoeff(), 1e-10) << p;
  }
  // Column order: the patches' zero columns, then ascending eigenvalues.
  int zeros = 0;
  for (const SpectralPatch& patch : b.patches)
    for (Eigen::Index i = 0; i < patch.eigenvalues.size(); ++i) zeros += patch.eigenvalues[i] == 0.0;
  EXPECT_EQ(b.num_components, zeros);
  EXPECT_GE(b.num_components, static_cast<int>(b.patches.size()));
  for (int i = 0; i < b.num_components; ++i) EXPECT_EQ(b.eigenvalues[i], 0.0);
  for (int i = b.num_components + 1; i < b.eigenvalues.size(); ++i) ASSERT_LE(b.eigenvalues[i - 1], b.eigenvalues[i]);
  // Orthonormal overall: the transform keeps norms and inverts exactly.
  EXPECT_LT(reconstruction_error(b, m.points), 1e-11);
  const Points cs = to_spectral(b, m.points);
  EXPECT_NEAR(cs.squaredNorm(), m.points.squaredNorm(), 1e-10 * m.points.squaredNorm());
  const Eigen::MatrixXd low = basis_columns(b, b.num_components, 40);
  EXPECT_LT((low.transpose() * low - Eigen::MatrixXd::Identity(40, 40)).cwiseAbs().maxCoeff(), 1e-12);
  for (int k = 0; k < 40; ++k) {
    Points unit = Points::Zero(m.num_vertices(), 3);
    unit(b.num_components + k, 1) = 1;
    EXPECT_LT((from_spectral(b, unit).col(1) - low.col(k)).cwiseAbs().maxCoeff(), 1e-15) << k;
  }
}

TEST(SpectralBasis, PatchedBasisIsDeterministicAndSerialisesExactly) {
  const Mesh m = test::quad_torus(90, 70, 6);
  const SpectralBasis b = compute_basis(m);
  const auto bytes = serialize_basis(b);
  EXPECT_EQ(serialize_basis(compute_basis(m)), bytes);
  const SpectralBasis c = deserialize_basis(bytes);
  EXPECT_EQ(serialize_basis(c), bytes);
  EXPECT_EQ(c.num_components, b.num_components);
  EXPECT_EQ(c.column_patch, b.column_patch);
  EXPECT_EQ(c.column_local, b.column_local);
  EXPECT_EQ(to_spectral(c, m.points), to_spectral(b, m.points));
  // Damage anywhere is refused: truncation, a flipped byte, a byte too many.
  for (std::size_t len : {std::size_t{0}, std::size_t{20}, bytes.size() / 2, bytes.size() - 1})
    EXPECT_THROW(deserialize_basis(std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + len)), InputError) << len;
  for (std::size_t i : {std::size_t{9}, std::size_t{13}, std::size_t{22}, std::size_t{30}, bytes.size() / 3, bytes.size() - 5}) {
    auto bad = bytes;
    bad[i] ^= 0x40;
    EXPECT_THROW(deserialize_basis(bad), InputError) << i;
  }
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(deserialize_basis(longer), InputError);
}

TEST(SpectralBasis, RefusesEmptyAndOversizedMeshes) {
  EXPECT_THROW(compute_basis(Mesh{}), InputError);
  Mesh big;
  big.points = Points::Zero(kMaxBasisVertices + 1, 3);
  EXPECT_THROW(compute_basis(big), InputError);
}

TEST(SpectralBasis, TransformsRejectWrongSizes) {
  const SpectralBasis b = compute_basis(test::cube());
  EXPECT_THROW(to_spectral(b, Points::Zero(7, 3)), std::invalid_argument);
  EXPECT_THROW(from_spectral(b, Points::Zero(9, 3)), std::invalid_argument);
}

}  // namespace
}  // namespace mm
