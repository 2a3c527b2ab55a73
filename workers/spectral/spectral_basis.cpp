#include "spectral/spectral_basis.h"

#include <sodium.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>

namespace mm {
namespace {

constexpr char kMagic[8] = {'M', 'M', 'S', 'P', 'E', 'C', 'B', '1'};
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

namespace {

// The dense basis of the graph on `vertices` (ascending) with `edges` given in local indices.
SpectralPatch dense_patch(std::vector<int> vertices, const std::vector<std::pair<int, int>>& edges,
                          int& components) {
  const int n = static_cast<int>(vertices.size());
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
  for (auto [a, b] : edges) {
    K(a, b) = K(b, a) = -1.0;
    K(a, a) += 1.0;
    K(b, b) += 1.0;
  }
  const std::vector<int> label = component_labels(n, edges, components);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(K, Eigen::ComputeEigenvectors);
  if (solver.info() != Eigen::Success)
    throw std::runtime_error("spectral basis: eigen-decomposition did not converge");

  SpectralPatch patch;
  patch.vertices = std::move(vertices);
  patch.eigenvalues = solver.eigenvalues();
  patch.W = solver.eigenvectors();
  // The solver returns some rotation of the null space; replace it by the canonical indicators.
  std::vector<double> size(components, 0.0);
  for (int v = 0; v < n; ++v) size[label[v]] += 1.0;
  patch.W.leftCols(components).setZero();
  for (int v = 0; v < n; ++v) patch.W(v, label[v]) = 1.0 / std::sqrt(size[label[v]]);
  patch.eigenvalues.head(components).setZero();
  for (int j = components; j < n; ++j) fix_sign(patch.W.col(j));
  return patch;
}

// Splits the vertices into parts of at most kPatchVertices by recursive bisection: each part is
// ordered breadth-first from a pseudo-peripheral vertex of its induced graph (pieces it does not
// reach follow, each from its lowest vertex) and cut in the middle of that order, so each half is
// a connected-ish band. Deterministic: only indices and adjacency order decide.
std::vector<std::vector<int>> partition(int n, const std::vector<std::pair<int, int>>& edges) {
  std::vector<int> offset(n + 1, 0), adjacent(2 * edges.size());
  for (auto [a, b] : edges) ++offset[a + 1], ++offset[b + 1];
  for (int v = 0; v < n; ++v) offset[v + 1] += offset[v];
  {
    std::vector<int> fill(offset.begin(), offset.end() - 1);
    for (auto [a, b] : edges) adjacent[fill[a]++] = b, adjacent[fill[b]++] = a;
  }
  std::vector<int> stamp(n, -1);
  int round = 0;
  // Breadth-first order over `set` from `from`, then from each unreached vertex of `set`;
  // `reached` is how many came from `from` itself.
  auto bfs = [&](const std::vector<int>& set, int from, std::size_t& reached) {
    const int member = ++round;
    for (int v : set) stamp[v] = member;
    const int seen = ++round;
    std::vector<int> order;
    order.reserve(set.size());
    auto grow = [&](int seed) {
      std::size_t head = order.size();
      order.push_back(seed);
      stamp[seed] = seen;
      while (head < order.size()) {
        const int v = order[head++];
        for (int k = offset[v]; k < offset[v + 1]; ++k)
          if (stamp[adjacent[k]] == member) stamp[adjacent[k]] = seen, order.push_back(adjacent[k]);
      }
    };
    grow(from);
    reached = order.size();
    for (int v : set)
      if (stamp[v] == member) grow(v);
    return order;
  };
  std::vector<std::vector<int>> parts, todo;
  std::vector<int> all(n);
  std::iota(all.begin(), all.end(), 0);
  todo.push_back(std::move(all));
  while (!todo.empty()) {
    std::vector<int> set = std::move(todo.back());
    todo.pop_back();
    if (static_cast<int>(set.size()) <= kPatchVertices) {
      parts.push_back(std::move(set));
      continue;
    }
    // The vertex reached last from the lowest one lies far out on its piece: start there.
    std::size_t reached = 0;
    const int start = bfs(set, set.front(), reached)[reached - 1];
    const std::vector<int> order = bfs(set, start, reached);
    const std::size_t half = order.size() / 2;
    std::vector<int> first(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(half)),
        second(order.begin() + static_cast<std::ptrdiff_t>(half), order.end());
    std::sort(first.begin(), first.end());
    std::sort(second.begin(), second.end());
    todo.push_back(std::move(second));
    todo.push_back(std::move(first));
  }
  return parts;
}

}  // namespace

namespace {

// Column order from the patches: every patch's zero-eigenvalue columns first (patch order), then
// the rest by eigenvalue, ties in patch and column order.
void order_columns(SpectralBasis& b, const std::vector<int>& patch_components) {
  b.column_patch.clear();
  b.column_local.clear();
  b.num_components = 0;
  std::vector<std::pair<int, int>> rest;
  for (int p = 0; p < static_cast<int>(b.patches.size()); ++p) {
    const int size = static_cast<int>(b.patches[p].vertices.size());
    for (int c = 0; c < size; ++c) {
      if (c < patch_components[p]) {
        b.column_patch.push_back(p);
        b.column_local.push_back(c);
        ++b.num_components;
      } else {
        rest.emplace_back(p, c);
      }
    }
  }
  std::stable_sort(rest.begin(), rest.end(), [&](const auto& x, const auto& y) {
    return b.patches[x.first].eigenvalues[x.second] < b.patches[y.first].eigenvalues[y.second];
  });
  for (auto [p, c] : rest) b.column_patch.push_back(p), b.column_local.push_back(c);
  b.eigenvalues.resize(static_cast<Eigen::Index>(b.column_patch.size()));
  for (std::size_t j = 0; j < b.column_patch.size(); ++j)
    b.eigenvalues[static_cast<Eigen::Index>(j)] = b.patches[b.column_patch[j]].eigenvalues[b.column_local[j]];
}

void check_rows(const SpectralBasis& b, const Points& x, const char* what) {
  if (x.rows() != b.num_vertices())
    throw std::invalid_argument(std::string(what) + ": " + std::to_string(x.rows()) + " rows for a basis of " +
                                std::to_string(b.num_vertices()));
}

}  // namespace

SpectralBasis compute_basis(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  if (n == 0) throw InputError("mesh", "has no vertices, so it has no spectral basis");
  if (n > kMaxBasisVertices)
    throw InputError("mesh", "has " + std::to_string(n) + " vertices; the spectral basis is limited to " +
                                 std::to_string(kMaxBasisVertices) +
                                 " (watermark the control polyhedron, not the dense mesh)");
  check_indices(mesh);
  const std::vector<std::pair<int, int>> edges = unique_edges(mesh);
  SpectralBasis basis;
  basis.vertices = n;
  std::vector<int> components;
  if (n <= kDenseBasisVertices) {
    std::vector<int> all(n);
    std::iota(all.begin(), all.end(), 0);
    components.push_back(0);
    basis.patches.push_back(dense_patch(std::move(all), edges, components.back()));
  } else {
    const std::vector<std::vector<int>> parts = partition(n, edges);
    std::vector<int> patch_of(n), local(n);
    for (int p = 0; p < static_cast<int>(parts.size()); ++p)
      for (int i = 0; i < static_cast<int>(parts[p].size()); ++i) patch_of[parts[p][i]] = p, local[parts[p][i]] = i;
    std::vector<std::vector<std::pair<int, int>>> inside(parts.size());
    for (auto [a, b] : edges)
      if (patch_of[a] == patch_of[b]) inside[patch_of[a]].emplace_back(local[a], local[b]);
    components.resize(parts.size());
    for (std::size_t p = 0; p < parts.size(); ++p)
      basis.patches.push_back(dense_patch(parts[p], inside[p], components[p]));
  }
  order_columns(basis, components);
  return basis;
}

Points to_spectral(const SpectralBasis& basis, const Points& points) {
  check_rows(basis, points, "to_spectral");
  if (basis.patches.size() == 1) return basis.patches[0].W.transpose() * points;
  std::vector<Eigen::MatrixXd> local(basis.patches.size());
  for (std::size_t p = 0; p < basis.patches.size(); ++p) {
    const SpectralPatch& patch = basis.patches[p];
    Eigen::MatrixXd x(patch.vertices.size(), 3);
    for (std::size_t i = 0; i < patch.vertices.size(); ++i) x.row(static_cast<Eigen::Index>(i)) = points.row(patch.vertices[i]);
    local[p] = patch.W.transpose() * x;
  }
  Points out(points.rows(), 3);
  for (std::size_t j = 0; j < basis.column_patch.size(); ++j)
    out.row(static_cast<Eigen::Index>(j)) = local[basis.column_patch[j]].row(basis.column_local[j]);
  return out;
}

Points from_spectral(const SpectralBasis& basis, const Points& coefficients) {
  check_rows(basis, coefficients, "from_spectral");
  if (basis.patches.size() == 1) return basis.patches[0].W * coefficients;
  std::vector<Eigen::MatrixXd> local(basis.patches.size());
  for (std::size_t p = 0; p < basis.patches.size(); ++p)
    local[p].resize(static_cast<Eigen::Index>(basis.patches[p].vertices.size()), 3);
  for (std::size_t j = 0; j < basis.column_patch.size(); ++j)
    local[basis.column_patch[j]].row(basis.column_local[j]) = coefficients.row(static_cast<Eigen::Index>(j));
  Points out(coefficients.rows(), 3);
  for (std::size_t p = 0; p < basis.patches.size(); ++p) {
    const SpectralPatch& patch = basis.patches[p];
    const Eigen::MatrixXd x = patch.W * local[p];
    for (std::size_t i = 0; i < patch.vertices.size(); ++i) out.row(patch.vertices[i]) = x.row(static_cast<Eigen::Index>(i));
  }
  return out;
}

Eigen::MatrixXd basis_columns(const SpectralBasis& basis, int first, int count) {
  if (first < 0 || count < 0 || first + count > basis.num_vertices())
    throw std::invalid_argument("basis_columns: columns " + std::to_string(first) + " + " + std::to_string(count) +
                                " of " + std::to_string(basis.num_vertices()));
  if (basis.patches.size() == 1) return basis.patches[0].W.middleCols(first, count);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(basis.num_vertices(), count);
  for (int k = 0; k < count; ++k) {
    const SpectralPatch& patch = basis.patches[basis.column_patch[first + k]];
    const int c = basis.column_local[first + k];
    for (std::size_t i = 0; i < patch.vertices.size(); ++i) out(patch.vertices[i], k) = patch.W(static_cast<Eigen::Index>(i), c);
  }
  return out;
}

std::vector<std::uint8_t> serialize_basis(const SpectralBasis& basis) {
  const auto n = static_cast<std::uint32_t>(basis.num_vertices());
  if (basis.patches.empty() || basis.eigenvalues.size() != basis.num_vertices())
    throw std::invalid_argument("serialize_basis: inconsistent basis dimensions");
  const bool dense = basis.patches.size() == 1;
  std::size_t doubles = 0;
  for (const SpectralPatch& p : basis.patches) doubles += p.vertices.size() * (p.vertices.size() + 1);
  std::vector<std::uint8_t> out;
  out.reserve(kHeaderBytes + 8 * doubles + 8 * (n + basis.patches.size()) + 4 + kHashBytes);
  for (char ch : kMagic) out.push_back(static_cast<std::uint8_t>(ch));
  put_u32(out, dense ? 1 : 2);
  put_u32(out, n);
  put_u32(out, static_cast<std::uint32_t>(basis.num_components));
  if (dense) {
    const SpectralPatch& p = basis.patches[0];
    for (std::uint32_t i = 0; i < n; ++i) put_f64(out, p.eigenvalues[i]);
    for (std::uint32_t j = 0; j < n; ++j)
      for (std::uint32_t i = 0; i < n; ++i) put_f64(out, p.W(i, j));
  } else {
    put_u32(out, static_cast<std::uint32_t>(basis.patches.size()));
    for (const SpectralPatch& p : basis.patches) {
      const auto size = static_cast<Eigen::Index>(p.vertices.size());
      int zeros = 0;
      while (zeros < size && p.eigenvalues[zeros] == 0.0) ++zeros;
      put_u32(out, static_cast<std::uint32_t>(size));
      put_u32(out, static_cast<std::uint32_t>(zeros));
      for (int v : p.vertices) put_u32(out, static_cast<std::uint32_t>(v));
      for (Eigen::Index i = 0; i < size; ++i) put_f64(out, p.eigenvalues[i]);
      for (Eigen::Index j = 0; j < size; ++j)
        for (Eigen::Index i = 0; i < size; ++i) put_f64(out, p.W(i, j));
    }
  }
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
  if (version != 1 && version != 2)
    throw InputError(source, "unsupported basis format version " + std::to_string(version));
  if (n == 0 || n > static_cast<std::uint32_t>(kMaxBasisVertices))
    throw InputError(source, "vertex count " + std::to_string(n) + " out of range");
  if (c == 0 || c > n)
    throw InputError(source, "component count " + std::to_string(c) + " out of range");
  const std::size_t body = bytes.size() - kHashBytes;
  std::uint8_t hash[kHashBytes];
  if (version == 1) {
    const size_t expected = kHeaderBytes + 8 * (size_t(n) + size_t(n) * n) + kHashBytes;
    if (bytes.size() != expected)
      throw InputError(source, "size " + std::to_string(bytes.size()) + " bytes, expected " +
                                   std::to_string(expected) + " for " + std::to_string(n) + " vertices");
  }
  crypto_hash_sha256(hash, bytes.data(), body);
  if (sodium_memcmp(hash, bytes.data() + body, kHashBytes) != 0)
    throw InputError(source, "checksum mismatch (corrupted basis)");

  SpectralBasis basis;
  basis.vertices = static_cast<int>(n);
  std::vector<int> components;
  std::size_t at = kHeaderBytes;
  auto need = [&](std::size_t count, const char* what) {
    if (count > body - at) throw InputError(source, std::string("truncated ") + what);
  };
  auto read_patch = [&](std::vector<int> vertices, int zeros) {
    const auto size = static_cast<Eigen::Index>(vertices.size());
    SpectralPatch patch;
    patch.vertices = std::move(vertices);
    need(8 * static_cast<std::size_t>(size) * static_cast<std::size_t>(size + 1), "patch values");
    patch.eigenvalues.resize(size);
    patch.W.resize(size, size);
    for (Eigen::Index i = 0; i < size; ++i, at += 8) patch.eigenvalues[i] = get_f64(bytes.data() + at);
    for (Eigen::Index j = 0; j < size; ++j)
      for (Eigen::Index i = 0; i < size; ++i, at += 8) patch.W(i, j) = get_f64(bytes.data() + at);
    if (!patch.eigenvalues.allFinite() || !patch.W.allFinite())
      throw InputError(source, "contains NaN or infinite values");
    for (Eigen::Index i = 1; i < size; ++i)
      if (patch.eigenvalues[i] < patch.eigenvalues[i - 1])
        throw InputError(source, "eigenvalues are not in ascending order");
    for (Eigen::Index i = 0; i < size; ++i)
      if ((i < zeros) != (patch.eigenvalues[i] == 0.0))
        throw InputError(source, "zero eigenvalues do not match the component count");
    basis.patches.push_back(std::move(patch));
    components.push_back(zeros);
  };
  if (version == 1) {
    std::vector<int> all(n);
    std::iota(all.begin(), all.end(), 0);
    // A dense basis's component count is its number of zero eigenvalues.
    read_patch(std::move(all), static_cast<int>(c));
  } else {
    need(4, "patch count");
    const std::uint32_t count = get_u32(bytes.data() + at);
    at += 4;
    if (count < 2 || count > n) throw InputError(source, "patch count " + std::to_string(count) + " out of range");
    std::vector<char> used(n, 0);
    std::uint32_t total = 0;
    for (std::uint32_t q = 0; q < count; ++q) {
      need(8, "patch header");
      const std::uint32_t size = get_u32(bytes.data() + at), zeros = get_u32(bytes.data() + at + 4);
      at += 8;
      if (size == 0 || size > n - total || zeros == 0 || zeros > size)
        throw InputError(source, "patch " + std::to_string(q) + " has a bad size or component count");
      total += size;
      need(4 * std::size_t(size), "patch vertices");
      std::vector<int> vertices(size);
      for (std::uint32_t i = 0; i < size; ++i, at += 4) {
        const std::uint32_t v = get_u32(bytes.data() + at);
        if (v >= n || used[v] || (i > 0 && v <= static_cast<std::uint32_t>(vertices[i - 1])))
          throw InputError(source, "patch " + std::to_string(q) + " lists vertex " + std::to_string(v) +
                                       " out of range, twice or out of order");
        used[v] = 1;
        vertices[i] = static_cast<int>(v);
      }
      read_patch(std::move(vertices), static_cast<int>(zeros));
    }
    if (total != n) throw InputError(source, "patches cover " + std::to_string(total) + " of " + std::to_string(n) + " vertices");
  }
  if (at != body)
    throw InputError(source, "size " + std::to_string(bytes.size()) + " bytes, " + std::to_string(body - at) +
                                 " bytes past the basis");
  order_columns(basis, components);
  if (basis.num_components != static_cast<int>(c))
    throw InputError(source, "component count " + std::to_string(c) + " does not match the patches' " +
                                 std::to_string(basis.num_components));
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
