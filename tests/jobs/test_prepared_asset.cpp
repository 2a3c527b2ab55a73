// Prepared assets: exact round trip of the cached polyhedron and basis, refusal of oversized or
// corrupted inputs, shape signatures and payload encoding.
#include <gtest/gtest.h>

#include "common/shared_meshes.h"
#include "jobs/payload.h"
#include "jobs/prepared_asset.h"
#include "meshio/read_mesh.h"

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

TEST(PreparedAsset, EncodeDecodeIsExact) {
  MM_REQUIRE_SHARED_MESHES();
  Mesh m = read_mesh(test::shared_mesh("fandisk_quads.off"));
  PreparedAsset a = prepare_asset(m, {}, "fandisk_quads.off");
  // The control polyhedron lies in the unit box and maps back to the original exactly enough.
  EXPECT_NEAR(a.control.points.maxCoeff(), 1.0, 1e-12);
  EXPECT_NEAR(a.control.points.minCoeff(), 0.0, 1e-12);
  auto poly = encode_polyhedron(a);
  auto basis = serialize_basis(a.basis);
  PreparedAsset b = decode_prepared(poly, basis, "test");
  EXPECT_EQ(b.control.faces, a.control.faces);
  EXPECT_TRUE((b.control.points.array() == a.control.points.array()).all());
  EXPECT_TRUE((b.basis.W.array() == a.basis.W.array()).all());
  EXPECT_EQ(b.normalization.scale, a.normalization.scale);
  EXPECT_EQ(b.signature.vertices, m.num_vertices());
  EXPECT_EQ(encode_polyhedron(b), poly);
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
  auto other = prepare_asset(read_mesh(test::shared_mesh("abc7.stl")), {}, "abc7");
  EXPECT_THROW(decode_prepared(poly, serialize_basis(other.basis), "mismatch"), InputError);
}

TEST(PreparedAsset, RefusesTooManyVerticesBeforeAllocating) {
  MM_REQUIRE_SHARED_MESHES();
  Mesh m = read_mesh(test::shared_mesh("fandisk_quads.off"));
  PrepareParams p;
  p.max_vertices = 100;
  try {
    prepare_asset(m, p, "fandisk_quads.off");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "fandisk_quads.off");
    EXPECT_NE(std::string(e.what()).find("766 vertices"), std::string::npos) << e.what();
  }
}

TEST(ShapeSignature, InvariantToScaleAndShiftNotToShape) {
  MM_REQUIRE_SHARED_MESHES();
  Mesh a = read_mesh(test::shared_mesh("abc7.stl"));
  Mesh moved = a;
  moved.points = (moved.points.array() * 3.5).matrix();
  moved.points.rowwise() += Eigen::RowVector3d(10, -4, 2);
  Mesh other = read_mesh(test::shared_mesh("abc9.stl"));
  double same = signature_distance(shape_signature(a), shape_signature(moved));
  double diff = signature_distance(shape_signature(a), shape_signature(other));
  EXPECT_LT(same, 1e-9);
  EXPECT_GT(diff, 0.05);
  auto s = shape_signature(a);
  auto back = ShapeSignature::from_json(s.to_json());
  EXPECT_LT(signature_distance(s, back), 1e-12);
  EXPECT_THROW(ShapeSignature::from_json("{\"vertices\": 3}"), InputError);
}

}  // namespace
}  // namespace mm::jobs
