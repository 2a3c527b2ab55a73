// Prepared assets: the compressed control polyhedron and its basis round-trip exactly through the
// cached records (old uncompressed records still read), oversized or uncompressible inputs are
// refused with the file and reason, shape signatures ignore tessellation, scale and pose.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <iostream>

#include "common/shared_meshes.h"
#include "jobs/payload.h"
#include "jobs/prepared_asset.h"
#include "jobs/protect.h"
#include "meshio/read_mesh.h"
#include "quality/surface_distance.h"
#include "subdivision/decompress.h"

namespace mm::jobs {
namespace {

TEST(Payload, BitsAndHexRoundTrip) {
  std::uint64_t v = 0x0123456789abcdefULL;
  EXPECT_EQ(bits_to_payload(payload_to_bits(v, 64)), v);
  EXPECT_EQ(bits_to_payload(payload_to_bits(v, 32)), v & 0xffffffffULL);
  EXPECT_EQ(payload_hex(0xabcULL, 32), "00000abc");
  EXPECT_EQ(parse_payload_hex("00000abc"), 0xabcULL);
  EXPECT_THROW(parse_payload_hex("xyz"), std::invalid_argument);
  EXPECT_THROW(parse_payload_hex(""), std::invalid_argument);
  EXPECT_THROW(payload_to_bits(1, 65), std::invalid_argument);
}

TEST(PreparedAsset, CompressedPolyhedronRoundTripsExactly) {
  MM_REQUIRE_SHARED_MESHES();
  Mesh m = read_mesh(test::shared_mesh("abc7.stl"));
  PrepareParams fit_only;
  fit_only.min_mark_vertices = 0;  // the compressor's polyhedron as it is
  PreparedAsset a = prepare_asset(m, fit_only, "abc7.stl");
  EXPECT_LT(a.control.num_vertices(), m.num_vertices());
  EXPECT_FALSE(a.control.creases.empty());
  EXPECT_EQ(a.levels, 3);
  EXPECT_EQ(a.basis.num_vertices(), a.control.num_vertices());
  // The polyhedron lies in the part's unit box (fitted control points may stand a little out).
  EXPECT_NEAR(a.control.points.maxCoeff(), 1.0, 0.05);
  EXPECT_NEAR(a.control.points.minCoeff(), 0.0, 0.05);
  auto poly = encode_polyhedron(a);
  auto basis = serialize_basis(a.basis);
  PreparedAsset b = decode_prepared(poly, basis, "test");
  EXPECT_EQ(b.control.faces, a.control.faces);
  EXPECT_EQ(b.control.creases, a.control.creases);
  EXPECT_EQ(b.control.corners, a.control.corners);
  EXPECT_EQ(b.levels, a.levels);
  EXPECT_TRUE((b.control.points.array() == a.control.points.array()).all());
  EXPECT_EQ(serialize_basis(b.basis), serialize_basis(a.basis));
  EXPECT_EQ(b.normalization.scale, a.normalization.scale);
  EXPECT_EQ(b.signature.vertices, m.num_vertices());
  EXPECT_EQ(encode_polyhedron(b), poly);
  // One record format: any other magic is refused.
  std::vector<std::uint8_t> v1 = poly;
  v1[7] = '1';
  EXPECT_THROW(decode_prepared(v1, basis, "v1"), InputError);
}

TEST(PreparedAsset, CacheKeyNamesEveryCompressionOption) {
  PrepareParams p;
  std::string k = p.key();
  for (auto change : {+[](PrepareParams& q) { q.compression.tolerance = 0.01; },
                      +[](PrepareParams& q) { q.compression.max_vertices = 500; },
                      +[](PrepareParams& q) { q.compression.levels = 2; },
                      +[](PrepareParams& q) { q.compression.angle_degrees = 40; },
                      +[](PrepareParams& q) { q.compression.rail_quads = false; },
                      +[](PrepareParams& q) { q.compression.coarsen = true; },
                      +[](PrepareParams& q) { q.compression.seed = 2; },
                      +[](PrepareParams& q) { q.fallback_angles = {}; },
                      +[](PrepareParams& q) { q.fallback_angles = {30, 20}; },
                      +[](PrepareParams& q) { q.min_mark_vertices = 0; },
                      +[](PrepareParams& q) { q.min_mark_vertices = 400; },
                      +[](PrepareParams& q) { q.max_copy_triangles = 1000000; }}) {
    PrepareParams q;
    change(q);
    EXPECT_NE(q.key(), k);
  }
  // The rounds' schedule comes from compress.cpp's constants, and names them.
  EXPECT_NE(k.find(rounds_schedule_key(p.compression)), std::string::npos) << k;
  EXPECT_NE(rounds_schedule_key(p.compression).find("first-warm-growth="), std::string::npos);
  // So does the fit's sampling.
  EXPECT_NE(k.find(mm::fit_sampling_key()), std::string::npos) << k;
  EXPECT_NE(mm::fit_sampling_key().find("crease-spacing="), std::string::npos);
  PrepareParams cap;
  cap.max_control_vertices = 2000;  // refuses, never changes a result
  EXPECT_EQ(cap.key(), k);
}

// A small part's polyhedron (abc7: 24 control vertices) is refined by whole subdivision steps
// until it has min_mark_vertices, within max_control_vertices, and decoded one level less: the
// decoded copy is the same surface with the same number of vertices.
TEST(PreparedAsset, SmallPolyhedraAreRefinedForTheMarkOnTheSameSurface) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(test::shared_mesh("abc7.stl"));
  PrepareParams fit_only;
  fit_only.min_mark_vertices = 0;
  const PreparedAsset coarse = prepare_asset(m, fit_only, "abc7.stl"), fine = prepare_asset(m, {}, "abc7.stl");
  ASSERT_EQ(coarse.refinements, 0);
  EXPECT_EQ(coarse.control.num_vertices(), 24);
  EXPECT_EQ(fine.refinements, 2);
  EXPECT_GE(fine.control.num_vertices(), PrepareParams{}.min_mark_vertices);
  EXPECT_EQ(fine.levels, coarse.levels - 2);
  EXPECT_EQ(fine.basis.num_vertices(), fine.control.num_vertices());
  EXPECT_EQ(fine.control.corners.size(), coarse.control.corners.size());  // children keep their index
  // The 24 vertices spread a 32-bit payload over 2 coefficients a bit, with a warning; refined, 33.
  EXPECT_NE(weak_spread_warning("abc7.stl", coarse, 32).find("2 coefficients a bit"), std::string::npos);
  EXPECT_EQ(weak_spread_warning("abc7.stl", fine, 32), "");
  const Mesh a = decompress_to_level(coarse.control, coarse.levels), b = decompress_to_level(fine.control, fine.levels);
  ASSERT_EQ(a.num_vertices(), b.num_vertices());
  double worst = 0;  // vertex numbering may differ: nearest vertex of the other surface
  for (int i = 0; i < a.num_vertices(); ++i)
    worst = std::max(worst, (b.points.rowwise() - a.points.row(i)).rowwise().norm().minCoeff());
  EXPECT_LT(worst, 1e-12);
  // A step that would pass the cap is not taken.
  Mesh once = coarse.control;
  EXPECT_EQ(refine_for_mark(once, 200, 150), 1);
  EXPECT_LE(once.num_vertices(), 150);
  EXPECT_GT(once.num_vertices(), 24);
}

// A copy over max_copy_triangles is decoded at the highest level within it, when the copy there
// still meets the tolerance by the dense measurement (which becomes the fit's numbers, so the
// mark gets what that level leaves); else the part is refused with both counts.
TEST(PreparedAsset, CopiesOverTheTriangleLimitAreDecodedLowerOrRefused) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(test::shared_mesh("abc9.stl"));
  // At 0.25 % (the daemon's fit share of the default tolerance) abc9 fits with a few hundred
  // control vertices, dense enough that one level less still meets it.
  PrepareParams p;
  p.min_mark_vertices = 0;
  p.compression.tolerance = 0.0025;
  const PreparedAsset full = prepare_asset(m, p, "abc9.stl");
  ASSERT_EQ(full.levels, 3);
  const long long at3 = subdivided_triangle_count(full.control, 3), at2 = subdivided_triangle_count(full.control, 2);
  p.max_copy_triangles = at3;  // the limit itself is allowed
  EXPECT_EQ(prepare_asset(m, p, "abc9.stl").levels, 3);
  p.max_copy_triangles = at3 - 1;
  const PreparedAsset lower = prepare_asset(m, p, "abc9.stl");
  EXPECT_EQ(lower.levels, 2);
  EXPECT_EQ(lower.control.points, full.control.points);  // the same polyhedron, decoded less
  const SurfaceDistance d = decoded_distance(m, lower.compression.control, 2);
  std::cout << "abc9: " << full.control.num_vertices() << " control vertices; level 3 "
            << 100 * full.compression.stats.hausdorff / full.compression.stats.diagonal << " %, level 2 "
            << 100 * d.hausdorff_relative() << " % (" << at2 << " triangles)\n";
  EXPECT_LE(d.hausdorff_relative(), p.compression.tolerance);
  EXPECT_EQ(lower.compression.stats.hausdorff, d.hausdorff);
  EXPECT_EQ(lower.compression.stats.rms, d.rms);
  EXPECT_EQ(triangle_count(make_copy_files(lower, lower.compression.control, {}, true).decoded), at2);
  // At 0.5 % abc9 fits with a few dozen vertices, whose level-2 surface lies outside it: refused,
  // naming both counts.
  PrepareParams loose;
  loose.min_mark_vertices = 0;
  const PreparedAsset coarse = prepare_asset(m, loose, "abc9.stl");
  const long long coarse3 = subdivided_triangle_count(coarse.control, 3);
  loose.max_copy_triangles = coarse3 - 1;
  try {
    prepare_asset(m, loose, "abc9.stl");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "abc9.stl");
    const std::string what = e.what();
    EXPECT_NE(what.find(std::to_string(coarse3) + " triangles, over the copy limit"), std::string::npos) << what;
    EXPECT_NE(what.find("at level 2 (" + std::to_string(subdivided_triangle_count(coarse.control, 2)) +
                        " triangles) it misses the tolerance"), std::string::npos) << what;
  }
}

// compression.coarsen = true in the daemon's config: the prepared polyhedron is the coarsened
// one, with fewer vertices than its rounds' that met the tolerance, within the tolerance
// (tolerance_met: the preparation's dense measurement confirmed it), and its basis is that
// polyhedron's. (Not fewer than without coarsening: the reweighted rounds without it end at 36
// vertices on abc9, the coarsened at 42.)
TEST(PreparedAsset, CoarseningShrinksThePolyhedronWithinTheTolerance) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(test::shared_mesh("abc9.stl"));
  PrepareParams plain, coarse;
  plain.min_mark_vertices = coarse.min_mark_vertices = 0;
  coarse.compression.coarsen = true;
  const PreparedAsset a = prepare_asset(m, plain, "abc9.stl"), b = prepare_asset(m, coarse, "abc9.stl");
  int fewest_met = 1 << 30;
  for (std::size_t k = 0; k < b.compression.round_vertices.size(); ++k)
    if (b.compression.round_errors[k] <= coarse.compression.tolerance)
      fewest_met = std::min(fewest_met, b.compression.round_vertices[k]);
  EXPECT_LT(b.control.num_vertices(), fewest_met);
  EXPECT_TRUE(b.compression.tolerance_met);
  EXPECT_LE(b.compression.stats.hausdorff / b.compression.stats.diagonal, coarse.compression.tolerance);
  EXPECT_EQ(b.basis.num_vertices(), b.control.num_vertices());
  EXPECT_EQ(b.control.corners.size(), a.control.corners.size());
}

// fandisk_quads has folds a little flatter than 35 degrees, which the smooth surface rounds off:
// at the configured 35 degrees the plain least-squares fit misses the tolerance in its first
// rounds and meets it only in the extended rounds, with many more vertices; with the fallback
// angles the preparation takes the first smaller one that meets it in the first rounds, by the
// dense measurement. (With compression.coarsen, whose
// rounds fit by plain least squares; without it, the reweighted fit holds the folds within the
// tolerance at 35 degrees, with 99 control vertices.)
TEST(PreparedAsset, SmallerAnglesWhenTheConfiguredOneMissesTheTolerance) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(test::shared_mesh("fandisk_quads.off"));
  PrepareParams coarsened;
  coarsened.compression.coarsen = true;
  PrepareParams only = coarsened;
  only.fallback_angles = {};
  const PreparedAsset at35 = prepare_asset(m, only, "fandisk_quads.off");
  EXPECT_TRUE(at35.compression.tolerance_met);
  EXPECT_GT(at35.compression.rounds, only.compression.max_rounds);
  EXPECT_EQ(at35.compression.angle_degrees, 35);
  const PreparedAsset a = prepare_asset(m, coarsened, "fandisk_quads.off");
  EXPECT_TRUE(a.compression.tolerance_met);
  EXPECT_LT(a.compression.angle_degrees, 35);
  // A crease where the fold is, not vertices spent rounding it: fewer of them.
  EXPECT_LT(a.control.num_vertices(), at35.control.num_vertices());
  std::cout << "fandisk_quads: " << at35.control.num_vertices() << " vertices at 35 degrees, "
            << a.control.num_vertices() << " at " << a.compression.angle_degrees << "\n";
  EXPECT_LE(decoded_distance(m, a.compression.control, a.levels).hausdorff_relative(), only.compression.tolerance);
  EXPECT_EQ(a.basis.num_vertices(), a.control.num_vertices());
  // A part that meets the tolerance at the configured angle is prepared as before.
  const Mesh part = read_mesh(test::shared_mesh("abc9.stl"));
  const PreparedAsset b = prepare_asset(part, coarsened, "abc9.stl"), c = prepare_asset(part, only, "abc9.stl");
  EXPECT_EQ(b.compression.angle_degrees, 35);
  EXPECT_EQ(b.control.points, c.control.points);
  EXPECT_EQ(b.control.faces, c.control.faces);
}

TEST(PreparedAsset, CorruptRecordsAreInputErrors) {
  MM_REQUIRE_SHARED_MESHES();
  PreparedAsset a = prepare_asset(read_mesh(test::shared_mesh("chamfer-cube.off")), {}, "cube");
  auto poly = encode_polyhedron(a);
  auto basis = serialize_basis(a.basis);
  for (std::size_t cut : {std::size_t(0), std::size_t(7), std::size_t(20), poly.size() / 2, poly.size() - 1}) {
    std::vector<std::uint8_t> t(poly.begin(), poly.begin() + static_cast<long>(cut));
    EXPECT_THROW(decode_prepared(t, basis, "cut"), InputError) << cut;
  }
  auto huge = poly;
  for (int i = 8; i < 16; ++i) huge[static_cast<std::size_t>(i)] = 0xff;  // absurd vertex count
  EXPECT_THROW(decode_prepared(huge, basis, "huge"), InputError);
  // A basis of another size (abc9's polyhedron; abc7's has chamfer-cube's 24 vertices).
  auto other = prepare_asset(read_mesh(test::shared_mesh("abc9.stl")), {}, "abc9");
  ASSERT_NE(other.control.num_vertices(), a.control.num_vertices());
  EXPECT_THROW(decode_prepared(poly, serialize_basis(other.basis), "mismatch"), InputError);
}

TEST(PreparedAsset, RefusesABudgetBeyondTheBasisLimitAndUncompressibleMeshes) {
  Mesh m;
  m.points.resize(5, 3);
  m.points << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 1;
  m.faces = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}, {0, 3, 2, 1}};
  PrepareParams p;
  p.max_control_vertices = 100;  // budget 1000: refused before any work
  EXPECT_THROW(prepare_asset(m, p, "pyramid.off"), std::invalid_argument);
  Mesh flat = m;
  flat.points.col(2).setZero();
  flat.points.col(1).setZero();  // every point on a line: no box to normalise into
  try {
    prepare_asset(flat, {}, "flat.off");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "flat.off") << e.what();
  }
}

TEST(ShapeSignature, IgnoresTessellationScalePoseNotShape) {
  MM_REQUIRE_SHARED_MESHES();
  Mesh a = read_mesh(test::shared_mesh("abc7.stl"));
  Mesh moved = a;
  Eigen::Matrix3d rot = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  moved.points = ((moved.points * rot.transpose()) * 3.5).rowwise() + Eigen::RowVector3d(10, -4, 2);
  // The decoded copy: about 10x the vertices, another tessellation of (nearly) the same surface.
  PreparedAsset prep = prepare_asset(a, {}, "abc7.stl");
  Mesh control = prep.control;
  undo(prep.normalization, control.points);
  Mesh decoded = make_copy_files(prep, control, {}, false).decoded;
  ASSERT_GT(decoded.num_vertices(), 5 * a.num_vertices());
  Mesh other = read_mesh(test::shared_mesh("abc9.stl"));
  double same = signature_distance(shape_signature(a), shape_signature(moved));
  double retessellated = signature_distance(shape_signature(a), shape_signature(decoded));
  double diff = signature_distance(shape_signature(a), shape_signature(other));
  std::cout << "signature distances: moved " << same << ", decoded " << retessellated << ", abc9 " << diff << "\n";
  EXPECT_LT(same, 1e-6);  // rounding of the rotation only
  EXPECT_LT(retessellated, 0.05);
  EXPECT_GT(diff, 0.1);
  auto s = shape_signature(a);
  auto back = ShapeSignature::from_json(s.to_json());
  EXPECT_LT(signature_distance(s, back), 1e-12);
  EXPECT_THROW(ShapeSignature::from_json("{\"vertices\": 3}"), InputError);
  // One signature version: another is refused.
  ShapeSignature old = s;
  old.version = 1;
  EXPECT_THROW(ShapeSignature::from_json(old.to_json()), InputError);
}

}  // namespace
}  // namespace mm::jobs
