#include "fitting/fit_control_points.h"

#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>

#include "fitting/fit_normal_equations.h"
#include "geometry/closest_point_bvh.h"
#include "subdivision/subdivide.h"

namespace mm {

using namespace fitting_detail;

namespace {

// Deterministic uniform double in [0, 1) independent of the standard library's distributions.
double uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

double diagonal_of(const Points& p) {
  if (p.rows() == 0) return 0;
  return (p.colwise().maxCoeff() - p.colwise().minCoeff()).norm();
}

// Crease samples along a sharp edge are at least the diagonal / kCreaseSpacing apart: a crease
// tessellated finer is fitted no better for more samples, which would weigh its creases over its
// surfaces and dominate the fit's queries on finely tessellated parts.
constexpr double kCreaseSpacing = 600;

// Target samples: every vertex, area-weighted random points on faces, and points along the
// sharp edges (those are matched against the subdivided creases).
struct TargetSamples {
  std::vector<Eigen::Vector3d> surface, crease;
};

TargetSamples sample_target(const Mesh& target, const std::vector<std::array<int, 3>>& tris,
                            const Features& features, const FitOptions& o) {
  TargetSamples s;
  for (int v = 0; v < target.num_vertices(); ++v) s.surface.push_back(target.points.row(v));
  std::vector<double> cumulative;
  double total = 0;
  for (const auto& t : tris) {
    Eigen::Vector3d a = target.points.row(t[0]), b = target.points.row(t[1]), c = target.points.row(t[2]);
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative.push_back(total);
  }
  std::mt19937_64 rng(o.seed);
  if (total > 0)
    for (int k = 0; k < o.area_samples; ++k) {
      double r = uniform(rng) * total;
      size_t t = std::min(cumulative.size() - 1,
                          static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), r) -
                                              cumulative.begin()));
      double u = uniform(rng), v = uniform(rng);
      if (u + v > 1) u = 1 - u, v = 1 - v;
      const auto& f = tris[t];
      Eigen::Vector3d a = target.points.row(f[0]), b = target.points.row(f[1]), c = target.points.row(f[2]);
      s.surface.push_back(a + u * (b - a) + v * (c - a));
    }
  // Crease samples: the crease vertices, and evenly spaced interior points on each sharp edge,
  // three or one per kCreaseSpacing of its length if fewer.
  const double spacing = diagonal_of(target.points) / kCreaseSpacing;
  std::set<int> crease_vertices;
  for (auto [a, b] : features.sharp_edges) {
    crease_vertices.insert(a);
    crease_vertices.insert(b);
    Eigen::Vector3d pa = target.points.row(a), pb = target.points.row(b);
    const double spacings = (pb - pa).norm() / spacing;
    const int interior = spacings >= 3 ? 3 : static_cast<int>(spacings);
    for (int j = 1; j <= interior; ++j) {
      const double t = static_cast<double>(j) / (interior + 1);
      s.crease.push_back((1 - t) * pa + t * pb);
    }
  }
  for (int v : crease_vertices) s.crease.push_back(target.points.row(v));
  return s;
}

// Edges used by one face only (the open boundary), each as (min, max), sorted.
std::vector<std::pair<int, int>> boundary_edges(const Mesh& m) {
  std::vector<std::pair<int, int>> edges;
  for (const auto& f : m.faces)
    for (size_t k = 0; k < f.size(); ++k) {
      int a = f[k], b = f[(k + 1) % f.size()];
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  std::vector<std::pair<int, int>> out;
  for (size_t k = 0; k < edges.size();) {
    size_t j = k;
    while (j < edges.size() && edges[j] == edges[k]) ++j;
    if (j - k == 1) out.push_back(edges[k]);
    k = j;
  }
  return out;
}

// Edges of the refined mesh that act as creases: tagged creases plus open boundary edges.
// `closed`: the caller knows the mesh has no boundary edge (subdivision of a control mesh
// without one adds none), which spares sorting all of its edges.
std::vector<std::pair<int, int>> crease_edges(const Mesh& m, bool closed = false) {
  std::vector<std::pair<int, int>> out(m.creases.begin(), m.creases.end());
  if (!closed) {
    const auto boundary = boundary_edges(m);
    out.insert(out.end(), boundary.begin(), boundary.end());
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// Umbrella Laplacian of the control mesh; crease vertices only see their crease neighbours
// (their limit curve depends on those alone) and corners are left free.
SpMat umbrella(const Mesh& control, const std::vector<std::pair<int, int>>& creases) {
  const int n = control.num_vertices();
  std::vector<std::set<int>> all(n), crease(n);
  for (auto [a, b] : unique_edges(control)) {
    all[a].insert(b);
    all[b].insert(a);
  }
  for (auto [a, b] : creases) {
    crease[a].insert(b);
    crease[b].insert(a);
  }
  std::vector<char> corner(n, 0);
  for (int c : control.corners) corner[c] = 1;
  std::vector<Trip> t;
  for (int v = 0; v < n; ++v) {
    if (corner[v]) continue;
    const auto& nb = crease[v].empty() ? all[v] : crease[v];
    if (nb.empty()) continue;
    t.emplace_back(v, v, 1.0);
    for (int w : nb) t.emplace_back(v, w, -1.0 / static_cast<double>(nb.size()));
  }
  SpMat L(n, n);
  L.setFromTriplets(t.begin(), t.end());
  return L;
}


// The reweighting's largest extra weight (FitOptions::reweight): a wrong correspondence far
// off (across a thin wall) must not outweigh its neighbours. Uncapped, one fit of the same
// control mesh came out with a larger Hausdorff distance than plain least squares in 5 of 24
// cases (parts x vertex counts, Fit.ReweightingLowersTheLargestDistance's), up to 2.2x (rocker,
// 400 vertices); capped at 10, in 2 of 24 (rocker at 400 by 1.16x, abc8 at 60 by 1.03x), and
// 0.89x in geometric mean (uncapped 0.99x; caps of 3, 5 and 20 gave 0.94x, 0.92x and 0.90x).
constexpr double kMaxReweight = 10.0;

struct Correspondences {
  RefinedNormalEquations* normal = nullptr;  // accumulated when given (not for measurements)
  double weight_sum = 0;
  std::vector<double> surface_dist;    // for statistics (surface terms only)
  std::vector<int> blame;              // per row: refined vertex mostly responsible
  int rows = 0;
  double reweight = 0;        // FitOptions::reweight over the last iteration's rms squared (0: off)
  // `slot`: index of the triangle, crease edge or vertex in the normal equations' slot tables.
  template <size_t N>
  void add(const std::array<std::pair<int, double>, N>& terms, int slot, const Eigen::Vector3d& p, double w,
           double dist, bool stat) {
    if (reweight > 0) w *= 1 + std::min(reweight * dist * dist, kMaxReweight);
    int best = -1;
    double bw = -1;
    for (auto [v, c] : terms) {
      if (c == 0) continue;
      if (c > bw) bw = c, best = v;
    }
    if (normal) {
      if constexpr (N == 3) normal->add(terms, normal->tri_slots[static_cast<size_t>(slot)], p, w);
      if constexpr (N == 2) normal->add(terms, normal->segment_slots[static_cast<size_t>(slot)], p, w);
      if constexpr (N == 1) normal->add(terms, normal->vertex_slots[static_cast<size_t>(slot)], p, w);
    }
    weight_sum += w;
    blame.push_back(best);
    if (stat) surface_dist.push_back(dist);
    ++rows;
  }
};

// Previous answers, used as hints for the next round's queries (positions move little).
struct Hints {
  std::vector<TriangleHit> on_surface;  // per target surface sample: hit on the refined surface
  std::vector<TriangleHit> on_target;   // per refined vertex: hit on the target
  std::vector<SegmentHit> on_target_crease;  // per refined vertex: hit on the target's sharp edges
  std::vector<SegmentHit> on_crease;    // per target crease sample: hit on the refined creases
};

// The order to make `count` queries in: by where their hints' triangles sit in the tree's leaf
// order, so consecutive queries read the nodes and triangles the one before left in cache (7.5 %
// less fit time over the bench parts); queries without a hint last, in index order. Each
// query's answer depends only on its point and hint, so the order changes no answer.
std::vector<int> query_order(const std::vector<TriangleHit>* hints, size_t count, const TriangleBvh& tree) {
  std::vector<int> order(count);
  if (!hints || hints->size() != count) {
    std::iota(order.begin(), order.end(), 0);
    return order;
  }
  const int positions = tree.size();
  std::vector<int> start(static_cast<size_t>(positions) + 2, 0);  // counting sort; slot `positions`: no hint
  const auto key = [&](size_t k) {
    const int t = (*hints)[k].triangle;
    return t >= 0 && t < positions ? tree.leaf_position(t) : positions;
  };
  for (size_t k = 0; k < count; ++k) ++start[static_cast<size_t>(key(k)) + 1];
  for (size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  for (size_t k = 0; k < count; ++k) order[static_cast<size_t>(start[static_cast<size_t>(key(k))]++)] = static_cast<int>(k);
  return order;
}

// The closest points on `tree` of `count` queries (point(k): the k-th query's point), each from
// its hint when given, made in query_order and returned in index order.
template <class Point>
std::vector<TriangleHit> closest_hits(const TriangleBvh& tree, size_t count, Point point,
                                      const std::vector<TriangleHit>* hints) {
  std::vector<TriangleHit> hits(count);
  for (const int k : query_order(hints, count, tree))
    hits[static_cast<size_t>(k)] = tree.closest(point(k), hints ? (*hints)[static_cast<size_t>(k)].triangle : -1);
  return hits;
}

Correspondences correspond(const Points& R, const TriangleBvh& surf, const SegmentBvh& crease,
                           const std::vector<std::pair<int, int>>& refined_creases,
                           const TargetSamples& samples, const TriangleBvh& target_tris,
                           const SegmentBvh& target_creases, const FitOptions& o,
                           bool with_creases, Hints* hints, RefinedNormalEquations* normal,
                           double reweight = 0) {
  Correspondences c;
  c.normal = normal;
  c.reweight = reweight;
  if (normal) normal->clear();
  if (hints) {
    hints->on_surface.resize(samples.surface.size());
    hints->on_target.resize(static_cast<size_t>(R.rows()));
  }
  if (hints) {
    hints->on_target_crease.resize(static_cast<size_t>(R.rows()));
    hints->on_crease.resize(samples.crease.size());
  }
  std::vector<char> on_crease(R.rows(), 0);
  for (auto [a, b] : refined_creases) on_crease[a] = on_crease[b] = 1;
  if (!surf.empty()) {
    std::vector<TriangleHit> on_surface =
        closest_hits(surf, samples.surface.size(), [&](int k) { return samples.surface[static_cast<size_t>(k)]; },
                     hints ? &hints->on_surface : nullptr);
    for (size_t k = 0; k < samples.surface.size(); ++k) {
      const auto& p = samples.surface[k];
      const TriangleHit& h = on_surface[k];
      const auto& t = surf.triangle(h.triangle);
      c.add(std::array<std::pair<int, double>, 3>{{{t[0], h.barycentric[0]}, {t[1], h.barycentric[1]}, {t[2], h.barycentric[2]}}},
            h.triangle, p, 1.0, h.distance, true);
    }
    if (hints) hints->on_surface = std::move(on_surface);
  }
  if (!target_tris.empty()) {
    std::vector<TriangleHit> on_target =
        closest_hits(target_tris, static_cast<size_t>(R.rows()), [&](int v) { return Eigen::Vector3d(R.row(v).transpose()); },
                     hints ? &hints->on_target : nullptr);
    for (Eigen::Index v = 0; v < R.rows(); ++v) {
      if (with_creases && on_crease[v] && !target_creases.empty()) {
        const SegmentHit h =
            target_creases.closest(R.row(v).transpose(), hints ? hints->on_target_crease[v].segment : -1);
        if (hints) hints->on_target_crease[v] = h;
        c.add(std::array<std::pair<int, double>, 1>{{{static_cast<int>(v), 1.0}}}, static_cast<int>(v), h.point, o.crease_weight,
              h.distance, false);
      }
      const TriangleHit& h = on_target[static_cast<size_t>(v)];
      c.add(std::array<std::pair<int, double>, 1>{{{static_cast<int>(v), 1.0}}}, static_cast<int>(v), h.point, 1.0,
            h.distance, true);
    }
    if (hints) hints->on_target = std::move(on_target);
  }
  if (with_creases && !crease.empty())
    for (size_t k = 0; k < samples.crease.size(); ++k) {
      const auto& p = samples.crease[k];
      const SegmentHit h = crease.closest(p, hints ? hints->on_crease[k].segment : -1);
      if (hints) hints->on_crease[k] = h;
      auto [a, b] = crease.segment(h.segment);
      c.add(std::array<std::pair<int, double>, 2>{{{a, 1 - h.t}, {b, h.t}}}, h.segment, p, o.crease_weight,
            h.distance, false);
    }
  return c;
}

FitStats stats_of(const std::vector<double>& d, double diagonal) {
  FitStats s;
  s.diagonal = diagonal;
  double sum = 0, sum2 = 0;
  for (double x : d) {
    s.hausdorff = std::max(s.hausdorff, x);
    sum += x;
    sum2 += x * x;
  }
  if (!d.empty()) {
    s.mean = sum / static_cast<double>(d.size());
    s.rms = std::sqrt(sum2 / static_cast<double>(d.size()));
  }
  return s;
}

}  // namespace

struct FitTarget::Impl {
  Impl(const Mesh& target, const Features& features, const FitOptions& o)
      : tris_list(triangle_list(target)),
        tris(target.points, tris_list),
        creases(target.points, features.sharp_edges),
        samples(sample_target(target, tris_list, features, o)),
        iteration_samples(samples),
        vertices(target.num_vertices()),
        diagonal(diagonal_of(target.points)),
        options(o) {
    // The iterations see a capped, evenly strided subset of the target's vertices.
    if (vertices > o.max_vertex_samples) {
      iteration_samples.surface.clear();
      for (long long k = 0; k < o.max_vertex_samples; ++k)
        iteration_samples.surface.push_back(samples.surface[static_cast<size_t>(k * vertices / o.max_vertex_samples)]);
      iteration_samples.surface.insert(iteration_samples.surface.end(), samples.surface.begin() + vertices,
                                       samples.surface.end());
    }
  }
  std::vector<std::array<int, 3>> tris_list;
  TriangleBvh tris;
  SegmentBvh creases;
  TargetSamples samples, iteration_samples;
  int vertices;
  double diagonal;
  FitOptions options;  // those the samples were drawn with
};

FitTarget::FitTarget(const Mesh& target, const Features& features, const FitOptions& options)
    : impl_(std::make_unique<Impl>(target, features, options)) {}
FitTarget::~FitTarget() = default;
double FitTarget::diagonal() const { return impl_->diagonal; }

FitResult fit_control_points(const Mesh& control, const Mesh& target, const Features& features,
                             const FitOptions& o) {
  return fit_control_points(control, FitTarget(target, features, o), o);
}

FitResult fit_control_points(const Mesh& control, const FitTarget& prepared, const FitOptions& o) {
  if (control.num_vertices() == 0 || control.faces.empty())
    throw std::invalid_argument("control mesh is empty");
  const FitTarget::Impl& tg = *prepared.impl_;
  if (tg.options.seed != o.seed || tg.options.area_samples != o.area_samples ||
      tg.options.max_vertex_samples != o.max_vertex_samples)
    throw std::invalid_argument("fit target was prepared with other sampling options");
  // S and the refined topology as flat lists (the refined points are R below).
  RefinedTopology refined;
  const SpMat S = subdivision_operator(control, o.levels, refined);
  // Tagged creases and, on an open control mesh, the refined boundary (crease_edges()).
  std::vector<std::pair<int, int>> refined_creases = std::move(refined.creases);
  if (!boundary_edges(control).empty())
    refined_creases.insert(refined_creases.end(), refined.boundary.begin(), refined.boundary.end());
  std::sort(refined_creases.begin(), refined_creases.end());
  refined_creases.erase(std::unique(refined_creases.begin(), refined_creases.end()), refined_creases.end());
  const std::vector<std::array<int, 3>> refined_tris = std::move(refined.triangles);
  const TriangleBvh& target_tris = tg.tris;
  // The refined surface keeps its triangles while it moves: one tree per fit, refitted.
  const Points R0 = times3(S, control.points);
  TriangleBvh surf(R0, refined_tris);
  SegmentBvh crease(R0, refined_creases);
  const SegmentBvh& target_creases = tg.creases;
  const TargetSamples& samples = tg.samples;
  const TargetSamples& iteration_samples = tg.iteration_samples;
  Hints hints;
  const bool with_creases = !target_creases.empty();

  std::set<std::pair<int, int>> control_creases(control.creases.begin(), control.creases.end());
  for (const auto& e : crease_edges(control)) control_creases.insert(e);
  const SpMat L = umbrella(control, {control_creases.begin(), control_creases.end()});
  const SpMat LtL = SpMat(Eigen::SparseMatrix<double>(L.transpose()) * Eigen::SparseMatrix<double>(L));

  const int n = control.num_vertices();
  const SpMat St = S.transpose();
  RefinedNormalEquations normal(static_cast<int>(S.rows()), refined_tris, refined_creases);
  // The solver reads the upper triangle of the row-major M = S^T G S (its arrays are handed
  // over as the column-major lower triangle, below): row i from column i on, which needs row r
  // of G S only from the first control vertex in S's row r on.
  std::vector<int> diagonal_on(static_cast<size_t>(n)), support_on(static_cast<size_t>(S.rows()));
  for (int i = 0; i < n; ++i) diagonal_on[static_cast<size_t>(i)] = i;
  for (Eigen::Index r = 0; r < S.rows(); ++r)
    support_on[static_cast<size_t>(r)] = S.outerIndexPtr()[r] < S.outerIndexPtr()[r + 1]
                                             ? S.innerIndexPtr()[S.outerIndexPtr()[r]]
                                             : n;
  FixedPatternProduct GS(normal.G, S, std::move(support_on)), StGS(St, GS.C, std::move(diagonal_on));
  RegularisedSystem system(StGS.C, LtL);
  Eigen::MatrixXd X = control.points;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  std::vector<int> analyzed_outer, analyzed_inner;  // the pattern the solver was analysed for
  double reweight = 0;  // none in the first iteration: no distances yet to scale by
  for (int it = 0; it < o.iterations; ++it) {
    Points R = it == 0 ? R0 : times3(S, X);  // X is still control.points in the first
    if (it > 0) {
      surf.refit(R);
      crease.refit(R);
    }
    auto c = correspond(R, surf, crease, refined_creases, iteration_samples, target_tris,
                        target_creases, o, with_creases, &hints, &normal, reweight);
    const double rms = stats_of(c.surface_dist, 1).rms;
    reweight = rms > 0 ? o.reweight / (rms * rms) : 0;
    const double scale = c.weight_sum / n;  // data weight per control vertex
    // A tiny pull towards the current positions (1e-6 I) keeps vertices without data well-posed.
    const SpMat& M = system(StGS(St, GS.consume(normal.G, S)), LtL, o.smoothness * scale, 1e-6 * scale);
    Eigen::MatrixXd rhs = times3(St, normal.Y) + (1e-6 * scale) * X;
    // M's row-major arrays read as column-major are its transpose, whose lower triangle (all
    // the solver reads) is M's upper triangle, all that was computed of S^T G S.
    const Eigen::Map<const Eigen::SparseMatrix<double>> Mc(n, n, M.nonZeros(), M.outerIndexPtr(),
                                                           M.innerIndexPtr(), M.valuePtr());
    // M's pattern is the same in every iteration of a fit: its fill-reducing ordering and
    // symbolic factorisation are computed once (compute() would redo both each time; the
    // numeric factorisation is the same either way).
    if (analyzed_outer.size() != static_cast<size_t>(n) + 1 || analyzed_inner.size() != static_cast<size_t>(M.nonZeros()) ||
        !std::equal(analyzed_outer.begin(), analyzed_outer.end(), M.outerIndexPtr()) ||
        !std::equal(analyzed_inner.begin(), analyzed_inner.end(), M.innerIndexPtr())) {
      solver.analyzePattern(Mc);
      analyzed_outer.assign(M.outerIndexPtr(), M.outerIndexPtr() + n + 1);
      analyzed_inner.assign(M.innerIndexPtr(), M.innerIndexPtr() + M.nonZeros());
    }
    solver.factorize(Mc);
    if (solver.info() != Eigen::Success) throw std::runtime_error("fitting system is singular");
    Eigen::MatrixXd Xn = solver.solve(rhs);
    if (!Xn.allFinite()) throw std::runtime_error("fitting produced non-finite positions");
    X = Xn;
  }

  FitResult out;
  out.control = control;
  out.control.points = X;
  Points R = times3(S, X);
  // The last iteration's answers start the final queries. Target vertices left out of the
  // strided subset get none: a neighbour in index order may lie far away on the part, and a far
  // hint costs more than the kd-tree's.
  Hints final_hints;
  if (!hints.on_surface.empty()) {
    const long long nt = tg.vertices;
    const long long iter_vertices =
        static_cast<long long>(iteration_samples.surface.size() - (samples.surface.size() - tg.vertices));
    final_hints.on_surface.resize(samples.surface.size());
    for (long long k = 0; k < iter_vertices; ++k)
      final_hints.on_surface[static_cast<size_t>(k * nt / iter_vertices)] = hints.on_surface[static_cast<size_t>(k)];
    std::copy(hints.on_surface.begin() + iter_vertices, hints.on_surface.end(),
              final_hints.on_surface.begin() + tg.vertices);
  }
  final_hints.on_target = std::move(hints.on_target);
  surf.refit(R);
  crease.refit(R);
  auto c = correspond(R, surf, crease, refined_creases, samples, target_tris,
                      target_creases, o, false, &final_hints, nullptr);
  // The first rows are the target vertices (sample_target puts them first).
  if (c.surface_dist.size() >= static_cast<size_t>(tg.vertices))
    out.target_error.assign(c.surface_dist.begin(), c.surface_dist.begin() + tg.vertices);
  // The surface's overshoot is measured from refined vertices, not target vertices: charge each
  // such distance to the three vertices of the target triangle it was measured to, so a caller
  // refining where the error is sees both directions.
  out.region_error = out.target_error;
  const size_t first_refined = samples.surface.size();
  if (!out.region_error.empty() && c.surface_dist.size() >= first_refined + static_cast<size_t>(R.rows()))
    for (Eigen::Index v = 0; v < R.rows(); ++v) {
      const int t = final_hints.on_target[static_cast<size_t>(v)].triangle;
      if (t < 0) continue;
      const double d = c.surface_dist[first_refined + static_cast<size_t>(v)];
      for (int i : tg.tris_list[static_cast<size_t>(t)]) out.region_error[i] = std::max(out.region_error[i], d);
    }
  // Inside the refined triangles too: one whose corners lie on the part may cut across a notch of
  // the face it lies on (fandisk at 0.1 %: corners on a plane, its middle 0.26 % off the part),
  // which no vertex distance shows. Its centroid is measured and charged like the vertices, so
  // the next round refines there (steering only: the stats stay the vertices', as measured).
  if (o.face_interiors && !out.region_error.empty()) {
    int hint = -1;
    for (const auto& f : refined_tris) {
      const Eigen::Vector3d centroid = (R.row(f[0]) + R.row(f[1]) + R.row(f[2])).transpose() / 3.0;
      const TriangleHit h = target_tris.closest(centroid, hint);
      if (h.triangle < 0) continue;
      hint = h.triangle;
      for (int i : tg.tris_list[static_cast<size_t>(h.triangle)])
        out.region_error[i] = std::max(out.region_error[i], h.distance);
    }
  }
  out.stats = stats_of(c.surface_dist, tg.diagonal);
  // Blame each distance on the control vertex with the largest weight in the refined vertex's row.
  out.vertex_error.assign(n, 0.0);
  std::vector<int> owner(S.rows(), -1);
  for (int r = 0; r < S.rows(); ++r) {
    double best = -1;
    for (SpMat::InnerIterator itr(S, r); itr; ++itr)
      if (itr.value() > best) best = itr.value(), owner[r] = static_cast<int>(itr.col());
  }
  for (int r = 0; r < c.rows; ++r)
    if (c.blame[r] >= 0 && owner[c.blame[r]] >= 0) {
      double& e = out.vertex_error[owner[c.blame[r]]];
      e = std::max(e, c.surface_dist[r]);
    }
  return out;
}

std::string fit_sampling_key() {
  return ";crease-spacing=1/" + std::to_string(static_cast<int>(kCreaseSpacing)) + ";steer=face-centroids";
}

FitStats measure_fit(const Mesh& control, int levels, const Mesh& target) {
  const auto op = build_subdivision(control, levels);
  Points R = op.S * control.points;
  const auto tris = triangle_list(target);
  const TriangleBvh target_tris(target.points, tris);
  const TriangleBvh surf(R, triangle_list(op.refined));
  const SegmentBvh none(target.points, {});
  const SegmentBvh no_creases(R, {});
  FitOptions o;
  Features no_features;
  auto samples = sample_target(target, tris, no_features, o);
  auto c = correspond(R, surf, no_creases, {}, samples, target_tris, none, o, false, nullptr, nullptr);
  return stats_of(c.surface_dist, diagonal_of(target.points));
}

}  // namespace mm
