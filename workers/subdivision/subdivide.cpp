#include "subdivision/subdivide.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "subdivision/refinement_level.h"

namespace mm {

using namespace subdivision_detail;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Sparse row accumulator: weights of one refined vertex on the coarse vertices.
class RowBuilder {
 public:
  explicit RowBuilder(int ncols) : slot_(ncols, -1) {}
  void add(int col, double w) {
    int& s = slot_[col];
    if (s < 0) {
      s = static_cast<int>(cols_.size());
      cols_.push_back(col);
      vals_.push_back(w);
    } else {
      vals_[s] += w;
    }
  }
  // Appends the row (sorted columns, zero weights dropped) to row `r` of a compressed row-major
  // matrix being filled in order, and resets.
  void flush(SparseOperator& M, int r) {
    // Rows are short (< 30 entries): insertion sort by column.
    for (size_t i = 1; i < cols_.size(); ++i)
      for (size_t j = i; j > 0 && cols_[j - 1] > cols_[j]; --j) {
        std::swap(cols_[j - 1], cols_[j]);
        std::swap(vals_[j - 1], vals_[j]);
      }
    auto& data = M.data();
    for (size_t i = 0; i < cols_.size(); ++i) {
      if (vals_[i] != 0.0) data.append(vals_[i], cols_[i]);
      slot_[cols_[i]] = -1;
    }
    cols_.clear();
    vals_.clear();
    M.outerIndexPtr()[r + 1] = static_cast<int>(data.size());
  }

 private:
  std::vector<int> slot_, cols_;
  std::vector<double> vals_;
};

// Loop's smooth vertex weights as OpenSubdiv computes them (exact values for valences 3 and 6).
void loop_weights(int n, double& vertex_w, double& edge_w) {
  if (n == 6) {
    edge_w = 0.0625;
    vertex_w = 0.625;
  } else if (n == 3) {
    edge_w = 0.1875;
    vertex_w = 0.4375;
  } else {
    const double inv = 1.0 / n;
    const double beta = 0.25 * std::cos(2.0 * kPi * inv) + 0.375;
    edge_w = (0.625 - beta * beta) * inv;
    vertex_w = 1.0 - edge_w * n;
  }
}

// Receives the rows of one step in order: add(coarse vertex, weight) ... end_row().
// MatrixSink assembles the sparse step matrix; PointSink evaluates the child points directly.
class MatrixSink {
 public:
  MatrixSink(SparseOperator& M, int nchild, int nv) : M_(M), row_(nv) {
    M_.resize(nchild, nv);
    M_.data().reserve(static_cast<Eigen::Index>(nchild) * 9);
  }
  void add(int col, double w) { row_.add(col, w); }
  void end_row() { row_.flush(M_, r_++); }

 private:
  SparseOperator& M_;
  RowBuilder row_;
  int r_ = 0;
};

class PointSink {
 public:
  PointSink(const Points& in, Points& out, int nchild) : in_(in), out_(out) { out_.resize(nchild, 3); }
  void add(int col, double w) {
    x_ += w * in_(col, 0);
    y_ += w * in_(col, 1);
    z_ += w * in_(col, 2);
  }
  void end_row() {
    out_(r_, 0) = x_;
    out_(r_, 1) = y_;
    out_(r_, 2) = z_;
    ++r_;
    x_ = y_ = z_ = 0.0;
  }

 private:
  const Points& in_;
  Points& out_;
  int r_ = 0;
  double x_ = 0, y_ = 0, z_ = 0;
};

// Face points only for non-triangles, numbered after the vertices in face order.
std::vector<int> face_point_indices(const Level& L, int& nfp) {
  std::vector<int> fpoint(L.nf(), -1);
  nfp = 0;
  for (int f = 0; f < L.nf(); ++f)
    if (L.fsize(f) != 3) fpoint[f] = L.nv + nfp++;
  return fpoint;
}

// The subdivision rules (docs/subdivision.md): one row per child vertex, in child order
// [vertex points, face points, edge points].
template <class Sink>
void emit_rows(const Level& L, const Adjacency& a, const std::vector<int>& fpoint, Sink& sink) {
  const int nv = L.nv, nf = L.nf(), ne = L.ne();
  auto sharp = [&](int e) { return L.ecrease[e] || a.efaces[e][1] < 0; };
  auto add_face_point = [&](int f, double w) {  // w * centroid of face f
    const double wi = w / L.fsize(f);
    for (int k = L.foff[f]; k < L.foff[f + 1]; ++k) sink.add(L.fverts[k], wi);
  };
  auto other_end = [&](int e, int v) { return L.everts[e][0] == v ? L.everts[e][1] : L.everts[e][0]; };

  // Vertex points.
  for (int v = 0; v < nv; ++v) {
    const int nedges = a.vedges.size(v);
    int nsharp = 0, s0 = -1, s1 = -1;
    for (const int* e = a.vedges.begin(v); e != a.vedges.end(v); ++e)
      if (sharp(*e)) {
        (nsharp == 0 ? s0 : s1) = *e;
        ++nsharp;
      }
    if (L.vcorner[v] || nsharp > 2 || a.vfaces.size(v) == 0) {
      sink.add(v, 1.0);  // corner
    } else if (nsharp == 2) {
      sink.add(v, 0.75);  // crease
      sink.add(other_end(s0, v), 0.125);
      sink.add(other_end(s1, v), 0.125);
    } else {
      int ntri = 0, nquad = 0;
      for (const int* f = a.vfaces.begin(v); f != a.vfaces.end(v); ++f)
        (L.fsize(*f) == 3 ? ntri : nquad)++;
      if (nquad == 0) {  // Loop
        double vw, ew;
        loop_weights(nedges, vw, ew);
        sink.add(v, vw);
        for (const int* e = a.vedges.begin(v); e != a.vedges.end(v); ++e) sink.add(other_end(*e, v), ew);
      } else if (ntri == 0) {  // Catmull-Clark
        const double n = nedges, w = 1.0 / (n * n);
        sink.add(v, (n - 2.0) / n);
        for (const int* e = a.vedges.begin(v); e != a.vedges.end(v); ++e) sink.add(other_end(*e, v), w);
        for (const int* f = a.vfaces.begin(v); f != a.vfaces.end(v); ++f) add_face_point(*f, w);
      } else {  // Stam-Loop averaging of the split mesh: 1 (vertex), 1/2 (edge midpoints),
                // 1/4 (quad centres), normalised.
        const double alpha = 1.0 / (1.0 + nedges / 2.0 + nquad / 4.0);
        sink.add(v, alpha * (1.0 + nedges / 4.0));
        for (const int* e = a.vedges.begin(v); e != a.vedges.end(v); ++e)
          sink.add(other_end(*e, v), alpha / 4.0);
        for (const int* f = a.vfaces.begin(v); f != a.vfaces.end(v); ++f)
          if (L.fsize(*f) != 3) add_face_point(*f, alpha / 4.0);
      }
    }
    sink.end_row();
  }
  // Face points.
  for (int f = 0; f < nf; ++f)
    if (fpoint[f] >= 0) {
      add_face_point(f, 1.0);
      sink.end_row();
    }
  // Edge points: 1/4 per endpoint plus each face's wing (triangle: 1/16 per endpoint and 1/8
  // opposite, i.e. Loop; other faces: 1/4 of the face point, i.e. Catmull-Clark). For triangles
  // and quads that is 3/8 per endpoint, 1/8 per opposite triangle vertex, 1/16 per far quad corner.
  for (int e = 0; e < ne; ++e) {
    const int v0 = L.everts[e][0], v1 = L.everts[e][1];
    if (sharp(e)) {
      sink.add(v0, 0.5);
      sink.add(v1, 0.5);
    } else if (L.fsize(a.efaces[e][0]) <= 4 && L.fsize(a.efaces[e][1]) <= 4) {
      sink.add(v0, 0.375);
      sink.add(v1, 0.375);
      for (int f : a.efaces[e]) {
        const double wing = L.fsize(f) == 3 ? 0.125 : 0.0625;
        for (int k = L.foff[f]; k < L.foff[f + 1]; ++k)
          if (L.fverts[k] != v0 && L.fverts[k] != v1) sink.add(L.fverts[k], wing);
      }
    } else {
      sink.add(v0, 0.25);
      sink.add(v1, 0.25);
      for (int f : a.efaces[e]) {
        if (L.fsize(f) == 3) {
          sink.add(v0, 0.0625);
          sink.add(v1, 0.0625);
          for (int k = L.foff[f]; k < L.foff[f + 1]; ++k)
            if (L.fverts[k] != v0 && L.fverts[k] != v1) sink.add(L.fverts[k], 0.125);
        } else {
          add_face_point(f, 0.25);
        }
      }
    }
    sink.end_row();
  }
}

// Child topology, numbered as OpenSubdiv: faces by parent face; edges interior to faces first
// (by face), then the two halves of each parent edge. Without `with_edges` only the faces and
// corners (a last level nothing refines further: its edge arrays were a third of a
// decompression's memory).
Level child_level(const Level& L, const std::vector<int>& fpoint, int nfp, bool with_edges = true) {
  const int nv = L.nv, nf = L.nf(), ne = L.ne();
  const int nchild = nv + nfp + ne;
  auto epoint = [&](int e) { return nv + nfp + e; };
  Level C;
  C.nv = nchild;
  // A triangle has 3 interior edges and 4 triangle children; an n-gon n edges and n quads.
  int nint = 0, nchild_faces = 0;
  size_t nchild_corners = 0;
  for (int f = 0; f < nf; ++f) {
    const int s = L.fsize(f);
    nint += s;
    nchild_faces += s == 3 ? 4 : s;
    nchild_corners += s == 3 ? 12 : 4 * static_cast<size_t>(s);
  }
  C.foff.resize(nchild_faces + 1);
  C.fverts.resize(nchild_corners);
  if (with_edges) {
    C.everts.resize(nint + 2 * static_cast<size_t>(ne));
    C.ecrease.assign(C.everts.size(), 0);
    C.fedges.resize(C.fverts.size());
  }
  for (int e = 0; with_edges && e < ne; ++e) {
    C.everts[nint + 2 * e] = {epoint(e), L.everts[e][0]};
    C.everts[nint + 2 * e + 1] = {epoint(e), L.everts[e][1]};
    C.ecrease[nint + 2 * e] = C.ecrease[nint + 2 * e + 1] = L.ecrease[e];
  }
  auto half = [&](int e, int v) { return nint + 2 * e + (L.everts[e][0] == v ? 0 : 1); };
  int ie = 0, cf = 0, cpos = 0;
  auto push_face = [&](std::initializer_list<int> vs, std::initializer_list<int> es) {
    auto ev = es.begin();
    for (int v : vs) {
      if (with_edges) C.fedges[cpos] = *ev++;
      C.fverts[cpos++] = v;
    }
    C.foff[++cf] = cpos;
  };
  C.foff[0] = 0;
  for (int f = 0; f < nf; ++f) {
    const int b = L.foff[f], s = L.fsize(f);
    const int* fv = &L.fverts[b];
    const int* fe = &L.fedges[b];
    if (s == 3) {
      const int e0 = fe[0], e1 = fe[1], e2 = fe[2];
      const int p0 = epoint(e0), p1 = epoint(e1), p2 = epoint(e2);
      const int i0 = ie, i1 = ie + 1, i2 = ie + 2;
      if (with_edges) {
        C.everts[i0] = {p0, p2};
        C.everts[i1] = {p1, p0};
        C.everts[i2] = {p2, p1};
      }
      ie += 3;
      push_face({fv[0], p0, p2}, {half(e0, fv[0]), i0, half(e2, fv[0])});
      push_face({p0, fv[1], p1}, {half(e0, fv[1]), half(e1, fv[1]), i1});
      push_face({p2, p1, fv[2]}, {i2, half(e1, fv[2]), half(e2, fv[2])});
      push_face({p1, p2, p0}, {i2, i0, i1});
    } else {
      const int fp = fpoint[f], i_first = ie;
      for (int j = 0; j < s; ++j, ++ie)
        if (with_edges) C.everts[ie] = {fp, epoint(fe[j])};
      for (int j = 0; j < s; ++j) {
        const int jp = (j + s - 1) % s;
        const int v = fv[j], en = fe[j], ep = fe[jp];
        std::array<int, 4> vs{v, epoint(en), fp, epoint(ep)};
        std::array<int, 4> es{half(en, v), i_first + j, i_first + jp, half(ep, v)};
        // Quads keep the corner vertex at the parent's corner position; other polygons start there.
        const int rot = s == 4 ? j : 0;
        std::array<int, 4> rv, re;
        for (int k = 0; k < 4; ++k) {
          rv[(k + rot) % 4] = vs[k];
          re[(k + rot) % 4] = es[k];
        }
        push_face({rv[0], rv[1], rv[2], rv[3]}, {re[0], re[1], re[2], re[3]});
      }
    }
  }
  C.vcorner.assign(nchild, 0);
  std::copy(L.vcorner.begin(), L.vcorner.end(), C.vcorner.begin());
  return C;
}

// A * B row by row with a dense accumulator (Gustavson); several times faster here than Eigen's
// generic sparse product, which dominated building the operator.
SparseOperator compose(const SparseOperator& A, const SparseOperator& B) {
  SparseOperator C(A.rows(), B.cols());
  // Reserve the exact nnz before deduplication is too much; half of it (rows of neighbouring
  // stencils overlap heavily) avoids most regrowth copies.
  long long bound = 0;
  for (int r = 0; r < A.rows(); ++r)
    for (SparseOperator::InnerIterator a(A, r); a; ++a) bound += B.outerIndexPtr()[a.col() + 1] - B.outerIndexPtr()[a.col()];
  // High-valence vertices make every nearby refined row carry their whole ring: refuse operators
  // that would not fit in memory rather than over-allocate (subdivide() has no such limit).
  if (bound > kMaxOperatorTerms)
    throw std::invalid_argument("composed subdivision operator would need up to " + std::to_string(bound) +
                                " terms (limit " + std::to_string(kMaxOperatorTerms) +
                                "); use subdivide() or fewer levels");
  C.data().reserve(static_cast<Eigen::Index>(bound / 2 + A.rows()));
  RowBuilder row(static_cast<int>(B.cols()));
  for (int r = 0; r < A.rows(); ++r) {
    for (SparseOperator::InnerIterator a(A, r); a; ++a)
      for (SparseOperator::InnerIterator b(B, a.col()); b; ++b) row.add(static_cast<int>(b.col()), a.value() * b.value());
    row.flush(C, r);
  }
  return C;
}

// A level's tagged crease edges (i < j), in edge order.
std::vector<std::pair<int, int>> level_creases(const Level& L) {
  std::vector<std::pair<int, int>> out;
  for (int e = 0; e < L.ne(); ++e)
    if (L.ecrease[e]) out.emplace_back(std::min(L.everts[e][0], L.everts[e][1]), std::max(L.everts[e][0], L.everts[e][1]));
  return out;
}

// The crease edges of L's child level, in the child's edge order, from L alone: every tagged
// edge's two halves, the edge point with each end (interior edges are never tagged).
std::vector<std::pair<int, int>> child_creases(const Level& L, int nfp) {
  std::vector<std::pair<int, int>> out;
  for (int e = 0; e < L.ne(); ++e)
    if (L.ecrease[e])
      for (int end : L.everts[e]) {
        const int ep = L.nv + nfp + e;
        out.emplace_back(std::min(ep, end), std::max(ep, end));
      }
  return out;
}

Mesh to_mesh(const Level& L, std::vector<std::pair<int, int>> creases, const std::vector<int>& tagged_corners) {
  Mesh m;
  m.faces.resize(L.nf());
  for (int f = 0; f < L.nf(); ++f) m.faces[f].assign(L.fverts.begin() + L.foff[f], L.fverts.begin() + L.foff[f + 1]);
  m.creases = std::move(creases);
  m.corners = tagged_corners;
  return m;
}

}  // namespace

namespace {

// Vertex count after 0..levels steps: V + F' + E per step (F' = non-triangles; all faces become
// quads or triangles after one step). Stops growing past the limit (no overflow).
std::vector<long long> vertex_counts(const Level& L, int levels) {
  long long v = L.nv, e = L.ne(), q = 0, t = 0, c = 0;
  for (int f = 0; f < L.nf(); ++f) (L.fsize(f) == 3 ? t : q)++, c += L.fsize(f);
  std::vector<long long> out{v};
  for (int k = 0; k < levels; ++k) {
    if (v <= kMaxRefinedVertices) {
      const long long corners_nontri = c - 3 * t;
      v = v + q + e;
      e = 2 * e + c;
      t = 4 * t;
      q = corners_nontri;
      c = 3 * t + 4 * q;
    }
    out.push_back(v);
  }
  return out;
}

struct Steps {
  std::vector<SparseOperator> steps;
  Mesh refined;  // topology only
};

// The final level as flat lists (what to_mesh gives, fanned, plus its boundary edges).
void fill_topology(const Level& L, RefinedTopology& t) {
  t.triangles.clear();
  t.creases.clear();
  t.boundary.clear();
  t.triangles.reserve(L.fverts.size() - 2 * static_cast<size_t>(L.nf()));
  for (int f = 0; f < L.nf(); ++f) {
    const int* v = &L.fverts[static_cast<size_t>(L.foff[f])];
    for (int k = 1; k + 1 < L.fsize(f); ++k) t.triangles.push_back({v[0], v[k], v[k + 1]});
  }
  std::vector<int> uses(static_cast<size_t>(L.ne()), 0);
  for (int e : L.fedges) ++uses[static_cast<size_t>(e)];
  for (int e = 0; e < L.ne(); ++e) {
    const auto& ev = L.everts[static_cast<size_t>(e)];
    const std::pair<int, int> edge(std::min(ev[0], ev[1]), std::max(ev[0], ev[1]));
    if (L.ecrease[static_cast<size_t>(e)]) t.creases.push_back(edge);
    if (uses[static_cast<size_t>(e)] == 1) t.boundary.push_back(edge);
  }
}

// With `points`, refines those points level by level instead of building the step matrices.
// With `topology`, the final level goes there instead of into a Mesh.
Steps build_steps(const Mesh& control, int levels, Points* points, RefinedTopology* topology = nullptr) {
  if (levels < 0 || levels > kMaxSubdivisionLevels)
    throw std::invalid_argument("subdivision levels must be in [0, " +
                                std::to_string(kMaxSubdivisionLevels) + "], got " +
                                std::to_string(levels));
  Level L = make_base_level(control);
  // Bound the result before allocating anything.
  if (vertex_counts(L, levels).back() > kMaxRefinedVertices)
    throw std::invalid_argument("subdivision to level " + std::to_string(levels) + " would make " +
                                "more than " + std::to_string(kMaxRefinedVertices) + " vertices");
  {
    Adjacency a = adjacency(L);
    mark_nonmanifold_vertices(L, a);
  }
  std::vector<int> corners = control.corners;
  std::sort(corners.begin(), corners.end());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());

  Steps out;
  if (points) *points = control.points;
  for (int k = 0; k < levels; ++k) {
    const Adjacency a = adjacency(L);
    int nfp = 0;
    const std::vector<int> fpoint = face_point_indices(L, nfp);
    const int nchild = L.nv + nfp + L.ne();
    if (points) {
      Points next;
      PointSink sink(*points, next, nchild);
      emit_rows(L, a, fpoint, sink);
      *points = std::move(next);
    } else {
      out.steps.emplace_back();
      MatrixSink sink(out.steps.back(), nchild, L.nv);
      emit_rows(L, a, fpoint, sink);
    }
    // Decompression's last level: faces only, its creases from the level before.
    if (points && !topology && k + 1 == levels) {
      std::vector<std::pair<int, int>> creases = child_creases(L, nfp);
      L = child_level(L, fpoint, nfp, false);
      out.refined = to_mesh(L, std::move(creases), corners);
      return out;
    }
    L = child_level(L, fpoint, nfp);
  }
  if (topology)
    fill_topology(L, *topology);
  else
    out.refined = to_mesh(L, level_creases(L), corners);
  return out;
}

Points apply_steps(const std::vector<SparseOperator>& steps, const Points& p0) {
  Points p = p0;
  for (const auto& M : steps) p = M * p;
  return p;
}

}  // namespace

namespace {

SparseOperator composed(const std::vector<SparseOperator>& steps, int n) {
  SparseOperator S(n, n);
  S.setIdentity();
  for (size_t k = 0; k < steps.size(); ++k) S = k == 0 ? steps[0] : compose(steps[k], S);
  return S;
}

}  // namespace

SubdivisionOperator build_subdivision(const Mesh& control, int levels) {
  Steps st = build_steps(control, levels, nullptr);
  SubdivisionOperator op;
  op.S = composed(st.steps, control.num_vertices());
  op.refined = std::move(st.refined);
  op.refined.points = apply_steps(st.steps, control.points);
  op.steps = std::move(st.steps);
  return op;
}

SparseOperator subdivision_operator(const Mesh& control, int levels, RefinedTopology& topology) {
  return composed(build_steps(control, levels, nullptr, &topology).steps, control.num_vertices());
}

std::vector<long long> subdivision_vertex_counts(const Mesh& control, int levels) {
  if (levels < 0 || levels > kMaxSubdivisionLevels)
    throw std::invalid_argument("subdivision levels must be in [0, " + std::to_string(kMaxSubdivisionLevels) +
                                "], got " + std::to_string(levels));
  return vertex_counts(make_base_level(control), levels);
}

Points apply_subdivision(const SubdivisionOperator& op, const Points& control_points) {
  if (control_points.rows() != op.S.cols())
    throw std::invalid_argument("apply_subdivision: " + std::to_string(control_points.rows()) +
                                " control points for an operator on " + std::to_string(op.S.cols()));
  return apply_steps(op.steps, control_points);
}

Mesh subdivide(const Mesh& control, int levels) {
  // No composed operator: refining the points level by level is all decompression needs.
  Points points;
  Steps st = build_steps(control, levels, &points);
  st.refined.points = std::move(points);
  return std::move(st.refined);
}

Mesh subdivide_linear(Mesh mesh, int levels) {
  for (int level = 0; level < levels; ++level) {
    // Crease edge points are midpoints, corners stay, a quad's face point is its centre.
    mesh.creases = unique_edges(mesh);
    mesh.corners.resize(static_cast<std::size_t>(mesh.num_vertices()));
    std::iota(mesh.corners.begin(), mesh.corners.end(), 0);
    mesh = subdivide(mesh, 1);
  }
  mesh.creases.clear();
  mesh.corners.clear();
  return mesh;
}

}  // namespace mm
