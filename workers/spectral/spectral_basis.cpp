#include "spectral/spectral_basis.h"

#include <sodium.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>

namespace mm {
namespace {

constexpr char kMagic[8] = {'M', 'M', 'S', 'P', 'E', 'C', 'B', '1'};
constexpr std::uint32_t kFormatVersion = 1;
constexpr size_t kHeaderBytes = sizeof(kMagic) + 3 * sizeof(std::uint32_t);
constexpr size_t kHashBytes = crypto_hash_sha256_BYTES;

void check_indices(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  for (size_t f = 0; f < mesh.faces.size(); ++f)
    for (int v : mesh.faces[f])
      if (v < 0 || v >= n)
        throw InputError("mesh", "face " + std::to_string(f) + " references vertex " +
                                     std::to_string(v) + " but the mesh has " + std::to_string(n) +
                                     " vertices");
}

// Component label per vertex, labels numbered by each component's lowest vertex index.
std::vector<int> component_labels(int n, const std::vector<std::pair<int, int>>& edges,
                                  int& count) {
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (auto [a, b] : edges) {
    int ra = find(a), rb = find(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);  // root = lowest index
  }
  std::vector<int> label(n, -1), root_label(n, -1);
  count = 0;
  for (int v = 0; v < n; ++v) {
    int r = find(v);
    if (root_label[r] < 0) root_label[r] = count++;
    label[v] = root_label[r];
  }
  return label;
}

void fix_sign(Eigen::Ref<Eigen::VectorXd> v) {
  const double largest = v.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (std::abs(v[i]) >= largest * (1.0 - 1e-9)) {
      if (v[i] < 0) v = -v;
      return;
    }
}

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t x) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<std::uint8_t>(x >> (8 * k)));
}
void put_f64(std::vector<std::uint8_t>& out, double d) {
  std::uint64_t x;
  std::memcpy(&x, &d, sizeof x);
  for (int k = 0; k < 8; ++k) out.push_back(static_cast<std::uint8_t>(x >> (8 * k)));
}
std::uint32_t get_u32(const std::uint8_t* p) {
  std::uint32_t x = 0;
  for (int k = 0; k < 4; ++k) x |= std::uint32_t(p[k]) << (8 * k);
  return x;
}
double get_f64(const std::uint8_t* p) {
  std::uint64_t x = 0;
  for (int k = 0; k < 8; ++k) x |= std::uint64_t(p[k]) << (8 * k);
  double d;
  std::memcpy(&d, &x, sizeof d);
  return d;
}

}  // namespace

Eigen::MatrixXd kirchhoff_matrix(const Mesh& mesh) {
  check_indices(mesh);
  const int n = mesh.num_vertices();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
  for (auto [a, b] : unique_edges(mesh)) {
    K(a, b) = K(b, a) = -1.0;
    K(a, a) += 1.0;
    K(b, b) += 1.0;
  }
  return K;
}

SpectralBasis compute_basis(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  if (n == 0) throw InputError("mesh", "has no vertices, so it has no spectral basis");
  if (n > kMaxBasisVertices)
    throw InputError("mesh", "has " + std::to_string(n) + " vertices; the dense spectral basis " +
                                 "is limited to " + std::to_string(kMaxBasisVertices) +
                                 " (watermark the control polyhedron, not the dense mesh)");
  const Eigen::MatrixXd K = kirchhoff_matrix(mesh);
  int components = 0;
  const std::vector<int> label = component_labels(n, unique_edges(mesh), components);

  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(K, Eigen::ComputeEigenvectors);
  if (solver.info() != Eigen::Success)
    throw std::runtime_error("spectral basis: eigen-decomposition did not converge");

  SpectralBasis basis;
  basis.num_components = components;
  basis.eigenvalues = solver.eigenvalues();
  basis.W = solver.eigenvectors();
  // The solver returns some rotation of the null space; replace it by the canonical indicators.
  std::vector<double> size(components, 0.0);
  for (int v = 0; v < n; ++v) size[label[v]] += 1.0;
  basis.W.leftCols(components).setZero();
  for (int v = 0; v < n; ++v) basis.W(v, label[v]) = 1.0 / std::sqrt(size[label[v]]);
  basis.eigenvalues.head(components).setZero();
  for (int j = components; j < n; ++j) fix_sign(basis.W.col(j));
  return basis;
}

Points to_spectral(const SpectralBasis& basis, const Points& points) {
  if (points.rows() != basis.W.rows())
    throw std::invalid_argument("to_spectral: " + std::to_string(points.rows()) +
                                " points for a basis of " + std::to_string(basis.W.rows()));
  return basis.W.transpose() * points;
}

Points from_spectral(const SpectralBasis& basis, const Points& coefficients) {
  if (coefficients.rows() != basis.W.rows())
    throw std::invalid_argument("from_spectral: " + std::to_string(coefficients.rows()) +
                                " coefficients for a basis of " + std::to_string(basis.W.rows()));
  return basis.W * coefficients;
}

std::vector<std::uint8_t> serialize_basis(const SpectralBasis& basis) {
  const auto n = static_cast<std::uint32_t>(basis.W.rows());
  if (basis.W.cols() != basis.W.rows() || basis.eigenvalues.size() != basis.W.rows())
    throw std::invalid_argument("serialize_basis: inconsistent basis dimensions");
  std::vector<std::uint8_t> out;
  out.reserve(kHeaderBytes + 8 * (size_t(n) + size_t(n) * n) + kHashBytes);
  for (char ch : kMagic) out.push_back(static_cast<std::uint8_t>(ch));
  put_u32(out, kFormatVersion);
  put_u32(out, n);
  put_u32(out, static_cast<std::uint32_t>(basis.num_components));
  for (std::uint32_t i = 0; i < n; ++i) put_f64(out, basis.eigenvalues[i]);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) put_f64(out, basis.W(i, j));
  std::uint8_t hash[kHashBytes];
  crypto_hash_sha256(hash, out.data(), out.size());
  for (std::uint8_t h : hash) out.push_back(h);
  return out;
}

SpectralBasis deserialize_basis(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  if (bytes.size() < kHeaderBytes + kHashBytes)
    throw InputError(source, "truncated: " + std::to_string(bytes.size()) + " bytes");
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError(source, "not a meshmark spectral basis (bad magic)");
  const std::uint8_t* p = bytes.data() + sizeof(kMagic);
  const std::uint32_t version = get_u32(p), n = get_u32(p + 4), c = get_u32(p + 8);
  if (version != kFormatVersion)
    throw InputError(source, "unsupported basis format version " + std::to_string(version));
  if (n == 0 || n > static_cast<std::uint32_t>(kMaxBasisVertices))
    throw InputError(source, "vertex count " + std::to_string(n) + " out of range");
  if (c == 0 || c > n)
    throw InputError(source, "component count " + std::to_string(c) + " out of range");
  const size_t expected = kHeaderBytes + 8 * (size_t(n) + size_t(n) * n) + kHashBytes;
  if (bytes.size() != expected)
    throw InputError(source, "size " + std::to_string(bytes.size()) + " bytes, expected " +
                                 std::to_string(expected) + " for " + std::to_string(n) +
                                 " vertices");
  std::uint8_t hash[kHashBytes];
  crypto_hash_sha256(hash, bytes.data(), expected - kHashBytes);
  if (sodium_memcmp(hash, bytes.data() + expected - kHashBytes, kHashBytes) != 0)
    throw InputError(source, "checksum mismatch (corrupted basis)");

  SpectralBasis basis;
  basis.num_components = static_cast<int>(c);
  basis.eigenvalues.resize(n);
  basis.W.resize(n, n);
  p = bytes.data() + kHeaderBytes;
  for (std::uint32_t i = 0; i < n; ++i, p += 8) basis.eigenvalues[i] = get_f64(p);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i, p += 8) basis.W(i, j) = get_f64(p);
  if (!basis.eigenvalues.allFinite() || !basis.W.allFinite())
    throw InputError(source, "contains NaN or infinite values");
  for (std::uint32_t i = 1; i < n; ++i)
    if (basis.eigenvalues[i] < basis.eigenvalues[i - 1])
      throw InputError(source, "eigenvalues are not in ascending order");
  return basis;
}

std::string basis_fingerprint(const SpectralBasis& basis) {
  const std::vector<std::uint8_t> bytes = serialize_basis(basis);
  std::uint8_t hash[kHashBytes];
  crypto_hash_sha256(hash, bytes.data(), bytes.size());
  char hex[2 * kHashBytes + 1];
  sodium_bin2hex(hex, sizeof hex, hash, kHashBytes);
  return hex;
}

}  // namespace mm
