// Compression of a CAD mesh into a subdivision control polyhedron (the paper's section III):
// normalise into the unit box, find the sharp-feature network, decimate to a feature-preserving
// control mesh, fit its points by least squares, and where the error stays above the tolerance
// spend more control vertices there and fit again, until the tolerance or the vertex budget is
// reached. Deterministic: the same input and options give the same control mesh.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "fitting/fit_control_points.h"
#include "fitting/sharp_features.h"
#include "meshio/mesh.h"
#include "meshio/normalize.h"

namespace mm {

// A yes/no question about a candidate control mesh. Only callables returning bool convert to
// it: std::function<bool(...)> would also take one returning a distance, and read every
// non-zero distance as "yes".
class CandidateCheck {
 public:
  CandidateCheck() = default;
  // Out of line: inlined into the callers' temporaries (Config{}, PrepareParams{}), the
  // std::function's destructor drew GCC 12's false -Wmaybe-uninitialized.
  ~CandidateCheck();
  CandidateCheck(const CandidateCheck&) = default;
  CandidateCheck(CandidateCheck&&) noexcept = default;
  CandidateCheck& operator=(const CandidateCheck&) = default;
  CandidateCheck& operator=(CandidateCheck&&) noexcept = default;
  template <class F, class = std::enable_if_t<std::is_same_v<std::invoke_result_t<F&, const Mesh&>, bool>>>
  CandidateCheck(F f) : f_(std::move(f)) {}
  explicit operator bool() const { return static_cast<bool>(f_); }
  bool operator()(const Mesh& control) const { return f_(control); }

 private:
  std::function<bool(const Mesh&)> f_;
};

// Rounds fitted at the control vertex budget before the tolerance is given up (a round there
// only moves vertices to where the error stays).
constexpr int kRoundsAtBudget = 3;
// A max_rounds that never ends the rounds: they end at the tolerance, at the budget (each round
// grows the polyhedron by 15 % or more) or when the polyhedron holds every vertex of the part.
constexpr int kUnlimitedRounds = 1 << 20;

struct CompressOptions {
  double tolerance = 0.005;     // target symmetric Hausdorff distance / bounding box diagonal
  int max_vertices = 1000;      // control vertex budget
  int levels = 3;               // subdivision levels the fit is measured at
  double angle_degrees = 35.0;  // dihedral angle above which an edge is a crease
  // Decimate-and-fit rounds at most; fewer once the tolerance is met (then a few bisection steps)
  // or after kRoundsAtBudget rounds at max_vertices.
  int max_rounds = 6;
  // Also fit each round's polyhedron with its crease-railed strips paired into quads
  // (fitting/rail_quads.h); both are candidates. Costs a second fit per round.
  bool rail_quads = true;
  // Then remove control vertices from the smallest polyhedron that met the tolerance, fitting
  // again after each removal, while it still meets it (fitting/collapse_control.h). Never below
  // the first round's vertex count (about one vertex per patch beyond the corners), which also
  // keeps the spectral watermark's capacity. Smaller streams for 3-5x the fit time, so off here
  // and in protect jobs, on in `meshmark compress` (scripts/bench-compress.sh measures both).
  // Without it, the rounds' polyhedron is the result, a round that follows one within 1.5x
  // the tolerance starts from that round's fit (warm start, fewer iterations), the others are
  // fitted a subdivision level lower only to steer (coarse rounds), and the fit reweights its
  // correspondences towards the largest distances (FitOptions::reweight); with it, every round
  // starts from the part at the full level with plain least squares, which the coarsening's
  // streams came out smaller from (docs/compression.md, pipeline steps 5-8).
  bool coarsen = false;
  // The fit's sampling seed. Each seed gives its own deterministic result; which vertex count
  // meets the tolerance varies with it by 10-20 %, so benchmarks compare over several.
  std::uint64_t seed = 1;
  // Optional: a denser measurement of a candidate control mesh (the part's units, creases and
  // corners tagged): whether its symmetric Hausdorff distance relative to the part's
  // bounding-box diagonal is within `tolerance`. When set, a round meets the tolerance only if
  // this measurement says so too (the fit's own measurement samples the subdivided surface at
  // its vertices and can miss a narrow peak between them: blade 0.46 % by the fit, 0.53 % by the
  // quality code's dense samples). Only the answer counts (quality/surface_distance.h's
  // decoded_within gives it without the numbers).
  CandidateCheck verify;
};

// A control polyhedron that met the tolerance, in the part's units, numbered for the stream.
struct CompressCandidate {
  Mesh control;
  FitStats stats;  // in the part's units
};

struct CompressResult {
  // In the input's units; creases and corners tagged; vertices numbered in the stream's
  // traversal order (mm::traversal_vertex_order), which the codec codes cheapest.
  Mesh control;
  int levels = 3;
  Normalization normalization;  // the unit-box transform the fit was done in
  FitStats stats;               // relative numbers: stats.x / stats.diagonal
  bool tolerance_met = false;
  // Every round's control polyhedron that met the tolerance, fewest vertices first (`control` is
  // the first). The fewest vertices need not give the smallest stream: a polyhedron with a few
  // more may keep its surface within the tolerance on a coarser grid (abc9: 52 vertices need 9
  // bits, 181 bytes; 56 need 8, 172 bytes), so a caller that quantises measures each and keeps
  // the smallest stream. Empty when no round met the tolerance.
  std::vector<CompressCandidate> candidates;
  int rounds = 0;
  // Per round, in order: its control vertices and the better variant's relative error by the
  // fit's own measurement (what steered the next round).
  std::vector<int> round_vertices;
  std::vector<double> round_errors;
  std::vector<bool> round_warm;  // the round's fit started from the round before's (coarsen off)
  // The subdivision level the round's error was measured at: `levels`, or one fewer for a coarse
  // round that stayed above the tolerance (coarsen off; compress.cpp, "Coarse rounds").
  std::vector<int> round_levels;
  double angle_degrees = 35.0;  // the crease angle it was fitted at (options.angle_degrees)
  // The rounds stopped because the control polyhedron held every vertex of the mesh it was
  // fitted to (the decimation can give no more), below the budget.
  bool all_vertices = false;
  // Times the part was split at its edges' midpoints before this fit (compression/compress_part.h).
  int part_splits = 0;
  int input_vertices = 0, sharp_edges = 0, corners = 0, patches = 0;
};

// Throws InputError(source, reason) for meshes that cannot be compressed (empty, no faces,
// degenerate bounding box, non-finite coordinates, out-of-range indices) and for meshes with no
// compact control polyhedron: more sharp-feature corners than max_vertices, or a first control
// mesh above twice max_vertices (checked before any fitting).
CompressResult compress(const Mesh& mesh, const CompressOptions& options = {},
                        const std::string& source = "mesh");

// compress() in two steps, for a caller that compares the rounds of several crease angles before
// it spends the coarsening (3-5 times the rounds' time) on one. compress_rounds() runs the rounds
// compress() with these options runs (cold ones when options.coarsen is set, so it is then not
// compress() without the coarsening) and stops there; it hands back in `state` what the
// coarsening needs (the target's trees, the rounds' polyhedra, the options with their verify);
// coarsen_rounds(*state) then gives bit for bit what compress() with coarsen = true gives.
// `state` must not outlive what options.verify refers to.
struct CompressState;
CompressResult compress_rounds(const Mesh& mesh, const CompressOptions& options, const std::string& source,
                               std::shared_ptr<const CompressState>& state);
CompressResult coarsen_rounds(const CompressState& state);

// The rounds' schedule `o` runs, as a cache key part built from compress.cpp's constants: a
// stored polyhedron fitted under another schedule is fitted again (jobs/prepared_asset.cpp).
// With coarsening ";coarsen=1", else ";rounds=coarse-warm;..." with the warm rounds'
// iterations, the bisection's fraction, the first full-level round's growth and the reweighting.
std::string rounds_schedule_key(const CompressOptions& o);

// Crease angles to try in turn when the chosen one misses the tolerance: 30, 25, 20 degrees. A
// fold a little flatter than the crease angle is smooth to the fit, and the subdivision surface
// rounds it off by the same distance however many control vertices are spent near it
// (fandisk_quads: 0.53-0.54 % from 176 to 412 vertices at 35 degrees; 96 meet 0.5 % at 30).
// `meshmark compress` after its default angles, protect jobs after `compression.angle`.
std::vector<double> fallback_crease_angles();

// Whether a result stopped at the control vertex budget (nine tenths of it or more), rather than
// in its refinement rounds below it (often an error that stopped falling: a fold flatter than the
// crease angle, which the smooth surface rounds off however many vertices are spent; a smaller
// angle makes it a crease).
bool stopped_at_budget(const CompressResult& r, const CompressOptions& o);

// Why a result misses the tolerance, for a message: "within the control vertex budget of B" when
// stopped_at_budget; "with every vertex of the part [split S time(s) at its edges' midpoints] (N)
// as a control vertex, under the budget of B" when all_vertices; else "in R refinement rounds: n
// control vertices, under the budget of B".
std::string tolerance_miss_reason(const CompressResult& r, const CompressOptions& o);

// The sharp-feature network compress() fits to (sharp edges and corners, in `mesh`'s vertex
// numbering). Of the options only angle_degrees changes it, and two angles with the same
// network give the same compress() result: a caller trying several angles fits each network
// once. Throws InputError as compress() does for invalid meshes (empty, non-finite, degenerate
// box); the budget checks are compress()'s.
Features compress_features(const Mesh& mesh, const CompressOptions& options = {}, const std::string& source = "mesh");

}  // namespace mm
