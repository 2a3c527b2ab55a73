// Fitting and the compress pipeline on the shared meshes: error below tolerance, multiple
// components, open boundaries, scale invariance, determinism, and clear failures.
#include <cmath>
#include <filesystem>
#include <numeric>
#include <type_traits>

#include "common/shared_meshes.h"
#include "codec/stream.h"
#include "fitting/compress.h"
#include "fitting/control_polyhedron.h"
#include "fitting/fit_control_points.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "quality/surface_distance.h"
#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"

namespace {

mm::Mesh load_normalized(const std::string& name) {
  auto m = mm::read_mesh(mm::test::shared_mesh(name));
  mm::apply(mm::unit_box_normalization(m.points), m.points);
  return m;
}

int components(const mm::Mesh& m) {
  std::vector<int> parent(m.num_vertices());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int v) { return parent[v] == v ? v : parent[v] = find(parent[v]); };
  for (const auto& f : m.faces)
    for (size_t k = 1; k < f.size(); ++k) parent[find(f[k])] = find(f[0]);
  int n = 0;
  for (int v = 0; v < m.num_vertices(); ++v) n += find(v) == v;
  return n;
}

double rel(double x, const mm::FitStats& s) { return x / s.diagonal; }

}  // namespace

TEST(Fit, FandiskFitMovesTheSurfaceOntoThePart) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = load_normalized("fandisk.off");
  auto f = mm::detect_features(m);
  auto s = mm::segment(m, f);
  mm::ControlOptions co;
  co.target_vertices = 100;
  auto c = mm::build_control_polyhedron(m, f, s, co);
  auto before = mm::measure_fit(c.mesh, 3, m);
  auto r = mm::fit_control_points(c.mesh, m, f);
  EXPECT_LT(r.stats.rms, 0.5 * before.rms);
  EXPECT_LT(r.stats.hausdorff, before.hausdorff);
  // One fit on the plain decimation (no refinement rounds) already meets the 0.1 % RMS;
  // the Hausdorff target needs the compress loop below.
  EXPECT_LE(rel(r.stats.rms, r.stats), 0.001);
  EXPECT_LT(rel(r.stats.hausdorff, r.stats), 0.01);
  // region_error: per target vertex, its own distance or a larger one measured from the surface
  // to a target triangle around it; the surface's overshoot shows there and nowhere else.
  ASSERT_EQ(r.region_error.size(), r.target_error.size());
  ASSERT_EQ(static_cast<int>(r.target_error.size()), m.num_vertices());
  int larger = 0;
  for (size_t v = 0; v < r.region_error.size(); ++v) {
    EXPECT_GE(r.region_error[v], r.target_error[v]);
    EXPECT_LE(r.region_error[v], r.stats.hausdorff);
    larger += r.region_error[v] > r.target_error[v];
  }
  EXPECT_GT(larger, 0);
  // The statistics are what measure_fit finds for the fitted control mesh.
  const auto again = mm::measure_fit(r.control, 3, m);
  EXPECT_NEAR(again.hausdorff, r.stats.hausdorff, 1e-9);
  // Topology is untouched: only positions move.
  EXPECT_EQ(r.control.faces, c.mesh.faces);
  EXPECT_EQ(r.control.creases, c.mesh.creases);
  EXPECT_EQ(r.control.corners, c.mesh.corners);
}

// Issue 3's fandisk target: at most 100 control vertices, Hausdorff <= 0.5 % and RMS <= 0.1 % of
// the diagonal, measured as a receiver sees it: the stream decoded (10-bit quantisation),
// subdivided at the fitted level, compared with the part by the quality code (dense sampling).
TEST(Compress, FandiskWithinHundredControlVertices) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("fandisk.off"));
  mm::CompressOptions o;
  o.max_vertices = 100;
  // A tenth of headroom on both, for the 10-bit grid: the protect path's reweighted fit sits
  // right at what it is asked for (at 0.5 % and no RMS check, 74 vertices whose RMS is 0.1006 %
  // by the fit's measurement and whose 10-bit stream decodes to 0.502 %). The RMS is checked by
  // the dense measurement (CompressOptions::verify), as a caller with an RMS target would.
  o.tolerance = 0.0045;
  o.verify = [&m, &o](const mm::Mesh& c) {
    const auto d = mm::decoded_distance(m, c, o.levels);
    return d.hausdorff_relative() <= o.tolerance && d.rms_relative() <= 0.0009;
  };
  auto r = mm::compress(m, o);
  std::cout << "fandisk: " << r.control.num_vertices() << " control vertices, Hausdorff " << rel(r.stats.hausdorff, r.stats)
            << ", RMS " << rel(r.stats.rms, r.stats) << "\n";
  EXPECT_LE(r.control.num_vertices(), 100);
  EXPECT_TRUE(r.tolerance_met) << rel(r.stats.hausdorff, r.stats);
  EXPECT_EQ(r.tolerance_met, rel(r.stats.hausdorff, r.stats) <= o.tolerance);
  EXPECT_LE(rel(r.stats.rms, r.stats), 0.001);
  mm::CodecParams p;
  p.quant_bits = 10;
  const auto decoded = mm::decode(mm::encode(r.control, p), "fandisk");
  const auto d = mm::decoded_distance(m, decoded.mesh, r.levels);
  EXPECT_LE(d.hausdorff_relative(), 0.005);
  EXPECT_LE(d.rms_relative(), 0.001);
  EXPECT_FALSE(r.control.creases.empty());
  EXPECT_FALSE(r.control.corners.empty());
  // Original units: the control mesh sits in the part's bounding box (slightly outside at most).
  Eigen::RowVector3d lo = m.points.colwise().minCoeff(), hi = m.points.colwise().maxCoeff();
  double slack = 0.05 * (hi - lo).norm();
  EXPECT_TRUE(((r.control.points.rowwise() - lo).array() >= -slack).all());
  EXPECT_TRUE(((r.control.points.rowwise() - hi).array() <= slack).all());
}

// compress numbers the control vertices in the stream's traversal order: the codec then stores
// no index for a new vertex, and the numbering is a permutation of a valid mesh.
TEST(Compress, ControlVerticesComeInStreamOrder) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc9.stl"));
  mm::CompressOptions o;
  o.max_rounds = 1;
  auto r = mm::compress(m, o);
  const auto order = mm::traversal_vertex_order(r.control);
  for (size_t k = 0; k < order.size(); ++k) EXPECT_EQ(order[k], static_cast<int>(k));
  const auto decoded = mm::decode(mm::encode(r.control), "abc9");
  EXPECT_EQ(decoded.mesh.creases, r.control.creases);
  EXPECT_EQ(decoded.mesh.corners, r.control.corners);
}

// The reason a miss is reported with: the budget when the fit stopped at it (fandisk at 40
// vertices), the rounds when it stopped below it (fandisk_quads' folds at 35 degrees: 176 of
// 1000 in 6 rounds, as `meshmark compress` fits them; the protect path's reweighted fit meets
// the tolerance there).
TEST(Compress, ToleranceMissReasonTellsTheBudgetFromTheRounds) {
  MM_REQUIRE_SHARED_MESHES();
  mm::CompressOptions o;
  o.max_vertices = 40;
  const auto budget = mm::compress(mm::read_mesh(mm::test::shared_mesh("fandisk.off")), o);
  ASSERT_FALSE(budget.tolerance_met);
  EXPECT_EQ(mm::tolerance_miss_reason(budget, o), "within the control vertex budget of 40");
  mm::CompressOptions q;
  q.coarsen = true;
  const auto rounds = mm::compress(mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off")), q);
  ASSERT_FALSE(rounds.tolerance_met);
  EXPECT_EQ(mm::tolerance_miss_reason(rounds, q), "in 6 refinement rounds: " +
                                                      std::to_string(rounds.control.num_vertices()) +
                                                      " control vertices, under the budget of 1000");
  EXPECT_LT(rounds.control.num_vertices(), 900);
}

TEST(Compress, MultipleComponentsStaySeparate) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc5.stl"));
  ASSERT_EQ(components(m), 10);
  mm::CompressOptions o;
  o.tolerance = 0.01;
  o.max_vertices = 400;
  auto r = mm::compress(m, o);
  EXPECT_EQ(components(r.control), 10);
  EXPECT_TRUE(r.tolerance_met) << rel(r.stats.hausdorff, r.stats);
}

TEST(Compress, OpenBoundaryHemisphere) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("hemisphere.off"));
  mm::CompressOptions o;
  o.tolerance = 0.01;
  o.max_vertices = 150;
  auto r = mm::compress(m, o);
  EXPECT_TRUE(r.tolerance_met) << rel(r.stats.hausdorff, r.stats);
  // The control mesh is open too: some edges have a single face.
  std::map<std::pair<int, int>, int> count;
  for (const auto& f : r.control.faces)
    for (size_t k = 0; k < f.size(); ++k) {
      int a = f[k], b = f[(k + 1) % f.size()];
      ++count[{std::min(a, b), std::max(a, b)}];
    }
  int boundary = 0;
  for (const auto& [e, n] : count) boundary += n == 1;
  EXPECT_GE(boundary, 3);
}

// Every tolerance is relative to the part's box, so the scale of its units must not matter.
// Scaled by a power of two the normalised part is the same bit for bit, and so must be the
// result: any absolute epsilon left in the pipeline would show here. Scaled by 1e-3 or 1e3 the
// normalised coordinates differ in their last bits, which can flip a tie of the decimation's
// float priorities (OpenMesh's), so the polyhedron may differ by a few vertices' placement:
// there the vertex count, the verdict and the Hausdorff distance must agree. (The RMS of
// abc6's two-round polyhedron at 1e3 differs by 12 % from the part's since the first
// full-level round grows by a quarter: 0.056 % against 0.063 %, both a sixth of the 0.1 %
// target.)
TEST(Compress, TinyAndHugeScalesGiveTheSameRelativeError) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc6.stl"));
  mm::CompressOptions o;
  o.max_vertices = 120;
  o.max_rounds = 2;
  auto base = mm::compress(m, o);
  for (double scale : {1.0 / 1048576, 1048576.0}) {
    auto scaled = m;
    scaled.points *= scale;
    auto r = mm::compress(scaled, o);
    EXPECT_EQ(r.control.faces, base.control.faces) << scale;
    EXPECT_EQ(r.control.creases, base.control.creases) << scale;
    EXPECT_TRUE((r.control.points.array() == (base.control.points * scale).array()).all()) << scale;
    EXPECT_EQ(r.stats.hausdorff, base.stats.hausdorff * scale) << scale;
    EXPECT_EQ(r.stats.rms, base.stats.rms * scale) << scale;
    EXPECT_EQ(r.round_vertices, base.round_vertices) << scale;
  }
  for (double scale : {1e-3, 1e3}) {
    auto scaled = m;
    scaled.points *= scale;
    auto r = mm::compress(scaled, o);
    EXPECT_NEAR(r.control.num_vertices(), base.control.num_vertices(), 2) << scale;
    EXPECT_EQ(r.tolerance_met, base.tolerance_met) << scale;
    EXPECT_NEAR(rel(r.stats.hausdorff, r.stats), rel(base.stats.hausdorff, base.stats),
                0.1 * rel(base.stats.hausdorff, base.stats))
        << scale;
    EXPECT_LE(rel(r.stats.rms, r.stats), 0.001) << scale;
    EXPECT_NEAR(r.stats.diagonal, base.stats.diagonal * scale, 1e-9 * base.stats.diagonal * scale);
  }
}

TEST(Compress, Deterministic) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc7.stl"));
  mm::CompressOptions o;
  o.max_vertices = 80;
  o.max_rounds = 2;
  auto a = mm::compress(m, o), b = mm::compress(m, o);
  EXPECT_EQ(a.control.faces, b.control.faces);
  EXPECT_EQ(a.control.creases, b.control.creases);
  EXPECT_TRUE(a.control.points == b.control.points);
}

// The seed is the fit's sampling: honoured, and deterministic per seed.
TEST(Compress, SeedIsHonouredAndDeterministic) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc7.stl"));
  mm::CompressOptions o;
  o.max_rounds = 1;
  const auto first = mm::compress(m, o);
  o.seed = 2;
  const auto second = mm::compress(m, o), again = mm::compress(m, o);
  EXPECT_TRUE(second.control.points == again.control.points);
  EXPECT_EQ(second.control.faces, again.control.faces);
  ASSERT_EQ(first.control.num_vertices(), second.control.num_vertices());  // one round: same decimation
  EXPECT_FALSE(first.control.points == second.control.points);
}

// A caller's own measurement (CompressOptions::verify) decides whether a round meets the
// tolerance: one that rejects everything leaves the tolerance unmet after every round, one that
// accepts everything changes nothing.
// verify takes a yes/no answer only: a function returning a distance does not compile into one
// that reads every non-zero distance as "yes".
struct DistanceOfCandidate {
  double operator()(const mm::Mesh&) const { return 0.01; }
};
struct AnswerForCandidate {
  bool operator()(const mm::Mesh&) const { return true; }
};
static_assert(!std::is_convertible_v<DistanceOfCandidate, mm::CandidateCheck>);
static_assert(std::is_convertible_v<AnswerForCandidate, mm::CandidateCheck>);

TEST(Compress, VerifyHasTheLastWord) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc7.stl"));
  mm::CompressOptions o;
  o.max_rounds = 3;
  const auto plain = mm::compress(m, o);
  ASSERT_TRUE(plain.tolerance_met);
  int calls = 0;
  o.verify = [&](const mm::Mesh& control) {
    ++calls;
    // Candidates come in the part's units, creases tagged.
    EXPECT_FALSE(control.creases.empty());
    EXPECT_NEAR((control.points.colwise().maxCoeff() - control.points.colwise().minCoeff()).norm(),
                (m.points.colwise().maxCoeff() - m.points.colwise().minCoeff()).norm(),
                0.1 * (m.points.colwise().maxCoeff() - m.points.colwise().minCoeff()).norm());
    return true;
  };
  const auto accepted = mm::compress(m, o);
  EXPECT_GE(calls, 1);
  EXPECT_TRUE(accepted.tolerance_met);
  EXPECT_TRUE(accepted.control.points == plain.control.points);
  EXPECT_EQ(accepted.control.faces, plain.control.faces);
  calls = 0;
  o.verify = [&](const mm::Mesh&) {
    ++calls;
    return false;
  };
  const auto rejected = mm::compress(m, o);
  EXPECT_GE(calls, 1);
  EXPECT_FALSE(rejected.tolerance_met);
  EXPECT_EQ(rejected.rounds, o.max_rounds);
}

// Every round that met the tolerance is offered, fewest vertices first, the chosen polyhedron
// first; each met the caller's measurement; none when no round did.
TEST(Compress, CandidatesAreTheRoundsThatMetTheTolerance) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("abc9.stl"));
  mm::CompressOptions o;
  std::vector<std::pair<int, double>> measured;  // vertex count, dense error
  o.verify = [&](const mm::Mesh& control) {
    const double h = mm::decoded_distance(m, control, o.levels).hausdorff_relative();
    measured.emplace_back(control.num_vertices(), h);
    return h <= o.tolerance;
  };
  const auto r = mm::compress(m, o);
  ASSERT_TRUE(r.tolerance_met);
  ASSERT_GE(r.candidates.size(), 1u);
  EXPECT_TRUE(r.candidates[0].control.points == r.control.points);
  EXPECT_EQ(r.candidates[0].control.faces, r.control.faces);
  size_t met = 0;
  for (const auto& [n, h] : measured) met += h <= o.tolerance;
  EXPECT_EQ(r.candidates.size(), met);
  for (size_t k = 0; k < r.candidates.size(); ++k) {
    const auto& c = r.candidates[k];
    if (k > 0) {
      EXPECT_GE(c.control.num_vertices(), r.candidates[k - 1].control.num_vertices());
    }
    // In the part's units, numbered for the stream, and within the tolerance.
    EXPECT_EQ(mm::traversal_vertex_order(c.control), [&] {
      std::vector<int> id(static_cast<size_t>(c.control.num_vertices()));
      std::iota(id.begin(), id.end(), 0);
      return id;
    }());
    EXPECT_LE(mm::decoded_distance(m, c.control, r.levels).hausdorff_relative(), o.tolerance);
    EXPECT_NEAR(c.stats.diagonal, r.stats.diagonal, 1e-9 * r.stats.diagonal);
  }
  o.verify = [](const mm::Mesh&) { return false; };
  EXPECT_TRUE(mm::compress(m, o).candidates.empty());
}

// The next round grows from the vertices a round had, also where the decimation stopped above
// its target: abc8's corners and crease floors keep 92 vertices where the first round asked for
// 53, and at an error of 4x the tolerance or more the second round gets twice the 92 (it got
// twice the 53, 106 vertices at nearly the same error, when it grew from the target).
TEST(Compress, RoundsGrowFromTheVerticesTheyHad) {
  MM_REQUIRE_SHARED_MESHES();
  const auto r = mm::compress(mm::read_mesh(mm::test::shared_mesh("abc8.stl")), {});
  ASSERT_EQ(r.round_vertices.size(), static_cast<size_t>(r.rounds));
  ASSERT_EQ(r.round_errors.size(), static_cast<size_t>(r.rounds));
  ASSERT_GE(r.rounds, 2);
  ASSERT_GE(r.round_errors[0], 4 * mm::CompressOptions{}.tolerance);
  EXPECT_GE(r.round_vertices[1], 2 * r.round_vertices[0]);
  EXPECT_TRUE(r.tolerance_met);
}

// Without coarsening, a round that follows one within 1.5x the tolerance starts from that
// round's fit and fits 4 times instead of 6; the rounds before it start from the part, and so do
// all of them when a coarsening follows (compress_rounds with coarsen set). On fandisk the warm
// rounds meet the tolerance with fewer control vertices than the cold ones (87 against 103; not
// everywhere: blade 474 against 440).
TEST(Compress, RoundsNearTheToleranceStartFromTheLastFit) {
  MM_REQUIRE_SHARED_MESHES();
  const mm::Mesh part = mm::read_mesh(mm::test::shared_mesh("fandisk.off"));
  mm::CompressOptions o;
  const mm::CompressResult warm = mm::compress(part, o, "fandisk");
  o.coarsen = true;
  std::shared_ptr<const mm::CompressState> state;
  const mm::CompressResult cold = mm::compress_rounds(part, o, "fandisk", state);
  ASSERT_EQ(warm.round_warm.size(), static_cast<size_t>(warm.rounds));
  ASSERT_EQ(cold.round_warm.size(), static_cast<size_t>(cold.rounds));
  int warm_rounds = 0;
  for (int k = 0; k < warm.rounds; ++k) {
    if (!warm.round_warm[static_cast<size_t>(k)]) continue;
    ++warm_rounds;
    ASSERT_GT(k, 0);
    EXPECT_LE(warm.round_errors[static_cast<size_t>(k) - 1], 1.5 * o.tolerance) << k;
  }
  EXPECT_GE(warm_rounds, 1);
  for (bool w : cold.round_warm) EXPECT_FALSE(w);
  EXPECT_FALSE(warm.round_warm[0]);
  ASSERT_TRUE(warm.tolerance_met);
  ASSERT_TRUE(cold.tolerance_met);
  EXPECT_LT(warm.control.num_vertices(), cold.control.num_vertices());
}

// Reweighting the correspondences by their distance (FitOptions::reweight) pulls the largest
// distances in, which is what the tolerance is on. One fit of the same control mesh, reweighted
// against plain least squares, over six parts and four vertex counts: a smaller Hausdorff
// distance in most cases (20 of 24 by 3 % or more when this was written, geometric mean of the
// ratios 0.89) and never much larger (at worst 1.16x, rocker at 400 vertices; uncapped, the
// extra weight made that fit 2.2x worse).
TEST(Fit, ReweightingLowersTheLargestDistance) {
  MM_REQUIRE_SHARED_MESHES();
  int better = 0, cases = 0;
  double log_sum = 0;
  for (const char* name : {"fandisk.off", "blade.stl", "rocker.stl", "bracket-3.stl", "abc5.stl", "abc8.stl"}) {
    const auto m = load_normalized(name);
    const auto f = mm::detect_features(m);
    const auto s = mm::segment(m, f);
    for (int vertices : {60, 120, 250, 400}) {
      mm::ControlOptions co;
      co.target_vertices = vertices;
      const auto c = mm::build_control_polyhedron(m, f, s, co);
      mm::FitOptions plain, reweighted;
      reweighted.reweight = 0.3;
      const double a = mm::fit_control_points(c.mesh, m, f, plain).stats.hausdorff;
      const double b = mm::fit_control_points(c.mesh, m, f, reweighted).stats.hausdorff;
      EXPECT_LT(b, 1.25 * a) << name << " " << vertices;
      better += b < 0.97 * a;
      log_sum += std::log(b / a);
      ++cases;
    }
  }
  EXPECT_GE(better, 16) << cases;
  EXPECT_LT(std::exp(log_sum / cases), 0.95);
}

// Without coarsening, a round far from the tolerance (the first; one after a round farther than
// 1.5x it) is fitted a subdivision level lower, only to steer the next; the result and every
// candidate are full-level fits, whose statistics measure_fit at `levels` reproduces. With
// max_rounds 1 the only round is fitted again at the full level to give a result. With
// coarsening every round is at the full level. (compress.cpp, kFirstWarmGrowth for the growth
// into the first full-level round.)
TEST(Compress, CoarseRoundsOnlySteer) {
  MM_REQUIRE_SHARED_MESHES();
  const mm::Mesh part = mm::read_mesh(mm::test::shared_mesh("abc8.stl"));
  mm::CompressOptions o;
  const auto r = mm::compress(part, o, "abc8");
  ASSERT_EQ(r.round_levels.size(), static_cast<size_t>(r.rounds));
  EXPECT_EQ(r.round_levels[0], o.levels - 1);
  EXPECT_GT(r.round_errors[0], o.tolerance);
  for (int k = 0; k < r.rounds; ++k)
    if (r.round_warm[static_cast<size_t>(k)]) {
      EXPECT_EQ(r.round_levels[static_cast<size_t>(k)], o.levels) << k;
    }
  ASSERT_TRUE(r.tolerance_met);
  // The first full-level round grows by a quarter at least from the coarse round before it, and
  // once a full-level round meets the tolerance, later rounds only bisect down towards counts
  // where a full-level round missed (a coarse round's miss bounds nothing).
  int transitions = 0, largest_full_miss = 0;
  bool met = false;
  for (int k = 0; k < r.rounds; ++k) {
    const auto i = static_cast<size_t>(k);
    if (k > 0 && r.round_levels[i - 1] < o.levels && r.round_levels[i] == o.levels && r.round_warm[i]) {
      ++transitions;
      EXPECT_GE(r.round_vertices[i], 1.25 * r.round_vertices[i - 1]) << k;
    }
    if (met) {
      EXPECT_GT(r.round_vertices[i], largest_full_miss) << k;
    }
    const bool within = r.round_levels[i] == o.levels && r.round_errors[i] <= o.tolerance;
    if (r.round_levels[i] == o.levels && !within && !met) largest_full_miss = std::max(largest_full_miss, r.round_vertices[i]);
    met = met || within;
  }
  EXPECT_EQ(transitions, 1);
  if (largest_full_miss == 0) {
    EXPECT_LE(r.round_errors.back(), o.tolerance);  // nothing to bisect towards: the met round is the last
    for (int k = 0; k + 1 < r.rounds; ++k)
      EXPECT_FALSE(r.round_levels[static_cast<size_t>(k)] == o.levels && r.round_errors[static_cast<size_t>(k)] <= o.tolerance) << k;
  }
  std::cout << "abc8 rounds:";
  for (int k = 0; k < r.rounds; ++k)
    std::cout << " " << r.round_vertices[static_cast<size_t>(k)] << "@L" << r.round_levels[static_cast<size_t>(k)];
  std::cout << "\n";
  for (const auto& c : r.candidates) {
    const auto again = mm::measure_fit(c.control, o.levels, part);
    EXPECT_NEAR(again.hausdorff, c.stats.hausdorff, 1e-6 * c.stats.diagonal);
  }
  mm::CompressOptions one = o;
  one.max_rounds = 1;
  const auto single = mm::compress(part, one, "abc8");
  ASSERT_EQ(single.round_levels.size(), 1u);
  EXPECT_EQ(single.round_levels[0], o.levels);
  EXPECT_NEAR(mm::measure_fit(single.control, o.levels, part).hausdorff, single.stats.hausdorff,
              1e-6 * single.stats.diagonal);
  mm::CompressOptions cold = o;
  cold.coarsen = true;
  std::shared_ptr<const mm::CompressState> state;
  const auto rounds = mm::compress_rounds(part, cold, "abc8", state);
  ASSERT_EQ(rounds.round_levels.size(), static_cast<size_t>(rounds.rounds));
  for (int level : rounds.round_levels) EXPECT_EQ(level, o.levels);
}

TEST(Compress, BadInputIsRejectedWithAReason) {
  mm::Mesh empty;
  EXPECT_THROW(mm::compress(empty, {}, "empty.off"), mm::InputError);
  mm::Mesh flat;
  flat.points.resize(3, 3);
  flat.points << 1, 1, 1, 1, 1, 1, 1, 1, 1;  // all points coincide
  flat.faces = {{0, 1, 2}};
  try {
    mm::compress(flat, {}, "flat.off");
    FAIL() << "degenerate bounding box accepted";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "flat.off");
    EXPECT_NE(std::string(e.reason()).find("degenerate"), std::string::npos) << e.reason();
  }
  mm::Mesh nan = flat;
  nan.points(0, 0) = std::nan("");
  EXPECT_THROW(mm::compress(nan, {}, "nan.off"), mm::InputError);
  mm::Mesh bad_index = flat;
  bad_index.points(1, 0) = 2;
  bad_index.faces = {{0, 1, 7}};
  EXPECT_THROW(mm::compress(bad_index, {}, "index.off"), mm::InputError);
}

// One Loop step of the faceted abc5 keeps its facets' edges above the crease angle: nearly every
// vertex becomes a corner, which no decimation removes. Fitting a control mesh of the input's
// size took 71 s and 726 MB; compress refuses it up front, naming the file and the reason, and
// a budget that does hold the corners still compresses the original part.
TEST(Compress, CornerHeavyInputIsRefusedBeforeFitting) {
  MM_REQUIRE_SHARED_MESHES();
  const mm::Mesh abc5 = mm::read_mesh(mm::test::shared_mesh("abc5.stl"));
  const mm::Mesh refined = mm::subdivide(abc5, 1);
  ASSERT_GT(refined.num_vertices(), 10000);
  mm::CompressOptions o;
  try {
    mm::compress(refined, o, "abc5_loop1.off");
    FAIL() << "a mesh with more corners than the budget was compressed";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "abc5_loop1.off");
    EXPECT_NE(std::string(e.reason()).find("corners"), std::string::npos) << e.reason();
    EXPECT_NE(std::string(e.reason()).find("budget of 1000"), std::string::npos) << e.reason();
  }
  o.max_rounds = 1;
  o.levels = 2;
  const auto r = mm::compress(abc5, o, "abc5.stl");
  EXPECT_LE(r.control.num_vertices(), o.max_vertices);
  EXPECT_LE(r.corners, o.max_vertices);
}

// Every shared mesh compresses (quickly, one round at level 2 here) or fails with an InputError
// that names it.
TEST(Compress, EverySharedMeshCompressesOrFailsClearly) {
  MM_REQUIRE_SHARED_MESHES();
  int compressed = 0;
  for (const auto& entry : std::filesystem::directory_iterator(mm::test::shared_meshes_dir())) {
    auto ext = entry.path().extension().string();
    if (ext != ".off" && ext != ".stl" && ext != ".obj" && ext != ".ply") continue;
    const std::string path = entry.path().string();
    SCOPED_TRACE(path);
    mm::Mesh m = mm::read_mesh(path);
    mm::CompressOptions o;
    o.max_vertices = 200;
    o.max_rounds = 1;
    o.levels = 2;
    try {
      auto r = mm::compress(m, o, path);
      EXPECT_GT(r.control.num_vertices(), 3);
      EXPECT_TRUE(r.control.points.allFinite());
      EXPECT_LT(rel(r.stats.hausdorff, r.stats), 0.1);
      // tolerance_met says whether the reported error is within the tolerance, nothing else.
      EXPECT_EQ(r.tolerance_met, rel(r.stats.hausdorff, r.stats) <= o.tolerance);
      ++compressed;
    } catch (const mm::InputError& e) {
      EXPECT_EQ(e.source(), path);
      EXPECT_FALSE(e.reason().empty());
    }
  }
  EXPECT_GE(compressed, 12);
}
