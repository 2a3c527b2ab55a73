#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <tuple>
#include <array>
#include <algorithm>

#include "codec/codec_test_meshes.h"
#include "codec/stream.h"
#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"

namespace {

std::vector<std::pair<int, int>> sorted_creases(const mm::Mesh& m) {
  std::vector<std::pair<int, int>> c;
  for (auto [a, b] : m.creases) c.emplace_back(std::min(a, b), std::max(a, b));
  std::sort(c.begin(), c.end());
  c.erase(std::unique(c.begin(), c.end()), c.end());
  return c;
}

// Faces as a multiset of oriented cycles: each rotated to start at its smallest vertex, sorted.
std::vector<std::vector<int>> canonical(std::vector<std::vector<int>> faces) {
  for (auto& f : faces) std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
  std::sort(faces.begin(), faces.end());
  return faces;
}

// Round trip: quantised values bit-exact, topology identical, re-encoding byte-identical.
void expect_round_trip(const mm::Mesh& m, int bits, const std::string& name) {
  SCOPED_TRACE(name + " at " + std::to_string(bits) + " bits");
  mm::CodecParams params;
  params.quant_bits = bits;
  params.metadata = {{"asset", "A-17"}, {"copy", "c0042"}};
  if (bits % 2 == 0) params.metadata["levels"] = "3";  // version 3 keeps it in the header
  const auto bytes = mm::encode(m, params);
  const mm::DecodedStream d = mm::decode(bytes, name);
  EXPECT_EQ(d.version, bits < 8 ? 4 : 3);  // version 4: 6 and 7 bits

  const mm::Quantization q = mm::quantization_for(m.points, bits);
  EXPECT_EQ(d.quantization.bits, bits);
  EXPECT_EQ(d.quantization.step, q.step);
  EXPECT_EQ(d.quantization.offset, q.offset);
  EXPECT_EQ(d.grid, mm::quantize(m.points, q));
  // Exact equality of doubles: decode(encode(m)) == dequantize(quantize(m)).
  EXPECT_TRUE(d.mesh.points == mm::dequantize(mm::quantize(m.points, q), q));
  EXPECT_LE((d.mesh.points - m.points).cwiseAbs().maxCoeff(), 0.5 * q.step * (1 + 1e-9));
  EXPECT_EQ(canonical(d.mesh.faces), canonical(m.faces));  // same oriented faces
  EXPECT_EQ(d.mesh.creases, sorted_creases(m));
  std::vector<int> corners = m.corners;
  std::sort(corners.begin(), corners.end());
  EXPECT_EQ(d.mesh.corners, corners);
  EXPECT_EQ(d.metadata, params.metadata);
  EXPECT_EQ(mm::encode(d.mesh, params), bytes);
}

}  // namespace

TEST(Stream, RoundTripSynthetic) {
  for (int bits : {6, 7, 8, 10, 12, 16, 20, 24}) {
    expect_round_trip(mm::test::crease_cube(), bits, "cube");
    expect_round_trip(mm::test::wavy_grid(17, 11, 3), bits, "grid");
    expect_round_trip(mm::test::wavy_grid(60, 45, 9), bits, "big grid");
  }
}

TEST(Stream, RoundTripCopiesQuadsAndComponents) {
  // Version 3's coordinate copying, quad predictions and several components: an axis-aligned
  // box of quads (every coordinate repeats a neighbour's), beside a grid and a lone triangle.
  mm::Mesh m = mm::test::crease_cube();
  const mm::Mesh g = mm::test::wavy_grid(7, 5, 2);
  const int base = m.num_vertices();
  m.points.conservativeResize(base + g.num_vertices() + 3, 3);
  m.points.block(base, 0, g.num_vertices(), 3) = g.points;
  m.points.bottomRows(3) << 9, 9, 9, 10, 9, 9, 9, 10, 9.5;
  for (auto f : g.faces) {
    for (int& v : f) v += base;
    m.faces.push_back(f);
  }
  const int t = base + g.num_vertices();
  m.faces.push_back({t, t + 1, t + 2});
  for (auto [a, b] : g.creases) m.creases.emplace_back(a + base, b + base);
  for (int bits : {8, 12, 24}) {
    expect_round_trip(m, bits, "components");
    // and renumbered as compress numbers its control meshes
    expect_round_trip(mm::in_traversal_order(m), bits, "components renumbered");
  }
}

// A numbering from any start vertex: the stream's own traversal order (encoding it keeps it),
// vertex 0 where asked, and the same faces, creases and corners between the same points.
TEST(Stream, InTraversalOrderFromAnyStartIsTheSameSurface) {
  mm::Mesh m = mm::test::wavy_grid(7, 5, 2);
  m.corners = {3, 20};
  const int n = m.num_vertices();
  const auto order = mm::traversal_vertex_order(m);
  const mm::Mesh zero = mm::in_traversal_order(m);
  for (int k = 0; k < n; ++k) EXPECT_TRUE(zero.points.row(k) == m.points.row(order[k])) << k;
  const auto as_points = [](const mm::Mesh& x) {
    const auto p = [&x](int v) { return std::array<double, 3>{x.points(v, 0), x.points(v, 1), x.points(v, 2)}; };
    std::set<std::vector<std::array<double, 3>>> faces, creases;
    for (const auto& f : x.faces) {
      std::vector<std::array<double, 3>> c;
      for (int v : f) c.push_back(p(v));
      std::rotate(c.begin(), std::min_element(c.begin(), c.end()), c.end());
      faces.insert(c);
    }
    for (auto [a, b] : x.creases) creases.insert({std::min(p(a), p(b)), std::max(p(a), p(b))});
    std::set<std::array<double, 3>> corners;
    for (int c : x.corners) corners.insert(p(c));
    return std::tuple{faces, creases, corners};
  };
  for (int first : {0, 5, 17, n - 1}) {
    const mm::Mesh r = mm::in_traversal_order(m, first);
    EXPECT_TRUE(r.points.row(0) == m.points.row(first)) << first;
    const auto again = mm::traversal_vertex_order(r);
    for (int k = 0; k < n; ++k) EXPECT_EQ(again[k], k) << first;
    EXPECT_TRUE(as_points(r) == as_points(m)) << first;
    EXPECT_TRUE(std::is_sorted(r.creases.begin(), r.creases.end()));
    EXPECT_TRUE(std::is_sorted(r.corners.begin(), r.corners.end()));
  }
  EXPECT_THROW(mm::in_traversal_order(m, n), std::invalid_argument);
}

TEST(Stream, RoundTripSharedMeshes) {
  MM_REQUIRE_SHARED_MESHES();
  for (const char* name : {"fandisk_quads.off", "chamfer-cube.off", "sphere_low.off"}) {
    mm::Mesh m = mm::read_mesh(mm::test::shared_mesh(name));
    // Tag the sharpest-looking edges so creases are exercised on real topology: every 7th edge.
    const auto edges = mm::unique_edges(m);
    for (size_t e = 0; e < edges.size(); e += 7) m.creases.push_back(edges[e]);
    m.corners = {0, m.num_vertices() / 2, m.num_vertices() - 1};
    for (int bits : {10, 12, 16, 24}) expect_round_trip(m, bits, name);
  }
}

TEST(Stream, HighDegreeVertexRoundTrips) {
  // A disc of 20000 triangles around one vertex: version 3's per-decision work (hints, copy
  // candidates) is bounded per decision, so this stays linear (it would be quadratic in the
  // hub's degree otherwise).
  const int n = 20000;
  mm::Mesh m;
  m.points.resize(n + 1, 3);
  m.points.row(0) << 0, 0, 0;
  for (int i = 0; i < n; ++i)
    m.points.row(i + 1) << std::cos(2 * M_PI * i / n), std::sin(2 * M_PI * i / n), (i % 7) * 1e-3;
  for (int i = 0; i < n; ++i) m.faces.push_back({0, 1 + i, 1 + (i + 1) % n});
  m.creases = {{0, 1}};
  m.corners = {0};
  expect_round_trip(m, 16, "fan");
}

TEST(Stream, VertexOrderIsPreserved) {
  // The same geometry in two vertex orders gives streams whose decoded points follow each order.
  const mm::Mesh a = mm::test::wavy_grid(12, 9, 1);
  mm::Mesh b = a;
  const int n = a.num_vertices();
  std::vector<int> perm(n);  // new index of old vertex i
  for (int i = 0; i < n; ++i) perm[i] = (i * 37 + 5) % n;  // 37 is coprime with 108
  for (int i = 0; i < n; ++i) b.points.row(perm[i]) = a.points.row(i);
  for (auto& f : b.faces)
    for (int& v : f) v = perm[v];
  for (auto& [x, y] : b.creases) {
    x = perm[x];
    y = perm[y];
  }
  for (int& c : b.corners) c = perm[c];
  const auto da = mm::decode(mm::encode(a), "a");
  const auto db = mm::decode(mm::encode(b), "b");
  EXPECT_EQ(da.quantization.step, db.quantization.step);
  for (int i = 0; i < n; ++i) EXPECT_EQ(da.grid.row(i), db.grid.row(perm[i]));
  EXPECT_EQ(canonical(db.mesh.faces), canonical(b.faces));
}

TEST(Stream, FaceOrderAndRotationDoNotChangeTheBytes) {
  // Face order carries no meaning, so the stream is canonical in it.
  const mm::Mesh a = mm::test::wavy_grid(15, 10, 4);
  mm::Mesh b = a;
  std::mt19937 rng(11);
  std::shuffle(b.faces.begin(), b.faces.end(), rng);
  for (auto& f : b.faces) std::rotate(f.begin(), f.begin() + rng() % f.size(), f.end());
  std::shuffle(b.creases.begin(), b.creases.end(), rng);
  for (auto& [x, y] : b.creases) std::swap(x, y);
  EXPECT_EQ(mm::encode(a), mm::encode(b));
  // Orientation does matter: reversing one face changes the stream.
  mm::Mesh c = a;
  std::reverse(c.faces[3].begin(), c.faces[3].end());
  EXPECT_NE(mm::encode(a), mm::encode(c));
  EXPECT_EQ(canonical(mm::decode(mm::encode(c), "c").mesh.faces), canonical(c.faces));
}

TEST(Stream, EmptyAndSingleVertexMeshes) {
  mm::Mesh empty;
  empty.points.resize(0, 3);
  const auto d = mm::decode(mm::encode(empty), "empty");
  EXPECT_EQ(d.mesh.num_vertices(), 0);
  EXPECT_TRUE(d.mesh.faces.empty());
  mm::Mesh one;
  one.points.resize(1, 3);
  one.points << 4, 5, 6;
  const auto d1 = mm::decode(mm::encode(one), "one");
  EXPECT_TRUE(d1.mesh.points == mm::quantized_positions(one.points, 12));
  EXPECT_LE((d1.mesh.points - one.points).cwiseAbs().maxCoeff(), std::ldexp(1.0, -40));
}

TEST(Stream, EncoderRejectsWhatTheFormatCannotHold) {
  const mm::Mesh good = mm::test::crease_cube();
  auto expect_reject = [](const mm::Mesh& m, const std::string& fragment, mm::CodecParams p = {}) {
    try {
      mm::encode(m, p);
      ADD_FAILURE() << "accepted, expected: " << fragment;
    } catch (const mm::InputError& e) {
      EXPECT_EQ(e.source(), "encode");
      EXPECT_NE(e.reason().find(fragment), std::string::npos) << e.what();
    }
  };
  mm::Mesh m = good;
  m.faces.push_back({0, 1, 2, 3, 4});
  expect_reject(m, "triangles and quads only");
  m = good;
  m.faces[2][1] = 8;
  expect_reject(m, "out of range");
  m = good;
  m.faces[2] = {0, 1, 1};
  expect_reject(m, "repeats");
  m = good;
  m.creases.push_back({0, 7});  // a diagonal, not an edge
  expect_reject(m, "not an edge");
  m = good;
  m.corners.push_back(-1);
  expect_reject(m, "corner");
  m = good;
  m.points(3, 2) = std::numeric_limits<double>::infinity();
  expect_reject(m, "non-finite");
  mm::CodecParams p;
  p.quant_bits = 30;
  expect_reject(good, "quantisation bits", p);
  p.quant_bits = 5;
  expect_reject(good, "quantisation bits 5 outside [6, 24]", p);
  p = {};
  p.metadata["bad key"] = "x";
  expect_reject(good, "metadata key", p);
  p = {};
  p.metadata["k"] = std::string(2000, 'v');
  expect_reject(good, "too long", p);
}

TEST(Stream, FilesAreWrittenAtomicallyAndReadBack) {
  const auto dir = std::filesystem::temp_directory_path() / ("mm_codec_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "cube.mmc").string();
  const auto bytes = mm::encode(mm::test::crease_cube());
  mm::write_stream_file(path, bytes);
  EXPECT_EQ(mm::read_stream_file(path), bytes);
  EXPECT_EQ(canonical(mm::decode_file(path).mesh.faces), canonical(mm::test::crease_cube().faces));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), {}), 1);
  EXPECT_THROW(mm::write_stream_file((dir / "missing" / "x.mmc").string(), bytes), mm::InputError);
  EXPECT_THROW(mm::read_stream_file((dir / "nope.mmc").string()), mm::InputError);
  {
    std::ofstream(dir / "text.mmc") << "OFF\n3 1 0\n";
  }
  try {
    mm::decode_file((dir / "text.mmc").string());
    ADD_FAILURE();
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), (dir / "text.mmc").string());
    EXPECT_NE(e.reason().find("magic"), std::string::npos);
  }
  std::filesystem::remove_all(dir);
}

TEST(Stream, SizesAreReported) {
  MM_REQUIRE_SHARED_MESHES();
  const mm::Mesh m = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  for (int bits : {12, 16}) {
    mm::CodecParams p;
    p.quant_bits = bits;
    const size_t size = mm::encode(m, p).size();
    std::cout << "fandisk_quads.off (" << m.num_vertices() << " vertices, " << m.num_faces()
              << " faces) at " << bits << " bits: " << size << " bytes\n";
    // Far below the 3 x 4-byte float + 4 x 4-byte index raw size.
    EXPECT_LT(size, m.num_vertices() * 12u + m.num_faces() * 16u);
  }
}
