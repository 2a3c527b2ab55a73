#include "fitting/compress.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <optional>
#include <string>

#include "codec/stream.h"
#include "fitting/collapse_control.h"
#include "fitting/control_polyhedron.h"
#include "fitting/rail_quads.h"
#include "fitting/segmentation.h"
#include "fitting/sharp_features.h"
#include "meshio/read_mesh.h"

namespace mm {
namespace {

void validate(const Mesh& mesh, const CompressOptions& o, const std::string& source) {
  check_mesh(mesh, source);
  if (mesh.num_vertices() < 3) throw InputError(source, "fewer than 3 vertices");
  if (!(o.tolerance > 0) || !(o.max_vertices >= 4) || o.levels < 1 || o.levels > 5 ||
      !(o.angle_degrees > 0 && o.angle_degrees < 180) || o.max_rounds < 1)
    throw std::invalid_argument("compress: options out of range");
}

// The next decimation keeps more vertices where the surface is still farther than `limit`: the
// importance multiplies the collapse cost there, by up to 33x (error 4x the limit or more).
void raise_importance(std::vector<double>& importance, const std::vector<double>& error, double limit) {
  for (size_t v = 0; v < error.size(); ++v)
    if (error[v] > limit) importance[v] *= 1.0 + 8.0 * std::min(error[v] / limit, 4.0);
}

// Coarsening: short refits from the fitted positions, a first batch of an eighth of the
// vertices, and an end after 8 single removals that missed. Candidates at three headroom levels,
// because a polyhedron right at the tolerance often needs 2 more bits than one with a tenth to
// spare. Tuned on scripts/bench-compress.sh (stream bytes); the measurements are in git history.
constexpr int kCoarsenIterations = 3;
constexpr int kCoarsenTries = 8;
constexpr int kCoarsenFirstBatch = 8;
constexpr double kCoarsenLevels[] = {1.0, 0.9, 0.8};

// Warm rounds (without coarsening): a round whose predecessor came within kWarmWithin times the
// tolerance starts each control vertex where that round's better variant put it and fits
// kWarmIterations times. Not farther out: there the fit pulls control points far off the part,
// and a denser polyhedron started there stalls.
constexpr int kWarmIterations = 4;
constexpr double kWarmWithin = 1.5;

// The fit's reweighting towards its largest distances (FitOptions::reweight), without coarsening
// only: with coarsening its tighter fits needed finer grids and the streams grew.
constexpr double kReweight = 0.3;

// Coarse rounds (without coarsening): a round that does not start warm -- the first, or one after
// a round farther than kWarmWithin times the tolerance -- only steers the next one, so it is
// fitted one subdivision level lower (a quarter of the queries). Should it come within the
// tolerance there, it is fitted again at the full level and that fit counts.

// Without coarsening (protect jobs): warm rounds fit no rail-quad variant, and the rounds stop
// bisecting once the gap is a sixth of the vertices that met the tolerance: about a third less
// fit time for a few percent more bytes (scripts/bench-compress.sh, speed table).
constexpr int kBisectFraction = 6;

// Into the first full-level round (without coarsening): after a coarse round within kWarmWithin
// times the tolerance the vertices grow by at least kFirstWarmGrowth, since a second full-level
// fit costs more than the extra vertices; coarse rounds' misses do not bound the bisection (their
// errors are the coarser surface's, and rounds bisecting towards them mostly missed again).
constexpr double kFirstWarmGrowth = 1.25;

// Where a warm round starts its control vertices, per input vertex: the last round's fitted
// position, if that vertex was a control vertex there.
struct WarmStart {
  Points position;
  std::vector<char> known;
  // Records `fitted` (control vertex i started on input vertex source[i]).
  void remember(const Points& fitted, const std::vector<int>& source, int input_vertices) {
    position.setZero(input_vertices, 3);
    known.assign(static_cast<size_t>(input_vertices), 0);
    for (size_t i = 0; i < source.size(); ++i) {
      if (source[i] < 0) continue;
      position.row(source[i]) = fitted.row(static_cast<Eigen::Index>(i));
      known[static_cast<size_t>(source[i])] = 1;
    }
  }
  void apply(Points& points, const std::vector<int>& source) const {
    for (size_t i = 0; i < source.size(); ++i)
      if (source[i] >= 0 && known[static_cast<size_t>(source[i])])
        points.row(static_cast<Eigen::Index>(i)) = position.row(source[i]);
  }
};

// Removes control vertices from the fewest-vertex polyhedron that met the tolerance, fitting
// again after each removal and keeping it while the fit's own measurement meets the tolerance.
// Vertices responsible for the smallest errors go first, each onto its nearest allowed
// neighbour, several at once where they are far apart (one fit per batch; a batch that misses
// is halved). Returns the chain of polyhedra kept, largest first.
std::vector<FitResult> coarsen(const FitResult& start, const FitTarget& target, FitOptions fit, double tolerance,
                              int floor) {
  fit.iterations = kCoarsenIterations;
  std::vector<FitResult> chain;
  const FitResult* best = &start;
  int batch = std::max(1, start.control.num_vertices() / kCoarsenFirstBatch);
  std::vector<char> failed(start.control.num_vertices(), 0);  // single removals that missed
  int failures = 0;
  while (best->control.num_vertices() > floor && failures < kCoarsenTries) {
    const Mesh& cur = best->control;
    const int n = cur.num_vertices();
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return best->vertex_error[a] < best->vertex_error[b]; });
    std::vector<std::vector<int>> neighbours(n);
    for (const auto& [a, b] : unique_edges(cur)) {
      neighbours[a].push_back(b);
      neighbours[b].push_back(a);
    }
    // Collapse up to `batch` vertices, no two in one another's one-ring, on a running copy
    // whose indices shift down past each removed vertex.
    Mesh smaller = cur;
    std::vector<int> index(n);
    std::iota(index.begin(), index.end(), 0);
    std::vector<char> locked(n, 0);
    std::vector<int> removed;
    for (int v : order) {
      if (static_cast<int>(removed.size()) == batch || n - static_cast<int>(removed.size()) <= floor) break;
      if (locked[v] || (batch == 1 && failed[v])) continue;
      std::vector<int> to = neighbours[v];
      std::stable_sort(to.begin(), to.end(), [&](int a, int b) {
        return (cur.points.row(a) - cur.points.row(v)).squaredNorm() <
               (cur.points.row(b) - cur.points.row(v)).squaredNorm();
      });
      for (int t : to) {
        if (auto next = collapse_control_vertex(smaller, index[v], index[t])) {
          smaller = std::move(*next);
          for (int w = v + 1; w < n; ++w) --index[w];
          index[v] = index[t];
          removed.push_back(v);
          locked[v] = 1;
          for (int w : neighbours[v]) locked[w] = 1;
          break;
        }
      }
    }
    if (removed.empty()) break;
    FitResult r = fit_control_points(smaller, target, fit);
    const bool fits = r.stats.hausdorff / r.stats.diagonal <= tolerance;
    if (fits) {
      // Single removals that missed stay marked away from this batch's neighbourhoods.
      std::vector<char> still(r.control.num_vertices(), 0);
      for (int w = 0; w < n; ++w)
        if (!locked[w]) still[index[w]] = failed[w];
      failed = std::move(still);
      chain.push_back(std::move(r));
      best = &chain.back();
    } else if (batch > 1) {
      batch /= 2;
    } else {
      failed[removed[0]] = 1;
      ++failures;
    }
  }
  return chain;
}

// The input validated, without its tags, moved into the unit box the fit works in.
Mesh in_unit_box(const Mesh& input, const CompressOptions& o, const std::string& source, Normalization* n) {
  validate(input, o, source);
  Mesh mesh = input;
  mesh.creases.clear();
  mesh.corners.clear();
  try {
    *n = unit_box_normalization(mesh.points);
  } catch (const std::invalid_argument& e) {
    throw InputError(source, e.what());
  }
  apply(*n, mesh.points);
  return mesh;
}

Features features_of(const Mesh& unit_box_mesh, const CompressOptions& o) {
  FeatureOptions fo;
  fo.angle_degrees = o.angle_degrees;
  return detect_features(unit_box_mesh, fo);
}

}  // namespace

std::vector<double> fallback_crease_angles() { return {30.0, 25.0, 20.0}; }

std::string rounds_schedule_key(const CompressOptions& o) {
  if (o.coarsen) return ";coarsen=1";
  return ";rounds=coarse-warm;warm-iterations=" + std::to_string(kWarmIterations) +
         ";warm-within=" + shortest_text(kWarmWithin) + ";warm-quads=0;bisect=" + std::to_string(kBisectFraction) +
         ";first-warm-growth=" + shortest_text(kFirstWarmGrowth) + ";fit=reweighted-" + shortest_text(kReweight);
}

bool stopped_at_budget(const CompressResult& r, const CompressOptions& o) {
  return r.control.num_vertices() >= o.max_vertices * 9 / 10;
}

std::string tolerance_miss_reason(const CompressResult& r, const CompressOptions& o) {
  if (stopped_at_budget(r, o)) return "within the control vertex budget of " + std::to_string(o.max_vertices);
  if (r.all_vertices)
    return "with every vertex of the part" +
           (r.part_splits > 0 ? " split " + std::to_string(r.part_splits) + " time(s) at its edges' midpoints" : std::string()) +
           " (" + std::to_string(r.input_vertices) + ") as a control vertex, under the budget of " +
           std::to_string(o.max_vertices);
  return "in " + std::to_string(r.rounds) + " refinement rounds: " + std::to_string(r.control.num_vertices()) +
         " control vertices, under the budget of " + std::to_string(o.max_vertices);
}

Features compress_features(const Mesh& input, const CompressOptions& o, const std::string& source) {
  Normalization n;
  return features_of(in_unit_box(input, o, source, &n), o);
}

// What compress() carries from its rounds to the coarsening and to its result, in the unit box.
struct CompressState {
  CompressOptions options;
  CompressResult out;  // the counts, the normalisation, the rounds so far
  std::unique_ptr<FitTarget> target;
  FitOptions fit;
  FitResult best;  // the fewest vertices among rounds that met the tolerance, else the smallest error
  bool best_fits = false;
  std::vector<CompressCandidate> fitting;  // every round's polyhedron that met the tolerance
  int first_round_vertices = 0;
};

namespace {

// The fit samples its surface at the refined vertices; a caller's denser measurement of a
// candidate (in the part's units) has the last word.
bool confirmed(const CompressState& s, const Mesh& unit_box_control) {
  if (!s.options.verify) return true;
  Mesh candidate = unit_box_control;
  undo(s.out.normalization, candidate.points);
  return s.options.verify(candidate);
}

// The decimate-and-fit rounds.
std::unique_ptr<CompressState> fit_rounds(const Mesh& input, const CompressOptions& o, const std::string& source) {
  auto state = std::make_unique<CompressState>();
  CompressState& st = *state;
  st.options = o;
  CompressResult& out = st.out;
  const Mesh mesh = in_unit_box(input, o, source, &out.normalization);
  out.levels = o.levels;
  out.angle_degrees = o.angle_degrees;
  out.input_vertices = input.num_vertices();
  const Features features = features_of(mesh, o);
  const Segmentation seg = segment(mesh, features);
  out.sharp_edges = static_cast<int>(features.sharp_edges.size());
  out.corners = static_cast<int>(features.corners.size());
  out.patches = seg.num_patches;
  // Corners are never collapsed, so they alone bound the control mesh from below. A faceted or
  // noisy mesh whose every other vertex is a corner (a Loop step of a coarse faceted part) has
  // no compact control polyhedron, and fitting one of the input's size at `levels` costs
  // 4^levels times the input in time and memory: refuse it before any of that work.
  if (static_cast<int>(features.corners.size()) > o.max_vertices)
    throw InputError(source, std::to_string(features.corners.size()) + " of " +
                                 std::to_string(mesh.num_vertices()) +
                                 " vertices are sharp-feature corners (kept as control vertices), more than the "
                                 "control vertex budget of " + std::to_string(o.max_vertices) +
                                 ": no compact control polyhedron (faceted or noisy surface? a larger "
                                 "crease angle or budget may help)");

  ControlOptions co;
  // Start small (the corners, a little per patch); rounds add vertices where they are needed.
  co.target_vertices = std::min(
      o.max_vertices, std::max(24, static_cast<int>(features.corners.size()) + seg.num_patches + 16));
  st.first_round_vertices = co.target_vertices;
  co.importance.assign(mesh.num_vertices(), 1.0);
  FitOptions& fit = st.fit;
  fit.seed = o.seed;
  fit.levels = o.levels;
  fit.reweight = o.coarsen ? 0.0 : kReweight;
  // The target's trees and samples are the same in every round (and in the coarsening).
  st.target = std::make_unique<FitTarget>(mesh, features, fit);
  const FitTarget& target = *st.target;
  // Rounds that keep the importance and lower the vertex count continue the last decimation.
  ControlDecimation decimation(mesh, features, seg);

  bool have = false;
  bool& best_fits = st.best_fits;
  FitResult& best = st.best;
  std::vector<CompressCandidate>& fitting = st.fitting;
  // Vertex counts that failed (largest) and met the tolerance (smallest) so far: once a round
  // meets it, the rounds left bisect between the two, since the growth step may overshoot.
  int failed_n = 0, fit_n = 0, at_budget = 0;
  WarmStart warm_start;
  // Whether the round after one with this error starts warm (kWarmWithin).
  const auto warm_after = [&o](double error) { return !o.coarsen && error <= kWarmWithin * o.tolerance; };
  for (int round = 0; round < o.max_rounds; ++round) {
    ++out.rounds;
    auto control = decimation.build(co);
    // The decimation stops early when only corners and crease floors are left; far above the
    // budget the fit's refined mesh (4^levels times the control mesh) is the blow-up above.
    if (round == 0 && control.mesh.num_vertices() > 2 * o.max_vertices)
      throw InputError(source, "the control polyhedron keeps " + std::to_string(control.mesh.num_vertices()) +
                                   " vertices (corners and crease polylines cannot shrink further), more than "
                                   "twice the control vertex budget of " + std::to_string(o.max_vertices) +
                                   ": no compact control polyhedron");
    // The next round refines where the better variant is too far from the part in either
    // direction (region_error: refining only where target vertices are too far left the rounds
    // blind to overshoot between them), and its error sets the growth.
    std::vector<double> result_error;
    Points steering;  // the better variant's fitted positions
    double rel = 0;
    const int n = control.mesh.num_vertices();
    // The rounds' last: the round count, or the last of kRoundsAtBudget at the budget.
    // A control mesh that holds every vertex of the part cannot grow: its round is the last.
    const bool whole = n >= mesh.num_vertices();
    const bool last = round + 1 == o.max_rounds || (n >= o.max_vertices && at_budget + 1 >= kRoundsAtBudget) || whole;
    // `steer_only`: a coarse round's fit, which steers and is no result.
    const auto consider = [&](FitResult&& variant, bool steer_only) {
      const double error = variant.stats.hausdorff / variant.stats.diagonal;
      if (result_error.empty() || error < rel) {
        result_error = variant.region_error;
        rel = error;
        if (!o.coarsen) steering = variant.control.points;
      }
      // (Within the tolerance at its level: a coarse round's quads would add nothing to steer by.)
      if (steer_only) return error <= o.tolerance;
      const bool variant_fits = error <= o.tolerance && confirmed(st, variant.control);
      if (variant_fits) fitting.push_back({variant.control, variant.stats});
      // Best: the fewest vertices among rounds that fit, else the smallest error.
      if (!have || (variant_fits && (!best_fits || n < best.control.num_vertices())) ||
          (!variant_fits && !best_fits && variant.stats.hausdorff < best.stats.hausdorff)) {
        best = std::move(variant);
        have = true;
        best_fits = variant_fits;
      }
      return variant_fits;
    };
    // The round's polyhedron fitted from `start`, then, where the triangles miss, with its
    // crease-railed strips as quads, whose walls do not sag, from the triangles' positions.
    // Neither variant wins everywhere (fandisk's rounds stalled at 0.55 % with quads alone), so
    // each is a candidate. Not when the triangles met the tolerance: the quads would only add a
    // candidate of as many vertices, whose stream is larger (version 3 codes a quad for about
    // twice a triangle's bits), and the next round is a bisection step that needs no errors to
    // steer. Nor in warm rounds (`quads_with` null): near the tolerance a second fit of the
    // round for the few bytes above (kBisectFraction).
    const Points from_part = control.mesh.points;
    const auto fit_variants = [&](const Points& start, const FitOptions& with, const FitOptions* quads_with) {
      const bool steer_only = with.levels != o.levels;
      control.mesh.points = start;
      FitResult triangles = fit_control_points(control.mesh, target, with);
      const Points fitted = triangles.control.points;
      bool met = consider(std::move(triangles), steer_only);
      if (o.rail_quads && quads_with && !met) {
        Mesh quads = pair_rail_quads(control.mesh);
        if (quads.num_faces() != control.mesh.num_faces()) {
          quads.points = fitted;
          // The full iteration count, also after a warm start: fewer left the quads' fits
          // short (a welded STL copy of fandisk_quads lost its mark).
          met = consider(fit_control_points(quads, target, *quads_with), steer_only);
        }
      }
      return met;
    };
    const bool warm = round > 0 && warm_after(out.round_errors.back());
    FitOptions warm_fit = fit;
    warm_fit.iterations = kWarmIterations;
    bool fits;
    int level = o.levels;
    if (warm) {
      Points start = from_part;
      warm_start.apply(start, control.source);
      fits = fit_variants(start, warm_fit, nullptr);
      // More vertices and no closer than the round before: fitted again from the part, and the
      // better fit counts (the hemisphere's warm rounds came out worse than its cold ones).
      if (!fits && n > out.round_vertices.back() && rel >= out.round_errors.back())
        fits = fit_variants(from_part, fit, nullptr);
    } else if (!o.coarsen && o.levels > 1) {
      FitOptions coarse = fit;
      coarse.levels = o.levels - 1;
      coarse.face_interiors = false;
      fit_variants(from_part, coarse, &coarse);
      fits = false;
      level = coarse.levels;
      // Within the tolerance, or the last round with no full-level fit yet to give as the result.
      if (rel <= o.tolerance || (!have && last)) {
        const Points start = steering;
        result_error.clear();
        fits = fit_variants(start, warm_fit, &fit);
        level = o.levels;
      }
    } else {
      fits = fit_variants(from_part, fit, &fit);
    }
    if (!o.coarsen) warm_start.remember(steering, control.source, mesh.num_vertices());
    out.round_vertices.push_back(n);
    out.round_errors.push_back(rel);
    out.round_warm.push_back(warm);
    out.round_levels.push_back(level);
    if (fits) {
      out.tolerance_met = true;
      fit_n = fit_n == 0 ? n : std::min(fit_n, n);
    } else if ((fit_n == 0 || n < fit_n) && level == o.levels) {
      failed_n = std::max(failed_n, n);  // (not a coarse round's miss: kFirstWarmGrowth)
    }
    if (fit_n > 0) {
      // Bisect while it could still save a tenth of the vertices (a sixth without coarsening:
      // kBisectFraction).
      if (failed_n == 0 || fit_n - failed_n <= std::max(4, fit_n / (o.coarsen ? 10 : kBisectFraction))) break;
      if (!fits) raise_importance(co.importance, result_error, o.tolerance * target.diagonal());
      co.target_vertices = (failed_n + fit_n) / 2;
      continue;
    }
    // At the budget, rounds only move vertices around (the importance keeps growing where the
    // error stays), which helps unevenly: a few of them, and the best is kept.
    if (n >= o.max_vertices && ++at_budget >= kRoundsAtBudget) break;
    if (whole) {
      out.all_vertices = true;
      break;
    }
    // Spend more vertices where the surface is still too far, and a few more overall.
    raise_importance(co.importance, result_error, o.tolerance * target.diagonal());
    // Grown from the smallest error so far: a round worse than an earlier one with fewer
    // vertices went astray in its decimation, and is no measure of how many more are needed
    // (flanged_cylinder: 68 vertices at 0.66 %, then 79 at 1.64 % grew to 144).
    const double grow_rel = have ? std::min(rel, best.stats.hausdorff / best.stats.diagonal) : rel;
    const double least = warm_after(rel) && level != o.levels ? kFirstWarmGrowth : 1.15;
    const double grow = std::clamp(std::sqrt(grow_rel / o.tolerance), least, 2.0);
    // From the vertices the round had, where the decimation stopped above its target (corners
    // and crease floors): grown from the target, abc8's second round had 106 vertices to the
    // first's 92 (3.26 % against 3.53 %), a round spent on nearly the same polyhedron.
    co.target_vertices =
        std::min(o.max_vertices, static_cast<int>(std::ceil(std::max(co.target_vertices, n) * grow)));
  }

  return state;
}

// The coarsening of the rounds' best polyhedron (which it replaces) and its candidates (added).
void coarsen_best(const CompressState& st, FitResult& best, std::vector<CompressCandidate>& fitting) {
  const CompressOptions& o = st.options;
  // Candidates for the stream: per headroom level, the smallest polyhedron whose fit error is
  // within that fraction of the tolerance (a polyhedron at the tolerance needs a fine grid, one
  // with headroom may take a coarser one). The dense measurement decides.
  std::vector<FitResult> chain = coarsen(st.best, *st.target, st.fit, o.tolerance, st.first_round_vertices);
  std::vector<char> taken(chain.size(), 0);
  bool first = true;
  for (double level : kCoarsenLevels) {
    for (int i = static_cast<int>(chain.size()) - 1, tries = 0; i >= 0 && tries < 3; --i) {
      if (chain[i].stats.hausdorff / chain[i].stats.diagonal > level * o.tolerance) continue;
      if (taken[i]) break;
      ++tries;
      if (!confirmed(st, chain[i].control)) continue;
      taken[i] = 1;
      fitting.push_back({chain[i].control, chain[i].stats});
      if (first) best = chain[i];
      first = false;
      break;
    }
  }
}

// The result: `best` and the candidates `fitting` back in the part's units, numbered for the stream.
CompressResult result_of(const CompressState& st, const FitResult& best, std::vector<CompressCandidate> fitting) {
  CompressResult out = st.out;
  // Back to the part's units.
  const auto in_part_units = [&](FitStats s) {
    for (double* x : {&s.hausdorff, &s.rms, &s.mean, &s.diagonal}) *x /= out.normalization.scale;
    return s;
  };
  out.control = in_traversal_order(best.control);
  out.stats = in_part_units(best.stats);
  undo(out.normalization, out.control.points);
  // Fitting rounds by vertex count, the one kept as `control` first (the earliest of equal
  // counts, as the loop keeps it).
  std::stable_sort(fitting.begin(), fitting.end(), [](const CompressCandidate& a, const CompressCandidate& b) {
    return a.control.num_vertices() < b.control.num_vertices();
  });
  if (st.best_fits) out.candidates.push_back({out.control, out.stats});
  for (const CompressCandidate& c : fitting) {
    if (c.control.points.rows() == best.control.points.rows() && c.control.points == best.control.points) continue;
    CompressCandidate p{in_traversal_order(c.control), in_part_units(c.stats)};
    undo(out.normalization, p.control.points);
    out.candidates.push_back(std::move(p));
  }
  return out;
}

}  // namespace

CandidateCheck::~CandidateCheck() = default;

CompressResult compress(const Mesh& input, const CompressOptions& o, const std::string& source) {
  const std::unique_ptr<CompressState> st = fit_rounds(input, o, source);
  return o.coarsen ? coarsen_rounds(*st) : result_of(*st, st->best, st->fitting);
}

CompressResult compress_rounds(const Mesh& input, const CompressOptions& o, const std::string& source,
                               std::shared_ptr<const CompressState>& state) {
  std::unique_ptr<CompressState> st = fit_rounds(input, o, source);
  CompressResult out = result_of(*st, st->best, st->fitting);
  state = std::move(st);
  return out;
}

CompressResult coarsen_rounds(const CompressState& st) {
  if (!st.best_fits) return result_of(st, st.best, st.fitting);
  FitResult best = st.best;
  std::vector<CompressCandidate> fitting = st.fitting;
  coarsen_best(st, best, fitting);
  return result_of(st, best, std::move(fitting));
}

}  // namespace mm
