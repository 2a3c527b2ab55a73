#include "registration/resynchronize.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <optional>
#include <array>
#include <cmath>
#include <atomic>
#include <mutex>
#include <random>
#include <stdexcept>

#include "geometry/closest_point.h"
#include "geometry/nearest_neighbours.h"

#include "registration/resync_context_impl.h"
#include "registration/smoothing_model.h"

namespace mm {

using namespace registration_detail;

namespace {

// Every suspect face lies within one refined face (equal, or a triangle of a split quad), and
// every refined face is covered: the same surface with the same vertex numbering.
bool faces_consistent(const LevelData& level, const Mesh& suspect) {
  std::vector<char> covered(level.op.refined.faces.size(), 0);
  for (const auto& f : suspect.faces) {
    bool found = false;
    for (int k = level.face_offsets[f[0]]; k < level.face_offsets[f[0] + 1] && !found; ++k) {
      const int rf = level.face_list[k];
      const auto& r = level.op.refined.faces[rf];
      if (r.size() < f.size()) continue;
      bool all = true;
      for (int v : f) all = all && std::find(r.begin(), r.end(), v) != r.end();
      if (all) found = true, covered[rf] = 1;
    }
    if (!found) return false;
  }
  return std::all_of(covered.begin(), covered.end(), [](char c) { return c != 0; });
}

// Least-squares control points from refined positions p (rows matched to refined vertices).
Points solve_level(const LevelData& level, int l, const Points& p) {
  if (l == 0) return p;
  const Eigen::MatrixXd rhs = SpMat(level.op.S.transpose()) * p;
  Points x = level.normal.solve(rhs);
  return x;
}

// The re-subdivided hypothesis: min |T x - p| with T = smooth_step * S_{L-1}.
Points solve_smooth(const LevelData& below, const LevelData& level, int l, const Points& p) {
  const Eigen::MatrixXd Utp = SpMat(level.smooth_step.transpose()) * p;
  const Eigen::MatrixXd rhs = l == 1 ? Utp : Eigen::MatrixXd(SpMat(below.op.S.transpose()) * Utp);
  Points x = level.smooth_normal.solve(rhs);
  return x;
}

Points apply_smooth(const LevelData& below, const LevelData& level, int l, const Points& x) {
  const Points coarse = l == 1 ? x : apply_subdivision(below.op, x);
  Points out = level.smooth_step * coarse;
  return out;
}

// Which operator explains the suspect's refined vertices: the original's S_L, or (resubdivided)
// T = smooth_step * S_{L-1}.
struct Hypothesis {
  const LevelData* level;
  const LevelData* below;  // level L-1 (resubdivided only)
  int l;
  bool resubdivided;

  Points apply(const Points& x) const {
    if (l == 0) return x;
    return resubdivided ? apply_smooth(*below, *level, l, x) : apply_subdivision(level->op, x);
  }
  Points solve(const Points& p) const {
    return resubdivided ? solve_smooth(*below, *level, l, p) : solve_level(*level, l, p);
  }
  // The operator's rows `rows` (refined vertices) as a matrix over the control points.
  SpMat rows_of(const std::vector<int>& rows) const {
    const SparseOperator& R = resubdivided ? level->smooth_step : level->op.S;
    std::vector<Trip> t;
    for (size_t r = 0; r < rows.size(); ++r)
      for (SparseOperator::InnerIterator it(R, rows[r]); it; ++it)
        t.emplace_back(static_cast<int>(r), static_cast<int>(it.col()), it.value());
    SpMat A(static_cast<Eigen::Index>(rows.size()), R.cols());
    A.setFromTriplets(t.begin(), t.end());
    if (!resubdivided || l == 1) return A;
    return A * SpMat(below->op.S);
  }
};

// The least squares for a subset of refined rows (order-free matching that missed some vertices).
Points solve_rows(const SpMat& A, const Points& p, const Points& prior) {
  SpMat M = SpMat(A.transpose()) * A;
  // A vanishing pull towards the original keeps control points without matched rows defined.
  const double eps = 1e-9 * std::max(1.0, M.diagonal().mean());
  SpMat I(M.rows(), M.cols());
  I.setIdentity();
  M += eps * I;
  Eigen::SimplicialLDLT<SpMat> solver(M);
  if (solver.info() != Eigen::Success) throw std::runtime_error("resync: matched normal equations are singular");
  const Eigen::MatrixXd rhs = SpMat(A.transpose()) * p + eps * prior;
  return solver.solve(rhs);
}

double rms_rows(const Points& a, const Points& b) {
  if (a.rows() == 0) return 0;
  return std::sqrt((a - b).rowwise().squaredNorm().mean());
}

struct Matching {
  Similarity transform;
  std::vector<int> suspect_of;  // per refined vertex: matched suspect vertex or -1
  int matched = 0;
};

// Mutual nearest neighbours between the aligned suspect vertices and `target` (the refined
// vertices, original or estimated), indexed by `target_tree`.
// `cur`: the suspect's vertices under m->transform, indexed by `cur_tree` (a caller pairing
// them with several targets builds it once).
void mutual_pairs(const Points& target, const PointTree& target_tree, const Points& cur, const PointTree& cur_tree,
                  Matching* m) {
  const int nr = static_cast<int>(target.rows());
  m->suspect_of.assign(static_cast<size_t>(nr), -1);
  m->matched = 0;
  for (int j = 0; j < nr; ++j) {
    const int i = cur_tree.nearest(target.row(j).transpose());
    if (i >= 0 && target_tree.nearest(cur.row(i).transpose()) == j) {
      m->suspect_of[j] = i;
      ++m->matched;
    }
  }
}
void mutual_pairs(const Points& target, const PointTree& target_tree, const Points& suspect, Matching* m) {
  const Points cur = m->transform.apply(suspect);
  mutual_pairs(target, target_tree, cur, PointTree(cur), m);
}

// Vertex neighbours along face sides, ascending (compressed rows): unique_edges is sorted, so
// each vertex receives its smaller neighbours first, then its larger ones, each in order.
struct Adjacency {
  std::vector<int> offsets, list;
  explicit Adjacency(const Mesh& mesh) : offsets(static_cast<std::size_t>(mesh.num_vertices()) + 1, 0) {
    const auto edges = unique_edges(mesh);
    for (const auto& [a, b] : edges) ++offsets[static_cast<std::size_t>(a) + 1], ++offsets[static_cast<std::size_t>(b) + 1];
    for (std::size_t v = 1; v < offsets.size(); ++v) offsets[v] += offsets[v - 1];
    list.resize(static_cast<std::size_t>(offsets.back()));
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (const auto& [a, b] : edges) list[static_cast<std::size_t>(fill[a]++)] = b, list[static_cast<std::size_t>(fill[b]++)] = a;
  }
};

// A renumbered copy's connectivity and that of the level it has as many vertices as: pairs then
// also grow along the edges (grow_pairs).
struct EdgesOfBoth {
  const Adjacency& refined;
  const Adjacency& suspect;
};

// A renumbered copy (a welded STL of a decoded file) keeps the refined mesh's connectivity. The
// pairs `seeds` (refined rows the estimate explains to float precision) are kept, and pairs grow
// from them along the edges: an unpaired neighbour of a paired refined vertex takes, of its partner's unpaired
// neighbours, the one nearest its estimate; what the growth does not reach keeps its mutual pair
// when that suspect vertex is still free. Mutual nearest neighbours alone swap neighbours where
// the mark moves vertices by a fair part of their spacing; the solve leaves those pairs out
// (pairs_in_line), and control points left with no pair stay at the original's positions, so
// their vertices were paired the same way again round after round (blade's issued STL copies: 0
// of 6 paired exactly, correlation down to 0.27, one of six not attributed; docs/registration.md).
void grow_pairs(const Adjacency& refined, const Adjacency& suspect, const Points& estimate, const Points& cur,
                const std::vector<int>& seeds, Matching* m) {
  const int nr = static_cast<int>(estimate.rows());
  std::vector<int> of(static_cast<std::size_t>(nr), -1), queue;
  std::vector<char> taken(static_cast<std::size_t>(cur.rows()), 0);
  queue.reserve(static_cast<std::size_t>(nr));
  for (int j : seeds) {
    const int i = m->suspect_of[static_cast<std::size_t>(j)];
    of[static_cast<std::size_t>(j)] = i;
    taken[static_cast<std::size_t>(i)] = 1;
    queue.push_back(j);
  }
  for (std::size_t q = 0; q < queue.size(); ++q) {
    const int j = queue[q], i = of[static_cast<std::size_t>(j)];
    for (int a = refined.offsets[static_cast<std::size_t>(j)]; a < refined.offsets[static_cast<std::size_t>(j) + 1]; ++a) {
      const int j2 = refined.list[static_cast<std::size_t>(a)];
      if (of[static_cast<std::size_t>(j2)] >= 0) continue;
      int best = -1;
      double best2 = std::numeric_limits<double>::infinity();
      for (int b = suspect.offsets[static_cast<std::size_t>(i)]; b < suspect.offsets[static_cast<std::size_t>(i) + 1]; ++b) {
        const int i2 = suspect.list[static_cast<std::size_t>(b)];
        if (taken[static_cast<std::size_t>(i2)]) continue;
        const double d2 = (estimate.row(j2) - cur.row(i2)).squaredNorm();
        if (d2 < best2) best2 = d2, best = i2;
      }
      if (best < 0) continue;
      of[static_cast<std::size_t>(j2)] = best;
      taken[static_cast<std::size_t>(best)] = 1;
      queue.push_back(j2);
    }
  }
  for (int j = 0; j < nr; ++j) {
    const int i = m->suspect_of[static_cast<std::size_t>(j)];
    if (of[static_cast<std::size_t>(j)] < 0 && i >= 0 && !taken[static_cast<std::size_t>(i)])
      of[static_cast<std::size_t>(j)] = i, taken[static_cast<std::size_t>(i)] = 1;
  }
  m->suspect_of = std::move(of);
  m->matched = static_cast<int>(std::count_if(m->suspect_of.begin(), m->suspect_of.end(), [](int i) { return i >= 0; }));
}

// The turn search: suspect vertices it scores turns on, local minima it refines, ICP rounds each.
constexpr int kTurnSamples = 1000;
constexpr std::size_t kTurnMinima = 16;
constexpr int kTurnIcpRounds = 20;
// A trimmed RMS this small, relative to the original's diagonal, is an exact pose.
constexpr double kTurnExact = 1e-12;

// A part that is round about an axis fixes a turn about it only up to its symmetry, so the
// closest-point alignment of a turned copy may settle anywhere along that turn with every vertex
// beside its own (abc6 turned 30 degrees: the alignment ended about 180 degrees off, 76 % of the
// vertices paired, surface fit, p 0.1). Turns about the axis of the original's most distinct
// principal moment, through its centroid, every degree: the local minima of the sample's
// distance to the nearest original vertex (icp_similarity's trimmed RMS, no round; abc6 has one
// every 60 degrees or so, and the right one was not the lowest) are each refined by
// nearest-vertex ICP (`nearest_vertex`), and the pose that ends nearest is returned (after
// `aligned`). A copy of the original's own vertices converges to 0 from near its pose.
Similarity turn_search(const LevelData& level, const Points& suspect, const Similarity& aligned,
                       const ClosestPoint& nearest_vertex, const IcpOptions& icp) {
  const Points& t = level.points;
  const Eigen::RowVector3d centre = t.colwise().mean();
  const Points centred = t.rowwise() - centre;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(centred.transpose() * centred);
  const Eigen::Vector3d lambda = pca.eigenvalues();  // ascending
  const Eigen::Vector3d axis = pca.eigenvectors().col(lambda(1) - lambda(0) > lambda(2) - lambda(1) ? 0 : 2);
  const Points sample = strided(suspect, kTurnSamples), none(0, 3);
  const auto turned = [&](int degrees) {
    Similarity r;
    r.rotation = Eigen::AngleAxisd(degrees * M_PI / 180, axis).toRotationMatrix();
    r.translation = centre - centre * r.rotation.transpose();
    return r.after(aligned);
  };
  const auto icp_from = [&](const Similarity& start, int rounds) {
    return icp_similarity(sample, nearest_vertex, none, start, icp, rounds);
  };
  std::vector<double> d(360);
  for (int k = 0; k < 360; ++k) d[static_cast<size_t>(k)] = icp_from(turned(k), 0).rms;
  std::vector<int> minima;
  for (int k = 0; k < 360; ++k)
    if (d[static_cast<size_t>(k)] < d[static_cast<size_t>((k + 359) % 360)] &&
        d[static_cast<size_t>(k)] <= d[static_cast<size_t>((k + 1) % 360)])
      minima.push_back(k);
  std::sort(minima.begin(), minima.end(),
            [&d](int a, int b) { return d[static_cast<size_t>(a)] < d[static_cast<size_t>(b)]; });
  if (minima.size() > kTurnMinima) minima.resize(kTurnMinima);
  const double exact = kTurnExact * diagonal_of(t);
  IcpResult best = icp_from(aligned, kTurnIcpRounds);
  for (int k : minima) {
    if (best.rms <= exact) break;
    IcpResult pose = icp_from(turned(k), kTurnIcpRounds);
    if (pose.rms < best.rms) best = pose;
  }
  return best.transform;
}

Matching match_vertices(const LevelData& level, const Points& suspect, const ResyncOptions& o) {
  Matching m;
  const PointTree& tree = *level.tree;
  const ClosestPoint nearest_vertex = [&tree](const Eigen::Vector3d& q, Eigen::Index) {
    return tree.point(tree.nearest(q));
  };
  if (o.align) {
    const Points moving = strided(suspect, o.alignment_samples);
    const Points fixed = strided(level.points, o.alignment_samples);
    m.transform = align_similarity(moving, moving, fixed, nearest_vertex, o.icp).transform;
  }
  // Refit the similarity on all mutual pairs (7 DOF from every vertex), then pair again.
  const auto pair_and_refit = [&](Matching& x) {
    for (int round = 0; round < 2; ++round) {
      mutual_pairs(level.points, *level.tree, suspect, &x);
      if (!o.align || x.matched < 3) break;
      Points src(x.matched, 3), dst(x.matched, 3);
      int k = 0;
      for (size_t j = 0; j < x.suspect_of.size(); ++j)
        if (x.suspect_of[j] >= 0) src.row(k) = suspect.row(x.suspect_of[j]), dst.row(k++) = level.points.row(j);
      x.transform = fit_similarity(src, dst);
    }
  };
  pair_and_refit(m);
  // Only when too few pair to start the rounds (min_start_fraction): a copy turned off its pose
  // pairs next to none (abc6 turned: 76 %), while a marked copy in its pose starts lower than
  // the rounds end (blade's issued STL copies: 88.6 % at first, all after the rounds), and the
  // search was 70 % of such a detection (4.1 s on blade) for a pose it did not change.
  if (o.align && m.matched < o.min_start_fraction * static_cast<double>(level.points.rows())) {
    Matching turned;
    turned.transform = turn_search(level, suspect, m.transform, nearest_vertex, o.icp);
    pair_and_refit(turned);
    if (turned.matched > m.matched) m = std::move(turned);
  }
  return m;
}

// The solve of each matching round leaves out the pairs whose residual under the solve from all
// of them exceeds kSwappedPair times the median residual (and kPairFloor of the diagonal): a mark
// that moves refined vertices by a fair fraction of their spacing swaps a few mutual pairs, and
// an estimate from all pairs puts the swapped vertices where the swap says, so the next pairing
// kept them (the chamfered block's issued STL copies: 0.3-0.8 % of the pairs, residual 5.7e-4 of
// the diagonal instead of float precision, 7 of 18 messages wrong). The pairs still count as
// paired, and the residual reported is over all of them. The floor is far below any refined
// spacing (a swapped pair is off by about one) but above what a stale estimate leaves on right
// pairs: control points whose pairs are all left out stay at the original's positions, their
// refined vertices off by the mark, and a floor at float precision left those pairs out round
// after round (up to a quarter of the pairs of blade's issued STL copies).
constexpr double kSwappedPair = 10, kPairFloor = 1e-4;

// The pairs (rows, p) whose residual against `refined` (the estimate's refined vertices) is in
// line as above, into kept_rows / kept_p. False when none is out of line.
bool pairs_in_line(const Points& refined, double diagonal, const std::vector<int>& rows, const Points& p,
                   std::vector<int>* kept_rows, Points* kept_p) {
  const std::size_t k = rows.size();
  if (k < 8) return false;
  std::vector<double> residual(k);
  for (std::size_t i = 0; i < k; ++i) residual[i] = (refined.row(rows[i]) - p.row(static_cast<Eigen::Index>(i))).norm();
  std::vector<double> sorted = residual;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k / 2), sorted.end());
  const double limit = std::max(kSwappedPair * sorted[k / 2], kPairFloor * diagonal);
  std::vector<Eigen::Index> kept;
  for (std::size_t i = 0; i < k; ++i)
    if (residual[i] <= limit) kept.push_back(static_cast<Eigen::Index>(i));
  if (kept.size() == k) return false;
  kept_rows->clear();
  kept_p->resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t i = 0; i < kept.size(); ++i) {
    kept_rows->push_back(rows[static_cast<std::size_t>(kept[i])]);
    kept_p->row(static_cast<Eigen::Index>(i)) = p.row(kept[i]);
  }
  return true;
}

// How much smaller the unmoved pairing's residual must be to replace the aligned one, unless it
// explains the suspect exactly (to float precision, relative to the diagonal: STL files store
// float coordinates), when a similarity could only take in part of the mark.
constexpr double kClearlyBetter = 0.5, kExact = 1e-7;

// A pair residual (relative to the diagonal) that only an exact copy leaves: float coordinates
// (an STL file) leave about 2e-8, noise of 5e-4 of the largest side about 3e-4.
constexpr double kExactPairs = 1e-6;

// Whether the suspect's bounding box is the level's within kSameFrame of the diagonal at both
// corners: a copy only renumbered is (its mark moves vertices by about 1e-3 of the diagonal), a
// moved one is not, and pairing it unmoved only pays for nearest-vertex queries far from every
// original vertex (a blade copy scaled by 3 and shifted: 4.0 s of detection).
constexpr double kSameFrame = 0.05;

bool in_same_frame(const Points& original, const Points& suspect, double diagonal) {
  if (suspect.rows() == 0) return false;
  const double lo = (original.colwise().minCoeff() - suspect.colwise().minCoeff()).norm();
  const double hi = (original.colwise().maxCoeff() - suspect.colwise().maxCoeff()).norm();
  return std::max(lo, hi) <= kSameFrame * diagonal;
}

// How many pairs (rows, p) `refined` explains to within `limit`.
int exact_pairs(const Points& refined, double limit, const std::vector<int>& rows, const Points& p) {
  int exact = 0;
  for (std::size_t i = 0; i < rows.size(); ++i)
    if ((refined.row(rows[i]) - p.row(static_cast<Eigen::Index>(i))).norm() <= limit) ++exact;
  return exact;
}

// `edges`: given for a suspect with as many vertices as the level (pairs then also grow along
// the edges). `need` > 0: the hypothesis (a piece) holds only with at least that many pairs,
// explained exactly, so the rounds stop once the last round's growth, kept up, could not get
// there (a remesh tried as a piece gains a fraction of a percent a round; real pieces pair over
// 90 % from the second round), or once the first solve explains fewer than half of them to
// float precision (real pieces: most of their pairs; a remesh: none).
Resynchronized from_matching(const ResyncContext::Impl& ctx, const Hypothesis& h, const Points& suspect,
                             Matching m, int rounds, const EdgesOfBoth* edges = nullptr, int need = 0) {
  const LevelData& level = *h.level;
  const int l = h.l;
  Resynchronized r;
  r.method = l == 0 ? "polyhedron" : "subdivided";
  r.level = l;
  r.order_recovered = true;
  r.resubdivided = h.resubdivided;
  r.to_control_frame = m.transform;
  const Points cur = m.transform.apply(suspect);
  std::optional<PointTree> cur_tree;  // built by the first round that pairs again
  const int nr = static_cast<int>(level.points.rows());
  std::vector<int> rows, kept_rows;
  Points p, kept_p;
  int previous = -1;
  for (int round = 0; round < rounds; ++round) {
    if (round > 0) {
      // The mark moves refined vertices by a fair fraction of their spacing, so pairs made with
      // the original refined vertices miss or swap some; pair again with the estimate S x until
      // the pairs stop changing (a swap put right leaves the count as it was) or shrink.
      const Points estimate = h.apply(r.points);
      Matching next = m;
      // The transform stays m's, so the suspect's vertices are `cur` in every round.
      if (!cur_tree) cur_tree.emplace(cur);
      mutual_pairs(estimate, PointTree(estimate), cur, *cur_tree, &next);
      if (edges) {
        // Seeds: the pairs the estimate explains to float precision. A noisy copy has none, and
        // keeps its mutual pairs: with noise a pair may be a neighbour's, and growth from it
        // would carry the mistake along the edges (a noisy STL copy of fandisk_quads, seeded with
        // the pairs in line, lost its payload).
        std::vector<int> seeds;
        for (int j = 0; j < nr; ++j)
          if (next.suspect_of[j] >= 0 &&
              (estimate.row(j) - cur.row(next.suspect_of[j])).norm() <= kExactPairs * ctx.diagonal)
            seeds.push_back(j);
        grow_pairs(edges->refined, edges->suspect, estimate, cur, seeds, &next);
      }
      if (next.matched < previous || next.suspect_of == m.suspect_of) break;
      if (need > 0 && next.matched + (rounds - 1 - round) * (next.matched - previous) < need) break;
      m = std::move(next);
    }
    previous = m.matched;
    rows.clear();
    p.resize(m.matched, 3);
    for (int j = 0; j < nr; ++j)
      if (m.suspect_of[j] >= 0) {
        p.row(static_cast<Eigen::Index>(rows.size())) = cur.row(m.suspect_of[j]);
        rows.push_back(j);
      }
    r.points = m.matched == nr ? h.solve(p) : solve_rows(h.rows_of(rows), p, ctx.control.points);
    if (l > 0 && pairs_in_line(h.apply(r.points), ctx.diagonal, rows, p, &kept_rows, &kept_p))
      r.points = solve_rows(h.rows_of(kept_rows), kept_p, ctx.control.points);
    if (need > 0 && round == 0 && 2 * exact_pairs(h.apply(r.points), kExactPairs * ctx.diagonal, rows, p) < need)
      break;
  }
  r.matched_fraction = static_cast<double>(m.matched) / nr;
  // Level 0: what separates the suspect from the original (mark, quantisation, noise).
  const Points refined = l == 0 ? level.points : h.apply(r.points);
  Points fitted(m.matched, 3);
  for (size_t k = 0; k < rows.size(); ++k) fitted.row(static_cast<Eigen::Index>(k)) = refined.row(rows[k]);
  r.residual_rms = rms_rows(fitted, p) / ctx.diagonal;
  return r;
}

// The coarse alignment (least squares on positions) absorbs part of the mark's lowest
// frequencies; re-estimate the similarity on the recovered control points so it does not.
void refine_alignment(const ResyncContext::Impl& ctx, const ResyncOptions& o, Resynchronized* r) {
  if (!o.align) return;
  const Similarity c = fit_similarity_preserving_mark(ctx.control, r->points);
  r->points = c.apply(r->points);
  r->to_control_frame = c.after(r->to_control_frame);
  r->residual_rms *= c.scale;
}

// A piece's pairs explain it to within this share of the diagonal (RMS): a crop of a decoded
// copy leaves float precision (1e-11 to 1e-8 on the shared parts). A simplified copy (vertices
// moved to the collapses' optimal points, 3e-3) or a noisy piece is left to the surface fit,
// which recovers more of the mark from it.
constexpr double kPieceResidual = 1e-6;

double median_edge_length(const Mesh& mesh) {
  std::vector<double> lengths;
  for (const auto& [a, b] : unique_edges(mesh)) lengths.push_back((mesh.points.row(a) - mesh.points.row(b)).norm());
  if (lengths.empty()) return 0;
  std::nth_element(lengths.begin(), lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2), lengths.end());
  return lengths[lengths.size() / 2];
}

// A piece cut from a copy as issued (a crop): fewer vertices than any whole level, but each one
// a refined vertex of the level its edge lengths name (halved per level), in the original's
// frame. Paired unmoved; accepted when the pairs cover min_matched_fraction of the suspect's
// vertices (not of the level's) and explain them to kPieceResidual. The control points the
// piece does not reach stay at the original's positions, so they carry no mark either way.
std::optional<Resynchronized> piece_of_copy(const ResyncContext::Impl& ctx, const Mesh& suspect,
                                            const ResyncOptions& o, int top) {
  const int ns = suspect.num_vertices();
  const double control_edge = median_edge_length(ctx.control), suspect_edge = median_edge_length(suspect);
  if (top < 1 || !(control_edge > 0) || !(suspect_edge > 0)) return std::nullopt;
  const int l = std::clamp(static_cast<int>(std::lround(std::log2(control_edge / suspect_edge))), 1, top);
  const double nr = static_cast<double>(ctx.vertex_counts[static_cast<size_t>(l)]);
  if (ns >= (1 - o.count_tolerance) * nr) return std::nullopt;  // whole levels were tried above
  const LevelData& level = ctx.level(l);
  ResyncOptions unmoved = o;
  unmoved.align = false;
  const Matching m = match_vertices(level, suspect.points, unmoved);
  if (m.matched < o.min_start_fraction * ns) return std::nullopt;
  Resynchronized r = from_matching(ctx, Hypothesis{&level, nullptr, l, false}, suspect.points, m, o.matching_rounds,
                                   nullptr, static_cast<int>(std::ceil(o.min_matched_fraction * ns)));
  const double paired = r.matched_fraction * nr / ns;
  if (paired < o.min_matched_fraction || !(r.residual_rms <= kPieceResidual)) return std::nullopt;
  r.matched_fraction = paired;
  r.method = "piece";
  return r;
}

}  // namespace

Resynchronized resynchronize(const ResyncContext& context, const Mesh& suspect, const ResyncOptions& o) {
  check_mesh(suspect, o.source);
  const ResyncContext::Impl& ctx = context.impl();
  const int top = std::min(o.max_level, ctx.max_level);
  const int ns = suspect.num_vertices();

  // Same numbering: vertices correspond by index.
  // Vertex counts come from the topology: only a level that could be the suspect's is built.
  for (int l = 0; l <= top && !o.force_surface_fit; ++l) {
    if (ctx.vertex_counts[static_cast<size_t>(l)] != ns) continue;
    const LevelData& level = ctx.level(l);
    // A level L-1 file refined once more (by us or OpenSubdiv) numbers its edge points in the
    // file's edge order: renumbered into the level-L order it is an in-order suspect too.
    Points in_order;
    if (faces_consistent(level, suspect)) {
      in_order = suspect.points;
    } else if (level.has_smooth && o.consider_resubdivision) {
      Mesh renumbered;
      renumbered.faces = suspect.faces;
      for (auto& f : renumbered.faces)
        for (int& v : f) v = level.smooth_order[static_cast<size_t>(v)];
      if (!faces_consistent(level, renumbered)) continue;
      in_order.resize(ns, 3);
      for (int v = 0; v < ns; ++v) in_order.row(level.smooth_order[static_cast<size_t>(v)]) = suspect.points.row(v);
    } else {
      continue;
    }
    Resynchronized r;
    r.method = l == 0 ? "polyhedron" : "subdivided";
    r.level = l;
    if (o.align) r.to_control_frame = fit_similarity(in_order, level.points);
    Points p = r.to_control_frame.apply(in_order);
    if (o.model_smoothing && l >= 1) {
      // A smoothed copy: aligned to the original smoothed the same way (a similarity fitted to
      // the unsmoothed one takes in the shrink), with the smoothing's change of the original
      // taken out; what is left is the mark as the smoothing left it.
      const SmoothingModel model = fit_smoothing(level.op.refined, level.points, in_order, o.align);
      if (model.iterations > 0) {
        r.to_control_frame = model.to_original;
        p = r.to_control_frame.apply(in_order) - (model.smoothed - level.points);
        r.attack_model = model.describe();
      }
    }
    r.points = solve_level(level, l, p);
    // Level 0: what separates the suspect from the original (mark, quantisation, noise).
    const Points refined = l == 0 ? level.points : apply_subdivision(level.op, r.points);
    r.residual_rms = rms_rows(refined, p) / ctx.diagonal;
    if (level.has_smooth && o.consider_resubdivision && r.attack_model.empty()) {
      // The same count and faces also come from a level L-1 copy subdivided once more without
      // crease tags (a decoded file has none); solving that with the creased S_L biases every
      // control point near a crease.
      // Keep whichever hypothesis explains the suspect better (a tie keeps the creased one).
      const LevelData& below = ctx.level(l - 1);
      Points xs = solve_smooth(below, level, l, p);
      const double residual = rms_rows(apply_smooth(below, level, l, xs), p) / ctx.diagonal;
      if (residual < r.residual_rms) {
        r.points = std::move(xs);
        r.residual_rms = residual;
        r.resubdivided = true;
      }
    }
    refine_alignment(ctx, o, &r);
    if (l == 0) r.residual_rms = rms_rows(r.points, ctx.control.points) / ctx.diagonal;
    return r;
  }
  // Same vertices, numbering lost (STL welding, re-export): mutual nearest neighbours, then
  // growth along the edges (grow_pairs).
  std::optional<Adjacency> suspect_edges, refined_edges;
  for (int l = 0; l <= top && !o.force_surface_fit; ++l) {
    const double nr = static_cast<double>(ctx.vertex_counts[static_cast<size_t>(l)]);
    if (std::abs(ns - nr) > o.count_tolerance * nr) continue;
    const LevelData& level = ctx.level(l);
    Matching m = match_vertices(level, suspect.points, o);
    if (m.matched < o.min_start_fraction * nr) continue;
    // Built once for the level and shared by its hypotheses (the re-subdivided one has the same
    // topology and numbering).
    std::optional<EdgesOfBoth> both;
    if (l > 0 && ns == static_cast<int>(nr)) {
      if (!suspect_edges) suspect_edges.emplace(suspect);
      refined_edges.emplace(level.op.refined);
      both.emplace(EdgesOfBoth{*refined_edges, *suspect_edges});
    }
    const EdgesOfBoth* edges = both ? &*both : nullptr;
    Resynchronized r =
        from_matching(ctx, Hypothesis{&level, nullptr, l, false}, suspect.points, m, o.matching_rounds, edges);
    // A copy that was only renumbered (welded STL, re-export) is already in the original's
    // frame, and a similarity fitted to its pairs with the original's vertices takes in the
    // mark's lowest frequencies (fandisk: scale 0.998, residual 3.7e-4 of the diagonal, p 1e-30
    // against 1e-94 in order). Pair it unmoved too: it wins when it pairs as many vertices and
    // explains them clearly better (unmoved fandisk: residual 4e-9), and then keeps the
    // original's frame, as an in-order copy whose similarity is within the mark does (no
    // refine_alignment). Merely smaller is not enough: where neither pairing is exact
    // (fandisk_quads at 3a85671: 3.0e-4 unmoved, 4.4e-4 aligned) the aligned one recovered more
    // of the mark (p 1e-51 against 2e-31).
    bool unmoved = false;
    if (o.align && in_same_frame(level.points, suspect.points, ctx.diagonal)) {
      ResyncOptions same_frame = o;
      same_frame.align = false;
      Matching m0 = match_vertices(level, suspect.points, same_frame);
      if (m0.matched >= o.min_start_fraction * nr) {
        Resynchronized r0 =
            from_matching(ctx, Hypothesis{&level, nullptr, l, false}, suspect.points, m0, o.matching_rounds, edges);
        if (r0.matched_fraction >= r.matched_fraction &&
            (r0.residual_rms < kClearlyBetter * r.residual_rms || r0.residual_rms <= kExact)) {
          r = std::move(r0);
          m = std::move(m0);
          unmoved = true;
        }
      }
    }
    if (level.has_smooth && o.consider_resubdivision) {
      // Re-subdividing a decoded file numbers its edge points by that file's own edge order, so
      // this leak arrives here rather than in the same-numbering branch. Same test as there; a
      // hypothesis that pairs fewer vertices does not win by its smaller residual.
      Resynchronized alt = from_matching(ctx, Hypothesis{&level, &ctx.level(l - 1), l, true},
                                         suspect.points, m, o.matching_rounds, edges);
      if (alt.matched_fraction >= r.matched_fraction && alt.residual_rms < r.residual_rms) r = std::move(alt);
    }
    if (r.matched_fraction < o.min_matched_fraction) continue;
    if (!unmoved) refine_alignment(ctx, o, &r);
    if (l == 0) r.residual_rms = rms_rows(r.points, ctx.control.points) / ctx.diagonal;
    return r;
  }
  if (!o.force_surface_fit) {
    if (auto piece = piece_of_copy(ctx, suspect, o, top)) return *piece;
  }
  // No refine_alignment: the fitted control points' Laplacian coordinates are mostly the
  // regulariser's, and re-estimating on them moved remeshed copies' scale by up to 12 %.
  return surface_fit(ctx, suspect, o);
}

}  // namespace mm

