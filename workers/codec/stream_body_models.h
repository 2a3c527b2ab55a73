// Internal to the codec: the range coder's integer codes, the body reader and the face
// traversal's models and sink/source, shared by the stream body's encoder and decoder
// (stream_v3.cpp). Not part of the codec's interface.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <string>

#include "codec/bytes.h"
#include "codec/connectivity.h"
#include "codec/range_coder.h"
#include "meshio/mesh.h"

namespace mm::codec_detail {

// ---------------------------------------------------------------------------------------------
// Integer codes over the range coder, shared by encoder and decoder.

// Exp-Golomb over adaptive bits: for u, let v = u + 1 with n + 1 significant bits; n is sent in
// unary (n one-bits then a zero, each with its own model per position), then the n bits of v
// below its leading one, most significant first: the first two with models per (n, position),
// the rest as plain bits.
constexpr int kMaxEgBits = 32;
struct EgModels {
  std::array<BitModel, kMaxEgBits + 1> unary{};
  std::array<std::array<BitModel, 2>, kMaxEgBits + 1> top{};
};

// `Coder`: RangeEncoder, or CostCounter (below) to price a decision without coding it.
template <class Coder>
void put_eg(Coder& rc, EgModels& m, std::uint64_t u) {
  const std::uint64_t v = u + 1;
  int n = 0;
  while ((v >> (n + 1)) != 0) ++n;
  for (int i = 0; i < n; ++i) rc.bit(m.unary[i], 1);
  rc.bit(m.unary[n], 0);
  for (int j = n - 1; j >= 0; --j) {
    const int b = static_cast<int>((v >> j) & 1);
    if (n - 1 - j < 2) rc.bit(m.top[n][n - 1 - j], b);
    else rc.bits(static_cast<std::uint32_t>(b), 1);
  }
}

// Prices decisions under the models' current state without adapting them: what the encoder's
// rate-distortion snapping weighs candidate values with.
struct CostCounter {
  std::uint64_t cost = 0;  // 1/256 bits
  void bit(const BitModel& m, int b) { cost += bit_cost_256(m, b); }
  void bits(std::uint32_t, int count) { cost += 256u * static_cast<std::uint64_t>(count); }
};

// Body decoder with the checks every read needs: unary lengths and values against their bounds.
class BodyReader {
 public:
  BodyReader(const std::uint8_t* data, std::size_t size, const std::string& source)
      : rc(data, size), source_(source) {}
  [[noreturn]] void fail(const std::string& reason) const { throw InputError(source_, reason); }
  int bit(BitModel& m) { return rc.bit(m); }
  std::uint32_t bits(int count) { return rc.bits(count); }
  std::uint64_t eg(EgModels& m, std::uint64_t max, const char* what) {
    int n = 0;
    while (rc.bit(m.unary[n])) {
      if (++n > kMaxEgBits) fail(std::string("overlong code for ") + what);
    }
    std::uint64_t v = 1;
    for (int j = n - 1; j >= 0; --j) {
      const int b = (n - 1 - j < 2) ? rc.bit(m.top[n][n - 1 - j]) : static_cast<int>(rc.bits(1));
      v = (v << 1) | static_cast<std::uint64_t>(b);
    }
    const std::uint64_t u = v - 1;
    if (u > max) fail(std::string(what) + " " + std::to_string(u) + " exceeds the limit " + std::to_string(max));
    return u;
  }
  RangeDecoder rc;

 private:
  const std::string& source_;
};

// ---------------------------------------------------------------------------------------------
// Faces: the traversal's decisions with context models.

struct FaceModels {
  BitModel start_quad;
  EgModels index;
  std::array<std::array<BitModel, 3>, 2> across{};  // [gate from a quad][previous symbol]
  std::array<BitModel, 2> quad{};                  // [gate from a quad]
  std::array<std::array<std::array<BitModel, 4>, 5>, 2> fresh{};  // [second][hint kind][degrees]
  std::array<std::array<BitModel, 2>, 5> hinted{};  // is the anchor's hint [hint kind][second]
  std::array<std::array<BitModel, 2>, 5> hinted_other{};  // is the other's hint
  std::array<BitModel, 2> escape{};
  BitModel other_side;
  std::array<EgModels, 2> neighbour{};  // [other side]
  EgModels escape_code;
};

inline int degree_context(const RankContext& c) { return std::min((c.anchor_degree + c.other_degree) / 3, 3); }

class RangeFaceSink : public FaceSink {
 public:
  RangeFaceSink(RangeEncoder& rc, FaceModels& m) : rc_(rc), m_(m) {}
  void start(int size) override { rc_.bit(m_.start_quad, size == 4); }
  void index(std::uint64_t code) override { put_eg(rc_, m_.index, code); }
  void symbol(int s, const GateContext& c) override {
    const int q = c.from_size == 4;
    rc_.bit(m_.across[q][c.previous], s != 0);
    if (s != 0) rc_.bit(m_.quad[q], s == 2);
  }
  void rank(std::uint64_t r, const RankContext& c) override {
    if (c.fresh_possible) rc_.bit(m_.fresh[c.second][c.hint_kind][degree_context(c)], r != 0);
    if (r == 0) return;
    if (c.hint_kind != 0 && c.hint_kind != 4) {
      rc_.bit(m_.hinted[c.hint_kind][c.second], r != c.hint_anchor);
      if (r == c.hint_anchor) return;
    }
    if (c.hint_kind == 2 || c.hint_kind == 4) {
      rc_.bit(m_.hinted_other[c.hint_kind][c.second], r != c.hint_other);
      if (r == c.hint_other) return;
    }
    rc_.bit(m_.escape[c.second], r == 1);
    if (r == 1) return;
    const int side = static_cast<int>(r % 2);  // 1: the other gate vertex's list
    rc_.bit(m_.other_side, side);
    put_eg(rc_, m_.neighbour[side], (r - 2) / 2);
  }
  void escape(std::uint64_t code) override { put_eg(rc_, m_.escape_code, code); }

 private:
  RangeEncoder& rc_;
  FaceModels& m_;
};

class RangeFaceSource : public FaceSource {
 public:
  RangeFaceSource(BodyReader& in, FaceModels& m) : in_(in), m_(m) {}
  int start() override { return in_.bit(m_.start_quad) ? 4 : 3; }
  std::uint64_t index(std::uint64_t max) override { return in_.eg(m_.index, max, "vertex index offset"); }
  int symbol(const GateContext& c) override {
    const int q = c.from_size == 4;
    if (!in_.bit(m_.across[q][c.previous])) return 0;
    return in_.bit(m_.quad[q]) ? 2 : 1;
  }
  std::uint64_t rank(const RankContext& c) override {
    // Without an unseen vertex left, rank 0 is impossible and not coded.
    if (c.fresh_possible && !in_.bit(m_.fresh[c.second][c.hint_kind][degree_context(c)])) return 0;
    if (c.hint_kind != 0 && c.hint_kind != 4 && !in_.bit(m_.hinted[c.hint_kind][c.second])) return c.hint_anchor;
    if ((c.hint_kind == 2 || c.hint_kind == 4) && !in_.bit(m_.hinted_other[c.hint_kind][c.second]))
      return c.hint_other;
    if (in_.bit(m_.escape[c.second])) return 1;
    const int side = in_.bit(m_.other_side);
    // A list holds at most every vertex; the caller checks the rank against the actual list.
    const std::uint64_t k = in_.eg(m_.neighbour[side], kMaxStreamVertices, "neighbour rank");
    return 2 + 2 * k + static_cast<std::uint64_t>(side);
  }
  std::uint64_t escape(std::uint64_t max) override { return in_.eg(m_.escape_code, max, "escape code"); }
  [[noreturn]] void fail(const std::string& reason) override { in_.fail("faces: " + reason); }

 private:
  BodyReader& in_;
  FaceModels& m_;
};


}  // namespace mm::codec_detail
