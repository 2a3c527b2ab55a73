// The watermark through resynchronisation, end to end on fandisk_quads.off (766-vertex control
// polyhedron): embed (Method 1, a = 0.01), turn the copy into what a leak would look like
// (subdivided and noisy, an STL file, the codec's polyhedron, a decimated surface), resynchronise
// against the original and extract. Marked copies must be detected with tiny p-values, unmarked
// ones must not be.
#include <gtest/gtest.h>
#include <sodium.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <chrono>
#include <filesystem>
#include <random>

#include "attacks/perturb.h"
#include "attacks/retessellate.h"
#include "codec/stream.h"
#include "common/shared_meshes.h"
#include "common/temp_dir.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "common/shuffled_mesh.h"
#include "fitting/sharp_features.h"
#include "registration/remesh.h"
#include "registration/resynchronize.h"
#include "registration/surface_offsets.h"
#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"
#include "watermark/matched_score.h"
#include "watermark/surface_evidence.h"
#include "watermark/watermark.h"

namespace {

using namespace mm;

constexpr int kBits = 64;

struct Fixture {
  Mesh control;
  SpectralBasis basis;
  Key key;
  Nonce nonce;
  std::vector<bool> message;
  EmbedParams params{Method::Multiplicative, 0.01, 0.05};
  Mesh marked;  // the watermarked control polyhedron
  std::unique_ptr<ResyncContext> context;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    x.control = read_mesh(test::shared_mesh("fandisk_quads.off"));
    apply(unit_box_normalization(x.control.points), x.control.points);
    x.basis = compute_basis(x.control);
    std::mt19937_64 rng(2026);
    for (auto& b : x.key) b = static_cast<std::uint8_t>(rng() >> 56);
    for (auto& b : x.nonce) b = static_cast<std::uint8_t>(rng() >> 56);
    x.message.resize(kBits);
    for (int i = 0; i < kBits; ++i) x.message[i] = (rng() >> 63) != 0;
    x.marked = x.control;
    x.marked.points = embed(x.basis, x.control.points, x.message, x.key, x.nonce, x.params);
    x.context = std::make_unique<ResyncContext>(x.control, 3);
    return x;
  }();
  return f;
}

Extraction detect(const Mesh& suspect, Resynchronized* out = nullptr, const ResyncOptions& o = {},
                  const EmbedParams* params = nullptr) {
  const Fixture& f = fixture();
  const Resynchronized r = resynchronize(*f.context, suspect, o);
  if (out) *out = r;
  return extract(f.basis, f.control.points, r.points, kBits, f.key, f.nonce, params ? *params : f.params,
                 &f.message);
}

// Uniform noise in [-amplitude, amplitude] per coordinate, seeded.
void add_noise(Mesh& m, double amplitude, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  for (Eigen::Index i = 0; i < m.points.size(); ++i)
    m.points.data()[i] += amplitude * (static_cast<double>(rng() >> 11) * 0x1.0p-52 - 1.0);
}

const std::filesystem::path& temp_dir() { return mm::test::scratch_dir("mm_registration_test"); }

void report(const char* what, const Resynchronized& r, const Extraction& x) {
  std::printf("  %-34s %-11s L%d matched %.3f residual %.2e corr %.3f -log10 p %.1f bits %s\n", what,
              r.method.c_str(), r.level, r.matched_fraction, r.residual_rms, x.correlation,
              x.neg_log10_p, x.bit_error_rate == 0 ? "exact" : "errors");
}

}  // namespace

TEST(ResyncWatermark, SubdividedNoisyCopyIsDetected) {
  MM_REQUIRE_SHARED_MESHES();
  ASSERT_GE(sodium_init(), 0);
  const Fixture& f = fixture();
  // Uniform noise of 0.05 % of the part's size on every refined coordinate. Method 1 with a = 0.01
  // on 766 control vertices is fragile: most coefficients are small, so are their marks (the
  // same noise put on the control points directly leaves a correlation of about 0.2).
  Mesh suspect = subdivide(f.marked, 3);
  add_noise(suspect, 0.0005, 1);
  Resynchronized r;
  const Extraction x = detect(suspect, &r);
  report("subdivided 3, noise 0.0005", r, x);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_EQ(r.level, 3);
  EXPECT_GT(x.correlation, 0.25);
  EXPECT_LT(x.p_value, 1e-30);

  Mesh clean = subdivide(f.control, 3);
  add_noise(clean, 0.0005, 1);
  const Extraction y = detect(clean, &r);
  report("unmarked, subdivided 3, noise", r, y);
  EXPECT_GT(y.p_value, 0.01);
  EXPECT_LT(std::abs(y.correlation), 0.1);
}

// A decoded copy smoothed 10 times (umbrella, lambda 0.5): every sign turns one way, so without
// the model nothing is found; with the smoothing modelled from the original and taken out, the
// mark as the smoothing left it is found, and the model is recorded. An unmarked copy smoothed the
// same way still shows nothing.
TEST(ResyncWatermark, SmoothedCopyIsDetectedThroughTheModelledSmoothing) {
  MM_REQUIRE_SHARED_MESHES();
  ASSERT_GE(sodium_init(), 0);
  const Fixture& f = fixture();
  Mesh suspect = subdivide(f.marked, 2);
  attacks::smooth_laplacian(suspect, 10, 0.5);
  Resynchronized r;
  ResyncOptions plain;
  plain.model_smoothing = false;
  const Extraction without = detect(suspect, &r, plain);
  report("subdivided 2, smoothed 10 x 0.5, no model", r, without);
  EXPECT_TRUE(r.attack_model.empty());
  EXPECT_GT(without.p_value, 1e-3);
  const Extraction with = detect(suspect, &r);
  report("subdivided 2, smoothed 10 x 0.5, modelled", r, with);
  EXPECT_EQ(r.method, "subdivided");
  // Smoothing at lambda 0.25 twice as often is about the same low-pass: either may explain it.
  EXPECT_EQ(r.attack_model.rfind("umbrella smoothing, lambda ", 0), 0u) << r.attack_model;
  EXPECT_LT(with.p_value, 1e-30);

  Mesh clean = subdivide(f.control, 2);
  attacks::smooth_laplacian(clean, 10, 0.5);
  const Extraction y = detect(clean, &r);
  report("unmarked, subdivided 2, smoothed", r, y);
  EXPECT_FALSE(r.attack_model.empty());
  EXPECT_GT(y.p_value, 0.01);
}

TEST(ResyncWatermark, ResubdividedDecodedCopyIsDetected) {
  MM_REQUIRE_SHARED_MESHES();
  ASSERT_GE(sodium_init(), 0);
  const Fixture& f = fixture();
  // fandisk_quads with its sharp edges tagged, as compress() makes control polyhedra (the plain
  // file has none, and then both hypotheses are the same operator). Tags do not change K.
  Mesh creased = f.control;
  const Features features = detect_features(creased);
  creased.creases = features.sharp_edges;
  creased.corners = features.corners;
  ASSERT_FALSE(creased.creases.empty());
  const ResyncContext context(creased, 3);
  Mesh marked = creased;
  marked.points = f.marked.points;
  auto detect_creased = [&](const Mesh& suspect, const ResyncOptions& o, Resynchronized* r) {
    *r = resynchronize(context, suspect, o);
    return extract(f.basis, f.control.points, r->points, kBits, f.key, f.nonce, f.params, &f.message);
  };

  // A leaker subdivides the decoded level-2 copy once more. The file has no crease tags, so the
  // step is the plain smooth scheme; the result has the level-3 vertex count and faces, its edge
  // points numbered by the decoded file's own edges.
  Mesh decoded = subdivide(marked, 2);
  decoded.creases.clear();
  decoded.corners.clear();
  const Mesh suspect = subdivide(decoded, 1);
  ASSERT_EQ(suspect.num_vertices(), context.refined_points(3).rows());

  ResyncOptions creased_only;
  creased_only.consider_resubdivision = false;
  Resynchronized before, r;
  const Extraction x0 = detect_creased(suspect, creased_only, &before);
  report("resubdivided 2+1, creased S_3 only", before, x0);
  const Extraction x = detect_creased(suspect, {}, &r);
  report("resubdivided 2+1", r, x);
  EXPECT_FALSE(before.resubdivided);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_EQ(r.level, 3);
  EXPECT_TRUE(r.resubdivided);
  EXPECT_EQ(r.matched_fraction, 1.0);
  EXPECT_LT(r.residual_rms, 1e-12);
  EXPECT_GT(before.residual_rms, 1e3 * r.residual_rms);
  EXPECT_GT(x.correlation, 0.9);
  EXPECT_LT(x.p_value, 1e-100);
  EXPECT_EQ(x.message, f.message);
  EXPECT_GT(x.correlation, x0.correlation);

  // In the known frame the marked control points come back exactly.
  ResyncOptions known_frame;
  known_frame.align = false;
  const Resynchronized exact = resynchronize(context, suspect, known_frame);
  EXPECT_TRUE(exact.resubdivided);
  EXPECT_LT((exact.points - marked.points).rowwise().norm().maxCoeff(), 1e-11);

  // The ordinary decoded copy at level 3 keeps the creased hypothesis, in order and as an STL
  // would number it (vertices shuffled).
  const Mesh level3 = subdivide(marked, 3);
  const Resynchronized plain = resynchronize(context, level3, known_frame);
  EXPECT_EQ(plain.level, 3);
  EXPECT_FALSE(plain.resubdivided);
  EXPECT_LT((plain.points - marked.points).rowwise().norm().maxCoeff(), 1e-11);
  Resynchronized lost;
  const Extraction xl = detect_creased(test::shuffled(level3, 5), {}, &lost);
  report("shuffled subdivided 3 (creased)", lost, xl);
  EXPECT_TRUE(lost.order_recovered);
  EXPECT_FALSE(lost.resubdivided);
  EXPECT_GT(xl.correlation, 0.9);

  // The leak saved as an STL (numbering lost): the order-free path weighs both hypotheses too.
  Resynchronized stl;
  const Extraction xs = detect_creased(test::shuffled(suspect, 5), {}, &stl);
  report("shuffled resubdivided 2+1", stl, xs);
  EXPECT_TRUE(stl.order_recovered);
  EXPECT_TRUE(stl.resubdivided);
  EXPECT_GT(xs.correlation, 0.9);
  Resynchronized stl_before;
  const Extraction xs0 = detect_creased(test::shuffled(suspect, 5), creased_only, &stl_before);
  report("shuffled resubdivided, creased only", stl_before, xs0);
  EXPECT_GT(xs.correlation, xs0.correlation);

  // With noise on the leak (as in SubdividedNoisyCopyIsDetected) the smooth hypothesis still
  // explains it better: the creased one adds its bias near every crease to the noise.
  Mesh noisy = suspect;
  add_noise(noisy, 0.0005, 1);
  Resynchronized n0, n;
  const Extraction xn0 = detect_creased(noisy, creased_only, &n0);
  report("resubdivided 2+1, noise, creased only", n0, xn0);
  const Extraction xn = detect_creased(noisy, {}, &n);
  report("resubdivided 2+1, noise 0.0005", n, xn);
  EXPECT_TRUE(n.resubdivided);
  EXPECT_GT(xn.correlation, 0.25);
  EXPECT_LT(xn.p_value, 1e-30);
}

TEST(ResyncWatermark, StlRoundTripLosesOrderNotTheMark) {
  MM_REQUIRE_SHARED_MESHES();
  const Fixture& f = fixture();
  // STL: float32 coordinates, triangles only, vertices welded and renumbered by first appearance.
  const auto path = (temp_dir() / "leak.stl").string();
  Mesh decoded = subdivide(f.marked, 2);
  Similarity part_units;
  part_units.scale = 120;
  part_units.rotation = Eigen::AngleAxisd(2.0, Eigen::Vector3d(0, 0, 1)).toRotationMatrix();
  part_units.translation << 10, 20, 30;
  decoded.points = part_units.apply(decoded.points);
  write_mesh(decoded, path);
  const Mesh suspect = read_mesh(path);
  ASSERT_EQ(suspect.num_vertices(), decoded.num_vertices());
  ASSERT_NE(suspect.points.row(1), Eigen::RowVector3d(decoded.points.row(1).cast<float>().cast<double>()));
  Resynchronized r;
  const Extraction x = detect(suspect, &r);
  report("STL of subdivided 2, part units", r, x);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_EQ(r.level, 2);
  EXPECT_TRUE(r.order_recovered);
  EXPECT_EQ(r.matched_fraction, 1.0);
  // The scale is known to 0.1 %: the mark itself (Method 1 rescales each coefficient by 1 +- a)
  // is what limits it (align_similarity.h).
  EXPECT_NEAR(r.to_control_frame.scale * 120, 1.0, 2e-3);
  EXPECT_GT(x.correlation, 0.9);
  EXPECT_EQ(x.message, f.message);

  // The same with noise (0.05 % of the part) before the export.
  Mesh noisy = subdivide(f.marked, 2);
  add_noise(noisy, 0.0005, 3);
  noisy.points = part_units.apply(noisy.points);
  write_mesh(noisy, path);
  const Extraction y = detect(read_mesh(path), &r);
  report("noisy STL of subdivided 2", r, y);
  EXPECT_EQ(r.level, 2);
  EXPECT_TRUE(r.order_recovered);
  EXPECT_GT(r.matched_fraction, 0.99);
  EXPECT_GT(y.correlation, 0.2);
  EXPECT_LT(y.p_value, 1e-20);
}

TEST(ResyncWatermark, LostOrderIsRepairedAgainstTheMarkedEstimate) {
  MM_REQUIRE_SHARED_MESHES();
  const Fixture& f = fixture();
  // At level 3 the mark moves refined vertices by a fair share of their spacing: pairs with the
  // original refined vertices miss some (and swap a few, which the solve leaves out: correlation
  // 0.59 from one pairing, 0.30 when they were solved with); pairing again with the estimate S x
  // finds them all.
  const Mesh level3 = subdivide(f.marked, 3);
  Mesh suspect;
  suspect.points.resize(level3.num_vertices(), 3);
  std::vector<int> perm(static_cast<size_t>(level3.num_vertices()));
  for (size_t i = 0; i < perm.size(); ++i) perm[i] = static_cast<int>((i * 7919) % perm.size());
  for (int v = 0; v < level3.num_vertices(); ++v) suspect.points.row(perm[v]) = level3.points.row(v);
  for (const auto& face : level3.faces) {
    std::vector<int> g;
    for (int v : face) g.push_back(perm[v]);
    suspect.faces.push_back(g);
  }
  ResyncOptions once;
  once.matching_rounds = 1;
  Resynchronized r1, r;
  const Extraction x1 = detect(suspect, &r1, once);
  report("shuffled subdivided 3, one pairing", r1, x1);
  const Extraction x = detect(suspect, &r);
  report("shuffled subdivided 3, re-paired", r, x);
  EXPECT_TRUE(r.order_recovered);
  EXPECT_LT(r1.matched_fraction, 1.0);
  EXPECT_EQ(r.matched_fraction, 1.0);
  EXPECT_LT(r.residual_rms, 1e-12);
  EXPECT_GT(x.correlation, 0.9);
}

TEST(ResyncWatermark, CodecPolyhedronIsDetected) {
  MM_REQUIRE_SHARED_MESHES();
  const Fixture& f = fixture();
  Mesh in_part_units = f.marked;
  in_part_units.points = 80.0 * in_part_units.points;
  in_part_units.points.rowwise() += Eigen::RowVector3d(5, -3, 2);
  // The property is about the grid step, not the bit count: version 3's power-of-two cells are
  // up to twice version 2's step at equal bits, so 13 bits there give a step of at most 1/4096
  // of the longest box side, as 12 bits did in version 2.
  CodecParams cp;
  cp.quant_bits = 13;
  const DecodedStream d = decode(encode(in_part_units, cp), "stream");
  const Eigen::Vector3d box = in_part_units.points.colwise().maxCoeff() - in_part_units.points.colwise().minCoeff();
  ASSERT_LE(d.quantization.step, box.maxCoeff() / 4095.0);
  Resynchronized r;
  const Extraction x = detect(d.mesh, &r);
  report("codec polyhedron (step <= 1/4095 of the box), part units", r, x);
  EXPECT_EQ(r.method, "polyhedron");
  EXPECT_FALSE(r.order_recovered);
  // Steps of 1/4096 of the box are below most small coefficients' marks.
  EXPECT_GT(x.correlation, 0.35);
  EXPECT_LT(x.p_value, 1e-50);
  EXPECT_EQ(x.message, f.message);
}

TEST(ResyncWatermark, AlignmentDoesNotAbsorbTheMark) {
  MM_REQUIRE_SHARED_MESHES();
  const Fixture& f = fixture();
  Similarity part_units;
  part_units.scale = 40;
  part_units.rotation = Eigen::AngleAxisd(-0.4, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  part_units.translation << -7, 3, 11;
  Mesh suspect = subdivide(f.marked, 1);
  add_noise(suspect, 0.0002, 2);
  Mesh known = suspect;  // the frame is known exactly: the best alignment can do
  suspect.points = part_units.apply(suspect.points);
  ResyncOptions fixed;
  fixed.align = false;
  Resynchronized r;
  const Extraction best = detect(known, &r, fixed);
  report("subdivided 1, noise, known frame", r, best);
  const Extraction aligned = detect(suspect, &r);
  report("same in part units, aligned", r, aligned);
  EXPECT_NEAR(r.to_control_frame.scale * part_units.scale, 1.0, 2e-3);
  // A plain least-squares similarity on the positions takes a share of the mark with it.
  Mesh plain = known;
  plain.points = fit_similarity(suspect.points, subdivide(f.control, 1).points).apply(suspect.points);
  const Extraction absorbed = detect(plain, &r, fixed);
  report("plain least-squares alignment", r, absorbed);
  EXPECT_GT(aligned.correlation, best.correlation - 0.05);
  EXPECT_LT(absorbed.correlation, aligned.correlation - 0.1);
}

TEST(ResyncWatermark, DecimatedSurfaceIsFitted) {
  MM_REQUIRE_SHARED_MESHES();
  const Fixture& f = fixture();
  // Quadric decimation of the decoded surface: unrelated connectivity, vertices still on it.
  // Only the mark's normal component can be seen on a surface. Method 2's additive part (every
  // small coefficient moved by T a) shows as bumps and survives; Method 1 at a = 0.01 mostly
  // rescales the large coefficients, a tangential-looking deformation, and survives barely
  // (paper_experiments measures both; docs/registration.md).
  const EmbedParams m2{Method::Additive, 0.01, 0.05};
  Mesh marked2 = f.control;
  marked2.points = embed(f.basis, f.control.points, f.message, f.key, f.nonce, m2);
  const Mesh suspect2 = test::decimate(subdivide(marked2, 3), 15000);
  Resynchronized r;
  const Extraction x2 = detect(suspect2, &r, {}, &m2);
  report("M2: decimated subdivided 3 (15k v)", r, x2);
  EXPECT_EQ(r.method, "surface-fit");
  EXPECT_GT(r.matched_fraction, 0.99);
  EXPECT_LT(r.residual_rms, 1e-4);
  EXPECT_GT(x2.correlation, 0.3);
  EXPECT_LT(x2.p_value, 1e-30);
  EXPECT_EQ(x2.message, f.message);

  const Mesh clean = test::decimate(subdivide(f.control, 3), 15000);
  const Extraction y = detect(clean, &r, {}, &m2);
  report("unmarked, decimated (M2 test)", r, y);
  // Half-edge collapses keep a subset of the refined vertices where they were: unmarked, they
  // pair exactly as a piece of the refined original (marked, the mark moves them off it).
  EXPECT_EQ(r.method, "piece");
  EXPECT_LT(r.residual_rms, 1e-12);
  EXPECT_GT(y.p_value, 0.01);
}

TEST(ResyncWatermark, RemeshedCopyIsTracedOnItsSurface) {
  MM_REQUIRE_SHARED_MESHES();
  const Fixture& f = fixture();
  // Isotropic remeshing at 2 % of the diagonal: about 4k vertices on the marked surface, none of
  // them a refined vertex. The control points fitted to it carry little of the mark; the
  // suspect's normal offsets regressed on the mark's shapes carry it whole.
  const EmbedParams m2{Method::Additive, 0.01, 0.05};
  Mesh marked2 = f.control;
  marked2.points = embed(f.basis, f.control.points, f.message, f.key, f.nonce, m2);
  const Mesh suspect = attacks::remesh_isotropic(subdivide(marked2, 3), 0.02);
  const Mesh clean = attacks::remesh_isotropic(subdivide(f.control, 3), 0.02);
  const int usable = usable_coefficients(f.basis);
  auto surface_score = [&](const Mesh& m, const Key& key, const std::vector<bool>& message) {
    const Resynchronized r = resynchronize(*f.context, m);
    EXPECT_EQ(r.method, "surface-fit");
    const SurfaceOffsets s = surface_offsets(*f.context, m, r.to_control_frame);
    EXPECT_GT(s.offsets.size(), m.num_vertices() * 9 / 10);
    const CoefficientEvidence ev =
        surface_evidence(f.basis, f.control.points, s.rows, s.normals, s.offsets, s.nuisance, kBits, m2);
    return matched_score(ev, key, f.nonce, message, usable);
  };
  const MatchedScore leak = surface_score(suspect, f.key, f.message);
  std::printf("  remeshed 2 %%: %d vertices, matched T %.1f, -log10 p %.1f\n", suspect.num_vertices(),
              leak.statistic, leak.neg_log10_p);
  EXPECT_GT(leak.neg_log10_p, 15);
  EXPECT_EQ(leak.message, f.message);
  // A shift and a slight rotation the alignment leaves: the nuisance terms take it, not the mark.
  Mesh moved = suspect;
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(2e-3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  moved.points = (moved.points * turn.transpose()).rowwise() + Eigen::RowVector3d(2e-3, -1e-3, 1e-3);
  const SurfaceOffsets off = surface_offsets(*f.context, moved, Similarity());
  const MatchedScore shifted = matched_score(
      surface_evidence(f.basis, f.control.points, off.rows, off.normals, off.offsets, off.nuisance, kBits, m2),
      f.key, f.nonce, f.message, usable);
  const MatchedScore shifted_bare = matched_score(
      surface_evidence(f.basis, f.control.points, off.rows, off.normals, off.offsets, Eigen::MatrixXd(), kBits, m2),
      f.key, f.nonce, f.message, usable);
  std::printf("  shifted, unaligned: -log10 p %.1f with the nuisance terms, %.1f without\n", shifted.neg_log10_p,
              shifted_bare.neg_log10_p);
  EXPECT_GT(shifted.neg_log10_p, 0.7 * leak.neg_log10_p);
  EXPECT_LT(shifted_bare.neg_log10_p, shifted.neg_log10_p);
  // Innocents: the unmarked surface remeshed alike, and the leak under another key.
  Key other = f.key;
  other[0] ^= 1;
  const MatchedScore unmarked = surface_score(clean, f.key, f.message);
  const MatchedScore wrong_key = surface_score(suspect, other, f.message);
  std::printf("  innocents: unmarked -log10 p %.2f, other key %.2f\n", unmarked.neg_log10_p, wrong_key.neg_log10_p);
  EXPECT_LT(unmarked.neg_log10_p, 3);
  EXPECT_LT(wrong_key.neg_log10_p, 3);
}
