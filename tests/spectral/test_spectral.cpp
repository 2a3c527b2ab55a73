#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "common/shared_meshes.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "spectral/spectral_basis.h"
#include "spectral/synthetic_meshes.h"

namespace mm {
namespace {

// max |K W - W diag(lambda)| / max |K|
double eigen_residual(const Mesh& mesh, const SpectralBasis& b) {
  const Eigen::MatrixXd K = kirchhoff_matrix(mesh);
  const Eigen::MatrixXd R = K * b.W - b.W * b.eigenvalues.asDiagonal();
  return R.cwiseAbs().maxCoeff() / K.cwiseAbs().maxCoeff();
}

double orthonormality_error(const SpectralBasis& b) {
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(b.W.cols(), b.W.cols());
  return (b.W.transpose() * b.W - I).cwiseAbs().maxCoeff();
}

double reconstruction_error(const SpectralBasis& b, const Points& x) {
  return (from_spectral(b, to_spectral(b, x)) - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
}

void expect_sound_basis(const Mesh& mesh, const SpectralBasis& b) {
  ASSERT_EQ(b.W.rows(), mesh.num_vertices());
  ASSERT_EQ(b.W.cols(), mesh.num_vertices());
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
  // Component order by lowest vertex: torus (30 vertices), grid (20), the lone point.
  const int sizes[3] = {30, 20, 1};
  int start = 0;
  for (int c = 0; c < 3; ++c) {
    for (int v = 0; v < m.num_vertices(); ++v) {
      const bool inside = v >= start && v < start + sizes[c];
      EXPECT_EQ(b.W(v, c), inside ? 1.0 / std::sqrt(double(sizes[c])) : 0.0);
    }
    start += sizes[c];
  }
}

TEST(SpectralBasis, SignConventionLargestEntryPositive) {
  const SpectralBasis b = compute_basis(test::quad_torus(9, 7));
  for (int j = b.num_components; j < b.W.cols(); ++j) {
    const double largest = b.W.col(j).cwiseAbs().maxCoeff();
    for (int i = 0; i < b.W.rows(); ++i)
      if (std::abs(b.W(i, j)) >= largest * (1 - 1e-9)) {
        EXPECT_GT(b.W(i, j), 0.0) << "column " << j;
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
  ASSERT_EQ(c.W.rows(), b.W.rows());
  EXPECT_EQ(std::memcmp(c.W.data(), b.W.data(), sizeof(double) * b.W.size()), 0);
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
