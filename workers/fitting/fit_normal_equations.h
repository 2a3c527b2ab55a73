// Internal to workers/fitting: the fit's linear algebra -- the data term's normal equations in
// refined-vertex space, their fixed-pattern product with the subdivision operator, the
// regularised control-space system and a three-column sparse product. Not part of the
// library's interface.
#pragma once
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <stdexcept>
#include <utility>
#include <vector>

#include "meshio/mesh.h"
#include "subdivision/subdivide.h"

namespace mm::fitting_detail {

using SpMat = Eigen::SparseMatrix<double, Eigen::RowMajor>;
using Trip = Eigen::Triplet<double>;

// The least-squares data term sum_r w_r |b_r . R - p_r|^2 over refined positions R, kept as its
// normal equations in refined-vertex space, G = B^T W B and Y = B^T W P: every correspondence
// row combines the vertices of one refined triangle, edge or vertex, so G has the pattern of the
// refined mesh's edges, fixed for a fit. The control-space system is then S^T G S, a product
// of much smaller matrices than forming A = B S and A^T W A row by row.
class RefinedNormalEquations {
 public:
  RefinedNormalEquations(int refined_vertices, const std::vector<std::array<int, 3>>& tris,
                         const std::vector<std::pair<int, int>>& segments) {
    // The pattern: per row the vertex itself and its neighbours along triangle sides and crease
    // segments, sorted, each once (the pattern setFromTriplets gave, without its two passes).
    const size_t n = static_cast<size_t>(refined_vertices);
    std::vector<int> start(n + 1, 0);
    for (size_t v = 0; v < n; ++v) start[v + 1] = 1;
    for (const auto& f : tris)
      for (int v : f) start[static_cast<size_t>(v) + 1] += 2;
    for (auto [a, b] : segments) ++start[static_cast<size_t>(a) + 1], ++start[static_cast<size_t>(b) + 1];
    for (size_t v = 0; v < n; ++v) start[v + 1] += start[v];
    std::vector<int> cols(static_cast<size_t>(start[n])), fill(start.begin(), start.end() - 1);
    auto put = [&](int a, int b) { cols[static_cast<size_t>(fill[static_cast<size_t>(a)]++)] = b; };
    for (size_t v = 0; v < n; ++v) put(static_cast<int>(v), static_cast<int>(v));
    for (const auto& f : tris) put(f[0], f[1]), put(f[1], f[0]), put(f[1], f[2]), put(f[2], f[1]), put(f[2], f[0]), put(f[0], f[2]);
    for (auto [a, b] : segments) put(a, b), put(b, a);
    std::vector<int> outer(n + 1, 0);
    size_t nnz = 0;
    for (size_t v = 0; v < n; ++v) {
      const auto begin = cols.begin() + start[v], end = cols.begin() + start[v + 1];
      std::sort(begin, end);
      const auto last = std::unique(begin, end);
      const size_t kept = static_cast<size_t>(last - begin);
      // Compacted in place: the row moves down to where the previous row ended (never past it).
      if (nnz != static_cast<size_t>(start[v])) std::copy(begin, last, cols.begin() + static_cast<std::ptrdiff_t>(nnz));
      nnz += kept;
      outer[v + 1] = static_cast<int>(nnz);
    }
    G.resize(refined_vertices, refined_vertices);
    G.resizeNonZeros(static_cast<Eigen::Index>(nnz));
    std::copy(outer.begin(), outer.end(), G.outerIndexPtr());
    std::copy(cols.begin(), cols.begin() + static_cast<std::ptrdiff_t>(nnz), G.innerIndexPtr());
    std::fill(G.valuePtr(), G.valuePtr() + G.nonZeros(), 0.0);
    Y.setZero(refined_vertices, 3);
    // Where each term pair lands in G, found once instead of once per correspondence.
    tri_slots.resize(tris.size());
    for (size_t k = 0; k < tris.size(); ++k)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) tri_slots[k][static_cast<size_t>(3 * i + j)] = slot(tris[k][static_cast<size_t>(i)], tris[k][static_cast<size_t>(j)]);
    segment_slots.resize(segments.size());
    for (size_t k = 0; k < segments.size(); ++k) {
      const int e[2] = {segments[k].first, segments[k].second};
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) segment_slots[k][static_cast<size_t>(2 * i + j)] = slot(e[i], e[j]);
    }
    vertex_slots.resize(static_cast<size_t>(refined_vertices));
    for (int v = 0; v < refined_vertices; ++v) vertex_slots[static_cast<size_t>(v)] = {slot(v, v)};
  }
  std::vector<std::array<int, 9>> tri_slots;      // per refined triangle: G slots of its 3 x 3 pairs
  std::vector<std::array<int, 4>> segment_slots;  // per refined crease edge: its 2 x 2 pairs
  std::vector<std::array<int, 1>> vertex_slots;   // per refined vertex: its diagonal slot
  // G is not cleared here: the product that reads it leaves it zero (FixedPatternProduct::
  // consume), which touches only its non-zero entries, a few of them, where filling all of G
  // with zeros was a memset of the refined mesh's edges every iteration.
  void clear() { Y.setZero(); }
  // `slots`: G slots of the terms' pairs (tri_slots, segment_slots or vertex_slots).
  template <size_t N>
  void add(const std::array<std::pair<int, double>, N>& terms, const std::array<int, N * N>& slots,
           const Eigen::Vector3d& p, double w) {
    double* g = G.valuePtr();
    for (size_t i = 0; i < N; ++i) {
      const double ca = terms[i].second;
      if (ca == 0) continue;
      Y.row(terms[i].first) += (w * ca) * p.transpose();
      for (size_t j = 0; j < N; ++j)
        if (terms[j].second != 0) g[slots[N * i + j]] += w * ca * terms[j].second;
    }
  }
  SpMat G;
  Eigen::MatrixXd Y;

 private:
  int slot(int a, int b) const {
    const int* begin = G.innerIndexPtr() + G.outerIndexPtr()[a];
    const int* end = G.innerIndexPtr() + G.outerIndexPtr()[a + 1];
    return static_cast<int>(std::lower_bound(begin, end, b) - G.innerIndexPtr());
  }
};

// C = A B for row-major A and B whose patterns stay fixed while their values change (the
// fit's G, S and S^T within one fit): C's pattern is found once, and each product accumulates
// a row in a dense buffer and gathers it into that pattern, without the per-row index sorting
// of a general sparse product. Row i of C is only computed from column first_col[i] on (the
// rest is left out of C): the solver reads one triangle of the symmetric S^T G S, and G S is
// needed only where that triangle reads it. The entries computed are summed in the same order
// as in the full product, so they are bit for bit its values.
class FixedPatternProduct {
 public:
  FixedPatternProduct(const SpMat& A, const SpMat& B, std::vector<int> first_col)
      : acc_(static_cast<size_t>(B.cols()), 0.0), first_col_(std::move(first_col)) {
    if (!A.isCompressed() || !B.isCompressed()) throw std::logic_error("FixedPatternProduct: uncompressed operand");
    // The pattern alone (every product term counts, none can cancel out), row by row with a
    // marker per column, each row's columns sorted.
    std::vector<int> outer(static_cast<size_t>(A.outerSize()) + 1, 0), inner, mark(static_cast<size_t>(B.cols()), -1);
    const int* b_outer = B.outerIndexPtr();
    const int* b_inner = B.innerIndexPtr();
    // Where each term of A starts in its row of B (the first column wanted), found once.
    start_.resize(static_cast<size_t>(A.nonZeros()));
    for (Eigen::Index i = 0; i < A.outerSize(); ++i) {
      const size_t row_begin = inner.size();
      const int from = first_col_[static_cast<size_t>(i)];
      for (int k = A.outerIndexPtr()[i]; k < A.outerIndexPtr()[i + 1]; ++k) {
        const int col = A.innerIndexPtr()[k];
        const int* end = b_inner + b_outer[col + 1];
        const int* y = std::lower_bound(b_inner + b_outer[col], end, from);
        start_[static_cast<size_t>(k)] = static_cast<int>(y - b_inner);
        for (; y != end; ++y)
          if (mark[static_cast<size_t>(*y)] != static_cast<int>(i)) {
            mark[static_cast<size_t>(*y)] = static_cast<int>(i);
            inner.push_back(*y);
          }
      }
      std::sort(inner.begin() + static_cast<std::ptrdiff_t>(row_begin), inner.end());
      outer[static_cast<size_t>(i) + 1] = static_cast<int>(inner.size());
    }
    C.resize(A.rows(), B.cols());
    C.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
    std::copy(outer.begin(), outer.end(), C.outerIndexPtr());
    std::copy(inner.begin(), inner.end(), C.innerIndexPtr());
    std::fill(C.valuePtr(), C.valuePtr() + C.nonZeros(), 0.0);
  }
  const SpMat& operator()(const SpMat& A, const SpMat& B) { return multiply<false>(A, A.valuePtr(), B); }
  // The same product, leaving A's values all zero (each non-zero one is cleared once read): for
  // a left factor accumulated afresh before every product (G).
  const SpMat& consume(SpMat& A, const SpMat& B) { return multiply<true>(A, A.valuePtr(), B); }
  SpMat C;

 private:
  template <bool kConsume, class Value>
  const SpMat& multiply(const SpMat& A, Value* a_value, const SpMat& B) {
    const int* b_outer = B.outerIndexPtr();
    const int* b_inner = B.innerIndexPtr();
    const double* b_value = B.valuePtr();
    const int* a_inner = A.innerIndexPtr();
    for (Eigen::Index i = 0; i < A.outerSize(); ++i) {
      for (int k = A.outerIndexPtr()[i]; k < A.outerIndexPtr()[i + 1]; ++k) {
        const double xv = a_value[k];
        // A zero term adds +-0 to each accumulator, which leaves it as it is: an accumulator
        // starts at +0 and a sum is -0 only when both operands are, so none ever holds -0.
        // Most of G's entries are zero (a refined edge gets a value only where a target sample
        // landed on a triangle next to it), so most of G S is skipped. (B is S or G S: finite.)
        if (xv == 0) continue;
        if constexpr (kConsume) a_value[k] = 0;
        const int end = b_outer[a_inner[k] + 1];
        for (int y = start_[static_cast<size_t>(k)]; y < end; ++y) acc_[static_cast<size_t>(b_inner[y])] += xv * b_value[y];
      }
      for (int k = C.outerIndexPtr()[i]; k < C.outerIndexPtr()[i + 1]; ++k) {
        double& v = acc_[static_cast<size_t>(C.innerIndexPtr()[k])];
        C.valuePtr()[k] = v;
        v = 0;
      }
    }
    return C;
  }

  std::vector<double> acc_;
  std::vector<int> first_col_;
  std::vector<int> start_;  // per term of A: index in B's arrays of the first term used
};

// M = C + a L + b I over a pattern fixed for the fit (C = S^T G S, L = LtL), filled in place:
// the values Eigen's two sparse sums (M += a L; M += b I) gave, which add an entry that only
// one operand has to zero, so (x or 0) + (y or 0) is bit for bit the same; and the same
// pattern, the union of the three. Spares two sparse sums and three matrices per iteration.
class RegularisedSystem {
 public:
  RegularisedSystem(const SpMat& C, const SpMat& L) {
    const int n = static_cast<int>(C.rows());
    std::vector<int> outer(static_cast<size_t>(n) + 1, 0), inner;
    for (int i = 0; i < n; ++i) {
      int c = C.outerIndexPtr()[i], l = L.outerIndexPtr()[i];
      const int c_end = C.outerIndexPtr()[i + 1], l_end = L.outerIndexPtr()[i + 1];
      bool diagonal_done = false;
      while (c < c_end || l < l_end || !diagonal_done) {
        const int cc = c < c_end ? C.innerIndexPtr()[c] : n, lc = l < l_end ? L.innerIndexPtr()[l] : n;
        int col = std::min(cc, lc);
        if (!diagonal_done && i <= col) col = i;
        Term t;
        t.c = cc == col ? c++ : -1;
        t.l = lc == col ? l++ : -1;
        t.diagonal = col == i;
        diagonal_done = diagonal_done || t.diagonal;
        inner.push_back(col);
        terms_.push_back(t);
      }
      outer[static_cast<size_t>(i) + 1] = static_cast<int>(inner.size());
    }
    M.resize(n, n);
    M.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
    std::copy(outer.begin(), outer.end(), M.outerIndexPtr());
    std::copy(inner.begin(), inner.end(), M.innerIndexPtr());
  }
  const SpMat& operator()(const SpMat& C, const SpMat& L, double a, double b) {
    const double* cv = C.valuePtr();
    const double* lv = L.valuePtr();
    double* m = M.valuePtr();
    for (size_t k = 0; k < terms_.size(); ++k) {
      const Term& t = terms_[k];
      const bool first_sum = t.c >= 0 || t.l >= 0;  // the entry is in C + a L
      const double v = first_sum ? (t.c >= 0 ? cv[t.c] : 0.0) + (t.l >= 0 ? a * lv[t.l] : 0.0) : 0.0;
      m[k] = v + (t.diagonal ? b : 0.0);
    }
    return M;
  }

 private:
  struct Term {
    int c, l;       // index in C's and L's values, -1 when absent
    bool diagonal;  // gets b (b I)
  };
  std::vector<Term> terms_;
  SpMat M;
};

// A * B for a row-major sparse A and a dense B of three columns (positions), all three columns
// in one pass over A, where Eigen's product walks A once per column: the same sums in the same
// order from the same zero, so the same numbers.
template <class Dense>
Points times3(const SpMat& A, const Dense& B) {
  if (B.cols() != 3 || B.rows() != A.cols()) throw std::logic_error("times3: shapes do not match");
  Points out(A.rows(), 3);
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  const double* value = A.valuePtr();
  for (Eigen::Index i = 0; i < A.rows(); ++i) {
    double x = 0, y = 0, z = 0;
    const int end = A.isCompressed() ? outer[i + 1] : outer[i] + A.innerNonZeroPtr()[i];
    for (int k = outer[i]; k < end; ++k) {
      const double v = value[k];
      const Eigen::Index c = inner[k];
      x += v * B(c, 0);
      y += v * B(c, 1);
      z += v * B(c, 2);
    }
    out(i, 0) = 0.0 + x;  // Eigen adds the row's sum to a zeroed result
    out(i, 1) = 0.0 + y;
    out(i, 2) = 0.0 + z;
  }
  return out;
}

}  // namespace mm::fitting_detail
