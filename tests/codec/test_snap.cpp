// Rate-distortion snapping (CodecParams::snap_cells): opt-in, within the allowance, a valid
// stream that is its own re-encoding, never larger than without it.
#include <gtest/gtest.h>

#include <random>

#include "codec/codec_test_meshes.h"
#include "codec/stream.h"
#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"

namespace {

// The same control mesh as compress would give the codec: renumbered in traversal order.
mm::Mesh renumbered(const mm::Mesh& m) {
  const auto order = mm::traversal_vertex_order(m);
  std::vector<int> where(order.size());
  for (size_t k = 0; k < order.size(); ++k) where[order[k]] = static_cast<int>(k);
  mm::Mesh r = m;
  for (size_t k = 0; k < order.size(); ++k) r.points.row(static_cast<int>(k)) = m.points.row(order[k]);
  for (auto& f : r.faces)
    for (int& v : f) v = where[v];
  for (auto& [a, b] : r.creases) a = where[a], b = where[b];
  for (int& c : r.corners) c = where[c];
  return r;
}

// Encodes with the allowance and checks everything snapping promises; returns the sizes
// (snapped, plain).
std::pair<std::size_t, std::size_t> check_snapped(const mm::Mesh& m, int bits,
                                                  const std::vector<std::uint8_t>& allowance,
                                                  const std::string& name) {
  SCOPED_TRACE(name + " at " + std::to_string(bits) + " bits");
  mm::CodecParams plain;
  plain.quant_bits = bits;
  plain.metadata = {{"levels", "3"}, {"asset", "A-17"}};
  mm::CodecParams snapping = plain;
  snapping.snap_cells = allowance;
  const auto reference = mm::encode(m, plain);
  const auto bytes = mm::encode(m, snapping);
  EXPECT_LE(bytes.size(), reference.size());
  EXPECT_EQ(mm::encode(m, snapping), bytes);  // deterministic

  const mm::DecodedStream d = mm::decode(bytes, name);
  const mm::Quantization q = mm::quantization_for(m.points, bits);
  EXPECT_EQ(d.quantization.step, q.step);
  EXPECT_EQ(d.quantization.offset, q.offset);
  const mm::GridPoints nearest = mm::quantize(m.points, q);
  int moved = 0;
  for (int v = 0; v < m.num_vertices(); ++v)
    for (int a = 0; a < 3; ++a) {
      const int delta = std::abs(d.grid(v, a) - nearest(v, a));
      EXPECT_LE(delta, allowance[3 * v + a]) << "vertex " << v << " axis " << a;
      moved += delta != 0;
    }
  EXPECT_EQ(d.mesh.faces.size(), m.faces.size());
  EXPECT_EQ(d.metadata, plain.metadata);
  // The decoded polyhedron, encoded again without snapping, is the same stream.
  EXPECT_EQ(mm::encode(d.mesh, plain), bytes) << moved << " coordinates moved";
  return {bytes.size(), reference.size()};
}

std::vector<mm::Mesh> test_meshes() {
  mm::Mesh components = mm::test::crease_cube();
  const mm::Mesh g = mm::test::wavy_grid(7, 5, 2);
  const int base = components.num_vertices();
  components.points.conservativeResize(base + g.num_vertices(), 3);
  components.points.bottomRows(g.num_vertices()) = g.points;
  for (auto f : g.faces) {
    for (int& v : f) v += base;
    components.faces.push_back(f);
  }
  return {renumbered(mm::test::wavy_grid(17, 11, 3)), renumbered(mm::test::wavy_grid(60, 45, 9)),
          mm::test::wavy_grid(30, 20, 5), renumbered(components), mm::test::crease_cube()};
}

}  // namespace

TEST(Snap, OffByDefaultAndZeroAllowanceChangesNothing) {
  for (const mm::Mesh& m : test_meshes())
    for (int bits : {8, 12}) {
      mm::CodecParams plain;
      plain.quant_bits = bits;
      EXPECT_TRUE(plain.snap_cells.empty());
      mm::CodecParams zero = plain;
      zero.snap_cells.assign(3 * static_cast<std::size_t>(m.num_vertices()), 0);
      EXPECT_EQ(mm::encode(m, zero), mm::encode(m, plain));
    }
}

TEST(Snap, UniformAllowanceStaysWithinItAndSavesBytes) {
  const auto meshes = test_meshes();
  for (std::size_t i = 0; i < meshes.size(); ++i)
    for (int bits : {8, 13})
      for (std::uint8_t k : {1, 3}) {
        const auto [snapped, plain] = check_snapped(
            meshes[i], bits, std::vector<std::uint8_t>(3 * meshes[i].num_vertices(), k),
            "mesh " + std::to_string(i) + " k " + std::to_string(k));
        // The wavy grids have smooth coordinates a cell or two off their predictions: snapping
        // must find savings there.
        if (i < 3 && k >= 2) {
          EXPECT_LT(snapped, plain) << "mesh " << i << " k " << int{k} << " bits " << bits;
        }
      }
}

TEST(Snap, PerCoordinateAllowance) {
  std::mt19937 rng(7);
  for (const mm::Mesh& m : test_meshes()) {
    std::vector<std::uint8_t> allowance(3 * static_cast<std::size_t>(m.num_vertices()));
    for (auto& k : allowance) k = static_cast<std::uint8_t>(rng() % 4 == 0 ? 0 : rng() % 6);
    check_snapped(m, 10, allowance, "random allowance");
    // Only one axis free: the others must not move (check_snapped checks every coordinate).
    std::vector<std::uint8_t> only_y(allowance.size(), 0);
    for (std::size_t v = 0; v < only_y.size() / 3; ++v) only_y[3 * v + 1] = 3;
    check_snapped(m, 10, only_y, "y only");
  }
}

TEST(Snap, SharedMeshes) {
  MM_REQUIRE_SHARED_MESHES();
  for (const char* name : {"fandisk_quads.off", "chamfer-cube.off", "sphere_low.off"}) {
    const mm::Mesh m = renumbered(mm::read_mesh(mm::test::shared_mesh(name)));
    for (int bits : {8, 11})
      for (std::uint8_t k : {1, 3}) check_snapped(m, bits, std::vector<std::uint8_t>(3 * m.num_vertices(), k), name);
  }
}

TEST(Snap, BadAllowanceIsRefused) {
  const mm::Mesh m = mm::test::crease_cube();
  mm::CodecParams p;
  p.snap_cells.assign(3 * 8 - 1, 1);
  try {
    mm::encode(m, p);
    FAIL() << "a short snap_cells was accepted";
  } catch (const mm::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("snap_cells"), std::string::npos) << e.what();
  }
}
