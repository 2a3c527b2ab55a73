// Hostile and damaged streams: every one must be refused with InputError (or, for fuzzed bytes
// that happen to form a valid stream, decode to a consistent mesh), never crash or over-allocate.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdlib>
#include <random>

#include "codec/codec_test_meshes.h"
#include "codec/stream.h"
#include "codec/rice.h"
#include "codec/bytes.h"
#include "codec/stream_detail.h"
#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"

namespace cd = mm::codec_detail;

namespace {

// Version 2 (zstd payload; split() and join() build hostile variants behind a valid checksum).
std::vector<std::uint8_t> valid_stream() {
  mm::CodecParams p;
  p.format_version = 2;
  p.metadata = {{"asset", "A-17"}, {"copy", "c0042"}};
  return mm::encode(mm::test::wavy_grid(9, 7, 5), p);
}

// Version 3 (range-coded body), with creases, corners, metadata and the levels header field.
std::vector<std::uint8_t> valid_stream_v3() {
  mm::CodecParams p;
  p.metadata = {{"asset", "A-17"}, {"copy", "c0042"}, {"levels", "3"}};
  return mm::encode(mm::test::wavy_grid(9, 7, 5), p);
}

// A version 3 stream from header fields and body bytes, with a valid checksum.
std::vector<std::uint8_t> v3_stream(int packed_bits, std::int64_t exponent, std::array<std::int64_t, 3> origin,
                                    std::uint64_t vertices, std::uint64_t faces,
                                    const std::vector<std::uint8_t>& body, int version = 3) {
  cd::Writer w;
  w.raw(cd::kMagic, 4);
  w.u8(static_cast<std::uint8_t>(version));
  w.u8(static_cast<std::uint8_t>(packed_bits));
  w.varint(cd::zigzag(exponent));
  for (auto o : origin) w.varint(cd::zigzag(o));
  w.varint(vertices);
  w.varint(faces);
  w.raw(body.data(), body.size());
  w.bytes.resize(w.bytes.size() + 4);
  const std::uint32_t crc = cd::checksum(w.bytes.data(), w.bytes.size() - 4);
  for (int i = 0; i < 4; ++i) w.bytes[w.bytes.size() - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  return std::move(w.bytes);
}

// Offset of the range-coded body in a version 3 stream (after six varints).
std::size_t v3_body_offset(const std::vector<std::uint8_t>& s) {
  std::size_t at = 6;
  for (int k = 0; k < 6; ++k)
    while (s[at++] & 0x80) {
    }
  return at;
}

// Recomputes the trailing CRC so damage behind the checksum reaches the deeper checks.
void reseal(std::vector<std::uint8_t>& s) {
  if (s.size() < 4) return;
  const std::uint32_t crc = cd::checksum(s.data(), s.size() - 4);
  for (int i = 0; i < 4; ++i) s[s.size() - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
}

std::string rejection(const std::vector<std::uint8_t>& s) {
  try {
    mm::decode(s, "hostile.mmc");
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "hostile.mmc");
    return e.reason();
  }
  return "";
}

#define EXPECT_REJECTED_WITH(stream, fragment)                                        \
  do {                                                                                \
    const std::string why = rejection(stream);                                        \
    EXPECT_NE(why, "") << "accepted a stream that should fail with: " << fragment;    \
    EXPECT_NE(why.find(fragment), std::string::npos) << "reason was: " << why;        \
  } while (0)

// A decoded mesh must always be internally consistent.
void expect_consistent(const mm::DecodedStream& d) {
  const int n = d.mesh.num_vertices();
  ASSERT_EQ(d.grid.rows(), n);
  for (const auto& f : d.mesh.faces) {
    ASSERT_TRUE(f.size() == 3 || f.size() == 4);
    for (int v : f) ASSERT_TRUE(v >= 0 && v < n);
  }
  for (auto [a, b] : d.mesh.creases) ASSERT_TRUE(a >= 0 && a < b && b < n);
  for (int c : d.mesh.corners) ASSERT_TRUE(c >= 0 && c < n);
  ASSERT_TRUE(d.mesh.points.allFinite());
}

}  // namespace

TEST(StreamHostile, EveryTruncationIsRejected) {
  for (const auto& s : {valid_stream(), valid_stream_v3()})
    for (size_t len = 0; len < s.size(); ++len) {
      std::vector<std::uint8_t> t(s.begin(), s.begin() + len);
      EXPECT_NE(rejection(t), "") << "truncated to " << len;
    }
}

TEST(StreamHostile, EveryBitFlipIsRejected) {
  for (const auto& s : {valid_stream(), valid_stream_v3()})
    for (size_t i = 0; i < s.size(); ++i)
      for (int bit = 0; bit < 8; ++bit) {
        auto t = s;
        t[i] ^= static_cast<std::uint8_t>(1u << bit);
        EXPECT_NE(rejection(t), "") << "byte " << i << " bit " << bit;
      }
}

TEST(StreamHostile, Version3HeaderFields) {
  const auto s = valid_stream_v3();
  ASSERT_EQ(s[4], 3);
  ASSERT_NO_THROW(mm::decode(s, "valid"));
  const std::vector<std::uint8_t> body = {0x5A, 0x31};
  // Quantisation bits beyond 24 (packed 17 = 25 bits).
  EXPECT_REJECTED_WITH((v3_stream(17, -8, {0, 0, 0}, 3, 1, body)), "quantisation bits 25");
  // Version 4 holds 6 and 7 bits (packed 0 and 1) and nothing version 3 can hold, so that each
  // stream has one form.
  EXPECT_NO_THROW(mm::decode(v3_stream(1, -8, {0, 0, 0}, 0, 0, {}, 4), "v4"));
  EXPECT_EQ(mm::decode(v3_stream(1, -8, {0, 0, 0}, 0, 0, {}, 4), "v4").quantization.bits, 7);
  EXPECT_REJECTED_WITH((v3_stream(2, -8, {0, 0, 0}, 0, 0, {}, 4)), "quantisation bits 8 outside [6, 7] for format version 4");
  EXPECT_REJECTED_WITH((v3_stream(0, -1001, {0, 0, 0}, 3, 1, body)), "cell exponent -1001 outside");
  EXPECT_REJECTED_WITH((v3_stream(0, 1001, {0, 0, 0}, 3, 1, body)), "cell exponent 1001 outside");
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, std::int64_t{1} << 50, 0}, 3, 1, body)), "cell origin");
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, -(std::int64_t{1} << 50) - 1, 0}, 3, 1, body)), "cell origin");
  // A finite exponent whose far cells are not finite doubles.
  EXPECT_REJECTED_WITH((v3_stream(0, 1000, {0, (std::int64_t{1} << 50) - 300, 0}, 3, 1, body)), "finite range");
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, 0, 0}, 1u << 25, 1, body)), "vertex count 33554432 exceeds the limit");
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, 0, 0}, 3, 1ull << 26, body)), "face count");
  // Counts a tiny body cannot justify are refused before anything is allocated.
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, 0, 0}, 1u << 20, 0, body)), "more than a 2-byte body can hold");
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, 0, 0}, 40000, 40000, body)), "more than a 2-byte body can hold");
  // Canonical ending: no trailing zero byte; nothing after the last byte the decoder reads.
  EXPECT_REJECTED_WITH((v3_stream(0, -8, {0, 0, 0}, 0, 0, {0x12, 0x00})), "ends in a zero byte");
  auto t = s;
  t.insert(t.end() - 4, 16, 0x55);
  reseal(t);
  EXPECT_NE(rejection(t), "");
  // Version 4 holds 6 and 7 bits only: this version 3 header's bits read as more are refused.
  t = s;
  t[4] = 4;
  reseal(t);
  EXPECT_REJECTED_WITH(t, "for format version 4");
  t = s;
  t[4] = 5;
  reseal(t);
  EXPECT_REJECTED_WITH(t, "unsupported format version 5");
  // Truncated header varints behind a valid checksum.
  std::vector<std::uint8_t> u = {'M', 'M', 'C', 'S', 3, 0, 0x8F, 0x8F, 0x8F, 0x8F, 0x8F, 0x8F};
  u.resize(u.size() + 4);
  reseal(u);
  EXPECT_REJECTED_WITH(u, "truncated");
}

TEST(StreamHostile, Version3CheapBodiesStayWithinTheirBound) {
  // An empty body (all zero bits) decodes zero-residual vertices for free; within the floor
  // (2^16 vertices and faces) that is a valid stream whose memory follows the counts.
  const auto d = mm::decode(v3_stream(0, -8, {5, 6, 7}, 60000, 0, {}), "cheap");
  EXPECT_EQ(d.mesh.num_vertices(), 60000);
  EXPECT_EQ(d.grid.rows(), 60000);
  // An empty mesh has an empty body: the decoder reads zeros past the end.
  const auto e = mm::decode(v3_stream(0, -8, {0, 0, 0}, 0, 0, {}), "empty");
  EXPECT_EQ(e.mesh.num_vertices(), 0);
}

TEST(StreamHostile, Version3BodyDamageBehindAValidChecksum) {
  // Every single-byte change of the body, resealed: rejected, or a consistent mesh.
  const auto s = valid_stream_v3();
  const std::size_t body = v3_body_offset(s);
  int rejected = 0, decoded = 0;
  for (std::size_t i = body; i + 4 < s.size(); ++i)
    for (int v : {0x00, 0xFF, 0x80, 0x01, s[i] ^ 0x10}) {
      auto t = s;
      t[i] = static_cast<std::uint8_t>(v);
      reseal(t);
      try {
        expect_consistent(mm::decode(t, "body"));
        ++decoded;
      } catch (const mm::InputError&) {
        ++rejected;
      }
    }
  EXPECT_GT(rejected, 0);
  std::cout << "version 3 body damage: " << rejected << " rejected, " << decoded << " decoded consistently\n";
}

TEST(StreamHostile, BadMagicVersionAndTrailingBytes) {
  auto s = valid_stream();
  auto t = s;
  t[0] = 'X';
  EXPECT_REJECTED_WITH(t, "bad magic");
  t = s;
  t[4] = 5;
  reseal(t);
  EXPECT_REJECTED_WITH(t, "unsupported format version 5");
  t = s;
  t[4] = 0;
  reseal(t);
  EXPECT_REJECTED_WITH(t, "unsupported format version 0");
  t = s;
  t.insert(t.end() - 4, 0);
  reseal(t);
  EXPECT_NE(rejection(t), "");
  t = s;
  t.push_back(0);
  EXPECT_REJECTED_WITH(t, "checksum");
  EXPECT_REJECTED_WITH(std::vector<std::uint8_t>{}, "truncated");
}

TEST(StreamHostile, HeaderFieldsOutOfRange) {
  const auto s = valid_stream();
  const cd::Parts parts = cd::split(s.data(), s.size(), "valid");

  cd::Header h = parts.header;
  h.flags |= 0x80;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "unknown flags");
  h = parts.header;
  h.bits = 31;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "quantisation bits 31");
  h = parts.header;
  h.step = -1;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "step is not positive");
  h = parts.header;
  h.step = 1e306;  // finite, but the far end of the grid is not
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "beyond the finite range");
  h = parts.header;
  h.offset[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "not finite");
  // Huge counts: refused from the header alone, before any allocation.
  h = parts.header;
  h.vertices = 0xFFFFFFFFu;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "vertex count 4294967295 exceeds the limit");
  h = parts.header;
  h.vertices = mm::kMaxStreamVertices;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "inconsistent with the counts");
  h = parts.header;
  h.faces = 1u << 24;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "inconsistent with the counts");
  h = parts.header;
  h.corners = h.vertices + 1;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "corner count");
  h = parts.header;
  h.creases += 1;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "crease flags mark");
  h = parts.header;
  h.metadata_entries = 1000;
  EXPECT_REJECTED_WITH(cd::join(h, parts.raw, 19), "metadata entry count");
  // Declared payload size disagreeing with the frame.
  auto t = cd::join(parts.header, parts.raw, 19);
  ASSERT_NO_THROW(mm::decode(t, "rejoined"));
  h = parts.header;
  auto raw = parts.raw;
  raw.push_back(0);
  EXPECT_REJECTED_WITH(cd::join(h, raw, 19), "trailing bytes");
  EXPECT_REJECTED_WITH(cd::join(h, raw, 0), "trailing bytes");
}

TEST(StreamHostile, PayloadContentsBehindAValidChecksum) {
  // Hand-built payloads: face streams (sizes, symbols, ranks, plain indices), crease bits,
  // coordinates (plain, 12 bits), so each field can be broken on its own.
  cd::Header h;
  h.version = 1;  // plain face indices (version 2 cases below)
  h.flags = 0;  // plain coordinates
  h.bits = 12;
  h.vertices = 4;
  h.faces = 1;
  // Coordinate section: three Rice parameters, byte length, bit stream of the values (x of every
  // vertex, then y, then z).
  auto coordinates = [](std::vector<std::uint64_t> values, int k, int vertices) {
    values.resize(3 * vertices, 0);
    cd::BitWriter bits;
    for (std::uint64_t u : values) bits.rice(u, k);
    std::vector<std::uint8_t> out = {static_cast<std::uint8_t>(k), static_cast<std::uint8_t>(k),
                                     static_cast<std::uint8_t>(k),
                                     static_cast<std::uint8_t>(bits.bytes().size())};
    for (std::uint8_t b : bits.bytes()) out.push_back(b);
    return out;
  };
  auto payload = [&](std::vector<std::uint8_t> symbols, std::vector<std::uint8_t> ranks,
                     std::vector<std::uint8_t> indices, std::uint8_t crease_bits, int vertices,
                     std::vector<std::uint64_t> coords = {}, int k = 0) {
    std::vector<std::uint8_t> raw;
    raw.push_back(static_cast<std::uint8_t>(symbols.size()));
    raw.push_back(static_cast<std::uint8_t>(ranks.size()));
    raw.push_back(static_cast<std::uint8_t>(indices.size()));
    for (auto* part : {&symbols, &ranks, &indices})
      for (std::uint8_t b : *part) raw.push_back(b);
    raw.push_back(crease_bits);
    for (std::uint8_t b : coordinates(coords, k, vertices)) raw.push_back(b);
    return raw;
  };
  // One quad (0, 1, 2, 3) starting a component.
  const auto good = payload({4}, {}, {0, 1, 2, 3}, 0, 4);
  const auto ok = mm::decode(cd::join(h, good, 0), "hand");
  EXPECT_EQ(ok.mesh.faces, (std::vector<std::vector<int>>{{0, 1, 2, 3}}));
  EXPECT_EQ(mm::decode(cd::join(h, good, 19), "hand").mesh.faces, ok.mesh.faces);
  // Two quads: the second across gate (0, 1), its new vertices 4 and 5 escaped to plain indices.
  cd::Header h2 = h;
  h2.vertices = 6;
  h2.faces = 2;
  const auto two = mm::decode(cd::join(h2, payload({4, 2}, {0, 0}, {0, 1, 2, 3, 4, 5}, 0, 6), 0), "two");
  EXPECT_EQ(two.mesh.faces, (std::vector<std::vector<int>>{{0, 1, 2, 3}, {1, 0, 4, 5}}));

  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 4}, 0, 4), 0), "vertex index 4 exceeds the limit 3");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 1, 3}, 0, 4), 0), "repeats a vertex");
  EXPECT_REJECTED_WITH(cd::join(h, payload({2}, {}, {0, 1, 2, 3}, 0, 4), 0), "expected a component start");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 3}, 0xF0, 4), 0), "padding bits");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 0x81, 0x00, 2, 3}, 0, 4), 0),
                       "non-canonical varint");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 3, 0}, 0, 4), 0), "trailing bytes in the face streams");
  EXPECT_REJECTED_WITH(cd::join(h2, payload({4, 9}, {0, 0}, {0, 1, 2, 3, 4, 5}, 0, 6), 0), "gate symbol 9");
  EXPECT_REJECTED_WITH(cd::join(h2, payload({4, 2}, {9, 0}, {0, 1, 2, 3, 5}, 0, 6), 0), "neighbour rank 9");
  // Rank 2 of vertex 0 is vertex 3 (its neighbours became known as 1, 3): repeats a vertex? No:
  // face (1, 0, 3, y) with y = rank 1 of vertex 1 = 0 repeats 0.
  EXPECT_REJECTED_WITH(cd::join(h2, payload({4, 2}, {2, 1}, {0, 1, 2, 3}, 0, 6), 0), "repeats a vertex");
  // Coordinates: plain values beyond the grid, deltas stepping below zero, bad Rice data.
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 3}, 0, 4, {4096}, 12), 0),
                       "outside the 12-bit grid");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 3}, 0, 4, {9000}, 12), 0),
                       "residual 9000 exceeds the grid");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 3}, 0, 4, {100}, 0), 0),
                       "Rice quotient too long");
  EXPECT_REJECTED_WITH(cd::join(h, payload({4}, {}, {0, 1, 2, 3}, 0, 4, {}, 31), 0),
                       "Rice parameter 31 too large");
  {
    auto raw = good;
    raw.back() |= 0x80;  // 12 zero bits use 2 bytes; bit 15 is padding
    EXPECT_REJECTED_WITH(cd::join(h, raw, 0), "padding bits set in the coordinate bit stream");
    raw = good;
    raw.push_back(0);
    raw[raw.size() - 4] = 3;  // bit stream length 3: one byte too many
    EXPECT_REJECTED_WITH(cd::join(h, raw, 0), "trailing bytes in the coordinate bit stream");
  }
  {
    cd::Header hd = h;
    hd.flags = 1 << cd::kPredictionShift;  // deltas from the previous vertex
    const auto below = payload({4}, {}, {0, 1, 2, 3}, 0, 4, {0, 1});  // zigzag 1 = -1 for vertex 1
    EXPECT_REJECTED_WITH(cd::join(hd, below, 0), "outside the 12-bit grid");
    // Neighbour prediction: vertex 1's only lower neighbour is vertex 0 (at 0), same failure.
    hd.flags = 2 << cd::kPredictionShift;
    EXPECT_REJECTED_WITH(cd::join(hd, below, 0), "outside the 12-bit grid");
    cd::Header h3 = hd;  // parallelogram prediction (3) arrived with version 2
    h3.flags = 3 << cd::kPredictionShift;
    EXPECT_REJECTED_WITH(cd::join(h3, below, 0), "unknown coordinate prediction 3 for format version 1");
    const auto d = mm::decode(cd::join(hd, payload({4}, {}, {0, 1, 2, 3}, 0, 4, {0, 2}), 0), "pred");
    EXPECT_EQ(d.grid(1, 0), 1);  // zigzag 2 = +1
    EXPECT_EQ(d.grid(2, 0), 1);  // lower neighbour 1 predicts 1, residual 0
    EXPECT_EQ(d.grid(3, 0), 1);  // lower neighbours 0 and 2: mean 0.5 rounds half up to 1
  }
  {
    // Version 2: plain indices are zigzag(index - vertices seen so far), rank 0 is the next
    // unseen vertex, and parallelogram prediction. Triangles (0, 1, 2) then (1, 0, 3) across
    // gate (0, 1): vertex 3 is predicted by 0 + 1 - 2. Gates (1, 2), (2, 0), (0, 3), (3, 1) have
    // nothing across; (1, 0) would be skipped as already placed.
    cd::Header v2 = h;
    v2.version = 2;
    v2.faces = 2;
    v2.flags = 3 << cd::kPredictionShift;
    const auto tri = payload({3, 1}, {0}, {0, 0, 0}, 0, 4, {0, 20, 1, 2});
    const auto d = mm::decode(cd::join(v2, tri, 0), "v2");
    EXPECT_EQ(d.version, 2);
    EXPECT_EQ(d.mesh.faces, (std::vector<std::vector<int>>{{0, 1, 2}, {1, 0, 3}}));
    EXPECT_EQ(d.grid(0, 0), 0);   // first vertex: previous-vertex rule, 0
    EXPECT_EQ(d.grid(1, 0), 10);  // lower neighbour 0 (at 0) predicts 0, zigzag 20 = +10
    EXPECT_EQ(d.grid(2, 0), 4);   // lower neighbours 0, 1: mean 5, zigzag 1 = -1
    EXPECT_EQ(d.grid(3, 0), 7);   // parallelogram 0 + 10 - 4 = 6, zigzag 2 = +1
    // The same face through an escape (rank 1) to index zigzag(0) relative to 3 seen.
    EXPECT_EQ(mm::decode(cd::join(v2, payload({3, 1}, {1}, {0, 0, 0, 0}, 0, 4), 0), "esc").mesh.faces,
              d.mesh.faces);
    // Rank 2: vertex 0's most recent known neighbour, 2 (the decoder does not judge geometry).
    EXPECT_EQ(mm::decode(cd::join(v2, payload({3, 1}, {2}, {0, 0, 0}, 0, 4), 0), "r2").mesh.faces[1],
              (std::vector<int>{1, 0, 2}));
    EXPECT_REJECTED_WITH(cd::join(v2, payload({3, 1}, {9}, {0, 0, 0}, 0, 4), 0),
                         "neighbour rank 9 but vertex 1 has 2 known neighbours");
    // Relative index out of range: zigzag 7 = -4 from 0.
    EXPECT_REJECTED_WITH(cd::join(v2, payload({3, 1}, {0}, {7, 0, 0}, 0, 4), 0),
                         "vertex index -4 outside [0, 3]");
    // A new vertex when every vertex is already used.
    cd::Header v3 = v2;
    v3.vertices = 3;
    EXPECT_REJECTED_WITH(cd::join(v3, payload({3, 1}, {0}, {0, 0, 0}, 0, 3), 0), "all 3 are used");
    // The same plain indices under version 1 mean vertex 0 three times.
    cd::Header v1 = v2;
    v1.version = 1;
    v1.flags = 2 << cd::kPredictionShift;
    EXPECT_REJECTED_WITH(cd::join(v1, payload({3, 1}, {0}, {0, 0, 0, 0}, 0, 4), 0),
                         "repeats a vertex");
  }
  {
    cd::Header hc = h;
    hc.creases = 1;
    hc.corners = 1;
    auto raw = payload({4}, {}, {0, 1, 2, 3}, 0x01, 4);
    const size_t corner_at = raw.size() - 6;  // before the coordinate section
    raw.insert(raw.begin() + corner_at, 0x04);  // corner gap 4 -> index 4, out of range
    EXPECT_REJECTED_WITH(cd::join(hc, raw, 0), "corner index 4 out of range");
    raw[corner_at] = 0x03;
    const auto d = mm::decode(cd::join(hc, raw, 0), "hand");
    EXPECT_EQ(d.mesh.corners, std::vector<int>{3});
    EXPECT_EQ(d.mesh.creases, (std::vector<std::pair<int, int>>{{0, 1}}));  // first sorted edge
  }
  {
    cd::Header hm = h;
    hm.metadata_entries = 2;
    auto raw = good;
    for (int b : {1, 98, 1, 120, 1, 97, 1, 121}) raw.push_back(static_cast<std::uint8_t>(b));
    EXPECT_REJECTED_WITH(cd::join(hm, raw, 0), "not strictly increasing");
    raw = good;
    for (int b : {1, 32, 0, 1, 98, 0}) raw.push_back(static_cast<std::uint8_t>(b));
    EXPECT_REJECTED_WITH(cd::join(hm, raw, 0), "invalid metadata key");
  }
}

TEST(StreamHostile, DecompressionBombIsRefusedBeforeAllocation) {
  // A payload of zeros is valid (a million vertices at one spot), but it compresses far beyond
  // any real control polyhedron, so the ratio limit refuses it before allocating.
  cd::Header h;
  h.flags = 1 << cd::kPredictionShift;  // deltas from the previous vertex
  h.vertices = 1u << 20;
  // Empty face streams, Rice parameters 0, then one zero bit per coordinate.
  std::vector<std::uint8_t> raw = {0, 0, 0, 0, 0, 0};
  const std::size_t bit_bytes = 3u * h.vertices / 8;
  for (std::size_t v = bit_bytes; v; v >>= 7) raw.push_back(static_cast<std::uint8_t>((v & 0x7F) | (v >> 7 ? 0x80 : 0)));
  raw.resize(raw.size() + bit_bytes, 0);
  const auto s = cd::join(h, raw, 3);
  ASSERT_LT(s.size() * cd::kMaxExpansion, raw.size());
  EXPECT_REJECTED_WITH(s, "expands beyond the allowed ratio");
  // The same content stored uncompressed is legitimate: memory follows the bytes present.
  const auto d = mm::decode(cd::join(h, raw, 0), "stored");
  EXPECT_EQ(d.mesh.num_vertices(), static_cast<int>(h.vertices));
}

TEST(StreamHostile, NotAZstdFrame) {
  const auto s = valid_stream();
  const cd::Parts parts = cd::split(s.data(), s.size(), "valid");
  auto t = cd::join(parts.header, parts.raw, 19);
  ASSERT_TRUE(parts.header.flags & cd::kFlagZstd || t.size() > 0);
  cd::Header h = parts.header;
  h.flags |= cd::kFlagZstd;
  // Stored payload bytes under a zstd flag: join with level 0 clears the flag, so set it by hand.
  auto stored = cd::join(h, parts.raw, 0);
  stored[5] |= cd::kFlagZstd;
  reseal(stored);
  EXPECT_REJECTED_WITH(stored, "zstd");
}

TEST(StreamHostile, SeededFuzzNeverCrashes) {
  // Three kinds of damage, 20k mutants in all: raw byte damage (mostly caught by the CRC),
  // damage with the CRC recomputed (reaches the header and frame checks), and damage to the
  // decompressed payload re-wrapped in a valid frame and CRC (reaches the payload checks).
  mm::CodecParams v2;
  v2.format_version = 2;
  mm::CodecParams v4;
  v4.quant_bits = 7;
  std::vector<std::vector<std::uint8_t>> seeds = {valid_stream(), mm::encode(mm::test::crease_cube(), v2),
                                                  valid_stream_v3(), mm::encode(mm::test::crease_cube()),
                                                  mm::encode(mm::test::wavy_grid(9, 7, 5), v4)};
  if (mm::test::shared_meshes_present()) {
    mm::CodecParams p;
    p.quant_bits = 16;
    seeds.push_back(mm::encode(mm::read_mesh(mm::test::shared_mesh("chamfer-cube.off")), p));
    p.format_version = 2;
    seeds.push_back(mm::encode(mm::read_mesh(mm::test::shared_mesh("chamfer-cube.off")), p));
  }
  std::mt19937_64 rng(20261122);
  int decoded = 0, rejected = 0;
  // MM_CODEC_FUZZ_ITERATIONS runs a longer campaign by hand (same seed, same mutants first).
  const char* env = std::getenv("MM_CODEC_FUZZ_ITERATIONS");
  const int iterations = env ? std::max(1, std::atoi(env)) : 20000;
  for (int it = 0; it < iterations; ++it) {
    const auto& seed = seeds[it % seeds.size()];
    const int kind = it % 3;
    std::vector<std::uint8_t> t;
    auto mutate = [&](std::vector<std::uint8_t>& b) {
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits && !b.empty(); ++e) {
        const size_t pos = rng() % b.size();
        switch (rng() % 5) {
          case 0: b[pos] ^= static_cast<std::uint8_t>(1u << (rng() % 8)); break;
          case 1: b[pos] = static_cast<std::uint8_t>(rng()); break;
          case 2: b.erase(b.begin() + pos); break;
          case 3: b.insert(b.begin() + pos, static_cast<std::uint8_t>(rng())); break;
          default: b[pos] = (rng() & 1) ? 0xFF : 0x00; break;
        }
      }
    };
    if (kind == 0) {
      t = seed;
      mutate(t);
    } else if (kind == 1) {
      t = seed;
      mutate(t);
      reseal(t);
    } else if (seed[4] >= 3) {
      // Versions 3 and 4: damage the range-coded body (or the header varints) and reseal.
      t = seed;
      std::vector<std::uint8_t> tail(t.begin() + 6, t.end() - 4);
      mutate(tail);
      t.resize(6);
      t.insert(t.end(), tail.begin(), tail.end());
      t.resize(t.size() + 4);
      reseal(t);
    } else {
      cd::Parts parts = cd::split(seed.data(), seed.size(), "seed");
      mutate(parts.raw);
      if (rng() % 4 == 0) parts.header.faces += static_cast<std::uint32_t>(rng() % 3) - 1;
      t = cd::join(parts.header, parts.raw, (rng() & 1) ? 19 : 0);
    }
    try {
      const mm::DecodedStream d = mm::decode(t, "fuzz");
      expect_consistent(d);
      ++decoded;
    } catch (const mm::InputError&) {
      ++rejected;
    }
  }
  std::cout << "fuzz: " << iterations << " mutants, " << rejected << " rejected, " << decoded
            << " decoded consistently\n";
  EXPECT_EQ(decoded + rejected, iterations);
  EXPECT_GT(rejected, iterations / 2);
  EXPECT_GT(decoded, 0);  // some mutants stay valid: the fuzz also reaches the accepting paths
}
