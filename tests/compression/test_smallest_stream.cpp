// smallest_stream(): the stream compress writes. Fitted control polyhedra of a sample part (no
// shared meshes needed); every claim is checked by decoding the returned bytes and measuring.
#include <gtest/gtest.h>

#include "codec/stream.h"
#include "fitting/compress.h"
#include "compression/smallest_stream.h"
#include "samples/samples.h"

namespace {

struct Fixture {
  mm::Mesh part;
  mm::CompressResult fit;
};

const Fixture& block() {
  static const Fixture f = [] {
    Fixture x;
    x.part = mm::samples::sample_parts().at(0).mesh;
    mm::CompressOptions o;
    o.verify = [&x, &o](const mm::Mesh& c) {
      return mm::decoded_distance(x.part, c, 3).hausdorff_relative() <= o.tolerance;
    };
    x.fit = mm::compress(x.part, o);
    return x;
  }();
  return f;
}

mm::SurfaceDistance measured(const Fixture& f, const mm::ChosenStream& s) {
  return mm::decoded_distance(f.part, mm::decode(s.bytes, "t").mesh, f.fit.levels);
}

mm::StreamSearch search_for(const Fixture& f) {
  mm::StreamSearch s;
  s.levels = f.fit.levels;
  s.metadata["levels"] = std::to_string(f.fit.levels);
  return s;
}

// compress --fast's search.
mm::StreamSearch quick_search_for(const Fixture& f) {
  mm::StreamSearch s = search_for(f);
  s.quick = true;
  return s;
}

// The fit's polyhedron stretched by a fifth along z: off the tolerance at any bits.
mm::Mesh off_the_part(const Fixture& f) {
  mm::Mesh off = f.fit.control;
  off.points.col(2) *= 1.2;
  return off;
}

}  // namespace

// A polyhedron pushed off the part misses the tolerance at every bits; the good one after it
// is chosen, and what is returned is what its bytes decode to.
TEST(SmallestStream, SkipsPolyhedraThatMissAndReportsTheDecodedDistance) {
  const Fixture& f = block();
  ASSERT_TRUE(f.fit.tolerance_met);
  const mm::Mesh off = off_the_part(f);
  const mm::ChosenStream s = mm::smallest_stream(f.part, {&off, &f.fit.control}, search_for(f), "t");
  EXPECT_TRUE(s.meets);
  EXPECT_EQ(s.polyhedron, 1);
  EXPECT_LE(s.distance.hausdorff_relative(), 0.005);
  EXPECT_EQ(measured(f, s).hausdorff, s.distance.hausdorff);
  EXPECT_LE(s.bytes.size(), s.unsnapped_bytes);
}

// Nothing meets: the first polyhedron at its conservative bits, marked as missing.
TEST(SmallestStream, NothingMeetsGivesTheFirstAtItsConservativeBits) {
  const Fixture& f = block();
  const mm::Mesh off = off_the_part(f);
  const mm::ChosenStream s = mm::smallest_stream(f.part, {&off}, search_for(f), "t");
  EXPECT_FALSE(s.meets);
  EXPECT_EQ(s.bits, mm::conservative_bits(off, 0.005));
  EXPECT_FALSE(s.snapped);
  EXPECT_GT(measured(f, s).hausdorff_relative(), 0.005);
  EXPECT_THROW(mm::smallest_stream(f.part, {}, search_for(f), "t"), std::invalid_argument);
}

// A polyhedron within the tolerance by a hair misses it at its conservative bits; finer grids
// are tried rather than writing a stream off the tolerance. (The polyhedron is the fit's, flattened
// by half a per cent: the block's fit itself is within 1e-5 of the diagonal, where no grid of
// up to 24 bits is fine enough for a tolerance a hair above that. Pushed up instead, by 0.1-2 %,
// a coarser grid than the conservative one happened to meet the tolerance every time.)
TEST(SmallestStream, ABarelyFittingPolyhedronGetsFinerBitsRatherThanMissing) {
  const Fixture& f = block();
  mm::Mesh pushed = f.fit.control;
  pushed.points.col(2) *= 0.995;
  mm::StreamSearch search = search_for(f);
  const double exact = mm::decoded_distance(f.part, pushed, f.fit.levels).hausdorff_relative();
  ASSERT_GT(exact, 1e-4);
  search.tolerance = exact * 1.0002;
  const int bound = mm::conservative_bits(pushed, search.tolerance);
  mm::CodecParams at_bound;
  at_bound.quant_bits = bound;
  const mm::Mesh coarse = mm::decode(mm::encode(pushed, at_bound), "t").mesh;
  ASSERT_GT(mm::decoded_distance(f.part, coarse, f.fit.levels).hausdorff_relative(), search.tolerance)
      << "the conservative bits must miss for this test to mean anything";
  const mm::ChosenStream s = mm::smallest_stream(f.part, {&pushed}, search, "t");
  EXPECT_TRUE(s.meets);
  EXPECT_GT(s.bits, bound);
  EXPECT_LE(measured(f, s).hausdorff_relative(), search.tolerance);
}

// Given bits are used as they are, unsnapped: the bytes are the plain encoding at those bits.
// Without them the search goes no higher than the conservative bits, and snapping never makes
// the stream larger than the plain one it starts from.
TEST(SmallestStream, GivenBitsAndSnapping) {
  const Fixture& f = block();
  mm::StreamSearch fixed = search_for(f);
  fixed.bits = 14;
  const mm::ChosenStream s = mm::smallest_stream(f.part, {&f.fit.control}, fixed, "t");
  mm::CodecParams p;
  p.quant_bits = 14;
  p.metadata = fixed.metadata;
  EXPECT_EQ(s.bytes, mm::encode(f.fit.control, p));
  EXPECT_FALSE(s.snapped);

  mm::StreamSearch plain = search_for(f), snapping = search_for(f);
  plain.snap = false;
  const mm::ChosenStream a = mm::smallest_stream(f.part, {&f.fit.control}, plain, "t");
  const mm::ChosenStream b = mm::smallest_stream(f.part, {&f.fit.control}, snapping, "t");
  EXPECT_FALSE(a.snapped);
  EXPECT_EQ(a.bytes.size(), a.unsnapped_bytes);
  EXPECT_LE(a.bits, mm::conservative_bits(f.fit.control, 0.005));
  EXPECT_TRUE(a.meets && b.meets);
  EXPECT_LE(b.bytes.size(), a.bytes.size());
  EXPECT_EQ(b.unsnapped_bytes, a.bytes.size());
  EXPECT_LE(measured(f, b).hausdorff_relative(), 0.005);
  // The numbers reported are the written stream's, whichever step measured it.
  for (const mm::ChosenStream* c : {&a, &b}) {
    const mm::SurfaceDistance d = measured(f, *c);
    EXPECT_EQ(d.hausdorff, c->distance.hausdorff);
    EXPECT_EQ(d.rms, c->distance.rms);
    EXPECT_EQ(d.mean, c->distance.mean);
  }
  // Deterministic.
  EXPECT_EQ(mm::smallest_stream(f.part, {&f.fit.control}, snapping, "t").bytes, b.bytes);
}

// The written stream is numbered from the start vertex that codes it smallest among those tried
// (64 evenly spaced): no other start gives fewer bytes for the same grid values, and the
// distance reported is the written stream's.
TEST(SmallestStream, TheCheapestNumberingStartIsWritten) {
  const Fixture& f = block();
  mm::StreamSearch plain = search_for(f);
  plain.snap = false;
  const mm::ChosenStream s = mm::smallest_stream(f.part, {&f.fit.control}, plain, "t");
  ASSERT_TRUE(s.meets);
  mm::CodecParams p;
  p.quant_bits = s.bits;
  p.metadata = plain.metadata;
  // Unsnapped, the stream before the start search is the polyhedron's plain encoding.
  const mm::DecodedStream first = mm::decode(mm::encode(f.fit.control, p), "t");
  const int n = first.mesh.num_vertices(), starts = std::min(n, 64);
  for (int k = 0; k < starts; ++k)
    EXPECT_LE(s.bytes.size(), mm::encode(mm::in_traversal_order(first.mesh, k * n / starts), p).size()) << k;
  EXPECT_LT(s.bytes.size(), mm::encode(f.fit.control, p).size()) << "the sample part's first numbering is not its cheapest";
  EXPECT_EQ(measured(f, s).hausdorff, s.distance.hausdorff);
}

// compress --fast: the first polyhedron at the fewest bits, from 6 up, whose nearest grid values
// meet the tolerance (each lower bits' stream measured here misses it), encoded as it is (its
// own numbering, nothing snapped), checked rather than measured. The others are not looked at.
TEST(SmallestStream, QuickWritesTheFewestBitsNearestValuesUnmeasured) {
  const Fixture& f = block();
  const mm::StreamSearch quick = quick_search_for(f);
  const mm::Mesh off = off_the_part(f);
  const mm::ChosenStream s = mm::smallest_stream(f.part, {&f.fit.control, &off}, quick, "t");
  EXPECT_TRUE(s.meets);
  EXPECT_FALSE(s.measured);
  EXPECT_FALSE(s.snapped || s.descended);
  EXPECT_EQ(s.polyhedron, 0);
  EXPECT_LE(measured(f, s).hausdorff_relative(), quick.tolerance);
  mm::CodecParams p;
  p.metadata = quick.metadata;
  p.quant_bits = s.bits;
  EXPECT_EQ(s.bytes, mm::encode(f.fit.control, p));
  EXPECT_EQ(s.unsnapped_bytes, s.bytes.size());
  ASSERT_GT(s.bits, mm::kMinQuantBits) << "the sample part meets the tolerance at 6 bits: nothing below to check";
  for (int b = mm::kMinQuantBits; b < s.bits; ++b) {
    p.quant_bits = b;
    EXPECT_GT(mm::decoded_distance(f.part, mm::decode(mm::encode(f.fit.control, p), "t").mesh, f.fit.levels)
                  .hausdorff_relative(),
              quick.tolerance)
        << b << " bits";
  }
  EXPECT_EQ(mm::smallest_stream(f.part, {&f.fit.control}, quick, "t").bytes, s.bytes);  // deterministic
  // The search proper writes no larger a stream.
  EXPECT_LE(mm::smallest_stream(f.part, {&f.fit.control}, search_for(f), "t").bytes.size(), s.bytes.size());
}

// Where it misses the tolerance, the quick stream is measured after all (the report says by how
// much); within it by a hair, it gets finer grids as the search does; an RMS bound needs the
// numbers, so they are measured and reported.
TEST(SmallestStream, QuickMeasuresAMissAndAnRmsBound) {
  const Fixture& f = block();
  const mm::StreamSearch quick = quick_search_for(f);
  const mm::Mesh off = off_the_part(f);
  const mm::ChosenStream missed = mm::smallest_stream(f.part, {&off}, quick, "t");
  EXPECT_FALSE(missed.meets);
  EXPECT_TRUE(missed.measured);
  EXPECT_EQ(missed.bits, mm::conservative_bits(off, quick.tolerance));
  EXPECT_EQ(measured(f, missed).hausdorff, missed.distance.hausdorff);
  EXPECT_GT(missed.distance.hausdorff_relative(), quick.tolerance);

  mm::Mesh pushed = f.fit.control;
  pushed.points.col(2) *= 0.995;
  mm::StreamSearch hair = quick;
  hair.tolerance = mm::decoded_distance(f.part, pushed, f.fit.levels).hausdorff_relative() * 1.0002;
  const mm::ChosenStream fine = mm::smallest_stream(f.part, {&pushed}, hair, "t");
  EXPECT_TRUE(fine.meets);
  EXPECT_FALSE(fine.measured);
  EXPECT_GT(fine.bits, mm::conservative_bits(pushed, hair.tolerance));
  EXPECT_LE(measured(f, fine).hausdorff_relative(), hair.tolerance);

  mm::StreamSearch rms = quick;
  rms.rms_tolerance = 0.001;
  const mm::ChosenStream r = mm::smallest_stream(f.part, {&f.fit.control}, rms, "t");
  EXPECT_TRUE(r.meets);
  EXPECT_TRUE(r.measured);
  const mm::SurfaceDistance d = measured(f, r);
  EXPECT_EQ(d.hausdorff, r.distance.hausdorff);
  EXPECT_EQ(d.rms, r.distance.rms);
  EXPECT_LE(d.rms_relative(), 0.001);
}
